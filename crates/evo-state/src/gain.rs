//! The gain network Ψ = Linear(D+3, 32) ReLU Linear(32, 32) ReLU Linear(32, 1) sigmoid, over N
//! rows. Parameters are one flat `Vec<f32>` (w0, b0, w1, b1, w2, b2; weights row-major
//! out × in) so an optimiser and the safetensors file see them as plain arrays.
//!
//! The backward pass recomputes the (tiny) hidden activations per row instead of caching
//! N × 64 floats.

use rand::{RngExt, SeedableRng};
use rayon::prelude::*;

/// Hidden width of Ψ.
pub const HIDDEN: usize = 32;
/// Rows per parallel task.
const CHUNK: usize = 2048;

/// Ψ with its parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct GainNet {
    inputs: usize,
    params: Vec<f32>,
}

/// Offsets of the parameter tensors in the flat vector.
struct Offsets {
    w0: usize,
    b0: usize,
    w1: usize,
    b1: usize,
    w2: usize,
    b2: usize,
    end: usize,
}

impl GainNet {
    fn offsets(inputs: usize) -> Offsets {
        let w0 = 0;
        let b0 = w0 + HIDDEN * inputs;
        let w1 = b0 + HIDDEN;
        let b1 = w1 + HIDDEN * HIDDEN;
        let w2 = b1 + HIDDEN;
        let b2 = w2 + HIDDEN;
        Offsets {
            w0,
            b0,
            w1,
            b1,
            w2,
            b2,
            end: b2 + 1,
        }
    }

    /// Number of parameters for `inputs` inputs.
    pub fn param_count(inputs: usize) -> usize {
        Self::offsets(inputs).end
    }

    /// Ψ with PyTorch's default initialisation (uniform ±1/√fan_in for weights and biases),
    /// deterministic from `seed`.
    pub fn new(inputs: usize, seed: u64) -> Self {
        let o = Self::offsets(inputs);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut params = vec![0.0f32; o.end];
        let mut fill = |range: std::ops::Range<usize>, fan_in: usize| {
            let bound = 1.0 / (fan_in as f32).sqrt();
            for p in &mut params[range] {
                *p = rng.random_range(-bound..bound);
            }
        };
        fill(o.w0..o.w1, inputs);
        fill(o.w1..o.w2, HIDDEN);
        fill(o.w2..o.end, HIDDEN);
        Self { inputs, params }
    }

    /// Ψ from saved parameters.
    pub fn from_params(inputs: usize, params: Vec<f32>) -> Option<Self> {
        (params.len() == Self::param_count(inputs)).then_some(Self { inputs, params })
    }

    /// Input width (D + 3).
    pub fn inputs(&self) -> usize {
        self.inputs
    }

    /// The flat parameters.
    pub fn params(&self) -> &[f32] {
        &self.params
    }

    /// The flat parameters, for an optimiser step.
    pub fn params_mut(&mut self) -> &mut [f32] {
        &mut self.params
    }

    /// Hidden activations and output logit of one row.
    #[inline]
    fn row_forward(&self, x: &[f32], h1: &mut [f32; HIDDEN], h2: &mut [f32; HIDDEN]) -> f32 {
        let o = Self::offsets(self.inputs);
        let p = &self.params;
        for (j, h) in h1.iter_mut().enumerate() {
            let w = &p[o.w0 + j * self.inputs..o.w0 + (j + 1) * self.inputs];
            let s: f32 = w.iter().zip(x).map(|(a, b)| a * b).sum();
            *h = (s + p[o.b0 + j]).max(0.0);
        }
        for (j, h) in h2.iter_mut().enumerate() {
            let w = &p[o.w1 + j * HIDDEN..o.w1 + (j + 1) * HIDDEN];
            let s: f32 = w.iter().zip(h1.iter()).map(|(a, b)| a * b).sum();
            *h = (s + p[o.b1 + j]).max(0.0);
        }
        let w = &p[o.w2..o.w2 + HIDDEN];
        let s: f32 = w.iter().zip(h2.iter()).map(|(a, b)| a * b).sum();
        s + p[o.b2]
    }

