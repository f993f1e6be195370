//! `evogs video` and `render --camera dataset:SPLIT:INDEX` end to end on a tiny trained run: frame
//! counts and sizes, frames equal to `evogs render` at the same cameras and times (PNG exactly,
//! GIF within its palette, mp4 decoded with ffmpeg within H.264's loss), side-by-side runs, and
//! one-line errors that leave nothing half-written.

use crate::support;

use std::path::{Path, PathBuf};
use std::process::Command;

use evogs_eval::LoadedRun;
use evogs_io::{CameraInfo, write_nerfies_camera};
use evogs_video::video::{LABEL_BAR, PathSpec, TimeSpec, plan_frames};
use image::{AnimationDecoder, RgbImage};
use support::{command, diff, evogs, ok, one_line_error, png, rigid_scene, s, train_tiny};

struct Fixture {
    dir: tempfile::TempDir,
    run: PathBuf,
    untrained: PathBuf,
    data: PathBuf,
}

/// A rigid synthetic scene (16 training frames, 32×32), a run trained on it with the tiny preset
/// and an untrained one (a single iteration).
fn fixture() -> Fixture {
    let dir = tempfile::tempdir().unwrap();
    let data = rigid_scene(dir.path(), 32, 16);
    let run = dir.path().join("trained");
    ok(&train_tiny(&data, &run, &["--iterations", "100"]));
    let untrained = dir.path().join("untrained");
    ok(&train_tiny(&data, &untrained, &["--iterations", "1"]));
    Fixture {
        dir,
        run,
        untrained,
        data,
    }
}

fn gif_frames(path: &Path) -> Vec<RgbImage> {
    let file = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    image::codecs::gif::GifDecoder::new(file)
        .unwrap()
        .into_frames()
        .collect_frames()
        .unwrap()
        .into_iter()
        .map(|f| image::DynamicImage::ImageRgba8(f.into_buffer()).to_rgb8())
        .collect()
}

/// `evogs render` of `run` from `camera` at `time`, written through a nerfies camera file.
fn render(
    f: &Fixture,
    run: &Path,
    camera: &splat_raster::Camera,
    time: f32,
    name: &str,
) -> RgbImage {
    let cam = f.dir.path().join(format!("{name}.json"));
    write_nerfies_camera(&cam, &CameraInfo::pinhole(*camera)).unwrap();
    let out = f.dir.path().join(format!("{name}.png"));
    let t = time.to_string();
    ok(&evogs(&[
        "render",
        "--run",
        s(run),
        "--camera",
        s(&cam),
        "--time",
        &t,
        "--out",
        s(&out),
    ]));
    png(&out)
}

fn names(dir: &Path) -> Vec<String> {
    let mut n: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    n.sort();
    n
}

