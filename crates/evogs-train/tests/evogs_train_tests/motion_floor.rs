//! The trainer's motion floor (DESIGN §4.7's θ, with the trainer's deliberate floor) through
//! densify's uncertainty trigger: a still Gaussian whose evolved position jitters below the floor
//! gets θ = 0 and densifies; a Gaussian that genuinely turns is still blocked. With evo-state's
//! default floor (1e-6 of the extent) the same jitter blocks the still Gaussian, which is the
//! failure the trainer's floor fixes.

use densify::{DensifyStats, PlanInput, make_plan};
use evo_state::EvoState;
use evogs_backbones::evo_settings::TRAINER_MOTION_FLOOR;
use evogs_backbones::{EvoConfig, EvoSettings};
use evogs_train::trainer::densify_config;
use evogs_train::{Method, Preset, TrainConfig};
use splat_raster::Gaussians;

const EXTENT: f32 = 7.0;
const D: usize = 10;

/// Commits `positions[k]` (frames 0, 1, 2; rotation and scale offsets zero) for every Gaussian,
/// in reverse order so that each commit sees no history and stores exactly z; then queries
/// frame 3 with z equal to the prior, so the residual is zero and only θ can block.
fn step_at_frame_3(
    settings: &EvoSettings,
    positions: &[[[f32; 3]; 3]],
) -> (EvoState, evo_state::Step) {
    let n = positions.len();
    let frames = evo_state::Frames::from_timestamps([0.0, 0.25, 0.5, 0.75, 1.0]).unwrap();
    let config = EvoConfig {
        extent: EXTENT,
        ..settings.evo
    };
    let mut st = EvoState::new(config, frames, n, 3).unwrap();
    let row = |p: [f32; 3]| {
        let mut r = [0.0f32; D];
        r[..3].copy_from_slice(&p);
        r
    };
    for k in (0..3).rev() {
        let z: Vec<f32> = positions.iter().flat_map(|p| row(p[k])).collect();
        let t = st.frames().times()[k];
        let step = st.forward(t, &z).unwrap();
        assert_eq!(step.history().len, 0);
        st.commit(&step).unwrap();
    }
    // Prior at frame 3 (uniform spacing, s = 1): 2 x_2 − x_1.
    let z: Vec<f32> = positions
        .iter()
        .flat_map(|p| row(std::array::from_fn(|j| 2.0 * p[2][j] - p[1][j])))
        .collect();
    let step = st.forward(st.frames().times()[3], &z).unwrap();
    (st, step)
}

/// Runs the trigger on one densification step for Gaussians with the given history; returns
/// their θ and the plan's summary.
fn trigger(
    motion_floor: f32,
    positions: &[[[f32; 3]; 3]],
) -> (Vec<f32>, densify::PlanSummary, Vec<u32>) {
    let defaults = EvoSettings::default();
    let settings = EvoSettings {
        evo: EvoConfig {
            motion_floor,
            ..defaults.evo
        },
        ..defaults
    };
    let (_, step) = step_at_frame_3(&settings, positions);
    let theta = step.thetas().expect("three history frames give statistics");
    let n = positions.len();
    let layout = settings.evo.layout;
    let z = {
        // The same z the step was made with: the prior, so every residual is zero.
        step.prior().unwrap().to_vec()
    };
    let residual = step.residual_norms(&z, layout, EXTENT).unwrap();

    let mut config = TrainConfig::preset(Preset::Tiny);
    config.method = Method::Evogs;
    config.backbones.evogs = settings;
    let densify = densify_config(&config);
    assert!(
        densify.trigger.is_some(),
        "EvoGS's default policy has the trigger"
    );
    let iteration = (1..100_000)
        .find(|&i| densify.schedule.densifies(i) && !densify.schedule.resets_opacity(i))
        .unwrap();

    let mut stats = DensifyStats::new(n);
    // A large projected-mean gradient (0.01 px on a 64-pixel image: 0.32 in NDC units) for all.
    stats
        .add_view(&vec![[0.01, 0.0]; n], &vec![2.0; n], 64, 64)
        .unwrap();
    stats
        .add_evolution(residual.as_deref(), Some(&theta))
        .unwrap();

    let mut g = Gaussians::with_degree(0);
    for i in 0..n {
        g.means.push([i as f32 * 0.5, 0.0, 0.0]);
        // Small (clone, not split) and opaque (not pruned).
        g.log_scales.push([(0.001 * EXTENT).ln(); 3]);
        g.rotations.push([1.0, 0.0, 0.0, 0.0]);
        g.opacity_logits.push(2.0);
        g.sh.extend([0.1, 0.2, 0.3]);
    }
    let plan = make_plan(
        &densify,
        &PlanInput {
            gaussians: g.view(),
            stats: &stats,
            extent: EXTENT,
            iteration,
            deformation: None,
        },
    )
    .unwrap();
    (theta, plan.summary, plan.rows.parent_from_new)
}

