//! One hand-built case per rule: clone, split, each prune reason, opacity reset, schedule
//! boundaries, and the EvoGS rules where they change the outcome.

use crate::common;

use common::*;
use densify::{
    Deformation, DensifyConfig, DensifyError, DensifyStats, Moments, PerGaussian, PlanInput, Rows,
    Schedule, Trigger, apply_plan, make_plan, scene_extent,
};
use glam::{Mat3, Vec3};
use splat_core::{Camera, Gaussians, Layout, NewRows, logit, sigmoid};
use tiny_nn::adam::{Adam, LrSchedule};

const EXTENT: f32 = 1.0;

fn plan_at(
    config: &DensifyConfig,
    g: &Gaussians,
    stats: &DensifyStats,
    iteration: u64,
) -> densify::DensifyPlan {
    make_plan(
        config,
        &PlanInput {
            gaussians: g.view(),
            stats,
            extent: EXTENT,
            iteration,
            deformation: None,
        },
    )
    .unwrap()
}

#[test]
fn ndc_gradient_is_pixel_gradient_times_half_image_size() {
    let mut s = DensifyStats::new(3);
    // W = 200, H = 100: (1e-3, 0) px → 0.1 NDC; (0, 2e-3) → 0.1; (3e-3, 8e-3) → (0.3, 0.4) → 0.5.
    s.add_view(
        &[[1e-3, 0.0], [0.0, 2e-3], [3e-3, 8e-3]],
        &[1.0, 2.0, 0.0],
        200,
        100,
    )
    .unwrap();
    s.add_view(
        &[[0.0; 2], [0.0; 2], [3e-3, 8e-3]],
        &[5.0, 0.0, 4.0],
        200,
        100,
    )
    .unwrap();
    assert!((s.mean_grad(0) - 0.05).abs() < 1e-7, "{}", s.mean_grad(0));
    assert!((s.mean_grad(1) - 0.1).abs() < 1e-7, "{}", s.mean_grad(1));
    assert!((s.mean_grad(2) - 0.5).abs() < 1e-6, "{}", s.mean_grad(2));
    assert_eq!(s.visible, vec![2, 1, 1]);
    assert_eq!(s.max_radius, vec![5.0, 2.0, 4.0]);
}

#[test]
fn clone_copies_small_high_gradient_gaussians_at_the_threshold() {
    // Max scale 0.005 <= 0.01 · extent: clone. Gradients: below, exactly at, above 0.0002.
    let g = gaussians(3, 0.005);
    let stats = stats_with_grads(&[0.000_199, 0.0002, 0.001]);
    let plan = plan_at(&standard(), &g, &stats, 600);
    assert_eq!(plan.rows.kept, vec![0, 1, 2]);
    assert_eq!(plan.rows.parent_from_new, vec![1, 2]);
    assert_eq!(plan.summary.cloned, 2);
    let mut after = g.clone();
    apply_plan(&plan, &mut [&mut after]).unwrap();
    assert_eq!(after.len(), 5);
    for (new, parent) in [(3, 1), (4, 2)] {
        assert_eq!(after.means[new], g.means[parent]);
        assert_eq!(after.log_scales[new], g.log_scales[parent]);
        assert_eq!(after.rotations[new], g.rotations[parent]);
        assert_eq!(after.opacity_logits[new], g.opacity_logits[parent]);
        assert_eq!(
            after.sh[new * 12..new * 12 + 12],
            g.sh[parent * 12..parent * 12 + 12]
        );
    }
}

