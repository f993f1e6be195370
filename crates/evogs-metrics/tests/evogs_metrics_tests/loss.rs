//! The photometric loss gradient against f64 finite differences, and its f32 version against f64.

use evogs_metrics::{ImageSize, photometric_loss, ssim};
use proptest::prelude::*;

use crate::common;
use common::image_pair;

fn loss_at(size: ImageSize, rendered: &[[f64; 3]], gt: &[[f64; 3]]) -> f64 {
    photometric_loss(size, rendered, gt).unwrap().loss
}

fn check_against_finite_differences(size: ImageSize, rendered: &[[f64; 3]], gt: &[[f64; 3]]) {
    let analytic = photometric_loss(size, rendered, gt).unwrap().d_rendered;
    common::assert_gradient_matches(size, rendered, &analytic, |x| loss_at(size, x, gt));
}

#[test]
fn gradient_matches_finite_differences_on_an_image_larger_than_the_window() {
    let (size, rendered, gt) = common::pair_larger_than_the_window();
    check_against_finite_differences(size, &rendered, &gt);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    #[test]
    fn gradient_matches_finite_differences_on_random_small_images((size, rendered, gt) in image_pair(9)) {
        check_against_finite_differences(size, &rendered, &gt);
    }

    #[test]
    fn f32_loss_and_gradient_agree_with_f64((size, rendered, gt) in image_pair(16)) {
        let r32: Vec<[f32; 3]> = rendered.iter().map(|p| p.map(|v| v as f32)).collect();
        let g32: Vec<[f32; 3]> = gt.iter().map(|p| p.map(|v| v as f32)).collect();
        // Compare against f64 run on the f32-rounded inputs.
        let r64: Vec<[f64; 3]> = r32.iter().map(|p| p.map(f64::from)).collect();
        let g64: Vec<[f64; 3]> = g32.iter().map(|p| p.map(f64::from)).collect();
        let lo = photometric_loss(size, &r32, &g32).unwrap();
        let hi = photometric_loss(size, &r64, &g64).unwrap();
        prop_assert!((lo.loss - hi.loss).abs() < 1e-5, "{} vs {}", lo.loss, hi.loss);
        let scale = hi.d_rendered.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
        for (a, b) in lo.d_rendered.iter().zip(&hi.d_rendered) {
            for c in 0..3 {
                prop_assert!((f64::from(a[c]) - b[c]).abs() <= 1e-4 * scale);
            }
        }
    }
}

#[test]
fn loss_of_identical_images_is_zero_with_zero_gradient() {
    let size = ImageSize::new(12, 11);
    let img: Vec<[f64; 3]> = (0..size.pixels())
        .map(|i| std::array::from_fn(|c| ((i * 5 + c) % 9) as f64 / 9.0))
        .collect();
    let out = photometric_loss(size, &img, &img).unwrap();
    assert!(out.loss.abs() < 1e-12);
    assert!((out.ssim - 1.0).abs() < 1e-12);
    assert_eq!(out.l1, 0.0);
    assert!(out.d_rendered.iter().flatten().all(|v| v.abs() < 1e-12));
}

#[test]
fn loss_combines_l1_and_ssim_with_the_spec_weights() {
    let size = ImageSize::new(9, 8);
    let gt: Vec<[f64; 3]> = (0..size.pixels())
        .map(|i| std::array::from_fn(|c| ((i * 3 + c * 5) % 7) as f64 / 7.0))
        .collect();
    let rendered: Vec<[f64; 3]> = gt.iter().map(|p| p.map(|v| v * 0.9 + 0.05)).collect();
    let out = photometric_loss(size, &rendered, &gt).unwrap();
    let l1: f64 = rendered
        .iter()
        .zip(&gt)
        .flat_map(|(a, b)| (0..3).map(move |c| (a[c] - b[c]).abs()))
        .sum::<f64>()
        / (3 * size.pixels()) as f64;
    let s = ssim(size, &rendered, &gt).unwrap();
    assert!((out.l1 - l1).abs() < 1e-14);
    assert!((out.ssim - s).abs() < 1e-14);
    assert!((out.loss - (0.8 * l1 + 0.2 * (1.0 - s))).abs() < 1e-14);
}

/// The plain loss and SSIM (the evaluation's metric) give the same bits on any thread count:
/// a 400×400 image is 40 partial sums, split differently by 1, 2, 3, 4 and 8 threads. In f64,
/// where the sums round (sums of f32 values in f64 are mostly exact in any order).
#[test]
fn loss_and_ssim_are_bit_identical_for_any_thread_count() {
    let size = ImageSize::new(400, 400);
    let pixel = |i: usize, s: usize| {
        [0, 1, 2].map(|c| (((i * 7 + c * 3 + s) * 2_654_435_761) % 1000) as f64 / 999.0)
    };
    let rendered: Vec<[f64; 3]> = (0..size.pixels()).map(|i| pixel(i, 0)).collect();
    let gt: Vec<[f64; 3]> = (0..size.pixels()).map(|i| pixel(i, 11)).collect();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let l = photometric_loss(size, &rendered, &gt).unwrap();
            let s = ssim(size, &rendered, &gt).unwrap();
            (
                l.loss.to_bits(),
                l.ssim.to_bits(),
                s.to_bits(),
                l.d_rendered,
            )
        })
    };
    let one = run(1);
    for threads in [2, 3, 4, 8] {
        assert!(run(threads) == one, "{threads} threads differ from one");
    }
}
