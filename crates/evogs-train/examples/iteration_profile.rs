//! Instruction profile of lego training iterations (issue P): the `iteration` bench's fixed
//! frame and state (the lego fixture's view `r_24` upsampled 4× to 400×400, the `cpu` preset's
//! settings, a 20-iteration warm-up, densification off), trained 25 iterations, then STEPS
//! iterations in [`measured`], the function to collect under callgrind:
//!
//! ```text
//! cargo build --release -p evogs-train --example iteration_profile
//! valgrind --tool=callgrind --collect-atstart=no --toggle-collect='iteration_profile::measured*' \
//!     target/release/examples/iteration_profile baseline|evogs STEPS ['{"init_points":38000}']
//! callgrind_annotate --inclusive=yes callgrind.out.PID
//! ```
//! The optional JSON is merged into the config (e.g. the Gaussian count, or EvoGS's settings
//! `{"evogs":{"gain":"0.5"}}`). Without valgrind it prints the trainer's phase times of the
//! measured iterations.
//!
//! Sampled time of the same iterations alone (the state changes over a run, so the iterations
//! callgrind counts are the ones to time): with `EVOGS_PERF_CONTROL` naming a FIFO, the example
//! writes `enable` to it before [`measured`] and `disable` after, for a perf started disabled:
//!
//! ```text
//! mkfifo ctl
//! EVOGS_PERF_CONTROL=ctl perf record -D -1 --control fifo:ctl -e cpu-clock -F 2000 \
//!     target/release/examples/iteration_profile evogs 2
//! ```
//! (Sampling costs time in a VM: at 2 kHz the iterations took up to ~15 % longer than without
//! perf, at 20 kHz 4× as long; BENCHMARKS.md, "Where one lego iteration's time goes".)

use std::io::Write;
use std::path::Path;

use evogs_io::Split;
use evogs_train::data::load_split;
use evogs_train::{Method, Preset, TrainConfig, Trainer};
use splat_raster::Rasterizer;

/// The iterations callgrind collects.
#[inline(never)]
fn measured(t: &mut Trainer, steps: u64) {
    for _ in 0..steps {
        t.step().expect("a training step");
    }
}

/// Opens perf's control FIFO at `path` and enables sampling.
fn perf_control(path: std::ffi::OsString) -> std::fs::File {
    let mut fifo = std::fs::OpenOptions::new()
        .write(true)
        .open(&path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    fifo.write_all(b"enable\n")
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    fifo
}

fn merge(base: &mut serde_json::Value, patch: &serde_json::Value) {
    match (base, patch) {
        (serde_json::Value::Object(b), serde_json::Value::Object(p)) => {
            for (k, v) in p {
                merge(b.entry(k.clone()).or_insert(serde_json::Value::Null), v);
            }
        }
        (b, p) => *b = p.clone(),
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let usage = "usage: iteration_profile baseline|evogs STEPS [CONFIG_PATCH_JSON]";
    let method: Method = args.get(1).ok_or(usage)?.parse()?;
    let steps: u64 = args.get(2).ok_or(usage)?.parse()?;
    let mut c = TrainConfig::preset(Preset::Cpu).with_iterations(1_000_000);
    c.method = method;
    c.seed = 1;
    c.warm_up = 20;
    c.densify.schedule.from = 999_999;
    c.densify.schedule.until = 1_000_000;
    if let Some(patch) = args.get(3) {
        let mut value = serde_json::to_value(&c)?;
        merge(&mut value, &serde_json::from_str(patch)?);
        c = serde_json::from_value(value)?;
    }
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../evogs-io/tests/data/dnerf-lego");
    let mut views = load_split(&data, Split::Train, c.time_from, c.background.rgb(), 4.0)?;
    views.views.retain(|v| v.path.ends_with("r_24.png"));
    let mut t = Trainer::new(c, views)?;
    while t.iteration() < 25 {
        t.step()?;
    }
    // Gaussian-pixel evaluations of one forward pass of this state (the deformed Gaussians at
    // the view's time, on the CPU kernels), for per-evaluation figures; before `measured`, so
    // outside the collected part.
    let (camera, time) = (
        t.train_views().views[0].camera,
        t.train_views().views[0].time,
    );
    let g = t.deformed_at(time)?;
    let opts = splat_raster::RenderOptions {
        background: t.config().background.rgb(),
        sh_degree: None,
    };
    let fwd = splat_raster::CpuRasterizer::new().forward(g.view(), &camera, &opts)?;
    eprintln!(
        "{} Gaussian-pixel evaluations, {} tile pairs, {:.2} contributors per pixel per forward pass",
        fwd.pair_evaluations(),
        fwd.tile_pairs(),
        fwd.mean_contributors()
    );
    t.reset_times();
    let perf = std::env::var_os("EVOGS_PERF_CONTROL").map(perf_control);
    measured(&mut t, steps);
    if let Some(mut p) = perf {
        p.write_all(b"disable\n")?;
    }
    eprintln!(
        "{method}, {} Gaussians, {steps} iterations:\n{}",
        t.state().len(),
        t.times()
    );
    Ok(())
}
