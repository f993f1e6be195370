//! Snapshot of plan summaries for a fixed, seeded scene of 1024 Gaussians under each policy.

use densify::{
    Deformation, DensifyConfig, DensifyStats, PlanInput, Trigger, apply_plan, make_plan,
};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use splat_core::Gaussians;
use splat_core::Layout;
use splat_core::logit;
use std::fmt::Write;

fn scene() -> (Gaussians, DensifyStats, Vec<f32>) {
    let n = 1024;
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    let mut g = Gaussians::with_degree(0);
    let mut stats = DensifyStats::new(n);
    for i in 0..n {
        g.means.push([
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            0.0,
        ]);
        let s: f32 = rng.random_range(0.002f32..0.25);
        g.log_scales.push([s.ln(), (0.5 * s).ln(), (0.5 * s).ln()]);
        g.rotations.push([1.0, 0.0, 0.0, 0.0]);
        g.opacity_logits
            .push(logit(rng.random_range(0.001f32..0.99)));
        g.sh.extend([0.1, 0.2, 0.3]);
        stats.grad_sum[i] = rng.random_range(0.0f32..0.0004) * 4.0;
        stats.visible[i] = 4;
        stats.max_radius[i] = rng.random_range(0.0f32..25.0);
        stats.residual_sum[i] = rng.random_range(0.0f32..0.015) * 3.0;
        stats.residual_count[i] = 3;
        stats.theta_sum[i] = rng.random_range(0.0f32..1.6) * 2.0;
        stats.theta_count[i] = 2;
    }
    let corrected = (0..n * 10).map(|_| rng.random_range(-0.05..0.05)).collect();
    (g, stats, corrected)
}

#[test]
fn plan_summaries_per_policy() {
    let (g, stats, corrected) = scene();
    let policies = [
        ("3DGS", DensifyConfig::default()),
        (
            "3DGS + trigger",
            DensifyConfig {
                trigger: Some(Trigger::default()),
                ..DensifyConfig::default()
            },
        ),
        (
            "3DGS + deformation-aware",
            DensifyConfig {
                deformation_alpha: Some(0.5),
                ..DensifyConfig::default()
            },
        ),
        ("EvoGS (both)", DensifyConfig::evogs()),
        (
            "3DGS + screen prune at 20 px (the paper's)",
            DensifyConfig {
                max_screen_radius: Some(20.0),
                ..DensifyConfig::default()
            },
        ),
        (
            "prune only",
            DensifyConfig {
                clone: false,
                split: false,
                ..DensifyConfig::default()
            },
        ),
    ];
    let mut out = String::new();
    for iteration in [600, 3000, 3100] {
        for (name, config) in &policies {
            let plan = make_plan(
                config,
                &PlanInput {
                    gaussians: g.view(),
                    stats: &stats,
                    extent: 2.0,
                    iteration,
                    deformation: Some(Deformation {
                        corrected: &corrected,
                        layout: Layout::default(),
                    }),
                },
            )
            .unwrap();
            let mut after = g.clone();
            apply_plan(&plan, &mut [&mut after]).unwrap();
            assert_eq!(after.len(), plan.summary.after);
            writeln!(out, "iteration {iteration}, {name}: {}", plan.summary).unwrap();
        }
    }
    insta::assert_snapshot!(out);
}
