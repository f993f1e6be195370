//! `evogs view` end to end through its HTTP API on a tiny trained run: views equal `evogs render`
//! bit for bit (dataset cameras and saved camera files), the run's description, hostile and
//! malformed requests (4xx with a reason, never a crash, no file ever served), the connection
//! bound, `--watch`, and runs that cannot be loaded.

use crate::support;

use std::path::Path;

use support::view::{ReplyImage, Viewer, fixture, train_run, train_run_with};
use support::{diff, evogs, png, s, stderr};

/// `evogs render --run RUN --camera CAMERA --time T [--width W --height H]`, decoded.
fn render(run: &Path, camera: &str, time: &str, size: Option<(u32, u32)>) -> image::RgbImage {
    let out = run.parent().unwrap().join("render_out.png");
    let mut args = vec![
        "render".to_string(),
        "--run".into(),
        s(run).into(),
        "--camera".into(),
        camera.into(),
        "--time".into(),
        time.into(),
        "--out".into(),
        s(&out).into(),
    ];
    if let Some((w, h)) = size {
        args.extend([
            "--width".into(),
            w.to_string(),
            "--height".into(),
            h.to_string(),
        ]);
    }
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = evogs(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    png(&out)
}

#[test]
fn views_equal_evogs_render_bit_for_bit_and_saved_cameras_round_trip() {
    let f = fixture();
    let v = Viewer::start(&[s(&f.run)]);
    assert!(v.stdout.contains("Gaussians"), "{}", v.stdout);

    // A dataset camera at a time between frames, resized.
    let r = v.get("/api/render?cam=dataset:test:1&t=0.37&w=40&h=28&fmt=png");
    assert_eq!(r.header("content-type"), Some("image/png"));
    assert_eq!(r.header("x-time"), Some("0.37"));
    let expected = render(&f.run, "dataset:test:1", "0.37", Some((40, 28)));
    assert_eq!(
        r.image(),
        expected,
        "dataset camera view differs from evogs render"
    );

    // Without w/h and t: the run's resolution and the camera's own time.
    let r = v.get("/api/render?cam=dataset:train:3&fmt=png");
    let info: serde_json::Value = serde_json::from_slice(&v.get("/api/info").body).unwrap();
    let t3 = info["runs"][0]["cameras"]["train"][3]["t"]
        .as_f64()
        .unwrap() as f32;
    assert_eq!(
        r.image(),
        render(&f.run, "dataset:train:3", &t3.to_string(), None)
    );

    // A free camera (orbited off the dataset's cameras): the API's view equals `evogs render`
    // with the camera file the page's "save camera" downloads.
    let (c, s2) = (0.6f32.cos(), 0.6f32.sin());
    let rot = [c, 0.0, -s2, 0.0, 1.0, 0.0, s2, 0.0, c];
    let rot = rot.map(|x| x.to_string()).join(",");
    let pose = format!("R={rot}&C=1.1,-0.3,-2.5&K=41.5,40.25,18.5,14&w=36&h=30");
    let saved = v.get(&format!("/api/camera?{pose}"));
    assert_eq!(saved.status, 200, "{}", saved.text());
    assert!(
        saved
            .header("content-disposition")
            .is_some_and(|d| d.contains("camera.json"))
    );
    let cam_path = f.dir.path().join("camera.json");
    std::fs::write(&cam_path, &saved.body).unwrap();
    let read = evogs_io::read_nerfies_camera(&cam_path).unwrap().camera;
    assert_eq!(
        (read.width, read.height, read.fx, read.fy),
        (36, 30, 41.5, 40.25)
    );
    assert_eq!((read.cx, read.cy), (18.5, 14.0));
    assert!((read.center() - glam::Vec3::new(1.1, -0.3, -2.5)).length() < 1e-5);
    let view = v.get(&format!("/api/render?{pose}&t=0.8&fmt=png")).image();
    assert_eq!(
        view,
        render(&f.run, s(&cam_path), "0.8", None),
        "free camera view differs from evogs render with the saved camera"
    );
    // The view moved: it is not the dataset camera's image at another size.
    assert_ne!(view.dimensions(), (40, 28));

    // The page's JPEG is the same view within JPEG's loss.
    let jpeg = v.get(&format!("/api/render?{pose}&t=0.8"));
    assert_eq!(jpeg.header("content-type"), Some("image/jpeg"));
    let (mean, _) = diff(&jpeg.image(), &view);
    assert!(mean < 4.0, "JPEG mean difference {mean}");

    // A dataset camera saved as a file reads back as that camera.
    let saved = v.get("/api/camera?cam=dataset:test:1");
    std::fs::write(&cam_path, &saved.body).unwrap();
    assert_eq!(
        v.get("/api/render?cam=dataset:test:1&t=0.2&fmt=png")
            .image(),
        render(&f.run, s(&cam_path), "0.2", None)
    );

    // Ground truth: the dataset image at the run's resolution.
    let gt = v.get("/api/gt?split=test&index=1&fmt=png").image();
    assert_eq!(gt.dimensions(), (32, 32));
    let file = f.data.join("test").join("r_001.png");
    if file.exists() {
        let (mean, _) = diff(&gt, &image::open(&file).unwrap().to_rgb8());
        assert!(mean < 40.0, "{mean}");
    }
}

#[test]
fn info_describes_the_run() {
    let f = fixture();
    let v = Viewer::start(&[s(&f.run)]);
    let r = v.get("/api/info");
    assert_eq!(r.status, 200);
    assert_eq!(r.header("content-type"), Some("application/json"));
    let info: serde_json::Value = serde_json::from_slice(&r.body).unwrap();
    let run = &info["runs"][0];
    assert_eq!(run["name"], "trained");
    assert_eq!(run["path"], s(&std::path::absolute(&f.run).unwrap()));
    assert!(
        ["D-3DGS", "EvoGS(D-3DGS)"].contains(&run["label"].as_str().unwrap()),
        "{run}"
    );
    assert_eq!(run["iteration"], 100);
    assert!(run["gaussians"].as_u64().unwrap() > 0);
    assert!(run["method"].is_string() && run["backend"].as_str().unwrap().contains("cpu"));
    let eval: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(f.run.join("eval_test.json")).unwrap())
            .unwrap();
    assert_eq!(run["psnr"]["test"], eval["mean_psnr"]);
    assert!(run["psnr"].get("train").is_none(), "no eval file, no PSNR");
    assert_eq!(
        (run["width"].as_u64(), run["height"].as_u64()),
        (Some(32), Some(32))
    );
    for split in ["train", "test"] {
        assert!(
            !run["cameras"][split].as_array().unwrap().is_empty(),
            "{split}"
        );
    }
    let cam = &run["cameras"]["test"][0];
    assert_eq!(cam["R"].as_array().unwrap().len(), 9);
    assert_eq!(cam["K"].as_array().unwrap().len(), 4);
    // The page and its assets come from the binary, with a policy that forbids other origins.
    let page = v.get("/");
    assert_eq!(page.status, 200);
    assert!(page.text().contains("evogs view"));
    assert!(
        page.header("content-security-policy")
            .is_some_and(|p| p.contains("default-src 'self'"))
    );
    for asset in ["/viewer.js", "/viewer.css"] {
        assert_eq!(v.get(asset).status, 200, "{asset}");
    }
    assert!(!page.text().contains("http://") && !page.text().contains("https://"));
    assert!(!v.get("/viewer.js").text().contains("https://"));
}