#[test]
fn videos_equal_renders_at_their_cameras_and_times() {
    let f = fixture();

    // Dataset replay into PNG frames: one frame per test camera, in time order, each exactly
    // `evogs render --camera dataset:test:K` (which renders at the camera's own time).
    let frames = f.dir.path().join("replay");
    let out = ok(&evogs(&[
        "video",
        "--run",
        s(&f.run),
        "--path",
        "dataset:test",
        "--out",
        s(&frames),
    ]));
    assert!(out.contains("3 frames, 32x32"), "{out}");
    assert_eq!(
        names(&frames),
        ["frame_0000.png", "frame_0001.png", "frame_0002.png"]
    );
    let transforms: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(f.data.join("transforms_test.json")).unwrap(),
    )
    .unwrap();
    let times: Vec<f64> = transforms["frames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|fr| fr["time"].as_f64().unwrap())
        .collect();
    let mut order: Vec<usize> = (0..times.len()).collect();
    order.sort_by(|&a, &b| times[a].total_cmp(&times[b]));
    for (k, &index) in order.iter().enumerate() {
        let single = f.dir.path().join(format!("dataset_{index}.png"));
        let camera = format!("dataset:test:{index}");
        let out = ok(&evogs(&[
            "render",
            "--run",
            s(&f.run),
            "--camera",
            &camera,
            "--out",
            s(&single),
        ]));
        assert!(
            out.contains(&format!("at time {}", times[index] as f32)),
            "{out}"
        );
        assert_eq!(
            png(&frames.join(format!("frame_{k:04}.png"))),
            png(&single),
            "frame {k}"
        );
    }

    // One dataset camera held still while time sweeps (D-3DGS's --mode time): frame k is
    // `evogs render --camera dataset:test:1 --time k/2`.
    let still = f.dir.path().join("still");
    let out = ok(&evogs(&[
        "video",
        "--run",
        s(&f.run),
        "--path",
        "dataset:test:1",
        "--frames",
        "3",
        "--out",
        s(&still),
    ]));
    assert!(out.contains("3 frames, 32x32"), "{out}");
    for (k, time) in [(0, "0"), (2, "1")] {
        let single = f.dir.path().join(format!("still_{k}.png"));
        ok(&evogs(&[
            "render",
            "--run",
            s(&f.run),
            "--camera",
            "dataset:test:1",
            "--time",
            time,
            "--out",
            s(&single),
        ]));
        assert_eq!(
            png(&still.join(format!("frame_{k:04}.png"))),
            png(&single),
            "still frame {k}"
        );
    }
    assert_ne!(
        png(&still.join("frame_0000.png")),
        png(&still.join("frame_0002.png")),
        "time moves"
    );

    // The same cameras the video planned, rendered one by one with `evogs render`.
    let loaded = LoadedRun::open(&f.run).unwrap();
    let planned = |path: PathSpec, n: usize, time: TimeSpec| {
        plan_frames(&loaded, &path, Some(n), time).unwrap()
    };

    // A JSON camera path: two cameras with times, listed out of time order, replayed one frame
    // per camera in time order, each exactly `evogs render` at that camera and time.
    let orbit2 = planned(PathSpec::Orbit, 2, TimeSpec::Sweep);
    let keyed = [(orbit2[1].0, 0.7f32), (orbit2[0].0, 0.2f32)];
    let entries: Vec<String> = keyed
        .iter()
        .map(|(c, t)| {
            evogs_io::nerfies_camera_json(&CameraInfo::pinhole(*c)).replacen(
                '{',
                &format!("{{\n  \"time\": {t},"),
                1,
            )
        })
        .collect();
    let cams = f.dir.path().join("cams.json");
    std::fs::write(&cams, format!("[{}]", entries.join(",\n"))).unwrap();
    let replay = f.dir.path().join("json_replay");
    let out = ok(&evogs(&[
        "video",
        "--run",
        s(&f.run),
        "--path",
        s(&cams),
        "--out",
        s(&replay),
    ]));
    assert!(out.contains("2 frames, 32x32"), "{out}");
    for (k, (camera, t)) in keyed.iter().rev().enumerate() {
        let direct = render(&f, &f.run, camera, *t, &format!("json{k}"));
        assert_eq!(
            png(&replay.join(format!("frame_{k:04}.png"))),
            direct,
            "json frame {k}"
        );
    }

    // An orbit GIF frozen at t = 0.4: four frames of the dataset's size, first and last equal
    // to the renders up to the GIF palette (256 colours per frame).
    let gif = f.dir.path().join("orbit.gif");
    ok(&evogs(&[
        "video",
        "--run",
        s(&f.run),
        "--path",
        "orbit",
        "--frames",
        "4",
        "--time",
        "0.4",
        "--out",
        s(&gif),
    ]));
    let decoded = gif_frames(&gif);
    assert_eq!(decoded.len(), 4);
    let plan = planned(PathSpec::Orbit, 4, TimeSpec::Fixed(0.4));
    for k in [0, 3] {
        assert_eq!(plan[k].1, 0.4);
        let direct = render(&f, &f.run, &plan[k].0, plan[k].1, &format!("orbit{k}"));
        let (mean, max) = diff(&decoded[k], &direct);
        // Measured: mean 0.28 and 0.50 levels, largest 5 and 7.
        assert!(
            mean < 1.0 && max <= 12,
            "orbit frame {k}: mean {mean}, max {max}"
        );
    }
    // The orbit moves: the first and second frames differ.
    assert!(diff(&decoded[0], &decoded[1]).0 > 1.0);

    // A spiral mp4 over the time range 0.2:0.8 at another size, decoded with ffmpeg.
    let mp4 = f.dir.path().join("spiral.mp4");
    ok(&evogs(&[
        "video",
        "--run",
        s(&f.run),
        "--path",
        "spiral",
        "--frames",
        "5",
        "--time",
        "0.2:0.8",
        "--size",
        "48x40",
        "--fps",
        "10",
        "--out",
        s(&mp4),
    ]));
    // Readable as every other output (the temporary file's private mode does not survive).
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(&mp4).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o644, "{mode:o}");
    }
    let decoded_dir = f.dir.path().join("decoded");
    std::fs::create_dir(&decoded_dir).unwrap();
    let o = Command::new("ffmpeg")
        .args(["-loglevel", "error", "-i", s(&mp4)])
        .arg(decoded_dir.join("%04d.png"))
        .output()
        .expect("ffmpeg is installed by scripts/test");
    ok(&o);
    assert_eq!(names(&decoded_dir).len(), 5);
    let plan: Vec<_> = planned(PathSpec::Spiral, 5, TimeSpec::Range(0.2, 0.8))
        .into_iter()
        .map(|(c, t)| (evogs_cli::render::resize_camera(c, Some(48), Some(40)), t))
        .collect();
    assert_eq!((plan[0].1, plan[4].1), (0.2, 0.8));
    for (k, file) in [(0, "0001.png"), (4, "0005.png")] {
        let frame = png(&decoded_dir.join(file));
        assert_eq!(frame.dimensions(), (48, 40));
        let direct = render(&f, &f.run, &plan[k].0, plan[k].1, &format!("spiral{k}"));
        let (mean, _) = diff(&frame, &direct);
        // Measured: mean 1.41 and 1.24 levels (CRF 18, chroma at half resolution).
        assert!(mean < 3.0, "spiral frame {k}: mean difference {mean}");
    }

    // Side by side: the trained run left, the untrained right, under the label bar.
    let both = f.dir.path().join("both");
    let out = ok(&evogs(&[
        "video",
        "--run",
        s(&f.run),
        "--compare",
        s(&f.untrained),
        "--path",
        "orbit",
        "--frames",
        "2",
        "--out",
        s(&both),
    ]));
    assert!(
        out.contains(&format!("2 frames, 64x{}", 32 + LABEL_BAR)),
        "{out}"
    );
    let frame = png(&both.join("frame_0001.png"));
    let plan = planned(PathSpec::Orbit, 2, TimeSpec::Sweep);
    assert_eq!(plan[1].1, 1.0);
    for (side, run) in [(0, &f.run), (1, &f.untrained)] {
        let direct = render(&f, run, &plan[1].0, plan[1].1, &format!("side{side}"));
        let half = image::imageops::crop_imm(&frame, 32 * side, LABEL_BAR, 32, 32).to_image();
        assert_eq!(half, direct, "side {side}");
    }
}

