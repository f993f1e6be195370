//! Statistics, plan and apply for 1M Gaussians with every array of a real run: SH degree 3
//! parameters (59 floats), their Adam m and v (one group per parameter kind, as 3DGS), the
//! evolution state (T = 34 frames of lego, D = 10, f16 buffer, f32 memory) and the statistics.

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use densify::{
    Deformation, DensifyConfig, DensifyStats, OptimiserMoments, PerGaussian, PlanInput, Planned,
    apply_plan, make_plan,
};
use evo_state::{EvoConfig, EvoState, Frames, Storage};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use splat_core::Gaussians;
use splat_core::Layout;
use std::hint::black_box;
use tiny_nn::adam::{Adam, GroupId, LrSchedule};

const N: usize = 1_000_000;
const FRAMES: usize = 34;

struct Run {
    gaussians: Gaussians,
    adam: Adam,
    evo: EvoState,
    stats: DensifyStats,
}

/// (name, row width, opacity column) of the Adam groups, 59 floats in all.
const GROUPS: [(&str, usize, Option<usize>); 6] = [
    ("means", 3, None),
    ("log_scales", 3, None),
    ("rotations", 4, None),
    ("opacity", 1, Some(0)),
    ("sh_dc", 3, None),
    ("sh_rest", 45, None),
];

fn run(rng: &mut ChaCha8Rng) -> Run {
    let mut g = Gaussians::with_degree(3);
    assert_eq!(3 + 3 + 4 + 1 + g.sh_stride(), 59);
    for _ in 0..N {
        g.means.push([
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            0.0,
        ]);
        let s: f32 = rng.random_range(0.005f32..0.08);
        g.log_scales.push([s.ln(), (0.5 * s).ln(), (0.3 * s).ln()]);
        g.rotations.push([1.0, 0.1, 0.0, 0.0]);
        g.opacity_logits.push(rng.random_range(-5.5..4.0));
    }
    g.sh = vec![0.1; N * g.sh_stride()];
    let mut adam = Adam::new();
    for (name, width, _) in GROUPS {
        let id = adam
            .add_group(name, N * width, width, LrSchedule::Constant(1e-3))
            .unwrap();
        adam.group_mut(id).m.fill(0.5);
        adam.group_mut(id).v.fill(0.25);
    }
    let frames = Frames::new(
        (0..FRAMES)
            .map(|k| k as f32 / (FRAMES - 1) as f32)
            .collect(),
    )
    .unwrap();
    let mut evo = EvoState::new(
        EvoConfig {
            storage: Storage::F16,
            ..EvoConfig::default()
        },
        frames,
        N,
        1,
    )
    .unwrap();
    let z = vec![0.01f32; N * 10];
    let step = evo.forward(0.0, &z).unwrap();
    evo.commit(&step).unwrap();
    let stats = DensifyStats::new(N);
    Run {
        gaussians: g,
        adam,
        evo,
        stats,
    }
}

fn apply_all(plan: &densify::DensifyPlan, run: &mut Run, with_evo: bool) {
    let Run {
        gaussians,
        adam,
        evo,
        stats,
    } = run;
    let groups: Vec<(GroupId, Option<usize>)> = GROUPS
        .iter()
        .enumerate()
        .map(|(i, &(_, _, opacity_column))| (GroupId(i), opacity_column))
        .collect();
    let mut moments = OptimiserMoments {
        adam,
        groups: &groups,
    };
    let mut evolution = Planned(evo);
    let mut arrays: Vec<&mut dyn PerGaussian> = vec![gaussians, stats];
    if with_evo {
        arrays.push(&mut evolution);
    }
    arrays.push(&mut moments);
    apply_plan(plan, &mut arrays).unwrap();
}

fn bench(c: &mut Criterion) {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut run = run(&mut rng);
    let means2d: Vec<[f32; 2]> = (0..N)
        .map(|_| {
            // About 8% of Gaussians get a gradient above the threshold.
            let a = if rng.random_bool(0.08) { 3e-6 } else { 3e-7 };
            [rng.random_range(-a..a), rng.random_range(-a..a)]
        })
        .collect();
    let radii: Vec<f32> = (0..N)
        .map(|_| rng.random_range(0.0f32..21.2).floor())
        .collect();
    let residual: Vec<f32> = (0..N).map(|_| rng.random_range(0.0..0.02)).collect();
    let theta: Vec<f32> = (0..N).map(|_| rng.random_range(0.0..1.2)).collect();
    let corrected: Vec<f32> = (0..N * 10).map(|_| rng.random_range(-0.01..0.01)).collect();

    c.bench_function("stats/add_view+add_evolution 1M", |b| {
        b.iter(|| {
            run.stats.add_view(&means2d, &radii, 800, 800).unwrap();
            run.stats
                .add_evolution(Some(&residual), Some(&theta))
                .unwrap();
        });
    });
    // A realistic interval: a few views accumulated, about 5% of Gaussians densified.
    run.stats.reset(N);
    for _ in 0..3 {
        run.stats.add_view(&means2d, &radii, 800, 800).unwrap();
        run.stats
            .add_evolution(Some(&residual), Some(&theta))
            .unwrap();
    }
    let config = DensifyConfig::evogs();
    let input = |run: &Run| {
        make_plan(
            &config,
            &PlanInput {
                gaussians: run.gaussians.view(),
                stats: &run.stats,
                extent: 4.0,
                iteration: 3100,
                deformation: Some(Deformation {
                    corrected: &corrected,
                    layout: Layout::default(),
                }),
            },
        )
        .unwrap()
    };
    c.bench_function("plan 1M (EvoGS policies)", |b| {
        b.iter(|| black_box(input(&run)));
    });
    let plan = input(&run);
    eprintln!("bench plan: {}", plan.summary);

    let mut group = c.benchmark_group("apply 1M");
    group.bench_function("all arrays (incl. evo buffer 34x10 f16)", |b| {
        b.iter_batched_ref(
            || clone_run(&run),
            |r| apply_all(&plan, r, true),
            BatchSize::PerIteration,
        );
    });
    group.bench_function("all arrays except evo state", |b| {
        b.iter_batched_ref(
            || clone_run(&run),
            |r| apply_all(&plan, r, false),
            BatchSize::PerIteration,
        );
    });
    // Floor for comparison: one plain copy of as many bytes as the parameters and moments
    // (59 floats × 3 per Gaussian), into memory already allocated.
    let bytes_floats = N * 59 * 3;
    let src = vec![1.0f32; bytes_floats];
    let mut dst = vec![0.0f32; bytes_floats];
    group.bench_function("reference: memcpy of params+moments bytes (708 MB)", |b| {
        b.iter(|| {
            dst.copy_from_slice(black_box(&src));
            black_box(&dst);
        });
    });
    group.finish();
}

fn clone_run(run: &Run) -> Run {
    Run {
        gaussians: run.gaussians.clone(),
        adam: run.adam.clone(),
        evo: run.evo.clone(),
        stats: run.stats.clone(),
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