#[test]
fn hostile_and_malformed_requests_get_4xx_with_a_reason() {
    let f = fixture();
    let v = Viewer::start(&[s(&f.run)]);
    let cases: &[(&str, u16, &str)] = &[
        ("/api/render?cam=dataset:test:0&t=NaN", 400, "finite"),
        ("/api/render?cam=dataset:test:0&t=inf", 400, "finite"),
        ("/api/render?cam=dataset:test:0&w=100000&h=10", 400, "`w`"),
        (
            "/api/render?cam=dataset:test:0&w=99999999999999999999",
            400,
            "`w`",
        ),
        ("/api/render?cam=dataset:dev:0", 400, "unknown split"),
        ("/api/render?cam=dataset:test:999", 404, "does not exist"),
        ("/api/render?cam=dataset:test:0&run=1", 400, "`run`"),
        ("/api/render?cam=/etc/passwd", 400, "not read from requests"),
        (
            "/api/render?cam=..%2F..%2Fetc%2Fpasswd",
            400,
            "not read from requests",
        ),
        (
            "/api/render?cam=dataset:test:0&file=/etc/passwd",
            400,
            "unknown parameter",
        ),
        (
            "/api/render?R=1,0,0,0,1,0,0,0,1&C=0,0,0&K=1,1,0,0&w=8",
            400,
            "`w` and `h`",
        ),
        (
            "/api/render?R=1,1,0,0,1,0,0,0,1&C=0,0,0&K=1,1,0,0&w=8&h=8",
            400,
            "not a rotation",
        ),
        ("/api/render?%ff%fe=1", 400, "unknown parameter"),
        (
            "/api/render?cam=dataset:test:0&controls=yes",
            400,
            "`controls`",
        ),
        // The fixture is a D-3DGS run: it has no control points to draw.
        (
            "/api/render?cam=dataset:test:0&controls=1",
            400,
            "no control points",
        ),
        ("/api/gt?split=test&index=999", 404, "does not exist"),
        ("/api/gt?split=../../etc&index=0", 400, "split"),
        (
            "/api/camera?R=nan,0,0,0,1,0,0,0,1&C=0,0,0&K=1,1,0,0&w=8&h=8",
            400,
            "finite",
        ),
        ("/../../../etc/passwd", 404, "not found"),
        ("/%2e%2e/%2e%2e/etc/passwd", 404, "not found"),
        ("/api/../../Cargo.toml", 404, "not found"),
        ("/page/index.html", 404, "not found"),
        ("/api/", 404, "not found"),
    ];
    for (path, status, reason) in cases {
        let r = v.get(path);
        assert_eq!(r.status, *status, "{path}: {}", r.text());
        assert!(r.text().contains(reason), "{path}: {}", r.text());
        assert!(
            r.text().lines().count() == 1,
            "{path}: one line: {}",
            r.text()
        );
        assert!(!r.text().contains("root:"), "{path}");
    }
    let long = format!("/api/render?cam=dataset:test:0&t={}", "1".repeat(3000));
    assert_eq!(v.get(&long).status, 400);
    let port = v.addr.port();
    let raw: &[(&[u8], u16)] = &[
        (b"POST /api/info HTTP/1.1\r\nHost: localhost\r\n\r\n", 405),
        (b"DELETE / HTTP/1.1\r\nHost: localhost\r\n\r\n", 405),
        (
            b"GET / HTTP/1.1\r\nHost: localhost\r\nContent-Length: 5\r\n\r\nhello",
            413,
        ),
        (b"GET / HTTP/1.1\r\nHost: evil.example\r\n\r\n", 403),
        (b"GET / HTTP/1.1\r\n\r\n", 403),
        (b"\x00\x01\x02 garbage\r\n\r\n", 400),
        (b"GET / HTTP/1.1\r\nHo st: x\r\n\r\n", 400),
    ];
    for (bytes, status) in raw {
        let r = v.raw(bytes);
        assert_eq!(
            r.status,
            *status,
            "{:?}: {}",
            String::from_utf8_lossy(bytes),
            r.text()
        );
    }
    let huge = format!(
        "GET / HTTP/1.1\r\nHost: localhost:{port}\r\nX-Pad: {}\r\n\r\n",
        "a".repeat(40_000)
    );
    assert_eq!(v.raw(huge.as_bytes()).status, 431);
    let r = v.raw(b"GET / HTTP/1.1\r\nHost: localhost\r\n\r\n");
    assert_eq!(r.status, 200, "a HEAD-less GET with a loopback name works");
    let r = v.raw(format!("HEAD / HTTP/1.1\r\nHost: [::1]:{port}\r\n\r\n").as_bytes());
    assert_eq!((r.status, r.body.len()), (200, 0));
    // Still serving after all of that.
    assert_eq!(v.get("/api/render?cam=dataset:test:0&w=8&h=8").status, 200);
}

