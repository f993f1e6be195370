//! One whole training iteration at 400×400 with the `cpu` preset's settings (issue 14's lego
//! setting), baseline (D-3DGS, width 64) and EvoGS, on a fixed lego frame and state.
//!
//! The frame is the repository's own lego fixture (`evogs-io/tests/data/dnerf-lego`, 100×100),
//! view `r_24`, upsampled 4× to 400×400 with its camera scaled alike, so the rasterizer and the
//! loss see the pixel count of the `cpu` preset's lego run (the image holds 100×100 detail). The
//! state: the preset's 10 000 random initial Gaussians trained 60 iterations on that frame with a
//! 20-iteration warm-up (so EvoGS runs its networks in every measured iteration) and densification
//! off (so the Gaussian count stays fixed while measuring).
//!
//! Measured with [`CpuTime::wall_equivalent`] (process CPU time over rayon's threads): the machine
//! is shared. After each method's measurement the trainer's own per-phase timers over the measured
//! iterations are printed (wall clock, so their shares, not their sums, are the comparable part),
//! and on a GPU backend the host–device traffic per iteration and the device's own time per
//! labelled span of work (GPU timestamps, where the adapter has them).
//!
//! Variants for a GPU machine (`scripts/gpu-check`), from the environment, all optional:
//! `EVOGS_ITER_BACKEND` (`cpu`, `wgpu`, `auto`; on a GPU backend the clock is wall time, since
//! process CPU time leaves out the GPU's work), `EVOGS_ITER_GAUSSIANS` (initial random
//! Gaussians, default the preset's 10 000), `EVOGS_ITER_SIZE` (image side, 400 or 800: the
//! fixture upsampled 4× or 8×), `EVOGS_ITER_SH` (active SH degree 0 to 3, default 0 as in the
//! first 500 iterations of the preset), `EVOGS_ITER_NET_BACKEND` (where the deformation network
//! runs, `TrainConfig::net_backend`: default the preset's, `auto`, which is the device on a
//! hardware GPU for the baseline's network).

use std::path::Path;

use bench_support::{CpuTime, clock_prefix};
use criterion::Criterion;
use criterion::measurement::{Measurement, WallTime};
use evogs_io::Split;
use evogs_train::data::load_split;
use evogs_train::{Method, Preset, TrainConfig, Trainer};
use splat_raster::BackendChoice;

/// The fixture's training frame the bench trains on.
const FRAME: &str = "r_24.png";

/// The variant the environment asks for (module doc).
struct Variant {
    backend: BackendChoice,
    net_backend: BackendChoice,
    gaussians: Option<usize>,
    size: u32,
    sh: u32,
}

impl Variant {
    fn from_env() -> Self {
        let var = |name: &str| std::env::var(name).ok().filter(|v| !v.is_empty());
        let parse = |name: &str, v: String| -> usize {
            v.parse()
                .unwrap_or_else(|_| panic!("{name}={v}: not a whole number"))
        };
        let backend = var("EVOGS_ITER_BACKEND").map_or(BackendChoice::Cpu, |v| {
            v.parse()
                .unwrap_or_else(|_| panic!("EVOGS_ITER_BACKEND={v}: cpu, wgpu or auto"))
        });
        let net_backend = var("EVOGS_ITER_NET_BACKEND").map_or(
            TrainConfig::preset(Preset::Cpu).net_backend,
            |v| {
                v.parse()
                    .unwrap_or_else(|_| panic!("EVOGS_ITER_NET_BACKEND={v}: cpu, wgpu or auto"))
            },
        );
        let size = var("EVOGS_ITER_SIZE").map_or(400, |v| parse("EVOGS_ITER_SIZE", v)) as u32;
        assert!(
            size.is_multiple_of(100) && size > 0,
            "EVOGS_ITER_SIZE={size}: a multiple of the fixture's 100"
        );
        let sh = var("EVOGS_ITER_SH").map_or(0, |v| parse("EVOGS_ITER_SH", v)) as u32;
        assert!(sh <= 3, "EVOGS_ITER_SH={sh}: 0 to 3");
        Self {
            backend,
            net_backend,
            gaussians: var("EVOGS_ITER_GAUSSIANS").map(|v| parse("EVOGS_ITER_GAUSSIANS", v)),
            size,
            sh,
        }
    }
}

