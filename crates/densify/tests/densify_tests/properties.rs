//! Property tests: after any plan every per-Gaussian array has the same length, kept rows keep
//! their data, and each new row inherits its parent's data except the documented overridden
//! parameter values (which match the rule that produced them).

// Index loops mirror the row arithmetic being checked.
#![allow(clippy::needless_range_loop)]

use densify::{
    Deformation, DensifyConfig, DensifyStats, Moments, PlanInput, Planned, Rows, Trigger,
    apply_plan, make_plan,
};
use evo_state::{EvoConfig, EvoState, Frames, Storage};
use proptest::prelude::*;
use splat_core::Gaussians;
use splat_core::logit;
use splat_core::{Layout, NewRows};
use tiny_nn::adam::{Adam, LrSchedule};

#[derive(Debug, Clone)]
struct Row {
    log_scale: [f32; 3],
    opacity: f32,
    grad: f32,
    radius: f32,
    residual: f32,
    theta: f32,
    deformation: [f32; 10],
    z: [[f32; 10]; 3],
}

fn row() -> impl Strategy<Value = Row> {
    (
        proptest::array::uniform3(0.001f32..0.2),
        0.001f32..0.99,
        prop_oneof![Just(0.0f32), 0.0f32..0.0006],
        0.0f32..30.0,
        0.0f32..0.02,
        0.0f32..2.0,
        proptest::array::uniform10(-0.2f32..0.2),
        proptest::array::uniform3(proptest::array::uniform10(-1.0f32..1.0)),
    )
        .prop_map(
            |(s, opacity, grad, radius, residual, theta, deformation, z)| Row {
                log_scale: s.map(f32::ln),
                opacity,
                grad,
                radius,
                residual,
                theta,
                deformation,
                z,
            },
        )
}

#[derive(Debug, Clone)]
struct Switches {
    clone: bool,
    split: bool,
    prune: bool,
    reset: bool,
    trigger: bool,
    deform: bool,
    iteration: u64,
    seed: u64,
}

fn switches() -> impl Strategy<Value = Switches> {
    (
        proptest::array::uniform6(any::<bool>()),
        prop_oneof![
            Just(600u64),
            Just(650),
            Just(3000),
            Just(3100),
            Just(14_900)
        ],
        any::<u64>(),
    )
        .prop_map(|(b, iteration, seed)| Switches {
            clone: b[0],
            split: b[1],
            prune: b[2],
            reset: b[3],
            trigger: b[4],
            deform: b[5],
            iteration,
            seed,
        })
}

