//! The training state: canonical Gaussians and every per-Gaussian array that must stay aligned
//! with them (Adam moments of each parameter group, densification statistics, and the
//! backbone's own rows), plus the network's optimiser groups.
//!
//! Parameter groups follow 3DGS/D-3DGS (`training_setup`): `xyz`, `f_dc`, `f_rest`, `opacity`,
//! `scaling`, `rotation`, and one group per backbone buffer. The Gaussians keep SH coefficient-
//! major rows (`splat-raster`); the `f_dc` and `f_rest` groups are gathered from and scattered
//! back to them around each Adam step, so their moments are rows of 3 and `3·((deg+1)²−1)`.

use densify::{DensifyPlan, DensifyStats, Moments, PerGaussian, apply_plan};
use splat_raster::{Gaussians, Gradients};
use tiny_nn::adam::AdamGroup;
use tiny_nn::{Adam, ExponentialLr, GroupId, LrSchedule, StoreMut};

use crate::backbone::Backbone;
use crate::config::LrSettings;
use crate::error::TrainError;

/// Names of the per-Gaussian groups, in order, as 3DGS names them.
pub const GAUSSIAN_GROUPS: [&str; 6] = ["xyz", "f_dc", "f_rest", "opacity", "scaling", "rotation"];

/// Ids of the per-Gaussian Adam groups, in the order of [`GAUSSIAN_GROUPS`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GaussianGroups {
    /// Means.
    pub xyz: GroupId,
    /// SH DC (3 per Gaussian).
    pub f_dc: GroupId,
    /// Higher SH bands.
    pub f_rest: GroupId,
    /// Opacity logits.
    pub opacity: GroupId,
    /// Log-scales.
    pub scaling: GroupId,
    /// Quaternions.
    pub rotation: GroupId,
}

impl GaussianGroups {
    /// The ids in the order of [`GAUSSIAN_GROUPS`].
    pub fn all(&self) -> [GroupId; 6] {
        [
            self.xyz,
            self.f_dc,
            self.f_rest,
            self.opacity,
            self.scaling,
            self.rotation,
        ]
    }
}

/// Canonical Gaussians, their optimiser and statistics, and the network's optimiser groups.
#[derive(Clone, Debug)]
pub struct SceneState {
    /// Canonical Gaussians at the maximum SH degree.
    pub gaussians: Gaussians,
    /// SH bands in use (raised during training).
    pub active_sh: u32,
    /// Densification statistics.
    pub stats: DensifyStats,
    /// Adam over every group.
    pub adam: Adam,
    /// The per-Gaussian groups.
    pub groups: GaussianGroups,
    /// One group per backbone parameter buffer, in the backbone's order.
    pub net_groups: Vec<GroupId>,
}

/// Per-Gaussian lr schedules (3DGS `training_setup` with D-3DGS's `spatial_lr_scale`).
pub fn gaussian_schedules(lr: &LrSettings) -> [LrSchedule; 6] {
    let s = lr.spatial_lr_scale;
    [
        LrSchedule::Exponential(ExponentialLr {
            lr_init: lr.position_init * s,
            lr_final: lr.position_final * s,
            delay_steps: 0,
            delay_mult: lr.position_delay_mult,
            max_steps: lr.position_max_steps,
        }),
        LrSchedule::Constant(lr.feature),
        LrSchedule::Constant(lr.feature / 20.0),
        LrSchedule::Constant(lr.opacity),
        LrSchedule::Constant(lr.scaling * s),
        LrSchedule::Constant(lr.rotation),
    ]
}

/// The network's schedule (D-3DGS `DeformModel.train_setting`): `position_init · 5` decaying to
/// `position_final` (not scaled) over `deform_max_steps`.
pub fn network_schedule(lr: &LrSettings) -> LrSchedule {
    LrSchedule::Exponential(ExponentialLr {
        lr_init: lr.position_init * lr.spatial_lr_scale,
        lr_final: lr.position_final,
        delay_steps: 0,
        delay_mult: lr.position_delay_mult,
        max_steps: lr.deform_max_steps,
    })
}

fn rest_width(g: &Gaussians) -> usize {
    g.sh_stride() - 3
}

impl SceneState {
    /// A fresh state: zero moments and statistics, SH degree 0 active.
    pub fn new(
        gaussians: Gaussians,
        backbone: &dyn Backbone,
        lr: &LrSettings,
    ) -> Result<Self, TrainError> {
        let n = gaussians.len();
        let widths = [3, 3, rest_width(&gaussians), 1, 3, 4];
        let mut adam = Adam::new();
        let schedules = gaussian_schedules(lr);
        let mut ids = Vec::with_capacity(6);
        for ((name, w), schedule) in GAUSSIAN_GROUPS.iter().zip(widths).zip(schedules) {
            ids.push(adam.add_group(name, n * w, w.max(1), schedule)?);
        }
        let groups = GaussianGroups {
            xyz: ids[0],
            f_dc: ids[1],
            f_rest: ids[2],
            opacity: ids[3],
            scaling: ids[4],
            rotation: ids[5],
        };
        let mut net_groups = Vec::new();
        for (name, buf) in backbone.params() {
            net_groups.push(adam.add_group(
                &format!("net.{name}"),
                buf.len(),
                1,
                network_schedule(lr),
            )?);
        }
        Ok(Self {
            stats: DensifyStats::new(n),
            gaussians,
            active_sh: 0,
            adam,
            groups,
            net_groups,
        })
    }

