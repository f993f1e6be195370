//! The GPU radix sort against `slice::sort_by_key` (stable) on the low `key_bits` bits, and the
//! prefix sum it runs (the backend's one scan, `gpu/scan.rs`) against the CPU's, both through
//! [`SortHarness`].
//!
//! These tests need a wgpu adapter (lavapipe in CI); a missing one fails them with the reason.

use std::sync::OnceLock;

use proptest::prelude::*;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::{SortHarness, level_lengths};

fn harness() -> &'static SortHarness {
    static HARNESS: OnceLock<SortHarness> = OnceLock::new();
    HARNESS.get_or_init(|| {
        SortHarness::new().unwrap_or_else(|e| panic!("GPU sort tests need a wgpu adapter: {e}"))
    })
}

/// The expected result: stable sort by the masked key; values are the original positions.
fn reference(keys: &[u32], key_bits: u32) -> (Vec<u32>, Vec<u32>) {
    let mask = if key_bits == 32 {
        u32::MAX
    } else {
        (1u32 << key_bits) - 1
    };
    let mut pairs: Vec<(u32, u32)> = keys.iter().copied().zip(0u32..).collect();
    pairs.sort_by_key(|&(k, _)| k & mask);
    pairs.into_iter().unzip()
}

fn check(h: &SortHarness, keys: &[u32], key_bits: u32) {
    let values: Vec<u32> = (0..keys.len() as u32).collect();
    let (got_keys, got_values) = h.sort(keys, &values, key_bits);
    let (want_keys, want_values) = reference(keys, key_bits);
    if let Some(i) = (0..keys.len()).find(|&i| got_values[i] != want_values[i]) {
        panic!(
            "n = {}, key_bits = {key_bits}: first difference at {i}: got (key {:#x}, value {}), \
             want (key {:#x}, value {})",
            keys.len(),
            got_keys[i],
            got_values[i],
            want_keys[i],
            want_values[i]
        );
    }
    assert_eq!(
        got_keys,
        want_keys,
        "n = {}, key_bits = {key_bits}",
        keys.len()
    );
}

fn random_keys(rng: &mut ChaCha8Rng, n: usize) -> Vec<u32> {
    (0..n).map(|_| rng.random::<u32>()).collect()
}

#[test]
fn block_edges_and_key_widths() {
    // Keys use all 32 bits, so the narrower widths also check that higher bits are ignored.
    let h = harness();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for n in [0, 1, 2, 255, 256, 257, 1023, 1024, 1025, 4097] {
        let keys = random_keys(&mut rng, n);
        for key_bits in [1, 4, 5, 13, 32] {
            check(h, &keys, key_bits);
        }
    }
}

#[test]
fn random_sizes_up_to_a_million() {
    let h = harness();
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    for _ in 0..3 {
        let n = rng.random_range(70_000..1_100_000);
        let keys = random_keys(&mut rng, n);
        check(h, &keys, 32);
        check(h, &keys, 13);
    }
}

#[test]
fn equal_keys_keep_their_order() {
    let h = harness();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let few: Vec<u32> = (0..100_000)
        .map(|_| rng.random_range(0..3u32) << 20)
        .collect();
    check(h, &few, 32);
    check(h, &few, 21);
    // With 20 bits every key is 0: the order must not change at all.
    check(h, &few, 20);
    let same = vec![7u32; 5000];
    check(h, &same, 32);
}

#[test]
fn all_max_keys() {
    let h = harness();
    let keys = vec![u32::MAX; 3000];
    check(h, &keys, 32);
    check(h, &keys, 13);
    check(h, &keys, 1);
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let mut mixed = random_keys(&mut rng, 3000);
    for k in mixed.iter_mut().step_by(3) {
        *k = u32::MAX;
    }
    check(h, &mixed, 32);
}

#[test]
fn already_sorted_and_reversed() {
    let h = harness();
    let up: Vec<u32> = (0..50_000).collect();
    let down: Vec<u32> = (0..50_000).rev().collect();
    check(h, &up, 16);
    check(h, &down, 16);
    check(h, &down, 32);
}

#[test]
fn two_dimensional_dispatch() {
    // 20 blocks on a grid at most 3 wide: 3 x 7 workgroups, the last one idle.
    let h = SortHarness::with_max_groups_per_dim(3)
        .unwrap_or_else(|e| panic!("GPU sort tests need a wgpu adapter: {e}"));
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let keys = random_keys(&mut rng, 20 * 1024 - 5);
    check(&h, &keys, 32);
    check(&h, &keys, 7);
    // Enough blocks for a two-level scan (counts longer than one 1024-element chunk).
    let keys = random_keys(&mut rng, 70_000);
    check(&h, &keys, 9);
}

