//! A diagnostic of EvoGS's motion statistics during training: how fast the Gaussians' evolved
//! positions move between history frames, and how the angular deviation θ behaves at each speed.
//!
//! Speeds are per frame spacing (evo-state's `|v1|`, `|v2|`); a sample's speed is the smaller of
//! the two, which is what the motion floor compares. Samples are binned by decade of
//! speed / scene extent; each bin reports its count, its mean θ and the fraction with θ below the
//! trigger's τ_θ, and the speed in pixels per frame spacing at the bin's lower edge for the
//! training cameras ([`pixels_per_unit`]). θ of directions drawn at random averages π/2, so bins
//! whose mean θ sits near π/2 hold noise, not motion: the motion floor belongs above them.
//!
//! The trainer only exposes the data ([`Trainer::motion_stats`], one step's statistics); the
//! report is filled by the caller (`evogs train --motion-report`).

use std::fmt::Write as _;

use evo_state::Stats;
use evogs_train::Trainer;
use glam::Vec3;
use splat_core::Camera;

/// Lower edge of the lowest decade bin (speed / extent); slower samples go to the first bin.
const LOWEST_DECADE: i32 = -7;
/// Decade bins: `< 1e-7`, `[1e-7, 1e-6)`, ..., `[1e-1, 1)`, `>= 1`.
const BINS: usize = (-LOWEST_DECADE) as usize + 2;

/// Pixels per scene unit at `centre` for a camera: `fx / distance` (the median over cameras).
pub fn pixels_per_unit(cameras: &[Camera], centre: Vec3) -> f32 {
    let mut v: Vec<f32> = cameras
        .iter()
        .map(|c| c.fx / (c.center() - centre).length().max(1e-6))
        .filter(|x| x.is_finite())
        .collect();
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f32::total_cmp);
    v[v.len() / 2]
}

/// Per-decade counts and θ sums, accumulated over training steps.
#[derive(Clone, Debug, PartialEq)]
pub struct MotionReport {
    /// Scene extent (scene units).
    pub extent: f32,
    /// Pixels per scene unit at the scene's centre ([`pixels_per_unit`]).
    pub pixels_per_unit: f32,
    /// The trigger's τ_θ.
    pub tau_theta: f32,
    count: [u64; BINS],
    theta_sum: [f64; BINS],
    below_tau: [u64; BINS],
}

impl MotionReport {
    /// An empty report.
    pub fn new(extent: f32, pixels_per_unit: f32, tau_theta: f32) -> Self {
        Self {
            extent,
            pixels_per_unit,
            tau_theta,
            count: [0; BINS],
            theta_sum: [0.0; BINS],
            below_tau: [0; BINS],
        }
    }

    /// An empty report for `trainer`'s run: its extent, the training cameras' pixels per scene
    /// unit at the centroid of the canonical means, and the trigger's τ_θ (densify's default
    /// when the run has no trigger).
    pub fn for_run(trainer: &Trainer) -> Self {
        let means = &trainer.state().gaussians().means;
        let centre = if means.is_empty() {
            Vec3::ZERO
        } else {
            means.iter().map(|m| Vec3::from(*m)).sum::<Vec3>() / means.len() as f32
        };
        let tau = trainer.densify().trigger.unwrap_or_default().tau_theta;
        Self::new(
            trainer.extent(),
            pixels_per_unit(&trainer.train_views().cameras(), centre),
            tau,
        )
    }

    /// The bin of a speed relative to the extent.
    fn bin(relative: f64) -> usize {
        if relative.is_nan() || relative <= 0.0 {
            return 0;
        }
        let decade = relative.log10().floor() as i64;
        (decade - LOWEST_DECADE as i64 + 1).clamp(0, BINS as i64 - 1) as usize
    }

