//! The `evogs render` binary end to end: renders from files written by the io crate, the demo
//! scene, and one-line errors naming the file for bad input, never touching an existing output.

use crate::support;
use std::path::PathBuf;

use evogs_io::{CameraInfo, Distortion, write_nerfies_camera, write_ply};
use glam::Vec3;
use splat_raster::{Camera, Gaussians};
use support::{evogs, s, stderr};

/// A small scene: a grid of Gaussians at SH degree 1 in front of the camera.
fn small_scene(n: usize) -> Gaussians {
    let mut g = Gaussians::with_degree(1);
    for i in 0..n {
        let f = i as f32 / n as f32;
        g.means
            .push([f * 2.0 - 1.0, (f * 7.0).sin() * 0.5, (f * 3.0).cos() * 0.3]);
        g.log_scales.push([-2.0, -2.5, -3.0]);
        g.rotations.push([1.0, f, 0.2, -0.1]);
        g.opacity_logits.push(1.0);
        g.sh.extend([
            f,
            0.5 - f,
            0.2,
            0.1,
            0.0,
            -0.1,
            0.0,
            0.2,
            0.0,
            0.05,
            0.05,
            0.05,
        ]);
    }
    g
}

fn camera() -> Camera {
    Camera::look_at(48, 32, 1.0, Vec3::new(0.0, -4.0, 1.0), Vec3::ZERO, Vec3::Z)
}

struct Fixture {
    dir: tempfile::TempDir,
    ply: PathBuf,
    camera: PathBuf,
    out: PathBuf,
}

fn fixture() -> Fixture {
    let dir = tempfile::tempdir().unwrap();
    let ply = dir.path().join("scene.ply");
    let camera_path = dir.path().join("camera.json");
    write_ply(&ply, small_scene(40).view()).unwrap();
    write_nerfies_camera(&camera_path, &CameraInfo::pinhole(camera())).unwrap();
    let out = dir.path().join("out.png");
    Fixture {
        ply,
        camera: camera_path,
        out,
        dir,
    }
}

#[test]
fn renders_a_ply_from_a_camera() {
    let f = fixture();
    let out = evogs(&[
        "render",
        "--ply",
        s(&f.ply),
        "--camera",
        s(&f.camera),
        "--out",
        s(&f.out),
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("of 40 Gaussians"), "{stdout}");
    assert!(out.stderr.is_empty());
    let img = image::open(&f.out).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (48, 32));
    assert!(img.pixels().any(|p| p.0 != [0, 0, 0]), "image is all black");
    // --width/--height resize the camera; the background shows where nothing is drawn.
    let out = evogs(&[
        "render",
        "--ply",
        s(&f.ply),
        "--camera",
        s(&f.camera),
        "--out",
        s(&f.out),
        "--width",
        "24",
        "--height",
        "20",
        "--background",
        "0,0,1",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let img = image::open(&f.out).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (24, 20));
    assert_eq!(img.get_pixel(0, 0).0, [0, 0, 255]);
    // No temporary files are left next to the output.
    let names: Vec<_> = std::fs::read_dir(f.dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 3, "{names:?}");
}

#[test]
fn renders_the_demo_scene_without_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("demo.png");
    let out = evogs(&[
        "render",
        "--out",
        s(&path),
        "--width",
        "160",
        "--height",
        "120",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.starts_with("drew "), "{stdout}");
    assert!(
        stdout.contains("wrote") && stdout.contains("(160x120)"),
        "{stdout}"
    );
    let img = image::open(&path).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (160, 120));
    // Something recognisable: many distinct colours, both dark background and bright objects.
    let mut colours: Vec<[u8; 3]> = img.pixels().map(|p| p.0).collect();
    colours.sort_unstable();
    colours.dedup();
    assert!(colours.len() > 500, "{} colours", colours.len());
    assert_eq!(img.get_pixel(2, 2).0, [0, 0, 0]);
    assert!(img.pixels().any(|p| p.0.iter().all(|&c| c > 150)));
}