#[test]
fn connections_beyond_the_bound_are_refused_at_once() {
    use std::io::Read;
    let f = fixture();
    let v = Viewer::start(&[s(&f.run)]);
    let limits = evogs_view::http::Limits::default();
    // Idle connections (no request head) wait in the head reader's list; at most
    // `limits.pending` are held, every further one is answered 503 and closed at once (not after
    // the head deadline). The workers are never theirs to hold.
    let extra = 4;
    let mut idle: Vec<std::net::TcpStream> = (0..limits.pending + extra)
        .map(|_| std::net::TcpStream::connect(v.addr).unwrap())
        .collect();
    // The connections beyond the bound are the last ones accepted: read those first and stop
    // once `extra` were refused, so the held ones (which answer nothing) cost no read timeouts.
    // An answer that came only after the server's own timeout would make this take longer than
    // `limits.timeout`; refused at once, it takes a few milliseconds plus at most a few 500 ms
    // waits for held connections met on the way.
    let start = std::time::Instant::now();
    let mut refused = 0;
    for stream in idle.iter_mut().rev() {
        stream
            .set_read_timeout(Some(std::time::Duration::from_millis(500)))
            .unwrap();
        let mut head = [0u8; 12];
        if stream.read_exact(&mut head).is_ok() && head.starts_with(b"HTTP/1.1 503") {
            refused += 1;
            if refused == extra {
                break;
            }
        }
    }
    assert_eq!(
        refused, extra,
        "{refused} of the idle connections were refused"
    );
    assert!(
        start.elapsed() < limits.head_timeout,
        "the refusals were not immediate"
    );
    drop(idle);
    // Once they close, the workers are free again.
    let mut status = 0;
    for _ in 0..50 {
        status = v.get("/api/info").status;
        if status == 200 {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    assert_eq!(status, 200);
}

/// `/api/info`'s description of run 0.
fn info0(v: &Viewer) -> serde_json::Value {
    let all: serde_json::Value = serde_json::from_slice(&v.get("/api/info").body).unwrap();
    all["runs"][0].clone()
}

/// Polls `/api/info` until `done` holds for run 0 (10 s at most); returns the last description.
fn wait_for(v: &Viewer, done: impl Fn(&serde_json::Value) -> bool) -> serde_json::Value {
    let mut now = info0(v);
    for _ in 0..100 {
        if done(&now) {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
        now = info0(v);
    }
    now
}

/// Copies `from` to `to` through a temporary file and a rename, as the trainer writes.
fn replace(from: &Path, to: &Path) {
    let tmp = to.with_extension("tmp");
    std::fs::copy(from, &tmp).unwrap();
    std::fs::rename(&tmp, to).unwrap();
}

#[test]
fn watch_follows_a_training_run_from_its_checkpoints_to_its_end_of_run_files() {
    let dir = tempfile::tempdir().unwrap();
    // Two stages of one EvoGS run: stopped after 60 iterations (past the warm-up, so the
    // network deforms), and finished at 100.
    let evogs_args = ["--method", "evogs"];
    let early = train_run_with(
        dir.path(),
        "early",
        100,
        &[&evogs_args[..], &["--stop-after", "60"]].concat(),
    );
    let done = train_run_with(dir.path(), "done", 100, &evogs_args);
    // A run in progress: its config and first checkpoint (with its evolution state), no
    // end-of-run files yet.
    let live = dir.path().join("live");
    std::fs::create_dir(&live).unwrap();
    for name in [
        "config.json",
        "evo_state.safetensors",
        "checkpoint.safetensors",
    ] {
        replace(&early.join(name), &live.join(name));
    }
    let v = Viewer::start(&[s(&live), "--watch"]);
    let now = info0(&v);
    assert_eq!(now["source"], "checkpoint", "{now}");
    assert_eq!(now["iteration"], 60, "{now}");
    let q = "/api/render?cam=dataset:test:0&t=0.3&fmt=png";
    let first = v.get(q).image();
    assert_eq!(
        first,
        render(&early, "dataset:test:0", "0.3", None),
        "the checkpoint's model is the one the run's end-of-run files hold at that iteration"
    );
    // A newer checkpoint lands as the trainer writes it: the evolution state pending first,
    // then the checkpoint, then the state.
    let pending = live.join("evo_state.100.safetensors");
    replace(&done.join("evo_state.safetensors"), &pending);
    replace(
        &done.join("checkpoint.safetensors"),
        &live.join("checkpoint.safetensors"),
    );
    std::fs::rename(&pending, live.join("evo_state.safetensors")).unwrap();
    let now = wait_for(&v, |r| r["version"] == 2);
    assert_eq!(now["version"], 2, "{now}");
    assert_eq!(now["iteration"], 100, "{now}");
    assert_eq!(now["source"], "checkpoint", "{now}");
    let second = v.get(q);
    assert_eq!(second.header("x-version"), Some("2"));
    let second = second.image();
    assert_ne!(second, first, "the newer checkpoint renders differently");
    assert_eq!(second, render(&done, "dataset:test:0", "0.3", None));
    // A half-written checkpoint (and then garbage) never stops the viewer: the previous model
    // stays and the error names the file.
    let bytes = std::fs::read(done.join("checkpoint.safetensors")).unwrap();
    let mut version = 2;
    for broken in [&bytes[..bytes.len() / 2], &b"not a checkpoint"[..]] {
        std::fs::write(live.join("checkpoint.safetensors"), broken).unwrap();
        let now = wait_for(&v, |r| r["reload_error"].is_string());
        let err = now["reload_error"].as_str().unwrap_or_default();
        assert!(err.contains("checkpoint.safetensors"), "{now}");
        assert_eq!(now["version"], version, "{now}");
        assert_eq!(
            v.get(q).image(),
            second,
            "the previous model is still shown"
        );
        // Repaired: the next load succeeds and clears the error.
        replace(
            &done.join("checkpoint.safetensors"),
            &live.join("checkpoint.safetensors"),
        );
        version += 1;
        let now = wait_for(&v, |r| r["version"] == version);
        assert_eq!(now["version"], version, "{now}");
        assert!(now["reload_error"].is_null(), "{now}");
    }
    // The end of the run: its files are written after the last checkpoint and are loaded.
    for name in ["canonical.ply", "deform.safetensors", "train_metrics.json"] {
        replace(&done.join(name), &live.join(name));
    }
    let now = wait_for(&v, |r| r["source"] == "end_of_run");
    assert_eq!(now["source"], "end_of_run", "{now}");
    assert_eq!(now["iteration"], 100, "{now}");
    assert_eq!(v.get(q).image(), second);
    // A broken end-of-run file does not stop the viewer either.
    let version = now["version"].clone();
    std::fs::write(live.join("canonical.ply"), b"not a ply").unwrap();
    let now = wait_for(&v, |r| r["reload_error"].is_string());
    let err = now["reload_error"].as_str().unwrap_or_default();
    assert!(err.contains("canonical.ply"), "{now}");
    assert_eq!(now["version"], version, "{now}");
    assert_eq!(v.get(q).image(), second);
}

/// An SC-GS run: the page is told how many control points it has, and `controls=1` draws them
/// exactly as `evogs render --show-controls` does.
#[test]
fn control_points_are_drawn_as_render_draws_them() {
    let dir = tempfile::tempdir().unwrap();
    let scgs = [
        "--backbone",
        "scgs",
        "--control-points",
        "24",
        "--control-width",
        "16",
        "--control-depth",
        "2",
    ];
    let run = train_run_with(dir.path(), "scgs", 60, &scgs);
    let v = Viewer::start(&[s(&run)]);
    let info: serde_json::Value = serde_json::from_slice(&v.get("/api/info").body).unwrap();
    assert_eq!(info["runs"][0]["control_points"], 24, "{info}");
    let q = "/api/render?cam=dataset:test:1&t=0.4&fmt=png";
    let with = v.get(&format!("{q}&controls=1")).image();
    let without = v.get(q).image();
    assert_ne!(with, without);
    assert_eq!(without, render(&run, "dataset:test:1", "0.4", None));
    let out = dir.path().join("controls.png");
    let o = evogs(&[
        "render",
        "--run",
        s(&run),
        "--camera",
        "dataset:test:1",
        "--time",
        "0.4",
        "--show-controls",
        "--out",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(with, png(&out));
}

/// One rule for view, eval and render: a finished run whose checkpoint was cut short after its
/// end (newer than its end-of-run files) is read from its end-of-run files by all three; the
/// viewer says why in the run's note.
#[test]
fn a_truncated_newer_checkpoint_falls_back_to_the_end_of_run_files_everywhere() {
    let dir = tempfile::tempdir().unwrap();
    let run = train_run(dir.path(), "cut", 20);
    let ckpt = run.join("checkpoint.safetensors");
    let bytes = std::fs::read(&ckpt).unwrap();
    std::thread::sleep(std::time::Duration::from_millis(20));
    std::fs::write(&ckpt, &bytes[..bytes.len() / 3]).unwrap();
    let o = evogs(&["eval", "--run", s(&run), "--split", "test"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let expected = render(&run, "dataset:test:0", "0.3", None);
    let v = Viewer::start(&[s(&run)]);
    let info = info0(&v);
    assert_eq!(info["source"], "end_of_run", "{info}");
    let note = info["note"].as_str().unwrap_or_default();
    assert!(note.contains("checkpoint.safetensors"), "{info}");
    let view = v
        .get("/api/render?cam=dataset:test:0&t=0.3&fmt=png")
        .image();
    assert_eq!(view, expected);
}

#[test]
fn two_runs_side_by_side_share_camera_and_time() {
    let f = fixture();
    let other = train_run(f.dir.path(), "other", 1);
    let v = Viewer::start(&[s(&f.run), s(&other)]);
    let info: serde_json::Value = serde_json::from_slice(&v.get("/api/info").body).unwrap();
    assert_eq!(info["runs"].as_array().unwrap().len(), 2);
    assert_eq!(info["runs"][1]["name"], "other");
    let q = "cam=dataset:test:2&t=0.5&fmt=png";
    let a = v.get(&format!("/api/render?run=0&{q}")).image();
    let b = v.get(&format!("/api/render?run=1&{q}")).image();
    assert_eq!(a, render(&f.run, "dataset:test:2", "0.5", None));
    assert_eq!(b, render(&other, "dataset:test:2", "0.5", None));
    assert_ne!(a, b);
    assert_eq!(v.get(&format!("/api/render?run=2&{q}")).status, 400);
}

#[test]
fn runs_that_cannot_be_loaded_stop_with_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let o = evogs(&["view", s(&dir.path().join("missing")), "--port", "0"]);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("missing"), "{err}");
    // A run directory whose config is damaged: the line names the file.
    let run = dir.path().join("broken");
    std::fs::create_dir(&run).unwrap();
    std::fs::write(run.join("config.json"), b"{\"data\": 3}").unwrap();
    let o = evogs(&["view", s(&run), "--port", "0"]);
    let err = stderr(&o);
    assert!(!o.status.success());
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("config.json"), "{err}");
    // Three runs are refused by the argument parser.
    let o = evogs(&["view", "a", "b", "c"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

#[test]
fn a_non_loopback_host_warns() {
    assert!(evogs_cli::view_cmd::host_warning("0.0.0.0".parse().unwrap()).is_some());
    assert!(evogs_cli::view_cmd::host_warning("127.0.0.1".parse().unwrap()).is_none());
    assert!(evogs_cli::view_cmd::host_warning("::1".parse().unwrap()).is_none());
}
