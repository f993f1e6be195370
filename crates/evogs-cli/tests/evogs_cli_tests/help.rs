//! `evogs --help` and each subcommand's help, as snapshots of the real binary's output.

use crate::support;

use support::{evogs, ok};

fn help(args: &[&str]) -> String {
    ok(&evogs(args))
}

#[test]
fn top_level_help() {
    insta::assert_snapshot!("evogs_help", help(&["--help"]));
}

#[test]
fn render_help() {
    let text = help(&["render", "--help"]);
    assert_eq!(text, help(&["help", "render"]));
    insta::assert_snapshot!("evogs_render_help", text);
}

#[test]
fn no_subcommand_shows_usage_and_fails() {
    let out = evogs(&[]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("Usage: evogs"));
}

#[test]
fn train_eval_export_video_help() {
    for name in ["train", "eval", "export", "video"] {
        let text = help(&[name, "--help"]);
        assert_eq!(text, help(&["help", name]));
        insta::assert_snapshot!(format!("evogs_{name}_help"), text);
    }
}

#[test]
fn ablate_help() {
    let text = help(&["ablate", "--help"]);
    assert_eq!(text, help(&["help", "ablate"]));
    insta::assert_snapshot!("evogs_ablate_help", text);
}

#[test]
fn bench_help() {
    let text = help(&["bench", "--help"]);
    assert_eq!(text, help(&["help", "bench"]));
    insta::assert_snapshot!("evogs_bench_help", text);
}
