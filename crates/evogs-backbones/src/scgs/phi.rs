//! EvoGS(SC-GS)'s Φ: SC-GS's control points and skinning as EvoGS's observation network
//! (`--method evogs --backbone scgs`), with the evolution state on every Gaussian, as the paper
//! words it (DESIGN §5.2d).
//!
//! `z = Φ(x, t)` is the skinned row of the Gaussian at canonical mean `x` ([`super::skinning`]),
//! in the evolution layout's columns (position, rotation, scale, or a subset: SC-GS deforms no
//! opacity or colour); the ARAP loss on the control points is Φ's regulariser. The control points
//! are placed as the baseline's ([`Observer::initialise`]). Φ observes one time per call (the
//! evolution asks for one time at once, the step's or a history frame's).

use tiny_nn::{DeformCache, Parameters, StoreMut, StoreRef};

use super::knn::{self, Neighbours};
use super::skinning::{self, ROW};
use super::{ScgsParams, ScgsSettings, arap_partner, evolved_columns};
use crate::error::BackboneError;
use crate::evo_settings::EvoSettings;
use crate::observer::Observer;

/// EvoGS(SC-GS)'s Φ (module docs).
pub struct ScgsPhi {
    settings: ScgsSettings,
    seed: u64,
    params: ScgsParams,
    /// Columns of the skinned row that the evolution layout keeps, in its order.
    columns: Vec<usize>,
}

/// What a forward of [`ScgsPhi`] keeps for its gradients.
#[derive(Default)]
pub struct ScgsPhiCache {
    time: f32,
    means: Vec<[f32; 3]>,
    neighbours: Neighbours,
    nodes: Vec<f32>,
    net: DeformCache,
}

impl ScgsPhi {
    /// Φ of SC-GS's `settings` for EvoGS's `evogs` (its components must be geometric), the
    /// control points spread over `[-h, h]³` until placed on the Gaussians.
    pub fn new(
        settings: &ScgsSettings,
        evogs: &EvoSettings,
        half_extent: f32,
        seed: u64,
    ) -> Result<Self, BackboneError> {
        let columns = evolved_columns(evogs.evo.layout)?;
        Ok(Self {
            settings: *settings,
            seed,
            params: ScgsParams::new(settings, half_extent, seed)?,
            columns,
        })
    }

    fn learns_positions(&self) -> bool {
        self.settings.position_lr_scale > 0.0
    }
}

impl Parameters for ScgsPhi {
    fn named_params(&self) -> Vec<(String, StoreRef<'_>)> {
        self.params.named_params()
    }

    fn named_params_mut(&mut self) -> Vec<(String, StoreMut<'_>)> {
        self.params.named_params_mut()
    }
}

impl Observer for ScgsPhi {
    type Cache = ScgsPhiCache;

    fn output_width(&self) -> usize {
        self.columns.len()
    }

    fn observe_into(
        &self,
        positions: &[f32],
        times: &[f32],
        rows: usize,
        cache: &mut ScgsPhiCache,
    ) -> Result<Vec<f32>, BackboneError> {
        if positions.len() != rows * 3 || times.len() != rows {
            return Err(BackboneError::config(
                "scgs",
                format!(
                    "Φ: {} positions and {} times for {rows} rows",
                    positions.len(),
                    times.len()
                ),
            ));
        }
        let time = times.first().copied().unwrap_or(0.0);
        if times.iter().any(|t| t.to_bits() != time.to_bits()) {
            return Err(BackboneError::config(
                "scgs",
                "SC-GS's Φ observes one time per call",
            ));
        }
        cache.time = time;
        cache.means.clear();
        cache
            .means
            .extend(positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
        cache.neighbours = knn::nearest(
            &self.params.positions,
            &cache.means,
            self.settings.neighbours,
        )?;
        cache.nodes = self.params.node_outputs(time, &mut cache.net)?;
        let mut full = Vec::new();
        skinning::skin_into(
            &cache.means,
            &cache.neighbours,
            self.params.controls(),
            &cache.nodes,
            &mut full,
        );
        if self.columns.len() == ROW {
            return Ok(full);
        }
        Ok(full
            .chunks_exact(ROW)
            .flat_map(|r| self.columns.iter().map(move |&c| r[c]))
            .collect())
    }

    fn gradients(&self, cache: &ScgsPhiCache, dz: &[f32]) -> Result<Vec<Vec<f32>>, BackboneError> {
        let d = self.columns.len();
        if dz.len() != cache.means.len() * d {
            return Err(BackboneError::config(
                "scgs",
                format!(
                    "Φ: {} gradients for {} rows of {d}",
                    dz.len(),
                    cache.means.len()
                ),
            ));
        }
        let mut d_rows = vec![0f32; cache.means.len() * ROW];
        for (row, g) in d_rows.chunks_exact_mut(ROW).zip(dz.chunks_exact(d)) {
            for (&c, &v) in self.columns.iter().zip(g) {
                row[c] = v;
            }
        }
        self.params.gradients(
            &cache.means,
            &cache.neighbours,
            &cache.nodes,
            &cache.net,
            &d_rows,
            self.learns_positions(),
        )
    }

    /// SC-GS's ARAP loss on the control points between the forward's time and its partner.
    fn regularise(
        &mut self,
        cache: &ScgsPhiCache,
        grads: &mut [Vec<f32>],
    ) -> Result<f64, BackboneError> {
        self.params.add_arap(
            self.settings.arap_weight,
            arap_partner(self.seed, cache.time),
            &cache.nodes,
            &cache.net,
            self.learns_positions(),
            grads,
        )
    }

    fn lr_scale(&self, name: &str, _grid_lr_scale: f32) -> f32 {
        super::position_lr_scale(name, &self.settings)
    }

    fn initialise(&mut self, means: &[[f32; 3]]) -> Result<(), BackboneError> {
        self.params.place(means, self.seed);
        Ok(())
    }

    fn gaussians_changed(&mut self, means: &[[f32; 3]]) -> Result<(), BackboneError> {
        if self.settings.follow_densify {
            self.params.follow(
                means,
                self.seed,
                self.settings.placement,
                self.settings.neighbours,
            )?;
        }
        Ok(())
    }

    fn control_points_at(&mut self, time: f32) -> Result<Option<Vec<[f32; 3]>>, BackboneError> {
        self.params.controls_at(time).map(Some)
    }
}