#[test]
fn bad_input_gives_one_line_errors_and_writes_nothing() {
    let f = fixture();
    let dir = f.dir.path();
    let video = |extra: &[&str]| evogs(&[&["video", "--run", s(&f.run)][..], extra].concat());
    // Unknown split, index out of range (names the split's file).
    let e = one_line_error(&video(&[
        "--path",
        "dataset:dev",
        "--out",
        s(&dir.join("a.gif")),
    ]));
    assert!(e.contains("unknown split `dev`"), "{e}");
    let out = dir.join("r.png");
    let e = one_line_error(&evogs(&[
        "render",
        "--run",
        s(&f.run),
        "--camera",
        "dataset:test:7",
        "--out",
        s(&out),
    ]));
    assert!(
        e.contains("transforms_test.json") && e.contains("index 7 is out of range"),
        "{e}"
    );
    let e = one_line_error(&evogs(&[
        "render",
        "--ply",
        s(&f.run.join("canonical.ply")),
        "--camera",
        "dataset:test:0",
        "--out",
        s(&out),
    ]));
    assert!(e.contains("needs --run"), "{e}");
    // Non-finite and reversed time ranges.
    for (time, expected) in [
        ("0.8:0.2", "reversed"),
        ("0:inf", "not a finite"),
        ("NaN", "not a finite"),
    ] {
        let e = one_line_error(&video(&["--time", time, "--out", s(&dir.join("t.gif"))]));
        assert!(e.contains(expected), "{time}: {e}");
    }
    // Unknown extension, unwritable output, a missing camera-path file.
    let e = one_line_error(&video(&["--out", s(&dir.join("v.avi"))]));
    assert!(e.contains("v.avi") && e.contains(".avi"), "{e}");
    let e = one_line_error(&video(&["--out", s(&dir.join("missing/v.gif"))]));
    assert!(e.contains("missing"), "{e}");
    let e = one_line_error(&video(&[
        "--path",
        s(&dir.join("cams.json")),
        "--out",
        s(&dir.join("p.gif")),
    ]));
    assert!(e.contains("cams.json"), "{e}");
    // A word that is neither a path name nor a file: the line lists what --path takes.
    let e = one_line_error(&video(&["--path", "bogus", "--out", s(&dir.join("b.gif"))]));
    assert!(
        e.contains("bogus") && e.contains("orbit, spiral, dataset:SPLIT"),
        "{e}"
    );
    // A missing network file is named once (its cause quoted in the message is not repeated).
    let elsewhere = tempfile::tempdir().unwrap();
    let broken = elsewhere.path().join("broken");
    std::fs::create_dir_all(&broken).unwrap();
    for name in ["config.json", "canonical.ply", "train_metrics.json"] {
        std::fs::copy(f.run.join(name), broken.join(name)).unwrap();
    }
    let e = one_line_error(&evogs(&[
        "render",
        "--run",
        s(&broken),
        "--camera",
        "dataset:test:0",
        "--out",
        s(&elsewhere.path().join("n.png")),
    ]));
    assert_eq!(e.matches("deform.safetensors").count(), 1, "{e}");
    // ffmpeg missing: the error says so and an existing video is untouched.
    let mp4 = dir.join("old.mp4");
    std::fs::write(&mp4, b"old").unwrap();
    let o = command()
        .args([
            "video",
            "--run",
            s(&f.run),
            "--frames",
            "2",
            "--out",
            s(&mp4),
        ])
        .env(evogs_io::video::FFMPEG_ENV, dir.join("no-ffmpeg"))
        .output()
        .unwrap();
    let e = one_line_error(&o);
    assert!(
        e.contains("mp4 needs ffmpeg") && e.contains("old.mp4"),
        "{e}"
    );
    assert_eq!(std::fs::read(&mp4).unwrap(), b"old");
    // A still camera out of range.
    let e = one_line_error(&video(&[
        "--path",
        "dataset:test:9",
        "--out",
        s(&dir.join("s.gif")),
    ]));
    assert!(e.contains("index 9 is out of range"), "{e}");
    // Export: a non-finite time, an output folder that is a file, an unwritable output file.
    let export = |extra: &[&str]| evogs(&[&["export", "--run", s(&f.run)][..], extra].concat());
    let e = one_line_error(&export(&["--time", "NaN", "--out", s(&dir.join("x.ply"))]));
    assert!(e.contains("not a finite"), "{e}");
    let e = one_line_error(&export(&["--frames", "2", "--out", s(&mp4)]));
    assert!(e.contains("old.mp4"), "{e}");
    let e = one_line_error(&export(&[
        "--time",
        "0.5",
        "--format",
        "compressed-ply",
        "--out",
        s(&dir.join("missing/f.compressed.ply")),
    ]));
    assert!(e.contains("missing/f.compressed.ply"), "{e}");
    // A --format the file name contradicts.
    let e = one_line_error(&export(&[
        "--time",
        "0.5",
        "--format",
        "ply",
        "--out",
        s(&dir.join("f.splat")),
    ]));
    assert!(e.contains("f.splat") && e.contains("contradicts"), "{e}");
    // Nothing half-written anywhere.
    assert_eq!(
        names(dir),
        ["old.mp4", "scene", "trained", "untrained"],
        "leftovers"
    );
}

