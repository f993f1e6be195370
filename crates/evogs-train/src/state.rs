//! The training state: canonical Gaussians and every per-Gaussian array that must stay aligned
//! with them (Adam moments of each parameter group, densification statistics, and the
//! backbone's own rows), plus the network's optimiser groups.
//!
//! Parameter groups follow 3DGS/D-3DGS (`training_setup`): `xyz`, `f_dc`, `f_rest`, `opacity`,
//! `scaling`, `rotation`, and one group per backbone buffer. The Gaussians keep SH coefficient-
//! major rows (`splat-raster`); the `f_dc` and `f_rest` groups are column ranges of those rows,
//! updated in place (`Adam::step_columns`), so their moments are rows of 3 and `3·((deg+1)²−1)`.

use densify::{DensifyPlan, DensifyStats, Moments, PerGaussian, apply_plan};
use splat_raster::{GaussianGrads, Gaussians};
use tiny_nn::adam::AdamGroup;
use tiny_nn::{Adam, ExponentialLr, GroupId, LrSchedule, StoreMut};

use evogs_backbones::Backbone;

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
///
/// The invariant: the Gaussians, the densification statistics and the moments of the six
/// per-Gaussian Adam groups have one row per Gaussian, in the same order. The fields are private
/// so that it holds: the rows change only through [`SceneState::apply_plan`] (densify's one
/// mechanism, which also remaps the backbone's rows) and, when a checkpoint is loaded
/// ([`crate::checkpoint::load_checkpoint`]), all together; the values through the Adam steps,
/// [`SceneState::add_view_stats`] and [`SceneState::add_evolution_stats`].
#[derive(Clone, Debug)]
pub struct SceneState {
    /// Canonical Gaussians at the maximum SH degree.
    gaussians: Gaussians,
    /// SH bands in use (raised during training).
    active_sh: u32,
    /// Densification statistics.
    stats: DensifyStats,
    /// Adam over every group.
    adam: Adam,
    /// The per-Gaussian groups.
    groups: GaussianGroups,
    /// One group per backbone parameter buffer, in the backbone's order.
    net_groups: Vec<GroupId>,
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
/// `position_final` (not scaled) over `deform_max_steps`, both ends times `deform_scale`.
pub fn network_schedule(lr: &LrSettings) -> LrSchedule {
    scaled_network_schedule(lr, 1.0)
}

/// [`network_schedule`] with both ends multiplied by `scale` (a backbone's per-buffer factor,
/// [`Backbone::lr_scale`]).
pub fn scaled_network_schedule(lr: &LrSettings, scale: f32) -> LrSchedule {
    let scale = scale * lr.deform_scale;
    LrSchedule::Exponential(ExponentialLr {
        lr_init: lr.position_init * lr.spatial_lr_scale * scale,
        lr_final: lr.position_final * scale,
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
            net_groups.push(
                adam.add_group(
                    &format!("net.{name}"),
                    buf.len(),
                    1,
                    backbone
                        .own_schedule(&name)
                        .unwrap_or_else(|| scaled_network_schedule(lr, backbone.lr_scale(&name))),
                )?,
            );
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

    /// The canonical Gaussians (at the maximum SH degree).
    pub fn gaussians(&self) -> &Gaussians {
        &self.gaussians
    }

    /// SH bands in use.
    pub fn active_sh(&self) -> u32 {
        self.active_sh
    }

    /// Uses one more SH band, up to `max` (3DGS's `oneupSHdegree`).
    pub fn raise_active_sh(&mut self, max: u32) {
        if self.active_sh < max {
            self.active_sh += 1;
        }
    }

    /// The densification statistics.
    pub fn stats(&self) -> &DensifyStats {
        &self.stats
    }

    /// Adds one view's projected-mean gradients and radii to the statistics.
    pub fn add_view_stats(
        &mut self,
        means2d: &[[f32; 2]],
        radii: &[f32],
        width: u32,
        height: u32,
    ) -> Result<(), TrainError> {
        Ok(self.stats.add_view(means2d, radii, width, height)?)
    }

    /// Adds one step's evolution cues (EvoGS's residual norms and θ) to the statistics.
    pub fn add_evolution_stats(
        &mut self,
        residual_norm: Option<&[f32]>,
        theta: Option<&[f32]>,
    ) -> Result<(), TrainError> {
        Ok(self.stats.add_evolution(residual_norm, theta)?)
    }

    /// The optimiser (every group, per-Gaussian and network).
    pub fn adam(&self) -> &Adam {
        &self.adam
    }

    /// Replaces the Gaussians, the statistics and the active SH bands with a checkpoint's, after
    /// `moments` has filled every Adam group (called once per group, in order; the checkpoint
    /// reads each per-Gaussian group's moments for the checkpoint's Gaussians, so the rows stay
    /// aligned). On an error nothing of the Gaussians or the statistics has changed.
    pub(crate) fn restore(
        &mut self,
        gaussians: Gaussians,
        stats: DensifyStats,
        active_sh: u32,
        mut moments: impl FnMut(&mut AdamGroup) -> Result<(), TrainError>,
    ) -> Result<(), TrainError> {
        let ids: Vec<GroupId> = (0..self.adam.groups().len()).map(GroupId).collect();
        for id in ids {
            moments(self.adam.group_mut(id))?;
        }
        self.gaussians = gaussians;
        self.stats = stats;
        self.active_sh = active_sh;
        Ok(())
    }

    /// The first parameter group holding a NaN or an infinity, with the index of the value:
    /// the Gaussians' arrays (`gaussians.means`, ...), every Adam group's moments
    /// (`adam.<group>.m` / `.v`) and the backbone's parameters (by their names). `None` when every
    /// value is finite. The trainer checks it at every log interval (it reads each value once).
    pub fn first_non_finite(&self, backbone: &dyn Backbone) -> Option<(String, usize)> {
        let bad = |v: &[f32]| v.iter().position(|x| !x.is_finite());
        let g = &self.gaussians;
        let arrays: [(&str, &[f32]); 5] = [
            ("gaussians.means", g.means.as_flattened()),
            ("gaussians.log_scales", g.log_scales.as_flattened()),
            ("gaussians.rotations", g.rotations.as_flattened()),
            ("gaussians.opacity_logits", &g.opacity_logits),
            ("gaussians.sh", &g.sh),
        ];
        for (name, values) in arrays {
            if let Some(i) = bad(values) {
                return Some((name.to_string(), i));
            }
        }
        for group in self.adam.groups() {
            for (moment, values) in [("m", &group.m), ("v", &group.v)] {
                if let Some(i) = bad(values) {
                    return Some((format!("adam.{}.{moment}", group.name), i));
                }
            }
        }
        for (name, store) in backbone.params() {
            let mut buf = Vec::new();
            if let Some(i) = bad(store.view_f32(&mut buf)) {
                return Some((name, i));
            }
        }
        None
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
        grads: &GaussianGrads,
        lr_step: i64,
        skip_opacity: bool,
    ) -> Result<(), TrainError> {
        let g = &mut self.gaussians;
        let stride = g.sh_stride();
        let ids = self.groups;
        let adam = &mut self.adam;
        adam.step(
            ids.xyz,
            lr_step,
            StoreMut::F32(g.means.as_flattened_mut()),
            grads.means.as_flattened(),
        )?;
        // The SH rows are updated in place: `f_dc` holds their first three values, `f_rest`
        // the others (3DGS's two groups, with their own rates).
        let sh_grads = grads.sh.as_slice();
        adam.step_columns(ids.f_dc, lr_step, &mut g.sh, sh_grads, stride, 0..3)?;
        adam.step_columns(ids.f_rest, lr_step, &mut g.sh, sh_grads, stride, 3..stride)?;
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

    /// One Adam step of the backbone's buffers on its device ([`Backbone::step_on_device`]),
    /// with the gradients its last backward left there, at the lr of `lr_step`: the host counts
    /// the step and gives each group's constants; the moments stay on the device.
    pub fn step_network_on_device(
        &mut self,
        backbone: &mut dyn Backbone,
        lr_step: i64,
    ) -> Result<(), TrainError> {
        let updates = self
            .net_groups
            .iter()
            .map(|&id| self.adam.next_update(id, lr_step))
            .collect::<Result<Vec<_>, _>>()?;
        let moments: Vec<&AdamGroup> = self
            .net_groups
            .iter()
            .map(|&id| self.adam.group(id))
            .collect();
        Ok(backbone.step_on_device(&updates, &moments)?)
    }

    /// Copies the backbone's parameters and the moments of its groups from its device into the
    /// host's ([`Backbone::sync_to_host`]; nothing on the host).
    pub fn sync_network(&mut self, backbone: &mut dyn Backbone) -> Result<(), TrainError> {
        let first = self.net_groups.first().map_or(0, |id| id.0);
        // The network's groups follow the per-Gaussian ones, in order (SceneState::new).
        let groups = &mut self.adam.groups_mut()[first..];
        let mut moments: Vec<&mut AdamGroup> = groups.iter_mut().collect();
        if moments.len() != self.net_groups.len() {
            return Err(TrainError::config(
                "backbone",
                format!(
                    "{} optimiser groups after the first network group, {} network groups",
                    moments.len(),
                    self.net_groups.len()
                ),
            ));
        }
        Ok(backbone.sync_to_host(&mut moments)?)
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
            // At SH degree 0 the `f_rest` group (index 2) holds no value, so it has no rows to
            // carry: the plan leaves it empty (densify cannot count the rows of an empty group).
            let rest_empty = rest_width(&self.gaussians) == 0;
            let mut moments: Vec<Moments<'_>> = taken
                .iter_mut()
                .enumerate()
                .filter(|&(k, _)| !(rest_empty && k == 2))
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{Preset, TrainConfig};
    use densify::{NewValues, PlanSummary};
    use evogs_backbones::{D3dgsBackbone, NetSettings};
    use splat_core::RowPlan;

    fn state(n: usize) -> (SceneState, D3dgsBackbone) {
        state_of_degree(n, 3)
    }

    fn state_of_degree(n: usize, sh_degree: u32) -> (SceneState, D3dgsBackbone) {
        let c = TrainConfig::preset(Preset::Tiny);
        let net = NetSettings {
            width: 8,
            depth: 2,
            skip_after: None,
            ..c.net
        };
        let backbone = D3dgsBackbone::new(&net, 1).unwrap();
        let g = crate::init::random_gaussians(n, 1.0, sh_degree, 5);
        let mut s = SceneState::new(g, &backbone, &c.lr).unwrap();
        // Distinct moments per row so that the plan's row movements are visible.
        for id in s.groups.all() {
            let group = s.adam.group_mut(id);
            let w = group.row_width;
            for (k, m) in group.m.iter_mut().enumerate() {
                *m = (k / w) as f32 + 1.0;
            }
            group.v.clone_from(&group.m);
        }
        (s, backbone)
    }

    #[test]
    fn a_nan_or_infinity_in_any_parameter_group_is_found_with_its_group_and_index() {
        let (mut s, mut backbone) = state(4);
        assert_eq!(s.first_non_finite(&backbone), None);
        s.gaussians.sh[7] = f32::NAN;
        assert_eq!(
            s.first_non_finite(&backbone),
            Some(("gaussians.sh".into(), 7))
        );
        s.gaussians.sh[7] = 0.0;
        s.gaussians.means[2][1] = f32::INFINITY;
        assert_eq!(
            s.first_non_finite(&backbone),
            Some(("gaussians.means".into(), 7))
        );
        s.gaussians.means[2][1] = 0.0;
        let id = s.groups.all()[0];
        s.adam.group_mut(id).v[3] = f32::NEG_INFINITY;
        let name = s.adam.groups()[0].name.clone();
        assert_eq!(
            s.first_non_finite(&backbone),
            Some((format!("adam.{name}.v"), 3))
        );
        s.adam.group_mut(id).v[3] = 0.0;
        let (param, _) = backbone.params().into_iter().next().unwrap();
        if let Some((_, StoreMut::F32(values))) = backbone.params_mut().into_iter().next() {
            values[5] = f32::NAN;
        }
        assert_eq!(s.first_non_finite(&backbone), Some((param, 5)));
    }

    /// Five rows to six: rows 0, 1, 3, 4 kept, two new rows cloned from 1 and 4, row 2's
    /// opacity reset.
    fn five_to_six() -> DensifyPlan {
        DensifyPlan {
            rows: RowPlan {
                kept: vec![0, 1, 3, 4],
                parent_from_new: vec![1, 4],
            },
            old_len: 5,
            new_values: NewValues {
                means: vec![[0.5; 3]; 2],
                log_scales: vec![[-3.0; 3]; 2],
                rotations: vec![[1.0, 0.0, 0.0, 0.0]; 2],
                opacity_logits: vec![0.0; 2],
                sh_dc: vec![[0.1; 3]; 2],
            },
            reset_rows: vec![2],
            reset_opacity: 0.01,
            clears_stats: true,
            summary: PlanSummary::default(),
        }
    }

    #[test]
    fn a_plan_applies_at_sh_degree_zero_where_the_rest_group_is_empty() {
        let (mut s, mut backbone) = state_of_degree(5, 0);
        s.apply_plan(&five_to_six(), &mut backbone).unwrap();
        assert_eq!((s.len(), s.stats.len()), (6, 6));
        for id in s.groups.all() {
            let g = s.adam.group(id);
            let rows = if g.name == "f_rest" { 0 } else { 6 };
            assert_eq!(g.m.len(), rows * g.row_width, "{}", g.name);
            assert_eq!(g.v.len(), g.m.len(), "{}", g.name);
        }
    }

    #[test]
    fn a_plan_keeps_every_group_aligned() {
        let (mut s, mut backbone) = state(5);
        let plan = five_to_six();
        let before = s.gaussians.clone();
        s.apply_plan(&plan, &mut backbone).unwrap();
        assert_eq!(s.len(), 6);
        assert_eq!(s.stats.len(), 6);
        for id in s.groups.all() {
            let g = s.adam.group(id);
            assert_eq!(g.m.len(), 6 * g.row_width, "{}", g.name);
            let w = g.row_width;
            let row = |r: usize| g.m[r * w];
            // Kept rows carry their moments, new rows start at zero (3DGS).
            assert_eq!(row(0), 1.0, "{}", g.name);
            assert_eq!(row(1), 2.0, "{}", g.name);
            assert_eq!(row(4), 0.0, "{}", g.name);
            assert_eq!(row(5), 0.0, "{}", g.name);
            if g.name == "opacity" {
                assert_eq!(row(2), 0.0, "reset row's opacity moment");
            } else {
                assert_eq!(row(2), 4.0, "{}", g.name);
            }
        }
        assert_eq!(s.gaussians.means[3], before.means[4]);
        assert_eq!(s.gaussians.means[4], [0.5; 3]);
        // The SH rest of a new row is its parent's; its DC is the plan's.
        let st = s.gaussians.sh_stride();
        assert_eq!(&s.gaussians.sh[4 * st..4 * st + 3], &[0.1; 3]);
        assert_eq!(
            &s.gaussians.sh[4 * st + 3..5 * st],
            &before.sh[st + 3..2 * st]
        );
        assert!(s.gaussians.opacity_logits[2] <= (0.01f32 / 0.99).ln() + 1e-6);
    }

    #[test]
    fn a_plan_for_the_wrong_row_count_changes_nothing() {
        let (mut s, mut backbone) = state(4);
        let plan = DensifyPlan::identity(5);
        let before = s.gaussians.clone();
        let err = s.apply_plan(&plan, &mut backbone).unwrap_err().to_string();
        assert!(err.contains("expected 5"), "{err}");
        assert_eq!(s.gaussians, before);
        assert_eq!(s.adam.group(s.groups.xyz).m.len(), 12);
    }

    #[test]
    fn grid_lr_scale_multiplies_only_phis_grid_and_spline() {
        use crate::config::{Method, Preset, TrainConfig};
        let mut c = TrainConfig::preset(Preset::Tiny);
        c.method = Method::Evogs;
        c.backbones.evogs.grid_lr_scale = 10.0;
        c.backbones.evogs.psi_lr = Some(3e-3);
        let backbone = evogs_backbones::make_backbone(&c.backbone_run()).unwrap();
        let g = crate::init::random_gaussians(4, 1.0, 0, 0);
        let s = SceneState::new(g, backbone.as_ref(), &c.lr).unwrap();
        let base = network_schedule(&c.lr);
        let names: Vec<String> = backbone.params().into_iter().map(|(n, _)| n).collect();
        let mut seen = [0usize; 2];
        for (name, &id) in names.iter().zip(&s.net_groups) {
            let sched = &s.adam.group(id).schedule;
            if name == "psi" {
                // Ψ trains at its own constant lr, not the decaying network schedule.
                assert_eq!(*sched, LrSchedule::Constant(3e-3));
                continue;
            }
            let grid = name.starts_with("phi.triplane") || name.starts_with("phi.bspline");
            let want = if grid { 10.0 } else { 1.0 };
            seen[usize::from(grid)] += 1;
            for step in [0, 500, 3_000] {
                let ratio = sched.at(step) / base.at(step);
                assert!((ratio - want).abs() < 1e-4, "{name} at {step}: {ratio}");
            }
        }
        assert!(seen[0] > 0 && seen[1] > 0, "{names:?}");
        // Runs recorded before `psi_lr` existed (None) train Ψ on the network schedule.
        c.backbones.evogs.psi_lr = None;
        let backbone = evogs_backbones::make_backbone(&c.backbone_run()).unwrap();
        let g = crate::init::random_gaussians(4, 1.0, 0, 0);
        let s = SceneState::new(g, backbone.as_ref(), &c.lr).unwrap();
        let psi = *s.net_groups.last().unwrap();
        assert_eq!(s.adam.group(psi).name, "net.psi");
        assert_eq!(s.adam.group(psi).schedule, base);
    }

    #[test]
    fn schedules_follow_d3dgs() {
        let lr = LrSettings::default();
        let s = gaussian_schedules(&lr);
        assert!((s[0].at(0) - 0.0008).abs() < 1e-9);
        assert!((s[0].at(30_000) - 0.000008).abs() < 1e-10);
        assert_eq!(s[2].at(5), 0.0025 / 20.0);
        assert!((s[4].at(5) - 0.005).abs() < 1e-9);
        let net = network_schedule(&lr);
        assert!((net.at(0) - 0.0008).abs() < 1e-9);
        assert!((net.at(40_000) - 0.0000016).abs() < 1e-11);
    }
}
