//! The fast loss workspace (`LossWorkspace`) against f64 finite differences of itself, against
//! the plain `photometric_loss` in f32 and f64, and on bad inputs.

use evogs_metrics::{ImageSize, LossWorkspace, MetricsError, photometric_loss};
use proptest::prelude::*;

use crate::common;
use common::image_pair;

fn check_against_finite_differences(size: ImageSize, rendered: &[[f64; 3]], gt: &[[f64; 3]]) {
    let mut ws = LossWorkspace::new();
    ws.compute(size, rendered, gt).unwrap();
    let analytic = ws.gradient().to_vec();
    common::assert_gradient_matches(size, rendered, &analytic, |x| {
        ws.compute(size, x, gt).unwrap().loss
    });
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
    fn f32_fast_loss_agrees_with_the_plain_f64_loss((size, rendered, gt) in image_pair(40)) {
        let r32: Vec<[f32; 3]> = rendered.iter().map(|p| p.map(|v| v as f32)).collect();
        let g32: Vec<[f32; 3]> = gt.iter().map(|p| p.map(|v| v as f32)).collect();
        // The plain f64 loss on the f32-rounded inputs.
        let r64: Vec<[f64; 3]> = r32.iter().map(|p| p.map(f64::from)).collect();
        let g64: Vec<[f64; 3]> = g32.iter().map(|p| p.map(f64::from)).collect();
        let mut ws = LossWorkspace::new();
        let lo = ws.compute(size, &r32, &g32).unwrap();
        let hi = photometric_loss(size, &r64, &g64).unwrap();
        prop_assert!((lo.loss - hi.loss).abs() < 1e-5, "{} vs {}", lo.loss, hi.loss);
        prop_assert!((lo.ssim - hi.ssim).abs() < 1e-5, "{} vs {}", lo.ssim, hi.ssim);
        prop_assert!((lo.l1 - hi.l1).abs() < 1e-6, "{} vs {}", lo.l1, hi.l1);
        let scale = hi.d_rendered.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
        for (a, b) in ws.gradient().iter().zip(&hi.d_rendered) {
            for c in 0..3 {
                prop_assert!((f64::from(a[c]) - b[c]).abs() <= 1e-4 * scale);
            }
        }
    }
}

#[test]
fn bad_inputs_are_errors_naming_the_image_and_pixel() {
    let size = ImageSize::new(5, 4);
    let a = vec![[0.5f32; 3]; 20];
    let mut ws = LossWorkspace::new();
    let err = ws.compute(size, &a, &a[..19]).unwrap_err();
    assert_eq!(err.to_string(), "image `gt` has 19 pixels, expected 20");
    for (bad, name) in [
        (f32::NAN, "rendered"),
        (f32::INFINITY, "gt"),
        (f32::NEG_INFINITY, "rendered"),
    ] {
        let mut b = a.clone();
        b[13][2] = bad;
        let (r, g) = if name == "rendered" {
            (&b, &a)
        } else {
            (&a, &b)
        };
        let err = ws.compute(size, r, g).unwrap_err();
        assert_eq!(
            err.to_string(),
            format!("image `{name}` has a non-finite value at pixel 13")
        );
    }
    let err = ws.compute(ImageSize::new(0, 3), &[], &[]).unwrap_err();
    assert!(matches!(err, MetricsError::EmptyImage { .. }));
    // The workspace still works after errors.
    let v = ws.compute(size, &a, &a).unwrap();
    assert_eq!(v.l1, 0.0);
    assert!((v.ssim - 1.0).abs() < 1e-6);
}