    /// K = Ψ(x) for each row of `x` (rows × inputs), into `k`.
    pub fn forward(&self, x: &[f32], k: &mut [f32]) {
        debug_assert_eq!(x.len(), k.len() * self.inputs);
        k.par_chunks_mut(CHUNK).enumerate().for_each(|(c, k)| {
            let (mut h1, mut h2) = ([0.0; HIDDEN], [0.0; HIDDEN]);
            for (r, k) in k.iter_mut().enumerate() {
                let row = c * CHUNK + r;
                let logit = self.row_forward(
                    &x[row * self.inputs..(row + 1) * self.inputs],
                    &mut h1,
                    &mut h2,
                );
                *k = sigmoid(logit);
            }
        });
    }

    /// Gradient of the loss with respect to the parameters, given the inputs `x` and the
    /// gradient with respect to each row's output K (`dk`). Rows with `dk = 0` are skipped.
    /// Deterministic: per-chunk partial sums are added in chunk order.
    ///
    /// Huge output gradients are scaled down by a power of two (exact) before accumulation and
    /// the result scaled back in f64 and saturated to the f32 range, so finite inputs give
    /// finite gradients.
    pub fn backward(&self, x: &[f32], dk: &[f32]) -> Vec<f32> {
        let largest = dk.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        let exponent = if largest > 1e18 {
            largest.log2().ceil() as i32
        } else {
            0
        };
        let down = (-exponent as f32).exp2();
        let o = Self::offsets(self.inputs);
        let n_in = self.inputs;
        let p = &self.params;
        let partials: Vec<Vec<f32>> = dk
            .par_chunks(CHUNK)
            .enumerate()
            .map(|(c, dk)| {
                let mut g = vec![0.0f32; o.end];
                let (mut h1, mut h2) = ([0.0; HIDDEN], [0.0; HIDDEN]);
                let (mut dh1, mut dh2) = ([0.0f32; HIDDEN], [0.0f32; HIDDEN]);
                for (r, &dk) in dk.iter().enumerate() {
                    if dk == 0.0 {
                        continue;
                    }
                    let row = c * CHUNK + r;
                    let xr = &x[row * n_in..(row + 1) * n_in];
                    let logit = self.row_forward(xr, &mut h1, &mut h2);
                    let k = sigmoid(logit);
                    let dlogit = dk * down * k * (1.0 - k);
                    // Layer 2.
                    g[o.b2] += dlogit;
                    for j in 0..HIDDEN {
                        g[o.w2 + j] += dlogit * h2[j];
                        dh2[j] = if h2[j] > 0.0 {
                            dlogit * p[o.w2 + j]
                        } else {
                            0.0
                        };
                    }
                    // Layer 1.
                    dh1.fill(0.0);
                    for j in 0..HIDDEN {
                        let d = dh2[j];
                        if d == 0.0 {
                            continue;
                        }
                        g[o.b1 + j] += d;
                        let gw = &mut g[o.w1 + j * HIDDEN..o.w1 + (j + 1) * HIDDEN];
                        let w = &p[o.w1 + j * HIDDEN..o.w1 + (j + 1) * HIDDEN];
                        for m in 0..HIDDEN {
                            gw[m] += d * h1[m];
                            dh1[m] += d * w[m];
                        }
                    }
                    // Layer 0.
                    for j in 0..HIDDEN {
                        let d = if h1[j] > 0.0 { dh1[j] } else { 0.0 };
                        if d == 0.0 {
                            continue;
                        }
                        g[o.b0 + j] += d;
                        let gw = &mut g[o.w0 + j * n_in..o.w0 + (j + 1) * n_in];
                        for (gw, &xi) in gw.iter_mut().zip(xr) {
                            *gw += d * xi;
                        }
                    }
                }
                g
            })
            .collect();
        let mut grads = vec![0.0f64; o.end];
        for part in partials {
            for (g, p) in grads.iter_mut().zip(part) {
                *g += p as f64;
            }
        }
        let up = (exponent as f64).exp2();
        grads
            .iter()
            .map(|g| (g * up).clamp(-(f32::MAX as f64), f32::MAX as f64) as f32)
            .collect()
    }
}