#[test]
fn split_replaces_a_large_gaussian_by_two_smaller_children_sampled_from_its_covariance() {
    // Scale (0.05, 1e-4, 1e-4) rotated 90° about z: the long axis points along world y.
    let n = 4000;
    let mut g = gaussians(n, 0.05);
    let half = std::f32::consts::FRAC_PI_4;
    for i in 0..n {
        g.means[i] = [1.0, 2.0, 3.0];
        g.log_scales[i] = [0.05f32.ln(), 1e-4f32.ln(), 1e-4f32.ln()];
        g.rotations[i] = [half.cos(), 0.0, 0.0, half.sin()];
    }
    let stats = stats_with_grads(&vec![0.001; n]);
    let plan = plan_at(&standard(), &g, &stats, 600);
    assert_eq!(plan.summary.split, n);
    assert_eq!(plan.summary.children, 2 * n);
    assert!(plan.rows.kept.is_empty(), "split parents are removed");
    // All first children, then all second children (3DGS's `repeat(N, 1)` order).
    let parents: Vec<u32> = (0..n as u32).chain(0..n as u32).collect();
    assert_eq!(plan.rows.parent_from_new, parents);
    let mut after = g.clone();
    apply_plan(&plan, &mut [&mut after]).unwrap();
    let ln16 = 1.6f32.ln();
    let (mut sx, mut sy, mut syy, mut sz) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for i in 0..2 * n {
        assert!((after.log_scales[i][0] - (0.05f32.ln() - ln16)).abs() < 1e-5);
        assert_eq!(after.rotations[i], g.rotations[0]);
        let d = Vec3::from(after.means[i]) - Vec3::new(1.0, 2.0, 3.0);
        sx += d.x.abs() as f64;
        sz += d.z.abs() as f64;
        sy += d.y as f64;
        syy += (d.y as f64).powi(2);
    }
    let m = (2 * n) as f64;
    // Along y the offsets have standard deviation 0.05 and mean 0; across, ~1e-4.
    let std_y = (syy / m - (sy / m).powi(2)).sqrt();
    assert!(
        (std_y - 0.05).abs() < 0.003,
        "std along the long axis {std_y}"
    );
    assert!((sy / m).abs() < 0.003, "mean offset {}", sy / m);
    assert!(sx / m < 2e-4 && sz / m < 2e-4, "{} {}", sx / m, sz / m);
}

#[test]
fn splitting_is_deterministic_for_a_seed_and_differs_across_seeds() {
    let g = gaussians(8, 0.05);
    let stats = stats_with_grads(&[0.001; 8]);
    let a = plan_at(&standard(), &g, &stats, 600);
    let b = plan_at(&standard(), &g, &stats, 600);
    assert_eq!(a, b);
    let other = DensifyConfig {
        seed: 7,
        ..standard()
    };
    assert_ne!(
        a.new_values.means,
        plan_at(&other, &g, &stats, 600).new_values.means
    );
}

#[test]
fn prune_removes_transparent_gaussians_at_any_densify_step() {
    let mut g = gaussians(3, 0.005);
    g.opacity_logits = vec![logit(0.004), logit(0.006), logit(0.9)];
    let stats = stats_with_grads(&[0.0; 3]);
    let plan = plan_at(&standard(), &g, &stats, 600);
    assert_eq!(plan.rows.kept, vec![1, 2]);
    assert_eq!(plan.summary.pruned_opacity, 1);
    // Clones of a transparent Gaussian are pruned with it, as in 3DGS.
    let stats = stats_with_grads(&[0.001, 0.0, 0.0]);
    let plan = plan_at(&standard(), &g, &stats, 600);
    assert_eq!(plan.summary.cloned, 1);
    assert_eq!(plan.summary.pruned_opacity, 2);
    assert_eq!(plan.new_len(), 2);
}

#[test]
fn screen_prune_is_off_by_default_as_in_3dgs_code() {
    let g = gaussians(3, 0.005);
    let mut stats = stats_with_grads(&[0.0; 3]);
    stats.max_radius = vec![500.0, 21.0, 3.0];
    assert_eq!(standard().max_screen_radius, None);
    let plan = plan_at(&standard(), &g, &stats, 3100);
    assert_eq!(plan.rows.kept, vec![0, 1, 2]);
    assert_eq!(plan.summary.pruned_screen, 0);
}

#[test]
fn screen_prune_when_set_applies_only_after_the_first_opacity_reset() {
    let config = DensifyConfig {
        max_screen_radius: Some(20.0),
        ..standard()
    };
    let g = gaussians(3, 0.005);
    let mut stats = stats_with_grads(&[0.0; 3]);
    stats.max_radius = vec![21.0, 20.0, 3.0];
    let before = plan_at(&config, &g, &stats, 3000);
    assert_eq!(before.rows.kept, vec![0, 1, 2]);
    let after = plan_at(&config, &g, &stats, 3100);
    assert_eq!(after.rows.kept, vec![1, 2], "radius 20 is not > 20");
    assert_eq!(after.summary.pruned_screen, 1);
}