#[test]
fn scratch_grows_and_is_reused() {
    let mut h =
        SortHarness::new().unwrap_or_else(|e| panic!("GPU sort tests need a wgpu adapter: {e}"));
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    for n in [100, 5000, 300, 40_000, 17] {
        let keys = random_keys(&mut rng, n);
        check(&h, &keys, 32);
    }
    // Resident data: sorting the restored original again gives the same result.
    let keys = random_keys(&mut rng, 3000);
    let values: Vec<u32> = (0..3000).collect();
    h.load(&keys, &values);
    h.sort_loaded(11);
    h.sort_loaded(11);
    let (got_keys, got_values) = h.read_loaded();
    let (want_keys, want_values) = reference(&keys, 11);
    assert_eq!(got_values, want_values);
    assert_eq!(got_keys, want_keys);
}

#[test]
fn sixteen_million_pairs() {
    // 2^24 + 3 pairs (16385 blocks): two digit passes, a two-level scan of 262160 counts.
    let h = harness();
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let keys = random_keys(&mut rng, (1 << 24) + 3);
    check(h, &keys, 8);
}

#[test]
fn scan_levels() {
    assert_eq!(level_lengths(1), vec![16, 1]);
    assert_eq!(level_lengths(1024 * 64), vec![1024, 1]);
    assert_eq!(level_lengths(1024 * 64 + 1), vec![1040, 2, 1]);
    assert_eq!(level_lengths(1 << 24), vec![1 << 18, 256, 1]);
    assert_eq!(level_lengths(u32::MAX), vec![1 << 26, 1 << 16, 64, 1]);
}

/// The exclusive prefix sum on the CPU, and the total.
fn scan_reference(data: &[u32]) -> (Vec<u32>, u32) {
    let mut run = 0u32;
    let scanned = data
        .iter()
        .map(|&v| {
            let before = run;
            run += v;
            before
        })
        .collect();
    (scanned, run)
}

#[test]
fn matches_the_cpu_scan_at_chunk_edges_and_on_a_2d_grid() {
    // A grid at most 3 wide: 70 000 values are 69 chunks, 3 x 23 workgroups, two levels.
    let narrow = SortHarness::with_max_groups_per_dim(3)
        .unwrap_or_else(|e| panic!("GPU scan tests need a wgpu adapter: {e}"));
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for n in [0, 1, 2, 255, 1023, 1024, 1025, 4097, 70_000, (1 << 20) + 1] {
        let data: Vec<u32> = (0..n).map(|_| rng.random_range(0..300u32)).collect();
        assert_eq!(narrow.prefix_sum(&data), scan_reference(&data), "n = {n}");
    }
}

#[test]
#[should_panic(expected = "key_bits must be in 1..=32")]
fn zero_key_bits_is_a_caller_bug() {
    harness().sort(&[1, 2], &[0, 1], 0);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 12, ..ProptestConfig::default() })]

    #[test]
    fn matches_stable_sort(
        keys in prop::collection::vec(any::<u32>(), 0..6000),
        spread in 1u32..=32,
        key_bits in 1u32..=32,
    ) {
        // Squeeze keys into `spread` bits so that equal keys are common at small spreads.
        let keys: Vec<u32> = keys.iter().map(|k| if spread == 32 { *k } else { k >> (32 - spread) }).collect();
        let values: Vec<u32> = (0..keys.len() as u32).collect();
        let (got_keys, got_values) = harness().sort(&keys, &values, key_bits);
        let (want_keys, want_values) = reference(&keys, key_bits);
        prop_assert_eq!(got_values, want_values);
        prop_assert_eq!(got_keys, want_keys);
    }
}

/// Two sorts in one submission, of other sizes and key widths (so other parameter records),
/// each sort holding its pooled records until the submission: both sorted, twice over (the
/// second time in records the pool hands out again). A sort that let its records go before
/// the submission would have the second sort's written over the first's.
#[test]
fn two_sorts_in_one_submission_keep_their_parameters() {
    let h = harness();
    let mut rng = ChaCha8Rng::seed_from_u64(91);
    for _ in 0..2 {
        let a = random_keys(&mut rng, 5_000);
        let b = random_keys(&mut rng, 1_234);
        let [(ak, av), (bk, bv)] = h.sort_two_in_one_submission((&a, 32), (&b, 7));
        assert_eq!((ak, av), reference(&a, 32));
        assert_eq!((bk, bv), reference(&b, 7));
    }
}
