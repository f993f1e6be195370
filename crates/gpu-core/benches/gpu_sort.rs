//! The GPU radix sort on 1M and 4M random (u32 key, u32 value) pairs, 32-bit keys (8 digit passes)
//! and 16-bit keys (4 passes, the width of a depth key). Each iteration restores the unsorted
//! pairs on the device (two buffer copies), encodes the sort, submits and waits; nothing crosses
//! to the CPU. Throughput is in pairs. On lavapipe (software Vulkan) the figures are a sanity
//! check, not GPU performance.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use gpu_core::test_support::SortHarness;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn bench(c: &mut Criterion) {
    let mut h = SortHarness::new().unwrap_or_else(|e| panic!("gpu_sort bench: {e}"));
    eprintln!("gpu_sort: adapter {}", h.adapter_name());
    let mut group = c.benchmark_group("gpu_sort");
    for n in [1usize << 20, 1 << 22] {
        let mut rng = ChaCha8Rng::seed_from_u64(n as u64);
        let keys: Vec<u32> = (0..n).map(|_| rng.random::<u32>()).collect();
        let values: Vec<u32> = (0..n as u32).collect();
        h.load(&keys, &values);
        group.throughput(Throughput::Elements(n as u64));
        for key_bits in [32, 16] {
            let id = BenchmarkId::new(format!("{key_bits}bit"), format!("{}M", n >> 20));
            group.bench_function(id, |b| b.iter(|| h.sort_loaded(key_bits)));
        }
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
