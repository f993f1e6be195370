//! Render options and the culling statistics of one forward pass.

use std::fmt;

/// Options of one render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    /// Background colour composited behind the Gaussians, `C += T_final * background`.
    pub background: [f32; 3],
    /// Active SH degree (bands 0..=d are used), at most the data's degree; `None` uses all.
    pub sh_degree: Option<u32>,
}

impl Default for RenderOptions {
    /// Black background, every SH band.
    fn default() -> Self {
        Self {
            background: [0.0; 3],
            sh_degree: None,
        }
    }
}

/// How many Gaussians a forward pass drew and why the others were culled.
///
/// Every Gaussian is counted once, under the first reason found; the checks run in the order
/// non-finite input, zero quaternion, low opacity, behind the near plane, degenerate covariance,
/// off screen. Two computed cases are folded in: a camera-space position or projected mean that
/// overflows `f32` counts as off screen, and an SH colour above `MAX_COLOR` counts as non-finite.
/// `total = drawn + (sum of the culled counts)`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CullStats {
    /// Gaussians in the input.
    pub total: usize,
    /// Gaussians that touched at least one tile and were composited.
    pub drawn: usize,
    /// Some raw parameter (mean, log-scale, quaternion, opacity logit, SH) is NaN or infinite, or
    /// the SH colour exceeds `MAX_COLOR` (1e18).
    pub non_finite: usize,
    /// `|q|²` below `1e-12`: no rotation can be recovered.
    pub zero_quaternion: usize,
    /// Opacity `sigmoid(logit) < 1/255`: no pixel could reach the blending threshold.
    pub low_opacity: usize,
    /// Camera-space `z <= 0.01`.
    pub behind_near_plane: usize,
    /// `det(Σ2d) <= 0`, the covariance overflowed (it is computed in f64), or its conic does not
    /// fit `f32`.
    pub degenerate_covariance: usize,
    /// The opacity-aware extent touches no pixel of the image (or the projection overflowed).
    pub off_screen: usize,
}

impl CullStats {
    /// Number of culled Gaussians, `total - drawn`.
    pub fn culled(&self) -> usize {
        self.non_finite
            + self.zero_quaternion
            + self.low_opacity
            + self.behind_near_plane
            + self.degenerate_covariance
            + self.off_screen
    }
}

impl fmt::Display for CullStats {
    /// One line, e.g. `drew 812 of 1000 Gaussians; culled: 100 behind near plane, 88 off screen`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "drew {} of {} Gaussians", self.drawn, self.total)?;
        let reasons = [
            (self.non_finite, "non-finite"),
            (self.zero_quaternion, "zero quaternion"),
            (self.low_opacity, "low opacity"),
            (self.behind_near_plane, "behind near plane"),
            (self.degenerate_covariance, "degenerate covariance"),
            (self.off_screen, "off screen"),
        ];
        let mut first = true;
        for (count, why) in reasons {
            if count == 0 {
                continue;
            }
            f.write_str(if first { "; culled: " } else { ", " })?;
            write!(f, "{count} {why}")?;
            first = false;
        }
        if first {
            f.write_str("; none culled")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn display_lists_only_nonzero_reasons() {
        let s = CullStats {
            total: 1000,
            drawn: 812,
            behind_near_plane: 100,
            off_screen: 88,
            ..CullStats::default()
        };
        assert_eq!(
            s.to_string(),
            "drew 812 of 1000 Gaussians; culled: 100 behind near plane, 88 off screen"
        );
        assert_eq!(s.culled(), 188);
        let none = CullStats {
            total: 3,
            drawn: 3,
            ..CullStats::default()
        };
        assert_eq!(none.to_string(), "drew 3 of 3 Gaussians; none culled");
    }
}
