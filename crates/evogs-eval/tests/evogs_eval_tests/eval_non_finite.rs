//! Evaluation catches non-finite *deformed* Gaussians (issue Q): a run whose canonical
//! Gaussians are finite but whose deformation network overflows at every time is reported as
//! such (views and Gaussians counted, a line in the table), and a healthy run reports none.

use crate::common;

use evogs_eval::eval::{EvalLpips, evaluate, markdown, non_finite_gaussians};
use evogs_io::Split;

#[test]
fn an_exploding_deformation_is_reported_and_a_healthy_one_is_not() {
    let dir = tempfile::tempdir().unwrap();
    let mut run = common::tiny_run(dir.path());
    assert!(run.deforms());
    let lpips = EvalLpips::default();
    let healthy = evaluate(&mut run, Split::Val, &lpips).unwrap();
    assert_eq!(
        (healthy.non_finite_views, healthy.non_finite_gaussians),
        (0, 0)
    );
    assert!(!markdown(&healthy).contains("Non-finite"));

    // Every network weight 1e30: the hidden activations overflow, the deformations are ±inf or
    // NaN, while the canonical Gaussians stay finite.
    assert_eq!(non_finite_gaussians(&run.canonical), 0);
    for (_, mut p) in run.backbone.params_mut() {
        let huge = vec![1e30f32; p.len()];
        p.write_from(&huge);
    }
    let n = run.canonical.len();
    let exploded = evaluate(&mut run, Split::Val, &lpips).unwrap();
    // 4 val views plus the temporal metrics' 4 distinct times.
    assert_eq!(exploded.non_finite_views, 8, "{exploded:?}");
    assert!(
        exploded.non_finite_gaussians > n / 2 && exploded.non_finite_gaussians <= n,
        "{} of {n}",
        exploded.non_finite_gaussians
    );
    assert!(markdown(&exploded).contains("**Non-finite deformed Gaussians** at 8"));
    // The JSON report carries the counts.
    let json = std::fs::read_to_string(run.paths.eval_json(Split::Val)).unwrap();
    let back: evogs_eval::eval::EvalReport = serde_json::from_str(&json).unwrap();
    assert_eq!(back.non_finite_views, 8);
}
