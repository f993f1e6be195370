//! A small timed client of a running `evogs view`: asks for `N` views (default 50) of run 0 one
//! after another, as the page does (one request in flight), each from a camera orbited a little
//! further around test camera 0's look-at point, and prints views per second with the server's
//! own times (median deformation, rasterization and encoding). Not a test: numbers depend on the
//! machine and its load.
//!
//! ```sh
//! evogs view RUN --port 8080 &
//! cargo run --release -p evogs-view --example view_client -- 127.0.0.1:8080 50 400 jpeg moving $!
//! ```
//!
//! Arguments: address, views, side in pixels, `jpeg` or `png`, `moving` (the time moves with
//! every view, as when the page plays) or `still` (one time, as when orbiting a paused scene),
//! and optionally the server's process id: then the server's CPU time over the views is read
//! from `/proc/PID/stat` and printed per view, a figure that other jobs on a shared machine
//! disturb much less than wall time.

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use evogs_view::client::{Reply, get};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let addr: SocketAddr = args
        .get(1)
        .map_or("127.0.0.1:8080", String::as_str)
        .parse()
        .expect("ADDR as IP:PORT");
    let n: usize = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(50);
    let side: u32 = args.get(3).and_then(|a| a.parse().ok()).unwrap_or(400);
    let fmt = args.get(4).map_or("jpeg", String::as_str);
    let still = match args.get(5).map_or("moving", String::as_str) {
        "moving" => false,
        "still" => true,
        other => panic!("expected moving or still, not {other}"),
    };
    let pid: Option<u32> = args.get(6).map(|a| a.parse().expect("PID"));
    let timeout = Duration::from_secs(120);
    let reply = get(addr, "/api/info", timeout).expect("connect");
    assert_eq!(reply.status, 200, "{}", reply.text());
    let info: serde_json::Value = serde_json::from_slice(&reply.body).expect("info JSON");
    let run = &info["runs"][0];
    let cams = &run["cameras"]["test"];
    let cam = if cams.as_array().is_some_and(|c| !c.is_empty()) {
        &cams[0]
    } else {
        &run["cameras"]["train"][0]
    };
    let f = |v: &serde_json::Value, k: usize| v[k].as_f64().expect("number") as f32;
    let rows: Vec<glam::Vec3> = (0..3)
        .map(|i| {
            glam::Vec3::new(
                f(&cam["R"], 3 * i),
                f(&cam["R"], 3 * i + 1),
                f(&cam["R"], 3 * i + 2),
            )
        })
        .collect();
    let centre = glam::Vec3::new(f(&cam["C"], 0), f(&cam["C"], 1), f(&cam["C"], 2));
    let target = glam::Vec3::new(
        f(&run["target"], 0),
        f(&run["target"], 1),
        f(&run["target"], 2),
    );
    let up = glam::Vec3::new(f(&run["up"], 0), f(&run["up"], 1), f(&run["up"], 2)).normalize();
    let scale = side as f32 / cam["w"].as_f64().expect("w") as f32;
    let k = [0, 1, 2, 3].map(|i| f(&cam["K"], i) * scale);
    println!(
        "{} ({} Gaussians, backend {}): {n} views of {side}x{side} as {fmt}, time {}",
        run["name"],
        run["gaussians"],
        run["backend"],
        if still { "still" } else { "moving" }
    );
    let names = ["x-render-ms", "x-deform-ms", "x-raster-ms", "x-encode-ms"];
    let mut server_ms: Vec<Vec<f64>> = vec![Vec::with_capacity(n); names.len()];
    let cpu_before = pid.map(cpu_seconds);
    let start = Instant::now();
    for i in 0..n {
        let q = glam::Quat::from_axis_angle(up, 0.02 * i as f32);
        let r: Vec<glam::Vec3> = rows.iter().map(|row| q * *row).collect();
        let c = target + q * (centre - target);
        let list = |v: &[f32]| {
            v.iter()
                .map(|x| x.to_string())
                .collect::<Vec<_>>()
                .join(",")
        };
        let rot: Vec<f32> = r.iter().flat_map(|v| v.to_array()).collect();
        let t = if still { 0.5 } else { i as f32 / n as f32 };
        let path = format!(
            "/api/render?R={}&C={}&K={}&w={side}&h={side}&t={t}&fmt={fmt}",
            list(&rot),
            list(&c.to_array()),
            list(&k)
        );
        let reply: Reply = get(addr, &path, timeout).expect("connect");
        assert_eq!(reply.status, 200, "{}", reply.text());
        for (name, times) in names.iter().zip(&mut server_ms) {
            if let Some(ms) = reply.header(name) {
                times.push(ms.parse::<f64>().unwrap_or(f64::NAN));
            }
        }
    }
    let secs = start.elapsed().as_secs_f64();
    let [render, deform, raster, encode] = [0, 1, 2, 3].map(|k| median(&mut server_ms[k]));
    println!(
        "{:.2} views/s ({:.1} ms per view end to end); server medians: render {render:.1} ms \
         (deformation {deform:.1}, rasterization {raster:.1}), encoding {encode:.1} ms",
        n as f64 / secs,
        1e3 * secs / n as f64
    );
    if let (Some(pid), Some(before)) = (pid, cpu_before) {
        let cpu = cpu_seconds(pid) - before;
        println!(
            "server CPU time {:.1} ms per view ({:.2} views per CPU-second)",
            1e3 * cpu / n as f64,
            n as f64 / cpu
        );
    }
}

/// The median of `v` (NaN when empty).
fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// User plus system CPU seconds of process `pid` so far (`/proc/PID/stat`, fields 14 and 15,
/// in clock ticks of 1/100 s, Linux's `USER_HZ`).
fn cpu_seconds(pid: u32) -> f64 {
    let stat =
        std::fs::read_to_string(format!("/proc/{pid}/stat")).expect("the server's /proc/PID/stat");
    // The command name (field 2) is in parentheses and may hold spaces: count after it.
    let rest = &stat[stat.rfind(')').expect("a stat line") + 2..];
    let fields: Vec<&str> = rest.split(' ').collect();
    let ticks = |k: usize| fields[k - 3].parse::<f64>().expect("a tick count");
    (ticks(14) + ticks(15)) / 100.0
}
