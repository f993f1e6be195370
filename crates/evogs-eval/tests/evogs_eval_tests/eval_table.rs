//! The evaluation table's format (insta snapshot) on a tiny trained run, with the digits masked
//! (the values depend on floating-point details of the machine; the layout must not), and the
//! JSON report's consistency with it.

use crate::common;

use evogs_eval::eval::{EvalLpips, EvalReport, evaluate, markdown};
use evogs_io::Split;
use evogs_metrics::lpips::Backbone;

/// Every run of digits becomes one `#`.
fn mask_digits(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        if !c.is_ascii_digit() {
            out.push(c);
        } else if !out.ends_with('#') {
            out.push('#');
        }
    }
    out
}

#[test]
fn eval_table_of_a_tiny_run() {
    let dir = tempfile::tempdir().unwrap();
    let mut run = common::tiny_run(dir.path());
    // AlexNet LPIPS as `evogs eval` computes it by default (scripts/test installs the weights).
    let lpips = EvalLpips::find(&[Backbone::Alex], None).unwrap();
    assert!(lpips.missing.is_empty(), "{:?}", lpips.missing);
    let report = evaluate(&mut run, Split::Val, &lpips).unwrap();
    assert_eq!(report.images.len(), 4);
    let mean = report.images.iter().map(|i| i.psnr).sum::<f64>() / 4.0;
    assert!((mean - report.mean_psnr).abs() < 1e-9);
    let table = std::fs::read_to_string(run.paths.eval_markdown(Split::Val)).unwrap();
    assert_eq!(table, markdown(&report));
    let back: EvalReport =
        serde_json::from_str(&std::fs::read_to_string(run.paths.eval_json(Split::Val)).unwrap())
            .unwrap();
    // serde_json's float parsing may differ from the written value in the last bit.
    assert_eq!(back.images.len(), report.images.len());
    assert!((back.mean_psnr - report.mean_psnr).abs() < 1e-9);
    assert_eq!(markdown(&back), markdown(&report));
    insta::assert_snapshot!(mask_digits(&table));
    let mean_lpips = report
        .images
        .iter()
        .map(|i| i.lpips_alex.unwrap())
        .sum::<f64>()
        / 4.0;
    assert!((mean_lpips - report.mean_lpips_alex.unwrap()).abs() < 1e-9);
    assert!(mean_lpips > 0.0 && back.mean_lpips_alex.is_some() && back.mean_lpips_vgg.is_none());

    // Without weights: no LPIPS column, and the table says why in one line.
    let mut without = report.clone();
    without.mean_lpips_alex = None;
    without.images.iter_mut().for_each(|i| i.lpips_alex = None);
    without.lpips_missing = vec![
        evogs_metrics::lpips::LpipsError::Missing {
            backbone: Backbone::Alex,
            path: "/nowhere/lpips_alex.safetensors".into(),
        }
        .to_string(),
    ];
    let text = markdown(&without);
    assert!(
        text.contains("| image | time | PSNR (dB) | SSIM |\n"),
        "{text}"
    );
    assert!(
        text.ends_with(
            "\nNot reported: LPIPS alex weights not found at /nowhere/lpips_alex.safetensors; \
         install them with `scripts/lpips-weights` (evogs repository).\n"
        ),
        "{text}"
    );
}