#[test]
fn world_prune_applies_only_after_the_first_opacity_reset() {
    let mut g = gaussians(3, 0.005);
    g.log_scales[0] = [0.11f32.ln(), 1e-3f32.ln(), 1e-3f32.ln()];
    g.log_scales[1] = [0.09f32.ln(); 3];
    let stats = stats_with_grads(&[0.0; 3]);
    assert_eq!(
        plan_at(&standard(), &g, &stats, 2900).rows.kept,
        vec![0, 1, 2]
    );
    let plan = plan_at(&standard(), &g, &stats, 3100);
    assert_eq!(plan.rows.kept, vec![1, 2]);
    assert_eq!(plan.summary.pruned_world, 1);
    // Pruning can be switched off on its own.
    let off = DensifyConfig {
        prune: false,
        ..standard()
    };
    assert_eq!(plan_at(&off, &g, &stats, 3100).rows.kept, vec![0, 1, 2]);
}

#[test]
fn opacity_reset_caps_opacity_and_zeroes_only_opacity_moments() {
    let mut g = gaussians(2, 0.005);
    g.opacity_logits = vec![logit(0.5), logit(0.006)];
    let stats = stats_with_grads(&[0.0; 2]);
    let plan = plan_at(&standard(), &g, &stats, 3000);
    assert_eq!(plan.reset_rows, vec![0, 1]);
    assert!(plan.clears_stats, "3000 is also a densification step");
    // One group holding only opacities, one packed 4-wide row with the opacity in column 3.
    let mut adam_opacity = Adam::new();
    let opacity = adam_opacity
        .add_group("opacity", 2, 1, LrSchedule::Constant(0.05))
        .unwrap();
    let mut adam_packed = Adam::new();
    let packed = adam_packed
        .add_group("packed", 2 * 4, 4, LrSchedule::Constant(0.05))
        .unwrap();
    for grp in [
        adam_opacity.group_mut(opacity),
        adam_packed.group_mut(packed),
    ] {
        grp.m.fill(1.0);
        grp.v.fill(2.0);
    }
    let mut after = g.clone();
    let mut m_opacity = Moments {
        group: adam_opacity.group_mut(opacity),
        opacity_column: Some(0),
    };
    let mut m_packed = Moments {
        group: adam_packed.group_mut(packed),
        opacity_column: Some(3),
    };
    apply_plan(&plan, &mut [&mut after, &mut m_opacity, &mut m_packed]).unwrap();
    assert!((sigmoid(after.opacity_logits[0]) - 0.01).abs() < 1e-6);
    assert!(
        (sigmoid(after.opacity_logits[1]) - 0.006).abs() < 1e-6,
        "min keeps lower ones"
    );
    assert_eq!(adam_opacity.group(opacity).m, vec![0.0; 2]);
    assert_eq!(adam_opacity.group(opacity).v, vec![0.0; 2]);
    assert_eq!(
        adam_packed.group(packed).m,
        vec![1.0, 1.0, 1.0, 0.0, 1.0, 1.0, 1.0, 0.0]
    );
    assert_eq!(
        adam_packed.group(packed).v,
        vec![2.0, 2.0, 2.0, 0.0, 2.0, 2.0, 2.0, 0.0]
    );
    // The whole optimiser as one container; a group listed twice is refused before any change.
    let mut adam = Adam::new();
    let a = adam
        .add_group("means", 2 * 3, 3, LrSchedule::Constant(0.1))
        .unwrap();
    let b = adam
        .add_group("opacity", 2, 1, LrSchedule::Constant(0.1))
        .unwrap();
    adam.group_mut(b).m.fill(3.0);
    let twice = [(a, None), (a, None)];
    let mut moments = densify::OptimiserMoments {
        adam: &mut adam,
        groups: &twice,
    };
    let err = apply_plan(&plan, &mut [&mut moments]).unwrap_err();
    assert!(err.to_string().contains("listed twice"), "{err}");
    let groups = [(a, None), (b, Some(0))];
    let mut moments = densify::OptimiserMoments {
        adam: &mut adam,
        groups: &groups,
    };
    apply_plan(&plan, &mut [&mut moments]).unwrap();
    assert_eq!(adam.group(b).m, vec![0.0, 0.0]);
    // Switched off, nothing is reset.
    let off = DensifyConfig {
        opacity_reset: false,
        ..standard()
    };
    assert!(plan_at(&off, &g, &stats, 3000).reset_rows.is_empty());
}