/// Logistic function, computed without overflow for any finite input.
#[inline]
pub(crate) fn sigmoid(x: f32) -> f32 {
    if x >= 0.0 {
        1.0 / (1.0 + (-x).exp())
    } else {
        let e = x.exp();
        e / (1.0 + e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// f64 reference of the scalar loss Σ_r c_r K_r, for finite differences.
    fn loss64(net: &GainNet, params: &[f64], x: &[f32], c: &[f32]) -> f64 {
        let o = GainNet::offsets(net.inputs);
        let n_in = net.inputs;
        let mut total = 0.0;
        for (r, &cr) in c.iter().enumerate() {
            let xr: Vec<f64> = x[r * n_in..(r + 1) * n_in]
                .iter()
                .map(|&v| v as f64)
                .collect();
            let h1: Vec<f64> = (0..HIDDEN)
                .map(|j| {
                    let s: f64 = (0..n_in).map(|m| params[o.w0 + j * n_in + m] * xr[m]).sum();
                    (s + params[o.b0 + j]).max(0.0)
                })
                .collect();
            let h2: Vec<f64> = (0..HIDDEN)
                .map(|j| {
                    let s: f64 = (0..HIDDEN)
                        .map(|m| params[o.w1 + j * HIDDEN + m] * h1[m])
                        .sum();
                    (s + params[o.b1 + j]).max(0.0)
                })
                .collect();
            let s: f64 = (0..HIDDEN).map(|m| params[o.w2 + m] * h2[m]).sum::<f64>() + params[o.b2];
            total += cr as f64 / (1.0 + (-s).exp());
        }
        total
    }

    #[test]
    fn parameter_gradients_match_f64_finite_differences() {
        let inputs = 13;
        let mut net = GainNet::new(inputs, 3);
        // Larger output weights so the sigmoid is not flat.
        for p in net.params_mut() {
            *p *= 2.0;
        }
        let rows = 5;
        let x: Vec<f32> = (0..rows * inputs)
            .map(|e| ((e * 37 % 17) as f32 - 8.0) / 5.0)
            .collect();
        let c: Vec<f32> = (0..rows).map(|r| r as f32 - 1.5).collect();
        let grads = net.backward(&x, &c);
        let base: Vec<f64> = net.params().iter().map(|&p| p as f64).collect();
        let h = 1e-6;
        let mut checked = 0;
        for i in 0..base.len() {
            let mut plus = base.clone();
            plus[i] += h;
            let mut minus = base.clone();
            minus[i] -= h;
            let fd = (loss64(&net, &plus, &x, &c) - loss64(&net, &minus, &x, &c)) / (2.0 * h);
            let err = (fd - grads[i] as f64).abs();
            assert!(
                err <= 1e-4 + 1e-3 * fd.abs(),
                "param {i}: fd {fd} vs {}",
                grads[i]
            );
            checked += (fd.abs() > 1e-4) as usize;
        }
        assert!(
            checked > 100,
            "too few non-trivial gradients checked: {checked}"
        );
    }

    #[test]
    fn forward_is_in_unit_interval_for_inputs_at_the_clamp() {
        let net = GainNet::new(4, 1);
        let x = [1e4, -1e4, 1e4, 0.0, 0.0, 0.0, 0.0, 0.0];
        let mut k = [0.0; 2];
        net.forward(&x, &mut k);
        assert!(k.iter().all(|k| (0.0..=1.0).contains(k)), "{k:?}");
        assert_eq!(sigmoid(-1e30), 0.0);
        assert_eq!(sigmoid(1e30), 1.0);
    }
}