/// Without --format, one file takes the format its name says.
#[test]
fn an_exported_file_takes_the_format_its_name_says() {
    let f = fixture();
    let n = LoadedRun::open(&f.run)
        .unwrap()
        .deformed(0.5)
        .unwrap()
        .len();
    let out = f.dir.path().join("frame.splat");
    ok(&evogs(&[
        "export",
        "--run",
        s(&f.run),
        "--time",
        "0.5",
        "--out",
        s(&out),
    ]));
    assert_eq!(evogs_io::read_splat(&out).unwrap().len(), n);
    let out = f.dir.path().join("frame.compressed.ply");
    ok(&evogs(&[
        "export",
        "--run",
        s(&f.run),
        "--time",
        "0.5",
        "--out",
        s(&out),
    ]));
    assert_eq!(evogs_io::read_compressed_ply(&out).unwrap().len(), n);
}

#[test]
fn exported_sequences_read_back_and_render_within_their_precision() {
    let f = fixture();
    let mut run = LoadedRun::open(&f.run).unwrap();
    let camera = evogs_video::camera_path::split_cameras(&run, evogs_io::Split::Test).unwrap()[0].0;
    for (format, extension) in [
        ("ply", "ply"),
        ("compressed-ply", "compressed.ply"),
        ("splat", "splat"),
    ] {
        let dir = f.dir.path().join(format);
        let out = ok(&evogs(&[
            "export",
            "--run",
            s(&f.run),
            "--frames",
            "3",
            "--format",
            format,
            "--out",
            s(&dir),
        ]));
        assert!(out.contains("3 file(s)"), "{out}");
        let seq: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("sequence.json")).unwrap())
                .unwrap();
        assert_eq!(seq["format"], format);
        assert_eq!(seq["count"], 3);
        assert_eq!(seq["times"], serde_json::json!([0.0, 0.5, 1.0]));
        let file = dir.join(format!("frame_0001.{extension}"));
        assert_eq!(seq["files"][1], format!("frame_0001.{extension}"));
        let direct = run.deformed(0.5).unwrap();
        assert_eq!(seq["gaussians"][1], direct.len());
        let size = std::fs::metadata(&file).unwrap().len();
        match format {
            "ply" => {
                // Lossless: the deformed Gaussians exactly.
                assert_eq!(evogs_io::read_ply(&file).unwrap().gaussians, direct);
            }
            "compressed-ply" => {
                // Every SH band kept (higher ones as one byte each); sizes as documented.
                let n = direct.len();
                assert_eq!(
                    size,
                    evogs_io::compressed_ply::compressed_ply_len(n, direct.sh_degree)
                );
                let back = evogs_io::read_compressed_ply(&file).unwrap();
                assert_eq!((back.len(), back.sh_degree), (n, direct.sh_degree));
                // The file holds the Gaussians in Morton order: `orig[j]` is the one `back[j]`
                // was written from.
                let mut order: Vec<usize> = (0..n).collect();
                evogs_io::compressed_ply::morton::sort_morton(&direct.means, &mut order);
                let orig = select(&direct, &order);
                assert_within_format_steps(&orig, &back, true);
                for degree in [Some(0), None] {
                    let (max, bound) =
                        compressed_render_within_bound(&orig, &back, &camera, degree);
                    eprintln!(
                        "compressed-ply: {n} Gaussians, SH degree {}, {size} bytes; bands \
                         {degree:?}: largest render error {max}, largest derived bound {bound}",
                        direct.sh_degree
                    );
                }
            }
            _ => {
                // 32 bytes a Gaussian; DC colour only, 8-bit colour, opacity and rotation.
                assert_eq!(size, 32 * direct.len() as u64);
                let back = evogs_io::read_splat(&file).unwrap();
                assert_eq!(back.len(), direct.len());
                // Written largest `volume · opacity` first (stable), as the writer orders them.
                let key = |i: usize| {
                    direct.log_scales[i].iter().sum::<f32>().exp()
                        * splat_core::sigmoid(direct.opacity_logits[i])
                };
                let mut order: Vec<usize> = (0..direct.len()).collect();
                order.sort_by(|&a, &b| key(b).total_cmp(&key(a)));
                let orig = select(&direct, &order);
                assert_within_format_steps(&orig, &back, false);
                let (max, bound) = compressed_render_within_bound(&orig, &back, &camera, Some(0));
                eprintln!("splat: largest render error {max}, largest derived bound {bound}");
            }
        }
    }
}

