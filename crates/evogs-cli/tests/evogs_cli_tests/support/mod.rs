//! What the binary's integration tests share: the `evogs` binary and running it, reading its
//! output and files, and the tiny synthetic scenes and runs they train on. Each test module
//! uses what it needs (`use crate::support;`).

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

pub mod capture;
pub mod cdp;
pub mod view;

/// The `evogs` binary Cargo built for these tests.
pub const BIN: &str = env!("CARGO_BIN_EXE_evogs");

/// A command running the `evogs` binary with help text wrapped at 100 columns (so that snapshots
/// are stable); add the arguments.
pub fn command() -> Command {
    let mut c = Command::new(BIN);
    c.env("COLUMNS", "100");
    c
}

/// Runs the `evogs` binary with `args` and waits for it.
pub fn evogs(args: &[&str]) -> Output {
    command().args(args).output().unwrap()
}

/// Runs `evogs` with `args`, asserts that it succeeded (showing its standard error otherwise),
/// and returns its standard output.
pub fn evogs_ok(args: &[&str]) -> String {
    ok(&evogs(args))
}

/// Asserts that `o` succeeded (showing its standard error otherwise); returns its standard
/// output.
pub fn ok(o: &Output) -> String {
    assert!(o.status.success(), "{}", stderr(o));
    stdout(o)
}

/// Asserts that `o` failed with an error of exactly one line; returns it.
pub fn one_line_error(o: &Output) -> String {
    assert!(!o.status.success(), "succeeded: {}", stdout(o));
    let e = stderr(o);
    assert_eq!(e.trim_end().lines().count(), 1, "not one line: {e}");
    e
}

/// A path as a command-line argument.
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The process's standard error as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The process's standard output as text.
pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// A JSON file.
pub fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// A PNG (or any image) file as 8-bit RGB.
pub fn png(path: &Path) -> image::RgbImage {
    image::open(path).unwrap().to_rgb8()
}

/// Mean and largest absolute channel difference of two images of one size, in 8-bit levels.
pub fn diff(a: &image::RgbImage, b: &image::RgbImage) -> (f64, u8) {
    assert_eq!(a.dimensions(), b.dimensions());
    let mut sum = 0u64;
    let mut max = 0u8;
    for (x, y) in a.as_raw().iter().zip(b.as_raw()) {
        let d = x.abs_diff(*y);
        sum += u64::from(d);
        max = max.max(d);
    }
    (sum as f64 / a.as_raw().len() as f64, max)
}

/// `evogs demo --quick`, run once per test process and shared by the tests that read it
/// (`demo_quick` checks its scores, `demo_cli` its table and files): its standard output and its
/// output folder (`quick-demo` under Cargo's `CARGO_TARGET_TMPDIR`, replaced at each run).
pub fn quick_demo() -> &'static (String, PathBuf) {
    static DEMO: OnceLock<(String, PathBuf)> = OnceLock::new();
    DEMO.get_or_init(|| {
        let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("quick-demo");
        if out.exists() {
            std::fs::remove_dir_all(&out).unwrap();
        }
        let o = evogs(&["demo", "--quick", "--out", s(&out)]);
        assert!(o.status.success(), "{}", stderr(&o));
        (stdout(&o), out)
    })
}

/// `evogs synth --preset PRESET --out OUT --size SIZE --frames FRAMES`, asserted to succeed.
pub fn synth(preset: &str, out: &Path, size: u32, frames: u32) {
    ok(&synth_with(preset, out, size, frames, &[]));
}

/// Runs `evogs synth --preset PRESET --out OUT --size SIZE --frames FRAMES EXTRA…`.
pub fn synth_with(preset: &str, out: &Path, size: u32, frames: u32, extra: &[&str]) -> Output {
    let (size, frames) = (size.to_string(), frames.to_string());
    let args = [
        "synth",
        "--preset",
        preset,
        "--out",
        s(out),
        "--size",
        &size,
        "--frames",
        &frames,
    ];
    evogs(&[&args[..], extra].concat())
}

/// Runs `evogs ablate --data DATA --out OUT --preset tiny --iterations ITERATIONS --seed 3
/// EXTRA…`: the ablation ladder on a tiny scene.
pub fn ablate_tiny(data: &Path, out: &Path, iterations: u32, extra: &[&str]) -> Output {
    let iterations = iterations.to_string();
    let args = ["--iterations", &iterations, "--seed", "3"];
    tiny("ablate", data, out, &[&args[..], extra].concat())
}

/// The tiny scene most tests train on: the rigid preset at `size`×`size` with `frames` frames,
/// written to `dir/scene`; returns that path.
pub fn rigid_scene(dir: &Path, size: u32, frames: u32) -> PathBuf {
    let data = dir.join("scene");
    synth("rigid", &data, size, frames);
    data
}

/// `evogs train --data DATA --out OUT --preset tiny EXTRA...` (not asserted: some tests expect
/// it to fail).
pub fn train_tiny(data: &Path, out: &Path, extra: &[&str]) -> Output {
    tiny("train", data, out, extra)
}

/// `evogs COMMAND --data DATA --out OUT --preset tiny EXTRA...`.
fn tiny(command: &str, data: &Path, out: &Path, extra: &[&str]) -> Output {
    let args = [
        command,
        "--data",
        s(data),
        "--out",
        s(out),
        "--preset",
        "tiny",
    ];
    evogs(&[&args[..], extra].concat())
}

/// Writes the small camera several tests render runs from: 24×20 pixels, looking at the
/// origin from (3, 0.5, 1), z up, as a nerfies camera JSON at `path`.
pub fn write_small_camera(path: &Path) {
    let camera = splat_raster::Camera::look_at(
        24,
        20,
        0.8,
        glam::Vec3::new(3.0, 0.5, 1.0),
        glam::Vec3::ZERO,
        glam::Vec3::Z,
    );
    evogs_io::write_nerfies_camera(path, &evogs_io::CameraInfo::pinhole(camera)).unwrap();
}
