//! The running root-mean-square of Ψ's inputs (DESIGN §4.9: each input feature is divided
//! by its running root-mean-square over training steps).
//!
//! Ψ reads `[m (D), |v2|, |v1|, θ]`. The first D + 2 features (the residual memory and the two
//! speeds, in the deformation's own units) are divided by their running RMS; θ is an angle in
//! radians, already of order one, and is passed as it is. The running mean square of feature j
//! is an exponential average over training steps of the step's mean over Gaussians of `x_j²`,
//! with decay [`INPUT_RMS_DECAY`] and Adam's bias correction: after n steps
//! `ema_j = Σ_s (1-ρ) ρ^(n-s) ms_j(s)`, `weight = 1 - ρ^n`, `rms_j = sqrt(ema_j / weight)`.
//!
//! What it is not: it does not learn (no gradient flows into it) and it never changes outside a
//! training step's commit; evaluation and rendering read it frozen. Before the first training
//! step with statistics (weight 0) a query normalises by its own batch's RMS.

/// ρ, the decay of the running mean square per training step (a window of about 100 steps).
pub const INPUT_RMS_DECAY: f64 = 0.99;

/// The smallest RMS floor, whatever the configuration (with a motion floor of 0).
pub const RMS_FLOOR: f64 = 1e-12;

/// The RMS floor of each of the D + 2 normalised features: an RMS below it is treated as the
/// floor, so that a feature that is zero up to rounding (a still scene's memory, times not
/// exact in binary) stays near zero instead of being blown up to order one. The floor is the
/// motion floor (DESIGN §4.7: below it motion is optimisation noise): `motion_floor · extent` for
/// features in scene units (the position memory and the two speeds), `motion_floor` for the
/// other memory components (offsets of raw rotation, log-scale, opacity logit, SH DC), and at
/// least [`RMS_FLOOR`].
pub fn rms_floors(
    dim: usize,
    position: Option<std::ops::Range<usize>>,
    motion_floor: f64,
    extent: f64,
) -> Vec<f64> {
    let scene = (motion_floor * extent).max(RMS_FLOOR);
    let mut floors = vec![motion_floor.max(RMS_FLOOR); dim + 2];
    for j in position.into_iter().flatten() {
        floors[j] = scene;
    }
    floors[dim] = scene;
    floors[dim + 1] = scene;
    floors
}

/// Running mean squares of Ψ's first D + 2 inputs.
#[derive(Debug, Clone, PartialEq)]
pub struct InputNorm {
    /// Bias-uncorrected exponential averages of the per-step mean squares.
    pub(crate) ema: Vec<f64>,
    /// `1 - ρ^n` after n updates (1 for a fixed legacy normaliser).
    pub(crate) weight: f64,
}

impl InputNorm {
    /// No statistics yet, for `features` (D + 2) features.
    pub fn new(features: usize) -> Self {
        Self {
            ema: vec![0.0; features],
            weight: 0.0,
        }
    }

    /// The fixed normaliser of states saved before running-RMS normalisation existed
    /// (`evo-state/1`): memory components and speeds in scene units divided by the scene
    /// extent, other memory components as they are. Loading such a state gives Ψ exactly the
    /// input scaling it was trained with.
    pub fn legacy(dim: usize, position: Option<std::ops::Range<usize>>, extent: f64) -> Self {
        let mut ema = vec![1.0; dim + 2];
        for j in position.into_iter().flatten() {
            ema[j] = extent * extent;
        }
        ema[dim] = extent * extent;
        ema[dim + 1] = extent * extent;
        Self { ema, weight: 1.0 }
    }

    /// Number of normalised features (D + 2).
    pub fn features(&self) -> usize {
        self.ema.len()
    }

    /// The running RMS per feature, or `None` before the first update.
    pub fn rms(&self) -> Option<Vec<f64>> {
        (self.weight > 0.0).then(|| {
            self.ema
                .iter()
                .map(|e| (e / self.weight).max(0.0).sqrt())
                .collect()
        })
    }

    /// Number of training steps folded in so far, as `1 - ρ^n` (0 before the first).
    pub fn weight(&self) -> f64 {
        self.weight
    }

    /// Folds one training step's per-feature mean squares in.
    pub(crate) fn update(&mut self, mean_sq: &[f64]) {
        debug_assert_eq!(mean_sq.len(), self.ema.len());
        let rho = INPUT_RMS_DECAY;
        for (e, &m) in self.ema.iter_mut().zip(mean_sq) {
            *e = rho * *e + (1.0 - rho) * m;
        }
        self.weight = rho * self.weight + (1.0 - rho);
    }

    /// The factors `1 / max(rms_j, floor_j)` to multiply the features by: the running RMS,
    /// or the batch's own (`batch_mean_sq`) before the first update ([`rms_floors`]).
    pub(crate) fn factors(&self, batch_mean_sq: &[f64], floors: &[f64]) -> Vec<f64> {
        let rms = self
            .rms()
            .unwrap_or_else(|| batch_mean_sq.iter().map(|m| m.max(0.0).sqrt()).collect());
        rms.iter()
            .zip(floors)
            .map(|(r, f)| 1.0 / r.max(*f))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bias_corrected_average_of_a_constant_is_the_constant() {
        let mut n = InputNorm::new(2);
        assert_eq!(n.rms(), None);
        for _ in 0..5 {
            n.update(&[4.0, 0.25]);
        }
        let rms = n.rms().unwrap();
        assert!((rms[0] - 2.0).abs() < 1e-12 && (rms[1] - 0.5).abs() < 1e-12);
        // By hand: two updates with 1 then 9: ema = 0.99·0.01·1 + 0.01·9, weight = 1 - 0.99².
        let mut n = InputNorm::new(1);
        n.update(&[1.0]);
        n.update(&[9.0]);
        let expected = (0.99 * 0.01 * 1.0 + 0.01 * 9.0) / (1.0 - 0.99f64 * 0.99);
        assert!((n.rms().unwrap()[0] - expected.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn factors_use_the_batch_before_any_update_and_floor_zero_features() {
        let n = InputNorm::new(3);
        let f = n.factors(&[4.0, 0.0, 1e-30], &[1e-3; 3]);
        assert_eq!(f, vec![0.5, 1e3, 1e3]);
        let legacy = InputNorm::legacy(4, Some(0..3), 2.0);
        assert_eq!(legacy.rms().unwrap(), vec![2.0, 2.0, 2.0, 1.0, 2.0, 2.0]);
        assert_eq!(legacy.factors(&[9.0; 6], &[0.0; 6])[3], 1.0);
    }

    #[test]
    fn floors_follow_the_motion_floor_in_each_features_units() {
        // D = 4: position memory (3), one dimensionless component, then |v2|, |v1|.
        let floors = rms_floors(4, Some(0..3), 1e-3, 2.0);
        assert_eq!(floors, vec![2e-3, 2e-3, 2e-3, 1e-3, 2e-3, 2e-3]);
        // Rounding noise of 5e-8 in a feature that has been zero stays far below one.
        let mut n = InputNorm::new(6);
        n.update(&[1.0, 0.0, 0.0, 0.0, 1.0, 1.0]);
        let f = n.factors(&[0.0; 6], &floors);
        assert!(5e-8 * f[1] < 1e-4);
        // A motion floor of 0 still gives a positive floor.
        assert!(
            rms_floors(1, None, 0.0, 1.0)
                .iter()
                .all(|&f| f == RMS_FLOOR)
        );
    }
}
