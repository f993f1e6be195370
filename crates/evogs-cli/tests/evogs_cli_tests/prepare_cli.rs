//! `evogs prepare` end to end on a procedural video (ffmpeg and COLMAP, installed by
//! `scripts/test`): frames registered, camera centres against the ground truth after a
//! similarity alignment, then a short training that beats an untrained model; and bad inputs,
//! each a one-line error that leaves nothing behind.

use crate::support;

use std::path::Path;

use evogs_io::{LoadOptions, load_dataset};
use glam::Vec3;
use support::capture;
use support::{evogs, s, stderr};

/// Frames of the test clip (3 s at 12 frames per second).
const FRAMES: usize = 36;

/// Only the named entries are in `dir` (no temporary folder left beside a failed output).
fn assert_only(dir: &Path, names: &[&str]) {
    let mut found: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    found.sort();
    let mut want: Vec<String> = names.iter().map(|n| n.to_string()).collect();
    want.sort();
    assert_eq!(found, want, "in {}", dir.display());
}

fn mean_psnr(run: &Path) -> f64 {
    let text = std::fs::read_to_string(run.join("eval_test.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    json["mean_psnr"].as_f64().unwrap()
}

#[test]
fn a_video_becomes_a_dataset_that_trains() {
    let root = tempfile::tempdir().unwrap();
    let started = std::time::Instant::now();
    let renders = root.path().join("renders");
    capture::render_frames(&renders, FRAMES);
    let clip = root.path().join("clip.mp4");
    capture::encode_mp4(&renders, &clip);
    eprintln!(
        "clip rendered and encoded at {:.1} s",
        started.elapsed().as_secs_f64()
    );

    let data = root.path().join("data");
    let out = evogs(&["prepare", "--video", s(&clip), "--out", s(&data)]);
    let log = stderr(&out);
    assert!(out.status.success(), "{log}");
    eprint!("{log}");
    for stage in ["frames", "features", "matching", "mapping", "dataset"] {
        assert!(log.contains(&format!("] {stage} done in")), "{log}");
    }
    // A clip that registers whole and is not cropped gets no warning (prepare's own tests
    // check the dropped and cropped cases).
    assert!(!log.contains("warning:"), "{log}");
    for name in ["frames", "features", "matching", "mapping"] {
        assert!(data.join("logs").join(format!("{name}.log")).is_file());
    }
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(data.join("prepare.json")).unwrap()).unwrap();
    assert_eq!(summary["frames"], FRAMES);

    // At least 90% registered.
    let all = LoadOptions {
        colmap_llff_hold: 0,
        ..LoadOptions::default()
    };
    let dataset = load_dataset(&data, &all).unwrap();
    let frames = &dataset.train;
    assert!(
        frames.len() * 10 >= FRAMES * 9,
        "{} of {FRAMES} registered",
        frames.len()
    );
    assert!(frames.iter().all(|f| f.camera.is_pinhole()));
    let index = |p: &Path| -> usize {
        let name = p.file_stem().unwrap().to_str().unwrap();
        name.trim_start_matches("frame_").parse().unwrap()
    };
    // Each frame keeps its time in the clip (times.json), whichever frames were registered.
    assert!(data.join("times.json").is_file());
    let last = (FRAMES - 1) as f32;
    for f in frames {
        let want = index(&f.image_path) as f32 / last;
        assert!(
            (f.time - want).abs() < 1e-6,
            "{}: {}",
            f.image_path.display(),
            f.time
        );
    }
    // Camera centres within 2% of the scene extent of the truth, after a similarity alignment.
    let got: Vec<Vec3> = frames.iter().map(|f| f.camera.camera.center()).collect();
    let want: Vec<Vec3> = frames
        .iter()
        .map(|f| capture::camera(index(&f.image_path), FRAMES).center())
        .collect();
    let aligned = capture::align_similarity(&got, &want);
    let worst = aligned
        .iter()
        .zip(&want)
        .map(|(a, b)| (*a - *b).length())
        .fold(0.0f32, f32::max);
    let extent = capture::extent();
    eprintln!(
        "registered {} of {FRAMES}; worst centre error {worst:.4} = {:.3}% of the extent {extent:.2}",
        frames.len(),
        100.0 * worst / extent
    );
    assert!(worst <= 0.02 * extent, "worst centre error {worst}");

    // A short training beats an untrained model on the held-out frames.
    let run = |dir: &Path, iterations: &str| {
        let out = evogs(&[
            "train",
            "--data",
            s(&data),
            "--out",
            s(dir),
            "--preset",
            "tiny",
            "--iterations",
            iterations,
            "--downscale",
            "2",
        ]);
        assert!(out.status.success(), "{}", stderr(&out));
        let out = evogs(&["eval", "--run", s(dir)]);
        assert!(out.status.success(), "{}", stderr(&out));
        mean_psnr(dir)
    };
    let untrained = run(&root.path().join("untrained"), "1");
    let trained = run(&root.path().join("trained"), "300");
    eprintln!(
        "trained and evaluated at {:.1} s",
        started.elapsed().as_secs_f64()
    );
    eprintln!("test PSNR: untrained {untrained:.2} dB, trained {trained:.2} dB");
    assert!(
        trained > untrained + 5.0,
        "trained {trained} vs untrained {untrained}"
    );
}

#[test]
fn bad_inputs_are_one_line_errors_that_leave_nothing() {
    let root = tempfile::tempdir().unwrap();
    let check = |args: &[&str], out: &Path, file: &str, problem: &str| {
        let output = evogs(args);
        assert!(!output.status.success());
        let all = stderr(&output);
        // Progress lines (`[k/6] …`) may precede it; the error itself is one line.
        let rest: Vec<&str> = all.lines().filter(|l| !l.starts_with('[')).collect();
        assert_eq!(rest.len(), 1, "{all}");
        let text = rest[0];
        assert!(text.starts_with("evogs: error: "), "{all}");
        assert!(text.contains(file), "expected `{file}` in: {text}");
        assert!(text.contains(problem), "expected `{problem}` in: {text}");
        assert!(!out.exists(), "{} was left behind", out.display());
    };
    // A "video" that ffmpeg cannot decode.
    let inputs = root.path().join("inputs");
    std::fs::create_dir_all(&inputs).unwrap();
    let clip = inputs.join("broken.mp4");
    std::fs::write(&clip, b"these bytes are not a video").unwrap();
    let out = root.path().join("out");
    check(
        &["prepare", "--video", s(&clip), "--out", s(&out)],
        &out,
        "broken.mp4",
        "no decodable video frames",
    );
    // The input of the other kind: a file for --images, a folder for --video.
    check(
        &["prepare", "--images", s(&clip), "--out", s(&out)],
        &out,
        "broken.mp4",
        "--images: is a file, not a folder of images (use --video)",
    );
    check(
        &["prepare", "--video", s(&inputs), "--out", s(&out)],
        &out,
        "inputs",
        "--video: is a folder (use --images)",
    );
    // A folder of one image.
    let one = inputs.join("one");
    std::fs::create_dir_all(&one).unwrap();
    capture::render_blank(&one.join("a.png"), 0.5);
    check(
        &["prepare", "--images", s(&one), "--out", s(&out)],
        &out,
        "one",
        "1 image file(s)",
    );
    // Blank frames: nothing for SIFT, nothing registers.
    let blank = inputs.join("blank");
    std::fs::create_dir_all(&blank).unwrap();
    for k in 0..6 {
        capture::render_blank(&blank.join(format!("{k:02}.png")), 0.1 * k as f32);
    }
    let logs = root.path().join("out.logs");
    check(
        &["prepare", "--images", s(&blank), "--out", s(&out)],
        &out,
        "blank",
        "COLMAP registered 0 of 6 frames",
    );
    // COLMAP's logs outlive its failure, named in the error line (checked by `check` through
    // the folder's name), beside the output that was not made.
    let output = evogs(&["prepare", "--images", s(&blank), "--out", s(&out)]);
    assert!(
        stderr(&output).contains(&format!("the stages' logs are in {}", logs.display())),
        "{}",
        stderr(&output)
    );
    for stage in ["features", "matching", "mapping"] {
        assert!(logs.join(format!("{stage}.log")).is_file(), "{stage}.log");
    }
    std::fs::remove_dir_all(&logs).unwrap();
    // Nothing else is left: no temporary folders beside the output.
    assert_only(root.path(), &["inputs"]);
    // An existing output is never overwritten.
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("keep.txt"), b"mine").unwrap();
    let output = evogs(&["prepare", "--images", s(&blank), "--out", s(&out)]);
    assert!(!output.status.success());
    assert!(stderr(&output).contains("already exists"));
    assert_only(&out, &["keep.txt"]);
}
