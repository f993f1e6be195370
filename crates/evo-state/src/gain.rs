//! The gain network Ψ = Linear(D+3, 32) ReLU Linear(32, 32) ReLU Linear(32, 1) sigmoid over N
//! rows: a [`tiny_nn::Mlp`] in f32 storage with PyTorch's default initialisation, plus the
//! exact power-of-two rescaling that keeps its parameter gradients finite for any finite dL/dK.

use tiny_nn::{Activation, Mlp, MlpCache, MlpConfig, Precision};

use crate::error::EvoError;

/// Hidden width of Ψ.
pub const HIDDEN: usize = 32;

/// Ψ with its parameters.
#[derive(Debug, Clone)]
pub struct GainNet {
    mlp: Mlp,
}

impl PartialEq for GainNet {
    /// Same shape and bit-identical parameters.
    fn eq(&self, other: &Self) -> bool {
        let bits = |n: &GainNet| n.params().iter().map(|p| p.to_bits()).collect::<Vec<_>>();
        self.mlp.config() == other.mlp.config() && bits(self) == bits(other)
    }
}

impl GainNet {
    /// Ψ for `inputs` inputs (D + 3), initialised deterministically from `seed`.
    pub fn new(inputs: usize, seed: u64) -> Result<Self, EvoError> {
        let mlp = MlpConfig::new(inputs, HIDDEN, 2, 1)
            .output_activation(Activation::Sigmoid)
            .precision(Precision::F32)
            .seed(seed)
            .build()?;
        Ok(Self { mlp })
    }

    /// Input width (D + 3).
    pub fn inputs(&self) -> usize {
        self.mlp.input_width()
    }

    /// Number of parameters.
    pub fn param_count(&self) -> usize {
        self.mlp.param_count()
    }

    /// The flat parameters (tiny-nn's layout: per layer W (in × out) then b).
    pub fn params(&self) -> Vec<f32> {
        self.mlp.params().to_vec_f32()
    }

    /// Replaces every parameter.
    pub fn set_params(&mut self, values: &[f32]) -> Result<(), EvoError> {
        self.mlp.set_params(values)?;
        Ok(())
    }

    /// The underlying network (for tiny-nn's `Adam::step` on `mlp_mut().params_mut()`).
    pub fn mlp(&self) -> &Mlp {
        &self.mlp
    }

    /// The underlying network, mutable.
    pub fn mlp_mut(&mut self) -> &mut Mlp {
        &mut self.mlp
    }

    /// K = Ψ(x) for `rows` rows of `x` (rows × inputs), and the cache for backward.
    pub fn forward(&self, x: &[f32], rows: usize) -> Result<(Vec<f32>, MlpCache), EvoError> {
        Ok(self.mlp.forward(x, rows)?)
    }

    /// Like [`GainNet::forward`], reusing `cache`'s buffers.
    pub fn forward_into(
        &self,
        x: &[f32],
        rows: usize,
        cache: &mut MlpCache,
    ) -> Result<Vec<f32>, EvoError> {
        let width = self.inputs();
        if x.len() != rows * width {
            return Err(EvoError::Length {
                what: "Ψ input",
                expected: rows * width,
                actual: x.len(),
            });
        }
        Ok(self.mlp.forward_into(
            rows,
            |r0, nr, buf| buf.copy_from_slice(&x[r0 * width..(r0 + nr) * width]),
            cache,
        ))
    }

    /// dL/dθ from dL/dK per row.
    ///
    /// dL/dK larger than 2^60 is scaled down by a power of two (exact) before tiny-nn's f32
    /// accumulation, and the result is scaled back in f64 and saturated to the f32 range, so
    /// finite inputs give finite gradients.
    pub fn backward(&self, cache: &MlpCache, dk: &[f32]) -> Result<Vec<f32>, EvoError> {
        let largest = dk.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        let exponent = if largest > 2f32.powi(60) {
            largest.log2().ceil() as i32
        } else {
            0
        };
        let grads = if exponent == 0 {
            self.mlp.backward(cache, dk, false)?.params
        } else {
            let down = (-exponent as f32).exp2();
            let scaled: Vec<f32> = dk.iter().map(|v| v * down).collect();
            let up = (exponent as f64).exp2();
            let g = self.mlp.backward(cache, &scaled, false)?.params;
            g.iter()
                .map(|&g| (g as f64 * up).clamp(-(f32::MAX as f64), f32::MAX as f64) as f32)
                .collect()
        };
        Ok(grads)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn loss(net: &GainNet, x: &[f32], c: &[f32]) -> f64 {
        let (k, _) = net.forward(x, c.len()).unwrap();
        k.iter().zip(c).map(|(k, c)| *k as f64 * *c as f64).sum()
    }

    /// Directional finite differences of Σ c_r K_r along random parameter directions.
    #[test]
    fn parameter_gradients_match_finite_differences() {
        let inputs = 13;
        let mut net = GainNet::new(inputs, 3).unwrap();
        let scaled: Vec<f32> = net.params().iter().map(|p| p * 2.0).collect();
        net.set_params(&scaled).unwrap();
        let rows = 5;
        let x: Vec<f32> = (0..rows * inputs)
            .map(|e| ((e * 37 % 17) as f32 - 8.0) / 5.0)
            .collect();
        let c: Vec<f32> = (0..rows).map(|r| r as f32 - 1.5).collect();
        let (_, cache) = net.forward(&x, rows).unwrap();
        let grads = net.backward(&cache, &c).unwrap();
        let base = net.params();
        let h = 1e-3f32;
        for trial in 0..6u32 {
            let u: Vec<f32> = (0..base.len())
                .map(|i| (((i as u32 * 7919 + trial * 104729) % 2001) as f32 / 1000.0) - 1.0)
                .collect();
            let at = |sign: f32| {
                let mut n = net.clone();
                let p: Vec<f32> = base.iter().zip(&u).map(|(p, u)| p + sign * h * u).collect();
                n.set_params(&p).unwrap();
                loss(&n, &x, &c)
            };
            let fd = (at(1.0) - at(-1.0)) / (2.0 * h as f64);
            let an: f64 = grads
                .iter()
                .zip(&u)
                .map(|(g, u)| *g as f64 * *u as f64)
                .sum();
            assert!(
                (fd - an).abs() <= 2e-3 + 5e-3 * fd.abs(),
                "direction {trial}: fd {fd} vs {an}"
            );
        }
    }

    #[test]
    fn huge_output_gradients_give_finite_scaled_parameter_gradients() {
        let net = GainNet::new(4, 1).unwrap();
        let x = [1e4, -1e4, 1e4, 0.0, 0.5, 0.25, -0.5, 1.0];
        let (k, cache) = net.forward(&x, 2).unwrap();
        assert!(k.iter().all(|k| (0.0..=1.0).contains(k)), "{k:?}");
        let small = net.backward(&cache, &[1.0, -2.0]).unwrap();
        let huge = net
            .backward(&cache, &[2f32.powi(100), -(2f32.powi(101))])
            .unwrap();
        assert!(huge.iter().all(|g| g.is_finite()));
        // Exactly 2^100 times the small gradients, saturated at the f32 limit.
        for (s, h) in small.iter().zip(&huge) {
            let expected =
                (*s as f64 * 2f64.powi(100)).clamp(-(f32::MAX as f64), f32::MAX as f64) as f32;
            assert_eq!(*h, expected);
        }
    }
}