fn trainer(method: Method, v: &Variant) -> Trainer {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../evogs-io/tests/data/dnerf-lego");
    let mut c = TrainConfig::preset(Preset::Cpu).with_iterations(1_000_000);
    c.method = method;
    c.seed = 1;
    c.warm_up = 20;
    c.densify.schedule.from = 999_999;
    c.densify.schedule.until = 1_000_000;
    c.backend = v.backend;
    c.net_backend = v.net_backend;
    if let Some(n) = v.gaussians {
        c.init_points = n;
    }
    // The active degree rises by one every `sh_interval` steps: reach `sh` within the 60
    // warm-up steps and stay there.
    c.sh_degree = v.sh;
    c.sh_interval = 10;
    let factor = v.size as f32 / 100.0;
    let mut views = load_split(&data, Split::Train, c.time_from, c.background.rgb(), factor)
        .expect("the lego fixture loads");
    views.views.retain(|view| view.path.ends_with(FRAME));
    assert_eq!(views.views.len(), 1, "fixture frame {FRAME}");
    assert_eq!(views.views[0].camera.width, v.size);
    let mut t = Trainer::new(c, views).unwrap();
    while t.iteration() < 60 {
        t.step().unwrap();
    }
    t
}

fn bench<M: Measurement>(c: &mut Criterion<M>, v: &Variant) {
    let n0 = v
        .gaussians
        .unwrap_or(TrainConfig::preset(Preset::Cpu).init_points);
    let mut group = c.benchmark_group(format!(
        "{}iteration_lego_{s}x{s}_{n0}_sh{sh}_{backend}_net_{net}",
        clock_prefix::<M>(),
        s = v.size,
        sh = v.sh,
        backend = v.backend,
        net = v.net_backend,
    ));
    group.sample_size(10);
    for method in [Method::Baseline, Method::Evogs] {
        let mut t = trainer(method, v);
        let n = t.state().len();
        t.reset_times();
        let start = t.iteration();
        let traffic_start = t.traffic();
        let device_start = t.device_times().unwrap_or_default();
        group.bench_function(format!("{method} ({n} Gaussians)"), |b| {
            b.iter(|| t.step().unwrap());
        });
        let steps = (t.iteration() - start).max(1) as f64;
        let total = t.times().total();
        let phases: Vec<String> = t
            .times()
            .entries()
            .iter()
            .map(|(name, s)| {
                format!(
                    "{name} {:.2} ms ({:.0}%)",
                    1e3 * s / steps,
                    100.0 * s / total
                )
            })
            .collect();
        eprintln!(
            "{method}: wall per phase, mean over {steps} iterations: {}",
            phases.join(", ")
        );
        if let Some((end, start)) = t.traffic().zip(traffic_start) {
            eprintln!(
                "{method}: host-device traffic per iteration: {} ({}; {})",
                end.since(&start).per(steps as u64),
                t.backend(),
                t.network()
            );
        }
        if let Some(end) = t.device_times() {
            let spans: Vec<String> = end
                .iter()
                .map(|(label, (ms, _))| {
                    let before = device_start.get(label).map_or(0.0, |b| b.0);
                    format!("{label} {:.2} ms", (ms - before) / steps)
                })
                .collect();
            eprintln!(
                "{method}: device time per iteration (GPU timestamps): {}",
                spans.join(", ")
            );
        }
    }
    group.finish();
}

fn main() {
    let v = Variant::from_env();
    if v.backend == BackendChoice::Cpu {
        let mut c = Criterion::default()
            .with_measurement(CpuTime::wall_equivalent())
            .configure_from_args();
        bench(&mut c, &v);
        c.final_summary();
    } else {
        let mut c = Criterion::default()
            .with_measurement(WallTime)
            .configure_from_args();
        bench(&mut c, &v);
        c.final_summary();
    }
}