#[test]
fn warns_about_non_finite_rows_and_distortion() {
    let f = fixture();
    let mut g = small_scene(10);
    g.means[3][1] = f32::NAN;
    write_ply(&f.ply, g.view()).unwrap();
    let info = CameraInfo {
        distortion: Distortion {
            radial: [0.1, 0.0, 0.0],
            tangential: [0.0; 2],
            ..Distortion::default()
        },
        ..CameraInfo::pinhole(camera())
    };
    write_nerfies_camera(&f.camera, &info).unwrap();
    let out = evogs(&[
        "render",
        "--ply",
        s(&f.ply),
        "--camera",
        s(&f.camera),
        "--out",
        s(&f.out),
    ]);
    assert!(out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 2, "{stderr}");
    assert!(
        lines[0].contains("scene.ply") && lines[0].contains("1 Gaussian(s) hold non-finite"),
        "{stderr}"
    );
    assert!(
        lines[1].contains("camera.json") && lines[1].contains("radial distortion"),
        "{stderr}"
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("1 non-finite"));
}

#[test]
fn bad_inputs_fail_with_one_line_naming_the_file_and_keep_the_output() {
    let f = fixture();
    std::fs::write(&f.out, b"previous image").unwrap();
    let garbage = f.dir.path().join("garbage.ply");
    std::fs::write(
        &garbage,
        b"ply\nformat binary_little_endian 1.0\nelement vertex 5\nend_header\n",
    )
    .unwrap();
    let truncated = f.dir.path().join("truncated.ply");
    let bytes = std::fs::read(&f.ply).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() - 10]).unwrap();
    let bad_json = f.dir.path().join("bad.json");
    std::fs::write(&bad_json, b"{\"orientation\": ").unwrap();
    let no_focal = f.dir.path().join("nofocal.json");
    let mut value: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&f.camera).unwrap()).unwrap();
    value.as_object_mut().unwrap().remove("focal_length");
    std::fs::write(&no_focal, value.to_string()).unwrap();
    let huge = f.dir.path().join("huge.json");
    value["focal_length"] = serde_json::json!(100.0);
    value["image_size"] = serde_json::json!([60000, 60000]);
    std::fs::write(&huge, value.to_string()).unwrap();
    let missing = f.dir.path().join("missing.ply");
    let (ply, cam, out) = (s(&f.ply), s(&f.camera), s(&f.out));
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["--ply", s(&missing), "--camera", cam, "--out", out],
            "missing.ply",
        ),
        (
            vec!["--ply", s(&garbage), "--camera", cam, "--out", out],
            "garbage.ply: vertex property `x` is missing",
        ),
        (
            vec!["--ply", s(&truncated), "--camera", cam, "--out", out],
            "truncated.ply: element `vertex`",
        ),
        (
            vec!["--ply", ply, "--camera", s(&bad_json), "--out", out],
            "bad.json: invalid JSON",
        ),
        (
            vec!["--ply", ply, "--camera", s(&no_focal), "--out", out],
            "nofocal.json: field `focal_length`: missing",
        ),
        (
            vec![
                "--ply",
                ply,
                "--camera",
                cam,
                "--out",
                out,
                "--background",
                "1,2",
            ],
            "--background",
        ),
        (
            vec![
                "--ply",
                ply,
                "--camera",
                cam,
                "--out",
                out,
                "--background",
                "0,x,0",
            ],
            "channel 1 `x` is not a number",
        ),
        (
            vec![
                "--ply",
                ply,
                "--camera",
                cam,
                "--out",
                out,
                "--background",
                "2,0,0",
            ],
            "outside [0, 1]",
        ),
        (vec!["--ply", ply, "--out", out], "--camera"),
        (
            vec!["--ply", ply, "--camera", cam, "--out", out, "--width", "0"],
            "--width",
        ),
        (
            vec!["--ply", ply, "--camera", cam, "--out", "picture.jpg"],
            "picture.jpg: output must be a .png file",
        ),
    ];
    for (args, expected) in &cases {
        let mut full = vec!["render"];
        full.extend(args);
        let result = evogs(&full);
        let stderr = String::from_utf8_lossy(&result.stderr);
        assert!(!result.status.success(), "{args:?} succeeded");
        assert_eq!(stderr.lines().count(), 1, "{args:?}: {stderr}");
        assert!(stderr.starts_with("evogs: "), "{args:?}: {stderr}");
        assert!(
            stderr.contains(expected),
            "{args:?}: expected `{expected}` in {stderr}"
        );
        assert!(result.stdout.is_empty(), "{args:?}");
        assert_eq!(
            std::fs::read(&f.out).unwrap(),
            b"previous image",
            "{args:?}"
        );
    }
    // An output directory that does not exist is named.
    let nowhere = f.dir.path().join("no/such/dir/out.png");
    let result = evogs(&[
        "render",
        "--ply",
        ply,
        "--camera",
        cam,
        "--out",
        s(&nowhere),
    ]);
    assert!(!result.status.success());
    assert!(String::from_utf8_lossy(&result.stderr).contains("no/such/dir/out.png"));
    // Nothing but the inputs and the untouched output is in the directory.
    let count = std::fs::read_dir(f.dir.path()).unwrap().count();
    assert_eq!(count, 8);
}

