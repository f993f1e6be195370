//! Statistics accumulated between densification steps, per Gaussian.
//!
//! - Projected-mean gradient norm in NDC units, summed over the views where the Gaussian is
//!   visible (radius > 0), and the number of such views (3DGS's `xyz_gradient_accum` / `denom`).
//!   The rasterizer gives dL/d(pixel mean); a pixel coordinate is `u = (ndc + 1) W/2 - 0.5`, so
//!   dL/d(ndc) = dL/du · W/2 and likewise H/2 (DESIGN §6.1).
//! - Maximum screen radius over the interval (`max_radii2D`).
//! - EvoGS: sum and count of the per-step residual norm and of the angular deviation θ, given
//!   as plain per-Gaussian values (evo-state's `Step::residual_norms` and `Step::thetas`
//!   compute them; densify knows nothing of the evolution state).

use crate::error::DensifyError;
use rayon::prelude::*;

/// Per-Gaussian statistics since the last densification step.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DensifyStats {
    /// Σ |dL/d(ndc mean)| over visible views.
    pub grad_sum: Vec<f32>,
    /// Number of visible views.
    pub visible: Vec<u32>,
    /// Maximum screen radius (px) over visible views.
    pub max_radius: Vec<f32>,
    /// Σ residual norm (relative to the scene extent) over steps that had one.
    pub residual_sum: Vec<f32>,
    /// Number of steps that gave a residual.
    pub residual_count: Vec<u32>,
    /// Σ θ over steps that gave statistics.
    pub theta_sum: Vec<f32>,
    /// Number of steps that gave θ.
    pub theta_count: Vec<u32>,
}

fn check_len(field: &'static str, actual: usize, expected: usize) -> Result<(), DensifyError> {
    if actual == expected {
        Ok(())
    } else {
        Err(DensifyError::Length {
            field,
            expected,
            actual,
        })
    }
}

/// Mean of a sum over a count, 0 when the count is 0 (3DGS sets NaN means to 0).
fn mean(sum: f32, count: u32) -> f32 {
    if count == 0 { 0.0 } else { sum / count as f32 }
}

impl DensifyStats {
    /// Zeroed statistics for `rows` Gaussians.
    pub fn new(rows: usize) -> Self {
        Self {
            grad_sum: vec![0.0; rows],
            visible: vec![0; rows],
            max_radius: vec![0.0; rows],
            residual_sum: vec![0.0; rows],
            residual_count: vec![0; rows],
            theta_sum: vec![0.0; rows],
            theta_count: vec![0; rows],
        }
    }

    /// Number of Gaussians.
    pub fn len(&self) -> usize {
        self.grad_sum.len()
    }

    /// True when there are no Gaussians.
    pub fn is_empty(&self) -> bool {
        self.grad_sum.is_empty()
    }

    /// Checks that every array has the same length.
    pub fn check(&self) -> Result<(), DensifyError> {
        let n = self.len();
        check_len("stats.visible", self.visible.len(), n)?;
        check_len("stats.max_radius", self.max_radius.len(), n)?;
        check_len("stats.residual_sum", self.residual_sum.len(), n)?;
        check_len("stats.residual_count", self.residual_count.len(), n)?;
        check_len("stats.theta_sum", self.theta_sum.len(), n)?;
        check_len("stats.theta_count", self.theta_count.len(), n)
    }

    /// Adds one rendered view: `means2d` is dL/d(projected mean) in pixels, `radii` the screen
    /// radius in px (0 when culled), for an image of `width` × `height`.
    ///
    /// A visible Gaussian with a non-finite gradient is an error naming it; nothing is added then.
    pub fn add_view(
        &mut self,
        means2d: &[[f32; 2]],
        radii: &[f32],
        width: u32,
        height: u32,
    ) -> Result<(), DensifyError> {
        self.check()?;
        check_len("means2d", means2d.len(), self.len())?;
        check_len("radii", radii.len(), self.len())?;
        if let Some(i) = radii.iter().position(|r| !r.is_finite()) {
            return Err(DensifyError::Input {
                field: "radii",
                problem: format!("non-finite radius {} at Gaussian {i}", radii[i]),
            });
        }
        if let Some(i) = (0..radii.len())
            .find(|&i| radii[i] > 0.0 && !(means2d[i][0].is_finite() && means2d[i][1].is_finite()))
        {
            return Err(DensifyError::Input {
                field: "means2d",
                problem: format!("non-finite gradient {:?} at Gaussian {i}", means2d[i]),
            });
        }
        let (hw, hh) = (0.5 * width as f32, 0.5 * height as f32);
        self.grad_sum
            .par_iter_mut()
            .zip(self.visible.par_iter_mut())
            .zip(self.max_radius.par_iter_mut())
            .zip(means2d.par_iter().zip(radii.par_iter()))
            .with_min_len(4096)
            .for_each(|(((g, v), m), (d, &r))| {
                if r > 0.0 {
                    *g += (d[0] * hw).hypot(d[1] * hh);
                    *v += 1;
                    *m = m.max(r);
                }
            });
        Ok(())
    }

    /// Adds one EvoGS step's uncertainty cues: per-Gaussian residual norm (relative to the scene
    /// extent) and θ, each when the step has them (evo-state's `Step::residual_norms`,
    /// `Step::thetas`).
    pub fn add_evolution(
        &mut self,
        residual_norm: Option<&[f32]>,
        theta: Option<&[f32]>,
    ) -> Result<(), DensifyError> {
        self.check()?;
        for (field, values) in [("residual_norm", residual_norm), ("theta", theta)] {
            if let Some(values) = values {
                check_len(field, values.len(), self.len())?;
                if let Some(i) = values.iter().position(|v| !v.is_finite() || *v < 0.0) {
                    return Err(DensifyError::Input {
                        field,
                        problem: format!(
                            "value {} at Gaussian {i} is not finite and >= 0",
                            values[i]
                        ),
                    });
                }
            }
        }
        if let Some(r) = residual_norm {
            add_samples(&mut self.residual_sum, &mut self.residual_count, r);
        }
        if let Some(t) = theta {
            add_samples(&mut self.theta_sum, &mut self.theta_count, t);
        }
        Ok(())
    }

    /// Mean NDC gradient norm of Gaussian `i` over its visible views (0 if never visible).
    pub fn mean_grad(&self, i: usize) -> f32 {
        mean(self.grad_sum[i], self.visible[i])
    }

    /// Mean residual norm of Gaussian `i` (0 without samples).
    pub fn mean_residual(&self, i: usize) -> f32 {
        mean(self.residual_sum[i], self.residual_count[i])
    }

    /// Mean θ of Gaussian `i` (0 without samples).
    pub fn mean_theta(&self, i: usize) -> f32 {
        mean(self.theta_sum[i], self.theta_count[i])
    }

    /// Zeroes every statistic and sets the row count (3DGS resets all statistics after each
    /// densification step, in `densification_postfix`).
    pub fn reset(&mut self, rows: usize) {
        *self = Self::new(rows);
    }
}

fn add_samples(sum: &mut [f32], count: &mut [u32], values: &[f32]) {
    sum.par_iter_mut()
        .zip(count.par_iter_mut())
        .zip(values.par_iter())
        .with_min_len(4096)
        .for_each(|((s, c), &v)| {
            *s += v;
            *c += 1;
        });
}
