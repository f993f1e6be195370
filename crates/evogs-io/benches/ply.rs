//! PLY read and write throughput for 1M Gaussians at SH degree 3 (248 bytes per row).

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use evogs_io::{read_ply, read_ply_bytes, write_ply, write_ply_to};
use splat_core::Gaussians;

const COUNT: usize = 1_000_000;

fn gaussians() -> Gaussians {
    let mut g = Gaussians::with_degree(3);
    let stride = g.sh_stride();
    // A cheap deterministic pattern; values do not affect throughput.
    let v = |i: usize, k: usize| ((i * 31 + k * 7) % 1000) as f32 * 1e-3 - 0.5;
    for i in 0..COUNT {
        g.means.push([v(i, 0), v(i, 1), v(i, 2)]);
        g.log_scales
            .push([v(i, 3) - 4.0, v(i, 4) - 4.0, v(i, 5) - 4.0]);
        g.rotations.push([1.0, v(i, 6), v(i, 7), v(i, 8)]);
        g.opacity_logits.push(v(i, 9));
        g.sh.extend((0..stride).map(|k| v(i, 10 + k)));
    }
    g
}

fn bench(c: &mut Criterion) {
    let g = gaussians();
    let mut bytes = Vec::new();
    write_ply_to(&mut bytes, g.view(), Path::new("mem.ply")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bench.ply");
    write_ply(&path, g.view()).unwrap();

    let mut group = c.benchmark_group("ply_1M_deg3");
    group.throughput(Throughput::Bytes(bytes.len() as u64));
    group.bench_function("write_memory", |b| {
        let mut out = Vec::with_capacity(bytes.len());
        b.iter(|| {
            out.clear();
            write_ply_to(&mut out, black_box(g.view()), Path::new("mem.ply")).unwrap();
        });
    });
    group.bench_function("write_file_atomic", |b| {
        b.iter(|| write_ply(&path, black_box(g.view())).unwrap());
    });
    group.bench_function("read_memory", |b| {
        b.iter(|| read_ply_bytes(black_box(&bytes), Path::new("mem.ply")).unwrap());
    });
    group.bench_function("read_file", |b| b.iter(|| read_ply(&path).unwrap()));
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}
criterion_main!(benches);
