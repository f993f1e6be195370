//! What the loss tests share: random image pairs away from L1's kink, a fixed pair larger than
//! SSIM's window, and the central finite-difference check of a loss gradient.

#![allow(dead_code)] // each test file uses its own subset

use evogs_metrics::ImageSize;
use proptest::prelude::*;

/// A ground truth and a rendering that differs from it by at least 0.02 in every channel (so the
/// L1 kink is far from the finite-difference stencil).
pub fn image_pair(
    max_side: usize,
) -> impl Strategy<Value = (ImageSize, Vec<[f64; 3]>, Vec<[f64; 3]>)> {
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

/// A 14×12 pair: interior pixels (full window), every kind of border pixel, two row blocks.
pub fn pair_larger_than_the_window() -> (ImageSize, Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let size = ImageSize::new(14, 12);
    let gt: Vec<[f64; 3]> = (0..size.pixels())
        .map(|i| std::array::from_fn(|c| ((i * 13 + c * 7) % 17) as f64 / 17.0))
        .collect();
    let rendered: Vec<[f64; 3]> = gt
        .iter()
        .enumerate()
        .map(|(i, g)| std::array::from_fn(|c| g[c] + if (i + c) % 3 == 0 { 0.15 } else { -0.05 }))
        .collect();
    (size, rendered, gt)
}

/// Asserts that `analytic` (d loss / d rendered) equals central differences (h = 1e-6) of
/// `loss` at `rendered`, within 1e-7 + 1e-5 relative.
pub fn assert_gradient_matches(
    size: ImageSize,
    rendered: &[[f64; 3]],
    analytic: &[[f64; 3]],
    mut loss: impl FnMut(&[[f64; 3]]) -> f64,
) {
    let h = 1e-6;
    let mut x = rendered.to_vec();
    for i in 0..x.len() {
        for c in 0..3 {
            let keep = x[i][c];
            x[i][c] = keep + h;
            let up = loss(&x);
            x[i][c] = keep - h;
            let down = loss(&x);
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
