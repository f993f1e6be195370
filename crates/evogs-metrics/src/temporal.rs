//! Temporal consistency metrics (DESIGN §8.3): fixed-camera flicker and trajectory jitter.

use crate::{ImageSize, MetricsError, check_image};

/// Flicker of a fixed-camera sequence.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Flicker {
    /// Mean absolute difference of consecutive rendered frames (over pixels, channels and pairs).
    pub rendered: f64,
    /// The same for the ground-truth frames, when given.
    pub ground_truth: Option<f64>,
    /// `rendered − ground_truth` (or `rendered` when there is no ground truth): the flicker the
    /// reconstruction adds beyond the scene's own change.
    pub excess: f64,
}

/// Mean over consecutive pairs of the mean absolute per-channel difference.
fn mean_consecutive_difference(
    size: ImageSize,
    frames: &[&[[f32; 3]]],
    field: &'static str,
) -> Result<f64, MetricsError> {
    if frames.len() < 2 {
        return Err(MetricsError::Length {
            field: field.to_string(),
            got: frames.len(),
            expected: 2,
        });
    }
    for f in frames {
        check_image(size, f, field)?;
    }
    let mut total = 0.0;
    for pair in frames.windows(2) {
        let sum: f64 = pair[0]
            .iter()
            .zip(pair[1])
            .flat_map(|(p, q)| (0..3).map(move |c| (f64::from(q[c]) - f64::from(p[c])).abs()))
            .sum();
        total += sum / (3 * size.pixels()) as f64;
    }
    Ok(total / (frames.len() - 1) as f64)
}

/// Flicker of frames rendered from one fixed camera at increasing times, optionally against the
/// ground-truth frames at the same times. Needs at least two frames; ground truth, when given,
/// has as many frames as the rendering.
pub fn flicker(
    size: ImageSize,
    rendered: &[&[[f32; 3]]],
    ground_truth: Option<&[&[[f32; 3]]]>,
) -> Result<Flicker, MetricsError> {
    let r = mean_consecutive_difference(size, rendered, "rendered")?;
    let g = match ground_truth {
        Some(gt) => {
            if gt.len() != rendered.len() {
                return Err(MetricsError::Length {
                    field: "ground_truth".into(),
                    got: gt.len(),
                    expected: rendered.len(),
                });
            }
            Some(mean_consecutive_difference(size, gt, "ground_truth")?)
        }
        None => None,
    };
    Ok(Flicker {
        rendered: r,
        ground_truth: g,
        excess: r - g.unwrap_or(0.0),
    })
}

/// Trajectory jitter over a sequence of frames.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Jitter {
    /// Mean of `|x[k+1] − 2 x[k] + x[k−1]|` over every Gaussian and interior frame `k` where the
    /// Gaussian is visible at all three frames; 0 when `count` is 0.
    pub mean: f64,
    /// Number of (Gaussian, frame) terms in the mean.
    pub count: usize,
}