/// The Gaussians `order` of `g`, in that order.
fn select(g: &splat_raster::Gaussians, order: &[usize]) -> splat_raster::Gaussians {
    let stride = g.sh_stride();
    let mut out = splat_raster::Gaussians::with_degree(g.sh_degree);
    for &i in order {
        out.means.push(g.means[i]);
        out.log_scales.push(g.log_scales[i]);
        out.rotations.push(g.rotations[i]);
        out.opacity_logits.push(g.opacity_logits[i]);
        out.sh
            .extend_from_slice(&g.sh[i * stride..(i + 1) * stride]);
    }
    out
}

/// Each read-back Gaussian `back[j]` within the format's steps of `orig[j]` in mean, DC colour and
/// opacity (the fields that move a DC render the most; `evogs-io`'s tests hold the writers to
/// every field on random Gaussians). Opacity: half of 1/255 in both formats. Compressed PLY
/// (`chunked`): means to half of 1/2047 (x, z) and 1/1023 (y) of the chunk's extent, colour to half
/// of 1/255 of the chunk's colour range, chunks of 256 in file order. `.splat`: means exact,
/// colour clamped to [0, 1] and to half of 1/255.
fn assert_within_format_steps(
    orig: &splat_raster::Gaussians,
    back: &splat_raster::Gaussians,
    chunked: bool,
) {
    use evogs_io::compressed_ply::CHUNK_SIZE;
    use splat_core::sh::rgb_from_dc;
    let stride = orig.sh_stride();
    let back_stride = back.sh_stride();
    let chunk = if chunked { CHUNK_SIZE } else { orig.len() };
    let rgb = |i: usize, k: usize| rgb_from_dc(orig.sh[i * stride + k]);
    let slack = |v: f32, range: f32| 4.0 * f32::EPSILON * (v.abs() + range);
    for start in (0..orig.len()).step_by(chunk.max(1)) {
        let members = start..(start + chunk).min(orig.len());
        let range = |f: &dyn Fn(usize) -> f32| {
            let values = members.clone().map(f);
            let lo = values.clone().fold(f32::INFINITY, f32::min);
            values.fold(f32::NEG_INFINITY, f32::max) - lo
        };
        for k in 0..3 {
            let extent = range(&|i| orig.means[i][k]);
            let colours = range(&|i| rgb(i, k));
            let levels = if k == 1 { 1023.0 } else { 2047.0 };
            for i in members.clone() {
                let (mean, mean_back) = (orig.means[i][k], back.means[i][k]);
                let error = (mean_back - mean).abs();
                let half_step = if chunked {
                    extent / (2.0 * levels) + slack(mean, extent)
                } else {
                    0.0
                };
                assert!(
                    error <= half_step,
                    "Gaussian {i} mean {k}: {error} > {half_step}"
                );
                let colour_back = rgb_from_dc(back.sh[i * back_stride + k]);
                let (error, half_step) = if chunked {
                    let error = (colour_back - rgb(i, k)).abs();
                    (error, colours / 510.0 + slack(1.0, colours))
                } else {
                    let error = (colour_back - rgb(i, k).clamp(0.0, 1.0)).abs();
                    (error, 1.0 / 510.0 + slack(1.0, 1.0))
                };
                assert!(
                    error <= half_step,
                    "Gaussian {i} colour {k}: {error} > {half_step}"
                );
            }
        }
    }
    for (i, (a, b)) in orig
        .opacity_logits
        .iter()
        .zip(&back.opacity_logits)
        .enumerate()
    {
        let error = (splat_core::sigmoid(*a) - splat_core::sigmoid(*b)).abs();
        assert!(error <= 1.0 / 510.0 + 1e-6, "Gaussian {i} opacity: {error}");
    }
}