    /// Number of Gaussians.
    pub fn len(&self) -> usize {
        self.gaussians.len()
    }

    /// True when there are no Gaussians.
    pub fn is_empty(&self) -> bool {
        self.gaussians.is_empty()
    }

    /// One Adam step of the per-Gaussian groups with the rasterizer's gradients, at the lr of
    /// `lr_step`. `skip_opacity` leaves the opacity group alone (an opacity reset replaced it
    /// this iteration, as 3DGS's `replace_tensor_to_optimizer` leaves it without gradient).
    pub fn step_gaussians(
        &mut self,
        grads: &Gradients,
        lr_step: i64,
        skip_opacity: bool,
    ) -> Result<(), TrainError> {
        let g = &mut self.gaussians;
        let stride = g.sh_stride();
        let rest = stride - 3;
        let ids = self.groups;
        let adam = &mut self.adam;
        adam.step(
            ids.xyz,
            lr_step,
            StoreMut::F32(g.means.as_flattened_mut()),
            grads.means.as_flattened(),
        )?;
        let (mut dc, mut dc_grad) = (Vec::new(), Vec::new());
        let (mut hi, mut hi_grad) = (Vec::new(), Vec::new());
        for (row, grow) in g.sh.chunks_exact(stride).zip(grads.sh.chunks_exact(stride)) {
            dc.extend_from_slice(&row[..3]);
            dc_grad.extend_from_slice(&grow[..3]);
            hi.extend_from_slice(&row[3..]);
            hi_grad.extend_from_slice(&grow[3..]);
        }
        adam.step(ids.f_dc, lr_step, StoreMut::F32(&mut dc), &dc_grad)?;
        adam.step(ids.f_rest, lr_step, StoreMut::F32(&mut hi), &hi_grad)?;
        for (i, row) in g.sh.chunks_exact_mut(stride).enumerate() {
            row[..3].copy_from_slice(&dc[i * 3..i * 3 + 3]);
            row[3..].copy_from_slice(&hi[i * rest..(i + 1) * rest]);
        }
        if !skip_opacity {
            adam.step(
                ids.opacity,
                lr_step,
                StoreMut::F32(&mut g.opacity_logits),
                &grads.opacity_logits,
            )?;
        }
        adam.step(
            ids.scaling,
            lr_step,
            StoreMut::F32(g.log_scales.as_flattened_mut()),
            grads.log_scales.as_flattened(),
        )?;
        adam.step(
            ids.rotation,
            lr_step,
            StoreMut::F32(g.rotations.as_flattened_mut()),
            grads.rotations.as_flattened(),
        )?;
        Ok(())
    }

    /// One Adam step of the backbone's buffers with their gradients, at the lr of `lr_step`.
    pub fn step_network(
        &mut self,
        backbone: &mut dyn Backbone,
        grads: &[Vec<f32>],
        lr_step: i64,
    ) -> Result<(), TrainError> {
        let params = backbone.params_mut();
        if params.len() != grads.len() || params.len() != self.net_groups.len() {
            return Err(TrainError::config(
                "backbone",
                format!(
                    "{} parameter buffers, {} gradients, {} optimiser groups",
                    params.len(),
                    grads.len(),
                    self.net_groups.len()
                ),
            ));
        }
        for (((_, p), g), &id) in params.into_iter().zip(grads).zip(&self.net_groups) {
            self.adam.step(id, lr_step, p, g)?;
        }
        Ok(())
    }

    /// Applies a densification plan to every per-Gaussian array through densify's one
    /// mechanism: the Gaussians, the moments of the six groups, the statistics and the
    /// backbone's rows.
    pub fn apply_plan(
        &mut self,
        plan: &DensifyPlan,
        backbone: &mut dyn Backbone,
    ) -> Result<(), TrainError> {
        let ids = self.groups.all();
        let mut taken: Vec<AdamGroup> = ids
            .iter()
            .map(|&id| {
                std::mem::replace(
                    self.adam.group_mut(id),
                    AdamGroup {
                        name: String::new(),
                        row_width: 1,
                        schedule: LrSchedule::Constant(0.0),
                        step: 0,
                        m: Vec::new(),
                        v: Vec::new(),
                    },
                )
            })
            .collect();
        let result = {
            let mut moments: Vec<Moments<'_>> = taken
                .iter_mut()
                .enumerate()
                .map(|(k, group)| Moments {
                    group,
                    // Only the opacity group (index 3) holds opacities.
                    opacity_column: (k == 3).then_some(0),
                })
                .collect();
            let mut arrays: Vec<&mut dyn PerGaussian> = vec![&mut self.gaussians, &mut self.stats];
            for m in &mut moments {
                arrays.push(m);
            }
            arrays.extend(backbone.rows_mut());
            apply_plan(plan, &mut arrays)
        };
        for (&id, group) in ids.iter().zip(taken) {
            *self.adam.group_mut(id) = group;
        }
        Ok(result?)
    }
}
