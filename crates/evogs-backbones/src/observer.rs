//! EvoGS's observation network Φ as an interface: what [`crate::EvoBackbone`] needs of the field
//! it wraps, so that a backbone's deformation field can be Φ.
//!
//! Two implementations: EvoGS(D-3DGS)'s tri-plane + B-spline + MLP ([`tiny_nn::ObservationNet`],
//! the paper's Φ) and EvoGS(Grid4D)'s hash-grid field
//! ([`crate::grid4d_phi::Grid4dPhi`]). Parameter buffers are Φ's [`Parameters`]; the
//! evolution backbone prefixes them with `phi.`.

use tiny_nn::{LrSchedule, ObservationCache, ObservationNet, Parameters};

use crate::error::BackboneError;

/// The observation network Φ of EvoGS: `z = Φ(canonical mean, t)`, N × D rows in the evolution
/// layout's column order.
pub trait Observer: Parameters + Send {
    /// What a forward keeps for its backward.
    type Cache: Default + Send;

    /// Values per row (the evolution layout's D).
    fn output_width(&self) -> usize;

    /// Observations of `rows` points (`positions` rows × 3, one time per row) into `cache`
    /// (its memory reused).
    fn observe_into(
        &self,
        positions: &[f32],
        times: &[f32],
        rows: usize,
        cache: &mut Self::Cache,
    ) -> Result<Vec<f32>, BackboneError>;

    /// Observations with a fresh cache.
    fn observe(
        &self,
        positions: &[f32],
        times: &[f32],
        rows: usize,
    ) -> Result<(Vec<f32>, Self::Cache), BackboneError> {
        let mut cache = Self::Cache::default();
        let z = self.observe_into(positions, times, rows, &mut cache)?;
        Ok((z, cache))
    }

    /// Parameter gradients (one buffer per [`Parameters`] entry, same order) from dL/dz of a
    /// forward; no gradient to the positions.
    fn gradients(&self, cache: &Self::Cache, dz: &[f32]) -> Result<Vec<Vec<f32>>, BackboneError>;

    /// Φ's own regulariser on the training forward `cache`: adds its gradient to `grads`, returns
    /// its weighted value (none for the tri-plane Φ).
    fn regularise(
        &mut self,
        _cache: &Self::Cache,
        _grads: &mut [Vec<f32>],
    ) -> Result<f64, BackboneError> {
        Ok(0.0)
    }

    /// Factor on the network schedule for the buffer `name` (without `phi.`), given EvoGS's
    /// `grid_lr_scale`.
    fn lr_scale(&self, name: &str, grid_lr_scale: f32) -> f32;

    /// A schedule of Φ's own for the buffer `name`, replacing the network schedule.
    fn own_schedule(&self, _name: &str) -> Option<LrSchedule> {
        None
    }

    /// Places what Φ derives from the canonical means (SC-GS's control points); the backbone's
    /// `Backbone::initialise`. Nothing by default.
    fn initialise(&mut self, _means: &[[f32; 3]]) -> Result<(), BackboneError> {
        Ok(())
    }

    /// After a densification changed the canonical means; the backbone's
    /// `Backbone::gaussians_changed`. Nothing by default.
    fn gaussians_changed(&mut self, _means: &[[f32; 3]]) -> Result<(), BackboneError> {
        Ok(())
    }

    /// The points that carry Φ's motion at `time` (SC-GS's control points); the backbone's
    /// `Backbone::control_points_at`. `None` by default.
    fn control_points_at(&mut self, _time: f32) -> Result<Option<Vec<[f32; 3]>>, BackboneError> {
        Ok(None)
    }
}

impl Observer for ObservationNet {
    type Cache = ObservationCache;

    fn output_width(&self) -> usize {
        self.mlp.output_width()
    }

    fn observe_into(
        &self,
        positions: &[f32],
        times: &[f32],
        rows: usize,
        cache: &mut ObservationCache,
    ) -> Result<Vec<f32>, BackboneError> {
        Ok(self.forward_into(positions, times, rows, cache)?)
    }

    fn gradients(
        &self,
        cache: &ObservationCache,
        dz: &[f32],
    ) -> Result<Vec<Vec<f32>>, BackboneError> {
        let g = self.backward(cache, dz, false)?;
        let flat: Vec<f32> = g
            .triplane
            .into_iter()
            .chain(g.bspline)
            .chain(g.mlp)
            .collect();
        let mut grads = Vec::new();
        let mut at = 0;
        for (name, buf) in self.named_params() {
            let part = flat.get(at..at + buf.len()).ok_or_else(|| {
                BackboneError::config("backbone", format!("Φ gradient too short at `{name}`"))
            })?;
            grads.push(part.to_vec());
            at += buf.len();
        }
        Ok(grads)
    }

    /// The tri-plane features and B-spline controls at `grid_lr_scale` (as grid-based fields
    /// train their grids), the decoder at 1.
    fn lr_scale(&self, name: &str, grid_lr_scale: f32) -> f32 {
        if name.starts_with("triplane") || name.starts_with("bspline") {
            grid_lr_scale
        } else {
            1.0
        }
    }
}