/// A Gaussian drawn at a pixel: its index, α and premultiplied colour α·c.
type Footprint = (usize, f32, [f32; 3]);

/// A Gaussian drawn at a pixel in either of two renders: its index, then α and α·c in each (0
/// where it is not drawn).
type Drawn = (usize, f32, [f32; 3], f32, [f32; 3]);

/// Per pixel, the Gaussians of `g` that draw there when rendered alone (black background), in
/// index order; and the largest colour c of any.
fn footprints(
    g: &splat_raster::Gaussians,
    camera: &splat_core::Camera,
    options: &splat_raster::RenderOptions,
) -> (Vec<Vec<Footprint>>, f32) {
    use splat_raster::{CpuRasterizer, Rasterizer};
    let raster = CpuRasterizer::new();
    let mut pixels = vec![Vec::new(); camera.pixel_count()];
    let mut c_max = 0.0f32;
    for i in 0..g.len() {
        let one = raster
            .forward(select(g, &[i]).view(), camera, options)
            .unwrap();
        for (p, (&a, c)) in one.alpha.iter().zip(&one.color).enumerate() {
            if a > 0.0 {
                pixels[p].push((i, a, *c));
                c_max = c.iter().fold(c_max, |m, &v| m.max(v / a));
            }
        }
    }
    (pixels, c_max)
}