/// Still, with jitter whose consecutive "velocities" are perpendicular (the paper's θ = π/2),
/// each of size `a`·extent per frame spacing.
fn jitter(a: f32) -> [[f32; 3]; 3] {
    let a = a * EXTENT;
    [[a, 0.0, 0.0], [0.0, a, 0.0], [-a, 0.0, 0.0]]
}

/// Moving at `a`·extent per frame spacing along +x, then turning 90° to +y.
fn turning(a: f32) -> [[f32; 3]; 3] {
    let a = a * EXTENT;
    [[0.0; 3], [a, 0.0, 0.0], [a, a, 0.0]]
}

#[test]
fn still_gaussian_below_the_floor_densifies_and_a_turning_one_is_blocked() {
    let f = TRAINER_MOTION_FLOOR;
    // Jitter of 0.3 floor per axis: both velocities are 0.3·√2 ≈ 0.42 floor, below it.
    let (theta, summary, parents) = trigger(f, &[jitter(0.3 * f), turning(10.0 * f)]);
    assert_eq!(theta[0], 0.0, "still Gaussian: θ = 0 below the floor");
    assert!(
        (theta[1] - std::f32::consts::FRAC_PI_2).abs() < 1e-3,
        "turning Gaussian: θ = π/2, got {}",
        theta[1]
    );
    assert_eq!(summary.cloned, 1, "{summary}");
    assert_eq!(summary.blocked, Some(1), "{summary}");
    assert_eq!(
        parents,
        vec![0],
        "the clone descends from the still Gaussian"
    );
}

#[test]
fn with_specs_floor_the_same_jitter_blocks_the_still_gaussian() {
    let spec_floor = evo_state::EvoConfig::default().motion_floor;
    assert_eq!(spec_floor, 1e-6, "evo-state keeps the paper's default");
    let (theta, summary, _) = trigger(spec_floor, &[jitter(0.3 * TRAINER_MOTION_FLOOR)]);
    assert!(
        (theta[0] - std::f32::consts::FRAC_PI_2).abs() < 1e-3,
        "{}",
        theta[0]
    );
    assert_eq!(summary.cloned, 0, "{summary}");
    assert_eq!(summary.blocked, Some(1), "{summary}");
}

#[test]
fn motion_just_above_the_floor_is_measured() {
    // A straight path at 2 floors per frame spacing: θ ≈ 0 because it is consistent, not
    // because of the floor (DESIGN §4.7's ε = 1e-6 in the denominator keeps it slightly above 0);
    // reversing it gives θ ≈ π, which blocks.
    let f = TRAINER_MOTION_FLOOR;
    let a = 2.0 * f * EXTENT;
    let straight = [[0.0; 3], [a, 0.0, 0.0], [2.0 * a, 0.0, 0.0]];
    let back = [[0.0; 3], [a, 0.0, 0.0], [0.0, 0.0, 0.0]];
    let (theta, summary, parents) = trigger(f, &[straight, back]);
    let a2 = f64::from(a) * f64::from(a);
    let cos = a2 / (a2 + 1e-6);
    assert!(
        (f64::from(theta[0]) - cos.acos()).abs() < 1e-3,
        "{}",
        theta[0]
    );
    assert!(
        (f64::from(theta[1]) - (-cos).acos()).abs() < 1e-3,
        "{}",
        theta[1]
    );
    assert!(theta[0] < std::f32::consts::FRAC_PI_3 && theta[1] > 2.5);
    assert_eq!(summary.blocked, Some(1), "{summary}");
    assert_eq!(parents, vec![0]);
}

#[test]
fn settings_record_the_floor_and_old_configs_read_specs() {
    let s = EvoSettings::default();
    assert_eq!(s.evo.motion_floor, TRAINER_MOTION_FLOOR);
    let mut json = serde_json::to_value(&s).unwrap();
    assert_eq!(
        json["motion_floor"],
        serde_json::json!(TRAINER_MOTION_FLOOR)
    );
    json.as_object_mut().unwrap().remove("motion_floor");
    let old: EvoSettings = serde_json::from_value(json).unwrap();
    assert_eq!(
        old.evo.motion_floor, 1e-6,
        "runs written before the field trained with the paper's"
    );
    let mut bad = EvoSettings::default();
    bad.evo.motion_floor = f32::NAN;
    let e = bad.validate().unwrap_err().to_string();
    assert!(e.contains("evogs.motion_floor"), "{e}");
}
