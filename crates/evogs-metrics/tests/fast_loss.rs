//! The fast loss workspace (`LossWorkspace`) against f64 finite differences of itself, against
//! the plain `photometric_loss` in f32 and f64, and on bad inputs.

use evogs_metrics::{ImageSize, LossWorkspace, MetricsError, photometric_loss};
use proptest::prelude::*;

/// A ground truth and a rendering that differs from it by at least 0.02 in every channel (so the
/// L1 kink is far from the finite-difference stencil).
fn image_pair(max_side: usize) -> impl Strategy<Value = (ImageSize, Vec<[f64; 3]>, Vec<[f64; 3]>)> {
    (1..=max_side, 1..=max_side).prop_flat_map(|(w, h)| {
        let n = w * h;
        (
            Just(ImageSize::new(w, h)),
            prop::collection::vec(prop::array::uniform3(0.0f64..1.0), n),
            prop::collection::vec(prop::array::uniform3((0.02f64..0.3, any::<bool>())), n),
        )
            .prop_map(|(size, gt, offsets)| {
                let rendered = gt
                    .iter()
                    .zip(&offsets)
                    .map(|(g, o)| {
                        std::array::from_fn(|c| g[c] + if o[c].1 { o[c].0 } else { -o[c].0 })
                    })
                    .collect();
                (size, rendered, gt)
            })
    })
}

fn check_against_finite_differences(size: ImageSize, rendered: &[[f64; 3]], gt: &[[f64; 3]]) {
    let mut ws = LossWorkspace::new();
    ws.compute(size, rendered, gt).unwrap();
    let analytic = ws.gradient().to_vec();
    let h = 1e-6;
    let mut x = rendered.to_vec();
    for i in 0..x.len() {
        for c in 0..3 {
            let keep = x[i][c];
            x[i][c] = keep + h;
            let up = ws.compute(size, &x, gt).unwrap().loss;
            x[i][c] = keep - h;
            let down = ws.compute(size, &x, gt).unwrap().loss;
            x[i][c] = keep;
            let numeric = (up - down) / (2.0 * h);
            let a = analytic[i][c];
            assert!(
                (a - numeric).abs() <= 1e-7 + 1e-5 * numeric.abs(),
                "{}x{} pixel {i} channel {c}: analytic {a:e} vs numeric {numeric:e}",
                size.width,
                size.height
            );
        }
    }
}

#[test]
fn gradient_matches_finite_differences_on_an_image_larger_than_the_window() {
    // 14x12 has interior pixels (full window), every kind of border pixel, and two row blocks.
    let size = ImageSize::new(14, 12);
    let gt: Vec<[f64; 3]> = (0..size.pixels())
        .map(|i| std::array::from_fn(|c| ((i * 13 + c * 7) % 17) as f64 / 17.0))
        .collect();
    let rendered: Vec<[f64; 3]> = gt
        .iter()
        .enumerate()
        .map(|(i, g)| std::array::from_fn(|c| g[c] + if (i + c) % 3 == 0 { 0.15 } else { -0.05 }))
        .collect();
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
