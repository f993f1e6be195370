//! One training iteration (render, loss, backward, backbone backward, Adam) of the baseline and of
//! EvoGS on the embedded synthetic scene (64×64), after the warm-up, with densification off so
//! both methods run on the same 2 000 Gaussians and every measured iteration runs the network;
//! plus EvoGS with the opacity and colour components (D = 14 instead of 10); and beside each, the
//! NaN/Inf check of every parameter group that training runs every log interval.

use criterion::{Criterion, criterion_group, criterion_main};
use evogs_backbones::Layout;
use evogs_io::Split;
use evogs_synth::{embedded_scene, write_dnerf};
use evogs_train::data::load_split;
use evogs_train::{Method, Preset, TrainConfig, Trainer};

fn trainer(method: Method, components: Layout, data: &std::path::Path) -> Trainer {
    let mut c = TrainConfig::preset(Preset::Tiny).with_iterations(1_000_000);
    c.method = method;
    c.backbones.evogs.evo.layout = components;
    c.warm_up = 50;
    c.densify.schedule.from = 999_999;
    c.densify.schedule.until = 1_000_000;
    let views = load_split(
        data,
        Split::Train,
        c.time_from,
        c.background.rgb(),
        c.downscale,
    )
    .unwrap();
    let mut t = Trainer::new(c, views).unwrap();
    while t.iteration() < 200 {
        t.step().unwrap();
    }
    t
}

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("scene");
    write_dnerf(&embedded_scene().unwrap(), &data).unwrap();
    let mut group = c.benchmark_group("train_step_embedded_64x64");
    let geometry = Layout::default();
    let every: Layout = "pos,rot,scale,opacity,colour".parse().unwrap();
    for (method, components, label) in [
        (Method::Baseline, geometry, ""),
        (Method::Evogs, geometry, ""),
        (Method::Evogs, every, " +opacity,colour"),
    ] {
        let mut t = trainer(method, components, &data);
        let n = t.state().len();
        group.bench_function(format!("{method}{label} ({n} Gaussians)"), |b| {
            b.iter(|| t.step().unwrap());
        });
        // The NaN/Inf check training runs every log interval, against one step above.
        group.bench_function(
            format!("{method}{label} non-finite check ({n} Gaussians)"),
            |b| b.iter(|| t.state().first_non_finite(t.backbone())),
        );
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