#[test]
fn schedule_boundaries_follow_3dgs() {
    let s = Schedule::default();
    assert!(!s.densifies(500), "iteration > densify_from_iter, strictly");
    assert!(!s.densifies(550));
    assert!(s.densifies(600));
    assert!(s.densifies(14_900));
    assert!(
        !s.densifies(15_000),
        "iteration < densify_until_iter, strictly"
    );
    assert!(s.accumulates(14_999) && !s.accumulates(15_000));
    assert!(s.resets_opacity(3000) && s.resets_opacity(12_000));
    assert!(!s.resets_opacity(15_000) && !s.resets_opacity(500));
    assert!(!s.prunes_large(3000) && s.prunes_large(3001));
    let white = Schedule {
        white_background: true,
        ..s
    };
    assert!(white.resets_opacity(500) && !white.densifies(500));
    // Between steps the plan is the identity.
    let g = gaussians(2, 0.005);
    let stats = stats_with_grads(&[0.01, 0.01]);
    let plan = plan_at(&standard(), &g, &stats, 650);
    assert_eq!(plan, densify::DensifyPlan::identity(2));
    // An opacity reset without densification keeps the statistics.
    let white_cfg = DensifyConfig {
        schedule: white,
        ..standard()
    };
    let plan = plan_at(&white_cfg, &g, &stats, 500);
    assert!(!plan.clears_stats && plan.summary.cloned == 0 && plan.reset_rows == vec![0, 1]);
    let mut kept_stats = stats.clone();
    apply_plan(&plan, &mut [&mut kept_stats]).unwrap();
    assert_eq!(kept_stats, stats);
    // A densification step restarts them.
    let plan = plan_at(&standard(), &g, &stats, 600);
    apply_plan(&plan, &mut [&mut kept_stats]).unwrap();
    assert_eq!(kept_stats, DensifyStats::new(4));
}

#[test]
fn uncertainty_trigger_blocks_high_gradient_gaussians_with_unstable_motion() {
    let g = gaussians(4, 0.005);
    let mut stats = stats_with_grads(&[0.001; 4]);
    // Two steps each: 0 stable, 1 large residual, 2 large θ, 3 no evolution samples at all.
    for _ in 0..2 {
        let r = [0.001, 0.02, 0.001, 0.0];
        let t = [0.1, 0.1, 1.5, 0.0];
        stats.add_evolution(Some(&r), Some(&t)).unwrap();
    }
    stats.residual_count[3] = 0;
    stats.theta_count[3] = 0;
    let without = plan_at(&standard(), &g, &stats, 600);
    assert_eq!(without.rows.parent_from_new, vec![0, 1, 2, 3]);
    assert_eq!(without.summary.blocked, None);
    let config = DensifyConfig {
        trigger: Some(Trigger::default()),
        ..standard()
    };
    let with = plan_at(&config, &g, &stats, 600);
    assert_eq!(with.rows.parent_from_new, vec![0, 3]);
    assert_eq!(with.summary.blocked, Some(2));
    assert!(with.summary.to_string().contains("blocked 2"));
}

#[test]
fn deformation_aware_clone_starts_at_canonical_plus_half_the_deformation() {
    let mut g = gaussians(2, 0.005);
    g.opacity_logits = vec![0.3, -0.2];
    let layout = Layout {
        position: true,
        rotation: true,
        scale: true,
        opacity: true,
        colour: true,
    };
    let dim = layout.dim();
    assert_eq!(dim, 14);
    let corrected: Vec<f32> = (0..2 * dim).map(|e| 0.01 * (e as f32 + 1.0)).collect();
    let stats = stats_with_grads(&[0.0, 0.001]);
    let config = DensifyConfig {
        deformation_alpha: Some(0.5),
        ..standard()
    };
    let plan = make_plan(
        &config,
        &PlanInput {
            gaussians: g.view(),
            stats: &stats,
            extent: EXTENT,
            iteration: 600,
            deformation: Some(Deformation {
                corrected: &corrected,
                layout,
            }),
        },
    )
    .unwrap();
    let mut after = g.clone();
    apply_plan(&plan, &mut [&mut after]).unwrap();
    assert_eq!(after.len(), 3);
    let d = &corrected[dim..];
    let close = |a: f32, b: f32| assert!((a - b).abs() < 1e-6, "{a} vs {b}");
    for k in 0..3 {
        close(after.means[2][k], g.means[1][k] + 0.5 * d[k]);
        close(after.log_scales[2][k], g.log_scales[1][k] + 0.5 * d[7 + k]);
        close(after.sh[2 * 12 + k], g.sh[12 + k] + 0.5 * d[11 + k]);
    }
    for k in 0..4 {
        close(after.rotations[2][k], g.rotations[1][k] + 0.5 * d[3 + k]);
    }
    close(after.opacity_logits[2], g.opacity_logits[1] + 0.5 * d[10]);
    // Higher SH coefficients are the parent's; the source itself is unchanged.
    assert_eq!(after.sh[2 * 12 + 3..3 * 12], g.sh[12 + 3..24]);
    assert_eq!(after.means[1], g.means[1]);
    assert_eq!(after.sh[12..24], g.sh[12..24]);
    // Standard clone differs: the child sits exactly on the parent.
    let standard_plan = plan_at(&standard(), &g, &stats, 600);
    assert_eq!(standard_plan.new_values.means[0], g.means[1]);
}