/// `--ply` reads every layout `evogs export` writes: the compressed PLY (whatever its name) and
/// the `.splat`, each drawing the same scene.
#[test]
fn renders_the_compressed_ply_and_splat_layouts() {
    let f = fixture();
    let g = small_scene(40);
    let compressed = f.dir.path().join("scene.compressed.ply");
    evogs_io::write_compressed_ply(&compressed, g.view()).unwrap();
    let splat = f.dir.path().join("scene.splat");
    evogs_io::write_splat(&splat, g.view()).unwrap();
    for file in [&compressed, &splat] {
        let out = evogs(&[
            "render",
            "--ply",
            s(file),
            "--camera",
            s(&f.camera),
            "--out",
            s(&f.out),
        ]);
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{}: {}",
            file.display(),
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(stdout.contains("of 40 Gaussians"), "{stdout}");
        let img = image::open(&f.out).unwrap().to_rgb8();
        assert!(img.pixels().any(|p| p.0 != [0, 0, 0]), "image is all black");
    }
}

/// Text a file puts into an error line cannot drive the terminal: its control characters are
/// escaped (a PLY header with an escape sequence that would clear the screen).
#[test]
fn control_characters_from_a_file_are_escaped_in_the_error_line() {
    let f = fixture();
    let ply = f.dir.path().join("evil.ply");
    std::fs::write(
        &ply,
        b"ply\nformat \x1b[2J\x1b]0;owned\x07 1.0\nelement vertex 1\nend_header\n",
    )
    .unwrap();
    let o = evogs(&[
        "render",
        "--ply",
        s(&ply),
        "--camera",
        s(&f.camera),
        "--out",
        s(&f.out),
    ]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(e.trim_end().lines().count(), 1, "{e}");
    assert!(e.contains("evil.ply"), "{e}");
    assert!(!e.trim_end().chars().any(char::is_control), "{e:?}");
}

/// A run whose dataset was moved away: every command that reads the dataset says, in one line,
/// that `config.json`'s `data` no longer holds it and what to do.
#[test]
fn a_moved_dataset_is_named_with_the_field_that_points_at_it() {
    let dir = tempfile::tempdir().unwrap();
    let data = support::rigid_scene(dir.path(), 32, 4);
    let run = dir.path().join("run");
    let o = support::train_tiny(&data, &run, &["--iterations", "3"]);
    assert!(o.status.success(), "{}", stderr(&o));
    std::fs::rename(&data, dir.path().join("moved")).unwrap();
    let image = dir.path().join("r.png");
    for args in [
        vec![
            "render",
            "--run",
            s(&run),
            "--camera",
            "dataset:test:0",
            "--out",
            s(&image),
        ],
        vec!["train", "--out", s(&run), "--resume"],
        vec![
            "video",
            "--run",
            s(&run),
            "--out",
            s(&dir.path().join("v.gif")),
        ],
    ] {
        let e = support::one_line_error(&evogs(&args));
        assert!(
            e.contains("config.json") && e.contains("field `data`") && e.contains("new location"),
            "{args:?}: {e}"
        );
    }
}
