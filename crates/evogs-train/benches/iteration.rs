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
//! iterations are printed (wall clock, so their shares, not their sums, are the comparable part).

use std::path::Path;

use bench_support::{CpuTime, clock_prefix};
use criterion::measurement::Measurement;
use criterion::{Criterion, criterion_group, criterion_main};
use evogs_io::Split;
use evogs_train::data::load_split;
use evogs_train::{Method, Preset, TrainConfig, Trainer};

/// The fixture's training frame the bench trains on.
const FRAME: &str = "r_24.png";
/// Upsampling of the 100×100 fixture to 400×400.
const FACTOR: f32 = 4.0;

fn trainer(method: Method) -> Trainer {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../evogs-io/tests/data/dnerf-lego");
    let mut c = TrainConfig::preset(Preset::Cpu).with_iterations(1_000_000);
    c.method = method;
    c.seed = 1;
    c.warm_up = 20;
    c.densify.schedule.from = 999_999;
    c.densify.schedule.until = 1_000_000;
    let mut views = load_split(&data, Split::Train, c.time_from, c.background.rgb(), FACTOR)
        .expect("the lego fixture loads");
    views.views.retain(|v| v.path.ends_with(FRAME));
    assert_eq!(views.views.len(), 1, "fixture frame {FRAME}");
    assert_eq!(views.views[0].camera.width, 400);
    let mut t = Trainer::new(c, views).unwrap();
    while t.iteration() < 60 {
        t.step().unwrap();
    }
    t
}

fn bench<M: Measurement>(c: &mut Criterion<M>) {
    let mut group = c.benchmark_group(format!("{}iteration_lego_400x400_cpu", clock_prefix::<M>()));
    group.sample_size(10);
    for method in [Method::Baseline, Method::Evogs] {
        let mut t = trainer(method);
        let n = t.state().len();
        t.reset_times();
        let start = t.iteration();
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
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().with_measurement(CpuTime::wall_equivalent());
    targets = bench::<CpuTime>
}
criterion_main!(benches);