const D: usize = 10;
const PACKED: usize = 14; // mean 3, log-scale 3, rotation 4, opacity 1 (column 10), SH DC 3

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn every_array_stays_aligned_and_children_inherit(
        rows in proptest::collection::vec(row(), 1..24),
        sw in switches(),
    ) {
        let n = rows.len();
        let mut g = Gaussians::with_degree(1);
        let stride = g.sh_stride();
        for (i, r) in rows.iter().enumerate() {
            g.means.push([i as f32, -(i as f32), 0.5]);
            g.log_scales.push(r.log_scale);
            g.rotations.push([1.0, 0.1 * i as f32, 0.0, -0.2]);
            g.opacity_logits.push(logit(r.opacity));
        }
        g.sh = (0..n * stride).map(|e| e as f32 * 0.01).collect();
        let mut stats = DensifyStats::new(n);
        for (i, r) in rows.iter().enumerate() {
            stats.grad_sum[i] = 2.0 * r.grad;
            stats.visible[i] = 2;
            stats.max_radius[i] = r.radius;
            stats.residual_sum[i] = r.residual;
            stats.residual_count[i] = 1;
            stats.theta_sum[i] = r.theta;
            stats.theta_count[i] = 1;
        }
        let corrected: Vec<f32> = rows.iter().flat_map(|r| r.deformation).collect();
        let layout = Layout::default();
        let config = DensifyConfig {
            clone: sw.clone,
            split: sw.split,
            prune: sw.prune,
            opacity_reset: sw.reset,
            trigger: sw.trigger.then(Trigger::default),
            deformation_alpha: sw.deform.then_some(0.5),
            seed: sw.seed,
            ..DensifyConfig::default()
        };
        let plan = make_plan(&config, &PlanInput {
            gaussians: g.view(),
            stats: &stats,
            extent: 1.0,
            iteration: sw.iteration,
            deformation: Some(Deformation { corrected: &corrected, layout }),
        }).unwrap();

        // The other per-Gaussian arrays of a run.
        let mut evo = EvoState::new(
            EvoConfig { storage: Storage::F16, ..EvoConfig::default() },
            Frames::new(vec![0.0, 0.25, 0.5, 0.75]).unwrap(),
            n,
            3,
        ).unwrap();
        for k in 0..3 {
            let z: Vec<f32> = rows.iter().flat_map(|r| r.z[k]).collect();
            let step = evo.forward(evo.frames().times()[k], &z).unwrap();
            evo.commit(&step).unwrap();
        }
        let evo_before = evo.clone();
        let mut adam = Adam::new();
        let id = adam.add_group("packed", n * PACKED, PACKED, LrSchedule::Constant(1e-3)).unwrap();
        let ms: Vec<f32> = (0..n * PACKED).map(|e| e as f32 + 1.0).collect();
        let vs: Vec<f32> = (0..n * PACKED).map(|e| e as f32 + 0.5).collect();
        adam.group_mut(id).m.copy_from_slice(&ms);
        adam.group_mut(id).v.copy_from_slice(&vs);
        let moments_before = adam.group(id).clone();
        let mut tags: Vec<u32> = (0..n as u32).collect();
        let mut after = g.clone();
        let mut after_stats = stats.clone();
        {
            let mut moments = Moments { group: adam.group_mut(id), opacity_column: Some(10) };
            let mut tag_rows = Rows { label: "tags", data: &mut tags, stride: 1, fill: NewRows::CopyParent };
            apply_plan(&plan, &mut [&mut after, &mut moments, &mut Planned(&mut evo), &mut after_stats, &mut tag_rows]).unwrap();
        }

        let m = plan.new_len();
        let s = &plan.summary;
        prop_assert_eq!(s.after, m);
        prop_assert_eq!(s.before + s.cloned + s.children, m + s.split + s.pruned());
        prop_assert!(after.view().check_lengths().is_ok());
        prop_assert_eq!(after.len(), m);
        prop_assert_eq!(adam.group(id).m.len(), m * PACKED);
        prop_assert_eq!(adam.group(id).v.len(), m * PACKED);
        prop_assert_eq!(evo.rows(), m);
        prop_assert_eq!(evo.memory_bytes(), m * D * Storage::F16.bytes() * evo.frames().len());
        prop_assert_eq!(after_stats.len(), m);
        prop_assert!(after_stats.check().is_ok());
        prop_assert_eq!(tags.len(), m);
        if plan.clears_stats {
            prop_assert_eq!(&after_stats, &DensifyStats::new(m));
        }

        let kept = plan.kept_len();
        let reset_logit = plan.reset_logit();
        let is_reset = |j: usize| plan.reset_rows.binary_search(&(j as u32)).is_ok();
        let ln16 = 1.6f32.ln();
        let alpha = if sw.deform { 0.5 } else { 0.0 };
        let mb = &moments_before;
        let ma = adam.group(id);
        for j in 0..m {
            let (old, new_index) = if j < kept {
                (plan.rows.kept[j] as usize, None)
            } else {
                (plan.rows.parent_from_new[j - kept] as usize, Some(j - kept))
            };
            prop_assert_eq!(tags[j] as usize, old);
            // Evolution buffer and memory (every valid frame) follow the row.
            for k in 0..3 {
                prop_assert_eq!(
                    evo.buffer().unwrap().row(k, j),
                    evo_before.buffer().unwrap().row(k, old)
                );
                prop_assert_eq!(
                    evo.memory().unwrap().row(k, j),
                    evo_before.memory().unwrap().row(k, old)
                );
            }
            // SH beyond DC is always the parent's.
            prop_assert_eq!(&after.sh[j * stride + 3..(j + 1) * stride], &g.sh[old * stride + 3..(old + 1) * stride]);
            let opacity_before_reset = match new_index {
                None => {
                    prop_assert_eq!(after.means[j], g.means[old]);
                    prop_assert_eq!(after.log_scales[j], g.log_scales[old]);
                    prop_assert_eq!(after.rotations[j], g.rotations[old]);
                    prop_assert_eq!(&after.sh[j * stride..j * stride + 3], &g.sh[old * stride..old * stride + 3]);
                    for c in 0..PACKED {
                        let e = j * PACKED + c;
                        let zeroed = c == 10 && is_reset(j);
                        let (em, ev) = if zeroed { (0.0, 0.0) } else { (mb.m[old * PACKED + c], mb.v[old * PACKED + c]) };
                        prop_assert_eq!(ma.m[e], em);
                        prop_assert_eq!(ma.v[e], ev);
                    }
                    g.opacity_logits[old]
                }
                Some(k) => {
                    let v = &plan.new_values;
                    prop_assert_eq!(after.means[j], v.means[k]);
                    prop_assert_eq!(after.log_scales[j], v.log_scales[k]);
                    prop_assert_eq!(after.rotations[j], v.rotations[k]);
                    prop_assert_eq!(&after.sh[j * stride..j * stride + 3], &v.sh_dc[k][..]);
                    prop_assert!(ma.m[j * PACKED..(j + 1) * PACKED].iter().all(|&x| x == 0.0));
                    prop_assert!(ma.v[j * PACKED..(j + 1) * PACKED].iter().all(|&x| x == 0.0));
                    // The overridden values follow the rule: source = canonical + α·d̃
                    // (position 0..3, rotation 3..7, scale 7..10 of the default layout).
                    let d = &rows[old].deformation;
                    let close = |a: f32, b: f32| (a - b).abs() <= 1e-5 * (1.0 + b.abs());
                    for c in 0..4 {
                        prop_assert!(close(v.rotations[k][c], g.rotations[old][c] + alpha * d[3 + c]));
                    }
                    prop_assert_eq!(v.opacity_logits[k], g.opacity_logits[old]);
                    prop_assert_eq!(&v.sh_dc[k][..], &g.sh[old * stride..old * stride + 3]);
                    let source_ls: Vec<f32> = (0..3).map(|c| g.log_scales[old][c] + alpha * d[7 + c]).collect();
                    let is_clone = (0..3).all(|c| close(v.log_scales[k][c], source_ls[c]));
                    let is_split = (0..3).all(|c| close(v.log_scales[k][c], source_ls[c] - ln16));
                    prop_assert!(is_clone || is_split);
                    if is_clone {
                        for c in 0..3 {
                            prop_assert!(close(v.means[k][c], g.means[old][c] + alpha * d[c]));
                        }
                    }
                    v.opacity_logits[k]
                }
            };
            let expected_opacity = if is_reset(j) { opacity_before_reset.min(reset_logit) } else { opacity_before_reset };
            prop_assert_eq!(after.opacity_logits[j], expected_opacity);
        }
    }
}
