//! Dataset loader throughput: COLMAP `points3D.bin` / `images.bin` parsing and `.npy` parsing
//! (a 1M-point sparse cloud, 1,000 registered images with 2,000 2D points each, and a
//! 1M × 3 f4 array), all from memory.

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use evogs_io::colmap::{
    ColmapImage, ColmapPoint, encode_images_bin, encode_points3d_bin, parse_images_bin,
    parse_points3d_bin,
};
use evogs_io::npy::{encode_npy, parse_npy};

const POINTS: usize = 1_000_000;

fn bench(c: &mut Criterion) {
    let points: Vec<ColmapPoint> = (0..POINTS)
        .map(|i| ColmapPoint {
            xyz: [i as f64 * 1e-3, 1.0, -2.0],
            rgb: [(i % 256) as u8, 7, 9],
        })
        .collect();
    let points_bin = encode_points3d_bin(&points);
    let images: Vec<ColmapImage> = (0..1000)
        .map(|i| ColmapImage {
            id: i + 1,
            qvec: [1.0, 0.0, 0.0, 0.0],
            tvec: [0.0, 0.0, 3.0],
            camera_id: 1,
            name: format!("frame_{i:05}.jpg"),
        })
        .collect();
    let images_bin = encode_images_bin(&images, 2000);
    let data: Vec<f64> = (0..POINTS * 3).map(|i| i as f64 * 1e-3).collect();
    let npy = encode_npy(&[POINTS, 3], &data, true);

    let mut group = c.benchmark_group("loaders");
    group.throughput(Throughput::Bytes(points_bin.len() as u64));
    group.bench_function("points3D.bin 1M points", |b| {
        b.iter(|| parse_points3d_bin(Path::new("points3D.bin"), black_box(&points_bin)).unwrap());
    });
    group.throughput(Throughput::Bytes(images_bin.len() as u64));
    group.bench_function("images.bin 1000 images x 2000 points", |b| {
        b.iter(|| parse_images_bin(Path::new("images.bin"), black_box(&images_bin)).unwrap());
    });
    group.throughput(Throughput::Bytes(npy.len() as u64));
    group.bench_function("npy 1M x 3 <f4", |b| {
        b.iter(|| parse_npy(Path::new("points.npy"), black_box(&npy)).unwrap());
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