#[test]
fn deformation_aware_split_samples_around_the_partially_deformed_source() {
    let n = 2000;
    let mut g = gaussians(n, 0.05);
    for m in &mut g.means {
        *m = [0.0; 3];
    }
    let layout = Layout::default(); // position, rotation, scale: D = 10
    let mut corrected = vec![0.0f32; n * 10];
    for row in corrected.chunks_mut(10) {
        row[..3].copy_from_slice(&[0.4, -0.2, 1.0]);
        row[7..10].copy_from_slice(&[0.2, 0.2, 0.2]);
    }
    let stats = stats_with_grads(&vec![0.001; n]);
    let config = DensifyConfig::evogs();
    let plan = make_plan(
        &config,
        &PlanInput {
            gaussians: g.view(),
            stats: &stats,
            extent: EXTENT,
            iteration: 600,
            deformation: Some(Deformation {
                corrected: &corrected,
                layout,
            }),
        },
    )
    .unwrap();
    assert_eq!(plan.summary.split, n);
    let mean: Vec3 = plan
        .new_values
        .means
        .iter()
        .map(|&m| Vec3::from(m))
        .sum::<Vec3>()
        / (2 * n) as f32;
    assert!(
        (mean - Vec3::new(0.2, -0.1, 0.5)).length() < 0.005,
        "{mean}"
    );
    let expected_ls = 0.05f32.ln() + 0.1 - 1.6f32.ln();
    for ls in &plan.new_values.log_scales {
        assert!((ls[0] - expected_ls).abs() < 1e-5);
    }
}

#[test]
fn extent_is_1_1_times_the_largest_camera_distance_from_their_mean() {
    let cam = |c: Vec3| Camera::from_center(8, 8, 8.0, 8.0, 4.0, 4.0, Mat3::IDENTITY, c);
    let cams = [
        cam(Vec3::new(1.0, 0.0, 0.0)),
        cam(Vec3::new(-1.0, 0.0, 0.0)),
        cam(Vec3::new(0.0, 0.5, 0.0)),
    ];
    // Mean (0, 1/6, 0); farthest: (±1, 0, 0) at sqrt(1 + 1/36).
    let expected = 1.1 * (1.0f32 + 1.0 / 36.0).sqrt();
    assert!((scene_extent(&cams).unwrap() - expected).abs() < 1e-6);
    assert!(matches!(
        scene_extent(&[]),
        Err(DensifyError::Input {
            field: "cameras",
            ..
        })
    ));
}