    /// Adds one step's statistics.
    pub fn add(&mut self, stats: &[Stats]) {
        let extent = f64::from(self.extent.max(f32::MIN_POSITIVE));
        for s in stats {
            let speed = f64::from(s.speed_last.min(s.speed_prev));
            let b = Self::bin(speed / extent);
            self.count[b] += 1;
            self.theta_sum[b] += f64::from(s.theta);
            self.below_tau[b] += u64::from(s.theta < self.tau_theta);
        }
    }

    /// Samples added.
    pub fn samples(&self) -> u64 {
        self.count.iter().sum()
    }

    /// `(count, mean θ, fraction below τ_θ)` of each bin, lowest first.
    pub fn bins(&self) -> Vec<(u64, f64, f64)> {
        (0..BINS)
            .map(|b| {
                let n = self.count[b];
                let d = n.max(1) as f64;
                (n, self.theta_sum[b] / d, self.below_tau[b] as f64 / d)
            })
            .collect()
    }

    /// Clears the counts.
    pub fn reset(&mut self) {
        *self = Self::new(self.extent, self.pixels_per_unit, self.tau_theta);
    }

    /// A plain-text table: one line per non-empty bin.
    pub fn table(&self) -> String {
        let mut out = format!(
            "motion: {} samples; speed = min(|v1|,|v2|) per frame spacing; extent {:.3}, {:.1} px per unit\n",
            self.samples(),
            self.extent,
            self.pixels_per_unit
        );
        let _ = writeln!(
            out,
            "  {:>18} {:>12} {:>9} {:>9} {:>10}",
            "speed/extent", "px at edge", "samples", "mean θ", "θ < τ_θ"
        );
        for (b, (n, theta, below)) in self.bins().into_iter().enumerate() {
            if n == 0 {
                continue;
            }
            let lower = if b == 0 {
                None
            } else {
                Some(10f64.powi(LOWEST_DECADE + b as i32 - 1))
            };
            let range = match lower {
                None => format!("< 1e{LOWEST_DECADE}"),
                Some(l) if b == BINS - 1 => format!(">= {l:.0e}"),
                Some(l) => format!("[{l:.0e}, {:.0e})", l * 10.0),
            };
            let px = lower.map_or(0.0, |l| {
                l * f64::from(self.extent) * f64::from(self.pixels_per_unit)
            });
            let _ = writeln!(
                out,
                "  {range:>18} {px:>12.2e} {n:>9} {theta:>9.3} {:>9.1}%",
                100.0 * below
            );
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stats(speed: f32, theta: f32) -> Stats {
        Stats {
            speed_prev: speed,
            speed_last: speed * 2.0,
            theta,
        }
    }

    #[test]
    fn samples_land_in_their_decade() {
        let mut r = MotionReport::new(2.0, 100.0, 1.0);
        r.add(&[
            stats(0.0, 1.5),
            stats(2e-3, 1.5),
            stats(3e-3, 0.5),
            stats(5.0, 0.1),
        ]);
        let bins = r.bins();
        assert_eq!(bins[0].0, 1, "zero speed goes to the lowest bin");
        // 2e-3 / 2 = 1e-3 and 3e-3 / 2 = 1.5e-3: the [1e-3, 1e-2) bin.
        let b = MotionReport::bin(1.5e-3);
        assert_eq!(bins[b].0, 2);
        assert!((bins[b].1 - 1.0).abs() < 1e-9);
        assert!((bins[b].2 - 0.5).abs() < 1e-9);
        assert_eq!(bins[BINS - 1].0, 1);
        assert_eq!(r.samples(), 4);
        let t = r.table();
        assert!(t.contains("[1e-3, 1e-2)"), "{t}");
        r.reset();
        assert_eq!(r.samples(), 0);
    }

    #[test]
    fn pixels_per_unit_is_focal_over_distance() {
        let c = Camera::look_at(64, 64, 0.69, Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, Vec3::Y);
        let p = pixels_per_unit(&[c], Vec3::ZERO);
        assert!((p - c.fx / 4.0).abs() < 1e-4, "{p}");
    }
}
