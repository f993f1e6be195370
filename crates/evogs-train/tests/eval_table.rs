//! The evaluation table's format (insta snapshot) on a tiny trained run, with the digits masked
//! (the values depend on floating-point details of the machine; the layout must not), and the
//! JSON report's consistency with it.

mod common;

use evogs_io::Split;
use evogs_train::eval::{EvalReport, evaluate, markdown};
use evogs_train::{LoadedRun, Preset, TrainConfig, TrainRequest, train};

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
    let data = dir.path().join("scene");
    common::write_scene(&data);
    let out = dir.path().join("run");
    let mut config = TrainConfig::preset(Preset::Tiny).with_iterations(40);
    config.init_points = 300;
    train(
        &TrainRequest {
            data,
            out: out.clone(),
            config,
            resume: false,
            stop_after: None,
            resume_backend: None,
        },
        &mut |_, _| {},
    )
    .unwrap();
    let mut run = LoadedRun::open(&out).unwrap();
    let report = evaluate(&mut run, Split::Val).unwrap();
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
}
