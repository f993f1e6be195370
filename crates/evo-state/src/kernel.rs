//! Per-Gaussian arithmetic of the forward pass: the time-scaled prior, the next residual memory,
//! the motion statistics and Ψ's raw (not yet normalised) inputs of one row, in f64 with results
//! saturated to f32.

use crate::buffer::FrameRef;
use crate::step::Stats;

/// Ψ's inputs are clamped to ±this after normalisation, so Ψ stays finite for any finite input.
pub const PSI_INPUT_CLAMP: f32 = 1e4;
/// ε in θ's denominator (the paper's 1e-6).
const THETA_EPS: f64 = 1e-6;

/// Saturates an f64 into the finite f32 range.
#[inline]
pub(crate) fn fin(x: f64) -> f32 {
    x.clamp(-(f32::MAX as f64), f32::MAX as f64) as f32
}

/// Everything a row of the forward pass reads.
pub(crate) struct RowContext<'a> {
    pub(crate) history: &'a [FrameRef<'a>],
    pub(crate) frames: [usize; 3],
    pub(crate) s: f64,
    pub(crate) beta: f64,
    pub(crate) dim: usize,
    pub(crate) position: Option<std::ops::Range<usize>>,
    pub(crate) floor: f64,
    /// M[k1], the residual memory committed with the latest history frame (`None`: zero).
    pub(crate) memory: Option<FrameRef<'a>>,
}

impl RowContext<'_> {
    /// Prior, next memory `m = β M[k1] + (1-β)(z - d̂)` and (h = 3) statistics and Ψ's raw
    /// inputs `[m, |v2|, |v1|, θ]` of row `i` (the caller normalises them).
    #[inline]
    pub(crate) fn row(
        &self,
        i: usize,
        z: &[f32],
        prior: &mut [f32],
        memory_next: &mut [f32],
        full: Option<(&mut Stats, &mut [f32])>,
    ) {
        const MAX_DIM: usize = 14;
        let d = self.dim;
        let mut h = [[0.0f64; MAX_DIM]; 3];
        for (slot, block) in h.iter_mut().zip(self.history) {
            block.read_row(i, &mut slot[..d]);
        }
        let mut m_old = [0.0f64; MAX_DIM];
        if let Some(m) = &self.memory {
            m.read_row(i, &mut m_old[..d]);
        }
        for j in 0..d {
            let p = fin(h[0][j] + self.s * (h[0][j] - h[1][j]));
            prior[j] = p;
            memory_next[j] =
                fin(self.beta * m_old[j] + (1.0 - self.beta) * (z[j] as f64 - p as f64));
        }
        let Some((stats, inputs)) = full else { return };
        let [k1, k2, k3] = self.frames;
        let (mut n1, mut n2, mut dot) = (0.0f64, 0.0f64, 0.0f64);
        if let Some(pos) = &self.position {
            for j in pos.clone() {
                let v1 = (h[0][j] - h[1][j]) / (k1 - k2) as f64;
                let v2 = (h[1][j] - h[2][j]) / (k2 - k3) as f64;
                n1 += v1 * v1;
                n2 += v2 * v2;
                dot += v1 * v2;
            }
        }
        let (n1, n2) = (n1.sqrt(), n2.sqrt());
        let theta = if n1 < self.floor || n2 < self.floor || !(n1 * n2).is_finite() {
            // Below the motion floor a Gaussian moves consistently; beyond f64 range (only with
            // absurd states) the angle is not measurable and counts as consistent too.
            0.0
        } else {
            (dot / (n1 * n2 + THETA_EPS)).clamp(-1.0, 1.0).acos()
        };
        *stats = Stats {
            speed_prev: fin(n2),
            speed_last: fin(n1),
            theta: theta as f32,
        };
        inputs[..d].copy_from_slice(memory_next);
        inputs[d] = stats.speed_prev;
        inputs[d + 1] = stats.speed_last;
        inputs[d + 2] = stats.theta;
    }
}