#[test]
fn bad_inputs_name_the_field_and_change_nothing() {
    let mut s = DensifyStats::new(2);
    let err = s.add_view(&[[0.0; 2]], &[1.0, 1.0], 10, 10).unwrap_err();
    assert!(err.to_string().contains("means2d"), "{err}");
    let err = s
        .add_view(&[[f32::NAN, 0.0], [0.0; 2]], &[1.0, 1.0], 10, 10)
        .unwrap_err();
    assert!(err.to_string().contains("Gaussian 0"), "{err}");
    // A NaN gradient of a culled Gaussian is ignored.
    s.add_view(&[[f32::NAN, 0.0], [0.0; 2]], &[0.0, 1.0], 10, 10)
        .unwrap();
    let err = s.add_evolution(Some(&[0.1, -1.0]), None).unwrap_err();
    assert!(err.to_string().contains("residual_norm"), "{err}");

    let g = gaussians(2, 0.005);
    let stats = stats_with_grads(&[0.01; 3]);
    let err = make_plan(
        &standard(),
        &PlanInput {
            gaussians: g.view(),
            stats: &stats,
            extent: EXTENT,
            iteration: 600,
            deformation: None,
        },
    )
    .unwrap_err();
    assert!(err.to_string().contains("stats"), "{err}");
    let bad = DensifyConfig {
        min_opacity: 1.5,
        ..standard()
    };
    let err = make_plan(
        &bad,
        &PlanInput {
            gaussians: g.view(),
            stats: &stats_with_grads(&[0.0; 2]),
            extent: EXTENT,
            iteration: 600,
            deformation: None,
        },
    )
    .unwrap_err();
    assert!(err.to_string().contains("min_opacity"), "{err}");
    for radius in [0.0, -1.0, f32::NAN, f32::INFINITY] {
        let bad = DensifyConfig {
            max_screen_radius: Some(radius),
            ..standard()
        };
        let err = bad.validate().unwrap_err();
        assert!(
            err.to_string().contains("max_screen_radius"),
            "{radius}: {err}"
        );
    }

    // A non-finite d̃ is an error naming the Gaussian when that row is densified, and unused
    // otherwise.
    let mut corrected = vec![0.0f32; 20];
    corrected[13] = f32::NAN;
    let deformation = Some(Deformation {
        corrected: &corrected,
        layout: Layout::default(),
    });
    let with = |grads: &[f32]| {
        make_plan(
            &DensifyConfig::evogs(),
            &PlanInput {
                gaussians: g.view(),
                stats: &stats_with_grads(grads),
                extent: EXTENT,
                iteration: 600,
                deformation,
            },
        )
    };
    let err = with(&[0.0, 0.01]).unwrap_err();
    assert!(
        err.to_string().contains("deformation.corrected") && err.to_string().contains("Gaussian 1"),
        "{err}"
    );
    assert_eq!(with(&[0.01, 0.0]).unwrap().summary.cloned, 1);

    // An array with the wrong row count is named, and no array is touched.
    let plan = plan_at(&standard(), &g, &stats_with_grads(&[0.01; 2]), 600);
    let mut after = g.clone();
    let mut tags = vec![0u32; 3];
    let mut rows = Rows {
        label: "tags",
        data: &mut tags,
        stride: 1,
        fill: NewRows::Fill(9),
    };
    let err = apply_plan(&plan, &mut [&mut after, &mut rows]).unwrap_err();
    assert!(err.to_string().contains("tags"), "{err}");
    assert_eq!(after, g);
    assert_eq!(rows.rows(), 3);
}

#[test]
fn evolution_cues_come_from_evo_state_steps() {
    use evo_state::{EvoConfig, EvoState, Frames, Gain};
    let config = EvoConfig {
        gain: Gain::Fixed(0.5),
        extent: 2.0,
        ..EvoConfig::default()
    };
    let layout = config.layout;
    let mut evo =
        EvoState::new(config, Frames::new(vec![0.0, 0.1, 0.2, 0.3]).unwrap(), 2, 1).unwrap();
    let mut stats = DensifyStats::new(2);
    // Gaussian 0 moves steadily along x; Gaussian 1 zig-zags.
    let z_at = |k: usize| -> Vec<f32> {
        let mut z = vec![0.0f32; 20];
        z[0] = 0.1 * k as f32;
        z[10] = 0.1 * k as f32;
        z[11] = if k.is_multiple_of(2) { 0.0 } else { 0.3 };
        z
    };
    for k in 0..4 {
        let z = z_at(k);
        let step = evo.forward(evo.frames().times()[k], &z).unwrap();
        let r = step.residual_norms(&z, layout, 2.0).unwrap();
        let t = step.thetas();
        match k {
            0 | 1 => assert!(r.is_none() && t.is_none(), "no prior before h = 2"),
            _ => {
                let r = r.as_ref().unwrap();
                let prior = step.prior().unwrap();
                for i in 0..2 {
                    let expected = (0..3)
                        .map(|j| (z[i * 10 + j] - prior[i * 10 + j]).powi(2))
                        .sum::<f32>()
                        .sqrt()
                        / 2.0;
                    assert!((r[i] - expected).abs() < 1e-6, "{} vs {expected}", r[i]);
                }
                assert_eq!(t.is_some(), k == 3, "θ only with h = 3");
            }
        }
        stats.add_evolution(r.as_deref(), t.as_deref()).unwrap();
        evo.commit(&step).unwrap();
    }
    assert_eq!(stats.residual_count, vec![2, 2]);
    assert_eq!(stats.theta_count, vec![1, 1]);
    assert!(
        stats.mean_residual(0) < 1e-6,
        "steady motion is predicted exactly"
    );
    assert!(stats.mean_residual(1) > 0.05);
    // Not exactly 0: DESIGN §4.7's θ divides by |v1||v2| + 1e-6 (here |v|² = 0.01, so θ ≈ 0.014).
    assert!(stats.mean_theta(0) < 0.05, "{}", stats.mean_theta(0));
    assert!(stats.mean_theta(1) > 1.0, "{}", stats.mean_theta(1));
}

