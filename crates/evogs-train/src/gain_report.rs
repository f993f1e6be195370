//! K's distribution during training (DESIGN §4.9): whether the "learned" gain varies at all.
//!
//! Samples are the gains of training steps in the run's gain stage (three history frames, so
//! that θ and the speeds exist), one per Gaussian and step. They are kept in a histogram of
//! [`BINS`] equal bins over [0, 1], so percentiles are exact to half a bin (0.0005); mean and
//! standard deviation are exact sums. A Gaussian counts as *moving* at a step when both of its
//! speeds are at or above the motion floor (the Gaussians whose θ is measured), *still*
//! otherwise. Steps with a fixed gain are counted too: their distribution is a single value.
//!
//! This is a diagnostic, not a metric of quality: it shows whether Ψ separates Gaussians at all.
//! Its table (`evogs train --gain-report`) is `evogs-experiments`' `gain_table`.

use evo_state::{Gains, Step};
use serde::{Deserialize, Serialize};

/// Histogram bins over [0, 1].
pub const BINS: usize = 1000;

/// The percentiles reported, in percent.
pub const PERCENTILES: [f64; 5] = [5.0, 25.0, 50.0, 75.0, 95.0];

/// A histogram of K with exact first and second moments.
#[derive(Clone, Debug, PartialEq)]
struct Histogram {
    counts: Vec<u64>,
    sum: f64,
    sum_sq: f64,
}

impl Default for Histogram {
    fn default() -> Self {
        Self {
            counts: vec![0; BINS],
            sum: 0.0,
            sum_sq: 0.0,
        }
    }
}

impl Histogram {
    fn add(&mut self, k: f32) {
        let k = f64::from(k);
        let b = ((k * BINS as f64).floor().max(0.0) as usize).min(BINS - 1);
        self.counts[b] += 1;
        self.sum += k;
        self.sum_sq += k * k;
    }

    fn samples(&self) -> u64 {
        self.counts.iter().sum()
    }

    /// The summary, or `None` without samples.
    fn summary(&self) -> Option<GainStats> {
        let n = self.samples();
        if n == 0 {
            return None;
        }
        let nf = n as f64;
        let mean = self.sum / nf;
        let var = (self.sum_sq / nf - mean * mean).max(0.0);
        let percentiles = PERCENTILES
            .iter()
            .map(|p| {
                // The smallest bin whose cumulative count reaches p% of the samples; its centre.
                let target = (p / 100.0 * nf).ceil().max(1.0) as u64;
                let mut seen = 0;
                let mut bin = BINS - 1;
                for (b, c) in self.counts.iter().enumerate() {
                    seen += c;
                    if seen >= target {
                        bin = b;
                        break;
                    }
                }
                (bin as f64 + 0.5) / BINS as f64
            })
            .collect();
        Some(GainStats {
            samples: n,
            mean,
            std: var.sqrt(),
            percentiles,
        })
    }
}

/// Mean, standard deviation and percentiles of K over a set of samples.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GainStats {
    /// Samples (Gaussian × step).
    pub samples: u64,
    /// Mean K.
    pub mean: f64,
    /// Standard deviation of K.
    pub std: f64,
    /// K at the [`PERCENTILES`] (centres of histogram bins of width 1/[`BINS`]).
    pub percentiles: Vec<f64>,
}

/// K's distribution over all samples, over moving and still Gaussians, and per frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GainSummary {
    /// Every sample.
    pub all: Option<GainStats>,
    /// Gaussians whose two speeds are at or above the motion floor.
    pub moving: Option<GainStats>,
    /// The others.
    pub still: Option<GainStats>,
    /// Per training frame (index = frame), `None` for frames without samples.
    pub per_frame: Vec<Option<GainStats>>,
}

/// Accumulates K over training steps.
#[derive(Clone, Debug, PartialEq)]
pub struct GainReport {
    /// Speed below which a Gaussian is still, in scene units per frame spacing
    /// (`motion_floor · extent`).
    pub still_below: f32,
    all: Histogram,
    moving: Histogram,
    still: Histogram,
    per_frame: Vec<Histogram>,
}

impl GainReport {
    /// An empty report; `still_below` is the motion floor in scene units per frame spacing.
    pub fn new(still_below: f32) -> Self {
        Self {
            still_below,
            all: Histogram::default(),
            moving: Histogram::default(),
            still: Histogram::default(),
            per_frame: Vec::new(),
        }
    }

    /// Adds a training step's gains if it is in the gain stage (it has motion statistics);
    /// other steps are ignored. Returns whether it was added.
    pub fn add(&mut self, step: &Step) -> bool {
        let Some(stats) = step.stats() else {
            return false;
        };
        let gains = step.gains();
        if matches!(gains, Gains::Observation) {
            return false;
        }
        let frame = step.frame();
        if let Some(k) = frame
            && self.per_frame.len() <= k
        {
            self.per_frame.resize_with(k + 1, Histogram::default);
        }
        for (i, s) in stats.iter().enumerate() {
            let k = gains.at(i);
            self.all.add(k);
            if s.speed_last.min(s.speed_prev) >= self.still_below {
                self.moving.add(k);
            } else {
                self.still.add(k);
            }
            if let Some(f) = frame {
                self.per_frame[f].add(k);
            }
        }
        true
    }

    /// Samples added.
    pub fn samples(&self) -> u64 {
        self.all.samples()
    }

    /// The distributions.
    pub fn summary(&self) -> GainSummary {
        GainSummary {
            all: self.all.summary(),
            moving: self.moving.summary(),
            still: self.still.summary(),
            per_frame: self.per_frame.iter().map(Histogram::summary).collect(),
        }
    }

    /// Clears the samples.
    pub fn reset(&mut self) {
        *self = Self::new(self.still_below);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moments_and_percentiles_of_a_known_sample() {
        let mut h = Histogram::default();
        // 0.0005, 0.0015, ..., 0.9995: one sample at the centre of each bin.
        for b in 0..BINS {
            h.add((b as f32 + 0.5) / BINS as f32);
        }
        let s = h.summary().unwrap();
        assert_eq!(s.samples, BINS as u64);
        assert!((s.mean - 0.5).abs() < 1e-6, "{}", s.mean);
        // Uniform on [0, 1]: std 1/sqrt(12).
        assert!((s.std - (1.0f64 / 12.0).sqrt()).abs() < 1e-3, "{}", s.std);
        let want = [0.0495, 0.2495, 0.4995, 0.7495, 0.9495];
        for (got, want) in s.percentiles.iter().zip(want) {
            assert!((got - want).abs() < 1e-9, "{got} vs {want}");
        }
    }

    #[test]
    fn a_constant_gain_has_zero_spread() {
        let mut h = Histogram::default();
        for _ in 0..10 {
            h.add(0.5);
        }
        let s = h.summary().unwrap();
        assert_eq!(s.mean, 0.5);
        assert_eq!(s.std, 0.0);
        assert!(s.percentiles.iter().all(|p| (p - 0.5005).abs() < 1e-12));
    }

    #[test]
    fn bounds_land_in_the_end_bins() {
        let mut h = Histogram::default();
        h.add(0.0);
        h.add(1.0);
        assert_eq!(h.counts[0], 1);
        assert_eq!(h.counts[BINS - 1], 1);
        assert!(Histogram::default().summary().is_none());
    }
}