/// Trajectory jitter: the mean norm of the second time difference of Gaussian positions,
/// counted where the Gaussian is visible in the three frames involved. `positions[k][i]` is
/// Gaussian `i`'s world position at frame `k`, `visible[k][i]` its visibility; every frame has
/// the same Gaussians. The difference is per frame step, not divided by `Δt²`, so it is in
/// world units and meant for uniformly spaced frames.
pub fn trajectory_jitter(
    positions: &[&[[f32; 3]]],
    visible: &[&[bool]],
) -> Result<Jitter, MetricsError> {
    if visible.len() != positions.len() {
        return Err(MetricsError::Length {
            field: "visible".into(),
            got: visible.len(),
            expected: positions.len(),
        });
    }
    let n = positions.first().map_or(0, |p| p.len());
    for (k, (p, v)) in positions.iter().zip(visible).enumerate() {
        if p.len() != n {
            return Err(MetricsError::Length {
                field: format!("positions[{k}]"),
                got: p.len(),
                expected: n,
            });
        }
        if v.len() != n {
            return Err(MetricsError::Length {
                field: format!("visible[{k}]"),
                got: v.len(),
                expected: n,
            });
        }
        if let Some(i) = p.iter().position(|x| x.iter().any(|c| !c.is_finite())) {
            return Err(MetricsError::NonFinitePosition {
                field: "positions",
                frame: k,
                index: i,
            });
        }
    }
    let mut sum = 0.0;
    let mut count = 0;
    for k in 1..positions.len().saturating_sub(1) {
        let (a, b, c) = (positions[k - 1], positions[k], positions[k + 1]);
        for i in 0..n {
            if !(visible[k - 1][i] && visible[k][i] && visible[k + 1][i]) {
                continue;
            }
            let norm2: f64 = (0..3)
                .map(|d| {
                    let v = f64::from(c[i][d]) - 2.0 * f64::from(b[i][d]) + f64::from(a[i][d]);
                    v * v
                })
                .sum();
            sum += norm2.sqrt();
            count += 1;
        }
    }
    Ok(Jitter {
        mean: if count == 0 { 0.0 } else { sum / count as f64 },
        count,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flicker_hand_computed() {
        let size = ImageSize::new(2, 1);
        // Rendered: pixel 0 goes 0 → 0.3 → 0.0 in red only; pixel 1 constant.
        let f0 = [[0.0, 0.0, 0.0], [0.5, 0.5, 0.5]];
        let f1 = [[0.3, 0.0, 0.0], [0.5, 0.5, 0.5]];
        let f2 = [[0.0, 0.0, 0.0], [0.5, 0.5, 0.5]];
        // Each pair: |Δ| sum 0.3 over 6 values = 0.05; mean over 2 pairs = 0.05.
        let r = flicker(size, &[&f0, &f1, &f2], None).unwrap();
        assert!((r.rendered - 0.05).abs() < 1e-7);
        assert_eq!(r.ground_truth, None);
        assert!((r.excess - 0.05).abs() < 1e-7);
        // Ground truth changes by 0.06 in one value on the first pair only: (0.01 + 0) / 2.
        let g0 = [[0.0, 0.0, 0.0], [0.5, 0.5, 0.5]];
        let g1 = [[0.0, 0.06, 0.0], [0.5, 0.5, 0.5]];
        let r = flicker(size, &[&f0, &f1, &f2], Some(&[&g0, &g1, &g1])).unwrap();
        assert!((r.ground_truth.unwrap() - 0.005).abs() < 1e-7);
        assert!((r.excess - 0.045).abs() < 1e-7);
    }

    #[test]
    fn flicker_rejects_short_or_misaligned_input() {
        let size = ImageSize::new(1, 1);
        let f = [[0.0f32; 3]];
        let err = flicker(size, &[&f], None).unwrap_err();
        assert_eq!(err.to_string(), "`rendered` has 1 entries, expected 2");
        let err = flicker(size, &[&f, &f], Some(&[&f])).unwrap_err();
        assert_eq!(err.to_string(), "`ground_truth` has 1 entries, expected 2");
    }

    #[test]
    fn jitter_hand_computed_and_masks_invisible_triples() {
        // Gaussian 0 moves uniformly (no jitter); Gaussian 1 zig-zags in x: 0, 1, 0, 1.
        let p0 = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]];
        let p1 = [[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]];
        let p2 = [[2.0, 0.0, 0.0], [0.0, 0.0, 0.0]];
        let p3 = [[3.0, 0.0, 0.0], [1.0, 0.0, 0.0]];
        let all = [true, true];
        let j = trajectory_jitter(&[&p0, &p1, &p2, &p3], &[&all, &all, &all, &all]).unwrap();
        // Terms: G0: 0, 0; G1: |0 - 2 + 0| = 2, |1 - 0 + 1| = 2 → mean 4/4 = 1.
        assert_eq!(j.count, 4);
        assert!((j.mean - 1.0).abs() < 1e-12);
        // Hide G0 at frame 3: its second term drops; mean (0 + 2 + 2) / 3.
        let hide0 = [false, true];
        let j = trajectory_jitter(&[&p0, &p1, &p2, &p3], &[&all, &all, &all, &hide0]).unwrap();
        assert_eq!(j.count, 3);
        assert!((j.mean - 4.0 / 3.0).abs() < 1e-12);
        // Fewer than three frames: nothing to measure.
        let j = trajectory_jitter(&[&p0, &p1], &[&all, &all]).unwrap();
        assert_eq!(
            j,
            Jitter {
                mean: 0.0,
                count: 0
            }
        );
    }

    #[test]
    fn jitter_rejects_misaligned_or_non_finite_positions() {
        let p = [[0.0f32; 3]; 2];
        let short = [[0.0f32; 3]; 1];
        let v = [true; 2];
        let err = trajectory_jitter(&[&p, &short], &[&v, &v]).unwrap_err();
        assert_eq!(err.to_string(), "`positions[1]` has 1 entries, expected 2");
        let err = trajectory_jitter(&[&p, &p], &[&v]).unwrap_err();
        assert_eq!(err.to_string(), "`visible` has 1 entries, expected 2");
        let mut bad = p;
        bad[1][2] = f32::INFINITY;
        let err = trajectory_jitter(&[&p, &bad], &[&v, &v]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "`positions` has a non-finite position at frame 1, Gaussian 1"
        );
    }
}