#[test]
fn max_gaussians_keeps_the_largest_gradients_and_never_grows_past_the_cap() {
    // Five small Gaussians (clone candidates) and two large ones (split candidates, 2 children),
    // all above the gradient threshold; gradients make the order 6, 2, 5, 0, 3, 4, 1.
    let mut g = gaussians(7, 0.005);
    g.log_scales[5] = [0.05f32.ln(); 3];
    g.log_scales[6] = [0.05f32.ln(); 3];
    let grads = [0.004, 0.001, 0.006, 0.003, 0.002, 0.005, 0.007];
    let stats = stats_with_grads(&grads);
    let uncapped = plan_at(&standard(), &g, &stats, 600);
    assert_eq!(uncapped.new_len(), 7 + 5 + 2);
    assert_eq!(uncapped.summary.capped, 0);
    for max in [0, 7, 8, 9, 10, 11, 13, 14, 20] {
        let config = DensifyConfig {
            max_gaussians: Some(max),
            ..standard()
        };
        let plan = plan_at(&config, &g, &stats, 600);
        assert!(
            plan.new_len() <= max.max(7),
            "cap {max}: {} rows",
            plan.new_len()
        );
        // Greedy by gradient: 6 splits (+1), 2 clones (+1), 5 splits (+1), then clones 0, 3, 4, 1.
        let expected = 7 + (max.saturating_sub(7)).min(7);
        assert_eq!(plan.new_len(), expected, "cap {max}");
        let densified = plan.summary.cloned + plan.summary.split;
        assert_eq!(densified + plan.summary.capped, 7, "cap {max}");
    }
    // At cap 9 the two largest gradients (split 6, clone 2) grow the set.
    let config = DensifyConfig {
        max_gaussians: Some(9),
        ..standard()
    };
    let plan = plan_at(&config, &g, &stats, 600);
    assert_eq!((plan.summary.split, plan.summary.cloned), (1, 1));
    assert_eq!(plan.rows.parent_from_new, vec![2, 6, 6]);
    assert!(
        plan.summary.to_string().contains("capped 5"),
        "{}",
        plan.summary
    );
}

/// A container that keeps its own rows follows the plan through `Planned`; its refusal is the
/// plan's error, naming the container, and no array is left at a row count of its own.
#[test]
fn planned_containers_follow_the_plan_and_name_themselves_when_they_refuse() {
    use densify::{DensifyPlan, Planned};
    use splat_core::{FollowsRowPlan, RowPlan};

    struct Tags {
        rows: Vec<u32>,
        refuse: bool,
    }
    impl FollowsRowPlan for Tags {
        fn label(&self) -> String {
            "tag store".into()
        }
        fn row_count(&self) -> usize {
            self.rows.len()
        }
        fn follow(
            &mut self,
            plan: &RowPlan,
        ) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
            if self.refuse {
                return Err("read-only".into());
            }
            Ok(plan.apply(&mut self.rows, 1, NewRows::CopyParent)?)
        }
    }
    let plan = DensifyPlan {
        rows: RowPlan {
            kept: vec![0, 2],
            parent_from_new: Vec::new(),
        },
        ..DensifyPlan::identity(3)
    };
    let mut tags = Tags {
        rows: vec![10, 11, 12],
        refuse: false,
    };
    apply_plan(&plan, &mut [&mut Planned(&mut tags)]).unwrap();
    assert_eq!(tags.rows, [10, 12]);
    let mut tags = Tags {
        rows: vec![10, 11, 12],
        refuse: true,
    };
    let e = apply_plan(&plan, &mut [&mut Planned(&mut tags)]).unwrap_err();
    assert!(matches!(e, DensifyError::Container { .. }), "{e}");
    assert_eq!(
        e.to_string(),
        "densify: applying the row plan to the tag store: read-only"
    );
}
