//! `--backend cpu|wgpu|auto` through the binary: training on the wgpu backend (lavapipe in CI)
//! lands within a small margin of the CPU backend with the same seed; the choice is recorded and
//! kept by `--resume` unless overridden; `auto` says what it chose and why; `wgpu` without an
//! adapter is a one-line error.

use crate::support;

use std::path::Path;

use support::{command, evogs, json, rigid_scene, s, stderr, stdout, train_tiny};

fn train(data: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    let args = ["--iterations", "60", "--seed", "5"];
    train_tiny(data, out, &[&args[..], extra].concat())
}

#[test]
fn wgpu_training_matches_cpu_training_and_resume_keeps_the_backend() {
    let dir = tempfile::tempdir().unwrap();
    let data = rigid_scene(dir.path(), 32, 8);

    let cpu_run = dir.path().join("cpu");
    let o = train(&data, &cpu_run, &["--backend", "cpu"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("backend: cpu (asked: cpu)"),
        "{}",
        stdout(&o)
    );

    // The wgpu run stops half-way and is resumed without --backend: it stays on wgpu.
    let gpu_run = dir.path().join("wgpu");
    let o = train(
        &data,
        &gpu_run,
        &["--backend", "wgpu", "--stop-after", "30"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("backend: wgpu on "), "{}", stdout(&o));
    // The loss runs where the image is, and says so (the CPU run's on the CPU).
    let on_device = "\nloss: wgpu (on the rasterizer's device, the ";
    assert!(stdout(&o).contains(on_device), "{}", stdout(&o));
    assert_eq!(
        json(&gpu_run.join("config.json"))["train"]["backend"],
        "wgpu"
    );
    let o = evogs(&["train", "--out", s(&gpu_run), "--resume"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("backend: wgpu on "), "{}", stdout(&o));
    assert!(
        stdout(&o).contains("trained 60 iterations (30 in this process"),
        "{}",
        stdout(&o)
    );
    // The host-device traffic is counted and recorded on wgpu (a forward's two read-backs and
    // a backward's one per iteration at least), and absent on the CPU.
    assert!(
        stdout(&o).contains("host-device traffic per iteration: "),
        "{}",
        stdout(&o)
    );
    let metrics = json(&gpu_run.join("train_metrics.json"));
    assert!(
        metrics["loss"]
            .as_str()
            .unwrap()
            .starts_with("loss: wgpu (on the rasterizer's"),
        "{metrics}"
    );
    assert_eq!(
        json(&cpu_run.join("train_metrics.json"))["loss"],
        "loss: cpu (the rasterizer runs on the CPU)"
    );
    // The device's own time per phase (lavapipe writes timestamps), printed and recorded.
    assert!(
        stdout(&o).contains("device time per iteration (GPU timestamps): loss "),
        "{}",
        stdout(&o)
    );
    let device = &metrics["device_ms_per_iteration"];
    for label in ["raster forward", "loss", "raster backward"] {
        let ms = device[label].as_f64();
        assert!(
            ms.is_some_and(|ms| ms.is_finite() && ms >= 0.0),
            "{label}: {metrics}"
        );
    }
    assert!(
        device["raster forward"].as_f64().unwrap() > 0.0,
        "{metrics}"
    );
    let traffic = &metrics["traffic_per_iteration"];
    assert!(traffic["waits"].as_f64().unwrap() >= 3.0, "{traffic}");
    assert!(traffic["bytes_down"].as_f64().unwrap() > 0.0, "{traffic}");
    assert!(traffic["bytes_up"].as_f64().unwrap() > 0.0, "{traffic}");
    for absent in ["traffic_per_iteration", "device_ms_per_iteration"] {
        assert!(
            json(&cpu_run.join("train_metrics.json"))
                .get(absent)
                .is_none()
        );
    }

    let cpu_psnr = json(&cpu_run.join("train_metrics.json"))["last_psnr"]
        .as_f64()
        .unwrap();
    let gpu_psnr = json(&gpu_run.join("train_metrics.json"))["last_psnr"]
        .as_f64()
        .unwrap();
    eprintln!("training PSNR after 60 iterations: cpu {cpu_psnr:.3} dB, wgpu {gpu_psnr:.3} dB");
    assert!(cpu_psnr.is_finite() && cpu_psnr > 10.0, "{cpu_psnr}");
    assert!(
        (cpu_psnr - gpu_psnr).abs() < 0.5,
        "cpu {cpu_psnr:.3} dB vs wgpu {gpu_psnr:.3} dB"
    );

    // A resume may switch the backend; the switch is recorded.
    let o = evogs(&[
        "train",
        "--out",
        s(&gpu_run),
        "--resume",
        "--backend",
        "cpu",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        json(&gpu_run.join("config.json"))["train"]["backend"],
        "cpu"
    );

    // Evaluation on either backend scores the same run alike.
    let o = evogs(&["eval", "--run", s(&cpu_run), "--backend", "wgpu"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("backend: wgpu on "), "{}", stdout(&o));
    let gpu_eval = json(&cpu_run.join("eval_test.json"))["mean_psnr"]
        .as_f64()
        .unwrap();
    let o = evogs(&["eval", "--run", s(&cpu_run)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("backend: cpu (asked: cpu)"),
        "{}",
        stdout(&o)
    );
    let cpu_eval = json(&cpu_run.join("eval_test.json"))["mean_psnr"]
        .as_f64()
        .unwrap();
    assert!(
        (gpu_eval - cpu_eval).abs() < 0.01,
        "{gpu_eval} vs {cpu_eval}"
    );
}

#[test]
fn auto_says_what_it_chose_and_why() {
    let adapter = splat_raster::GpuContext::new()
        .unwrap_or_else(|e| panic!("this test needs an adapter (CI installs lavapipe): {e}"))
        .adapter()
        .clone();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo.png");
    let o = evogs(&[
        "render",
        "--backend",
        "auto",
        "--out",
        s(&out),
        "--width",
        "64",
        "--height",
        "48",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    let line = text
        .lines()
        .find(|l| l.starts_with("backend: "))
        .unwrap_or_else(|| panic!("no backend line in {text}"));
    if adapter.hardware {
        assert!(line.starts_with("backend: wgpu on "), "{line}");
    } else {
        // lavapipe (this machine, CI): software, so the CPU, naming the adapter.
        assert!(line.starts_with("backend: cpu (auto: adapter "), "{line}");
        assert!(
            line.contains(&adapter.name) && line.contains("software"),
            "{line}"
        );
    }
    assert!(out.is_file());

    // Training says the same, and records `auto` (not what it resolved to).
    let data = rigid_scene(dir.path(), 32, 8);
    let run = dir.path().join("auto");
    let o = train_tiny(&data, &run, &["--iterations", "2", "--backend", "auto"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    let expected = if adapter.hardware {
        "backend: wgpu on "
    } else {
        "backend: cpu (auto: adapter "
    };
    assert!(text.lines().any(|l| l.starts_with(expected)), "{text}");
    assert_eq!(json(&run.join("config.json"))["train"]["backend"], "auto");
}

#[test]
fn demo_runs_on_wgpu() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo");
    let o = evogs(&[
        "demo",
        "--iterations",
        "10",
        "--backend",
        "wgpu",
        "--out",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("evogs demo: backend: wgpu on "),
        "{}",
        stderr(&o)
    );
    assert!(stdout(&o).contains("| evogs |"), "{}", stdout(&o));
    for m in ["baseline", "evogs"] {
        assert_eq!(
            json(&out.join(m).join("config.json"))["train"]["backend"],
            "wgpu"
        );
        assert!(out.join(m).join("sweep/strip.png").is_file(), "{m} strip");
    }
}

#[test]
fn wgpu_without_an_adapter_is_a_one_line_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo.png");
    // Only Vulkan, and a driver list that names no existing driver: no adapter at all.
    let o = command()
        .args([
            "render",
            "--backend",
            "wgpu",
            "--out",
            s(&out),
            "--width",
            "32",
            "--height",
            "32",
        ])
        .env("WGPU_BACKEND", "vulkan")
        .env("VK_DRIVER_FILES", dir.path().join("none.json"))
        .env("VK_ICD_FILENAMES", dir.path().join("none.json"))
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = stderr(&o);
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.starts_with("evogs: error: "), "{err}");
    assert!(err.contains("adapter"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(!out.exists());

    // auto falls back to the CPU instead.
    let o = command()
        .args([
            "render",
            "--backend",
            "auto",
            "--out",
            s(&out),
            "--width",
            "32",
            "--height",
            "32",
        ])
        .env("WGPU_BACKEND", "vulkan")
        .env("VK_DRIVER_FILES", dir.path().join("none.json"))
        .env("VK_ICD_FILENAMES", dir.path().join("none.json"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("\nbackend: cpu (auto: "),
        "{}",
        stdout(&o)
    );
    assert!(out.is_file());
}

#[test]
fn unknown_backend_is_a_usage_error() {
    let o = evogs(&["render", "--backend", "gpu", "--out", "x.png"]);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert!(
        err.contains("unknown backend `gpu`; expected cpu, wgpu or auto"),
        "{err}"
    );
}

#[test]
fn the_network_on_the_device_trains_like_the_cpus_and_says_where_it_runs() {
    let dir = tempfile::tempdir().unwrap();
    let data = rigid_scene(dir.path(), 32, 8);
    let psnr = |run: &Path| {
        json(&run.join("train_metrics.json"))["last_psnr"]
            .as_f64()
            .unwrap()
    };

    // The same wgpu rasterizer; the network on the CPU, then on the device (lavapipe here, where
    // the network is slow: 30 iterations, the network in 25 of them).
    let train = |data: &Path, out: &Path, extra: &[&str]| {
        let args = ["--iterations", "30", "--seed", "5"];
        train_tiny(data, out, &[&args[..], extra].concat())
    };
    let cpu_net = dir.path().join("cpu-net");
    let o = train(
        &data,
        &cpu_net,
        &["--backend", "wgpu", "--net-backend", "cpu"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("\nnetwork: cpu (asked: cpu)\n"),
        "{}",
        stdout(&o)
    );
    let gpu_net = dir.path().join("gpu-net");
    let o = train(
        &data,
        &gpu_net,
        &[
            "--backend",
            "wgpu",
            "--net-backend",
            "wgpu",
            "--stop-after",
            "25",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let on_device = "network: wgpu (wgpu: on the rasterizer's device)";
    assert!(stdout(&o).contains(on_device), "{}", stdout(&o));
    assert_eq!(
        json(&gpu_net.join("config.json"))["train"]["net_backend"],
        "wgpu"
    );
    // Resumed without the flag it stays on the device, and says so in its metrics.
    let o = evogs(&["train", "--out", s(&gpu_net), "--resume"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains(on_device), "{}", stdout(&o));
    assert_eq!(
        json(&gpu_net.join("train_metrics.json"))["network"],
        on_device
    );
    // On the device the network's parameters, gradient and moments stay there: its forward
    // waits for the rows, its backward and Adam step do not wait. One more wait per iteration
    // than the rasterizer's alone (the resumed process deforms in each of its 5 iterations), and
    // two read-backs of the parameters and moments in those 5: the last iteration's check for
    // non-finite values and the last checkpoint.
    let waits = |run: &Path| {
        json(&run.join("train_metrics.json"))["traffic_per_iteration"]["waits"]
            .as_f64()
            .unwrap()
    };
    let (cpu_waits, gpu_waits) = (waits(&cpu_net), waits(&gpu_net));
    assert!(
        (gpu_waits - cpu_waits - (1.0 + 2.0 / 5.0)).abs() < 0.01,
        "waits per iteration: network on the cpu {cpu_waits}, on wgpu {gpu_waits}"
    );
    let (cpu_psnr, gpu_psnr) = (psnr(&cpu_net), psnr(&gpu_net));
    eprintln!(
        "training PSNR after 30 iterations: network on the cpu {cpu_psnr:.3} dB, on wgpu {gpu_psnr:.3} dB"
    );
    assert!(cpu_psnr.is_finite() && cpu_psnr > 8.0, "{cpu_psnr}");
    assert!(
        (cpu_psnr - gpu_psnr).abs() < 0.5,
        "network on the cpu {cpu_psnr:.3} dB vs on wgpu {gpu_psnr:.3} dB"
    );

    // A resume may move the network back; the switch is recorded.
    let o = evogs(&[
        "train",
        "--out",
        s(&gpu_net),
        "--resume",
        "--net-backend",
        "cpu",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        json(&gpu_net.join("config.json"))["train"]["net_backend"],
        "cpu"
    );

    // auto keeps it on the CPU beside a software rasterizer, and says why; the CPU rasterizer
    // has no device to share.
    let short = |run: &str, backend: &str| {
        let args = ["--iterations", "2", "--backend", backend];
        train_tiny(&data, &dir.path().join(run), &args)
    };
    let o = short("auto", "wgpu");
    assert!(o.status.success(), "{}", stderr(&o));
    let adapter = splat_raster::GpuContext::new().unwrap().adapter().clone();
    let expected = if adapter.hardware {
        on_device.replace("wgpu: on", "auto: on")
    } else {
        format!("network: cpu (auto: adapter {} is a software", adapter.name)
    };
    assert!(stdout(&o).contains(&expected), "{}", stdout(&o));
    let o = short("auto-cpu", "cpu");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("network: cpu (auto: the rasterizer runs on the CPU)"),
        "{}",
        stdout(&o)
    );

    // Asking for the device where there is none, or for a backbone without a device form, is a
    // one-line error naming the setting.
    for (extra, says) in [
        (
            &["--backend", "cpu", "--net-backend", "wgpu"][..],
            "the rasterizer runs on the CPU",
        ),
        (
            &[
                "--backend",
                "wgpu",
                "--net-backend",
                "wgpu",
                "--method",
                "evogs",
            ][..],
            "has no GPU form yet",
        ),
    ] {
        let run = dir.path().join("refused");
        let o = train(&data, &run, extra);
        assert!(!o.status.success(), "{extra:?}");
        let err = stderr(&o);
        // Mesa's Vulkan loader, asked for a device, may print its own line when the machine has
        // no XDG_RUNTIME_DIR (CI's has none): that line is the driver's, not ours.
        let ours: Vec<&str> = err
            .lines()
            .filter(|l| !l.contains("XDG_RUNTIME_DIR"))
            .collect();
        assert_eq!(ours.len(), 1, "{err}");
        assert!(
            ours[0].contains("net_backend") && ours[0].contains(says),
            "{err}"
        );
        std::fs::remove_dir_all(&run).ok();
    }
}