/// Asserts that every pixel's render error between `orig` and `back` (the same Gaussians, index
/// for index, before and after an export) is within the worst case that compositing allows for
/// their per-Gaussian changes; returns the largest error and the largest bound.
///
/// α and premultiplied colour αc of each Gaussian come from renders of it alone, so the 1/255
/// cut and the 0.99 clamp are the rasterizer's own (the 8-bit opacity's steps push Gaussians
/// across the cut, which a first-order bound misses). The bound, `c_max` the largest colour of
/// any Gaussian (the background is black):
/// - changing the Gaussians one at a time, front to back in `orig`'s depth order, changes the
///   colour by at most `T'·(|α'c' − αc| + c_max·|α' − α|)`, `T'` the transmittance of the
///   changed ones in front;
/// - reordering to `back`'s depth order by adjacent swaps, by at most `α_i α_j |c_i − c_j|` per
///   swapped pair (pairs of distinct means within f32 rounding of a depth tie count too);
/// - each render leaves out at most `T·c_max` after its early stop (`T'` < 1e-4 stops the pixel
///   before blending the Gaussian, DESIGN §3), `T` the transmittance before that Gaussian;
/// - each render is within 1e-5 of the exact one.
fn compressed_render_within_bound(
    orig: &splat_raster::Gaussians,
    back: &splat_raster::Gaussians,
    camera: &splat_core::Camera,
    degree: Option<u32>,
) -> (f32, f32) {
    use splat_raster::{CpuRasterizer, Rasterizer, RenderOptions};
    let options = RenderOptions {
        background: [0.0; 3],
        sh_degree: degree,
    };
    let render = |g: &splat_raster::Gaussians| {
        CpuRasterizer::new()
            .forward(g.view(), camera, &options)
            .unwrap()
            .color
    };
    let (a, b) = (render(orig), render(back));
    let (before, c_before) = footprints(orig, camera, &options);
    let (after, c_after) = footprints(back, camera, &options);
    let c_max = c_before.max(c_after);
    let depth = |g: &splat_raster::Gaussians| -> Vec<f32> {
        g.means
            .iter()
            .map(|&m| camera.world_to_camera(glam::Vec3::from(m)).z)
            .collect()
    };
    let (z, z_back) = (depth(orig), depth(back));
    // Depths this close may be ordered either way by the rasterizer's own arithmetic (equal
    // means give equal depths, ordered by index in both).
    let tie = |a: f32, b: f32| (a - b).abs() <= 4.0 * f32::EPSILON * a.abs().max(b.abs());
    let (mut largest_error, mut largest_bound) = (0.0f32, 0.0f32);
    for (p, (x, y)) in a.iter().zip(&b).enumerate() {
        // The Gaussians drawn at p in either render.
        let mut drawn: Vec<Drawn> = Vec::new();
        let (mut u, mut v) = (before[p].iter().peekable(), after[p].iter().peekable());
        loop {
            let entry = match (u.peek(), v.peek()) {
                (None, None) => break,
                (Some(&&(i, a, c)), Some(&&(j, a2, c2))) if i == j => {
                    u.next();
                    v.next();
                    (i, a, c, a2, c2)
                }
                (Some(&&(i, a, c)), Some(&&(j, _, _))) if i < j => {
                    u.next();
                    (i, a, c, 0.0, [0.0; 3])
                }
                (Some(&&(i, a, c)), None) => {
                    u.next();
                    (i, a, c, 0.0, [0.0; 3])
                }
                (_, Some(&&(j, a2, c2))) => {
                    v.next();
                    (j, 0.0, [0.0; 3], a2, c2)
                }
            };
            drawn.push(entry);
        }
        drawn.sort_by(|l, r| z[l.0].total_cmp(&z[r.0]).then(l.0.cmp(&r.0)));
        // The transmittance before the Gaussian that stops the pixel (0 when none does).
        let stop = |alphas: &mut dyn Iterator<Item = f32>| {
            let mut t = 1.0f32;
            for alpha in alphas {
                if t * (1.0 - alpha) < 1e-4 {
                    return t;
                }
                t *= 1.0 - alpha;
            }
            0.0
        };
        let mut in_back_order: Vec<_> = drawn.iter().map(|e| (z_back[e.0], e.0, e.3)).collect();
        in_back_order.sort_by(|l, r| l.0.total_cmp(&r.0).then(l.1.cmp(&r.1)));
        let left_out =
            stop(&mut drawn.iter().map(|e| e.1)) + stop(&mut in_back_order.iter().map(|e| e.2));
        let mut bound = [left_out * c_max + 2e-5; 3];
        let mut transmittance = 1.0f32;
        for (k, &(i, a, c, a2, c2)) in drawn.iter().enumerate() {
            for ch in 0..3 {
                bound[ch] += transmittance * ((c2[ch] - c[ch]).abs() + c_max * (a2 - a).abs());
            }
            transmittance *= 1.0 - a2;
            for &(j, b, d, b2, d2) in &drawn[k + 1..] {
                let swapped = (z_back[i], i) > (z_back[j], j);
                let tie = (orig.means[i] != orig.means[j] && tie(z[i], z[j]))
                    || (back.means[i] != back.means[j] && tie(z_back[i], z_back[j]));
                if swapped || tie {
                    for ch in 0..3 {
                        // α_i α_j |c_i − c_j| from the premultiplied colours, before and after.
                        bound[ch] +=
                            (b * c[ch] - a * d[ch]).abs() + (b2 * c2[ch] - a2 * d2[ch]).abs();
                    }
                }
            }
        }
        for ch in 0..3 {
            let error = (x[ch] - y[ch]).abs();
            assert!(
                error <= bound[ch],
                "bands {degree:?}: pixel {p} channel {ch}: render error {error} > derived bound {}",
                bound[ch]
            );
            largest_error = largest_error.max(error);
            largest_bound = largest_bound.max(bound[ch]);
        }
    }
    (largest_error, largest_bound)
}
