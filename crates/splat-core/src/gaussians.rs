//! Gaussians as structure-of-arrays in raw (pre-activation) parameters, DESIGN §2.1.
//!
//! Per Gaussian: mean (3), log-scale (3), quaternion `w, x, y, z` (4, unnormalised), opacity
//! logit (1), and SH coefficients `[(deg+1)²][3]`, coefficient-major (all three channels of
//! coefficient 0, then coefficient 1, ...).

use thiserror::Error;

/// Why a [`GaussiansView`] is not a consistent set of Gaussians.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum ShapeError {
    /// The SH degree is above 3.
    #[error("SH degree {0} is above 3")]
    ShDegree(u32),
    /// An array's length does not match the number of means.
    #[error("{field} has {got} entries, expected {expected}")]
    Length {
        /// The array (field of [`GaussiansView`]).
        field: &'static str,
        /// Its length.
        got: usize,
        /// The length the means imply.
        expected: usize,
    },
}

/// Number of SH coefficients per channel for a degree: `(deg + 1)²`.
pub const fn sh_coeff_count(degree: u32) -> usize {
    ((degree + 1) * (degree + 1)) as usize
}

/// Owned Gaussians in raw parameters, structure of arrays.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Gaussians {
    /// SH degree, 0..=3.
    pub sh_degree: u32,
    /// Means in world coordinates.
    pub means: Vec<[f32; 3]>,
    /// Natural-log scales.
    pub log_scales: Vec<[f32; 3]>,
    /// Raw quaternions `w, x, y, z`; normalised when used.
    pub rotations: Vec<[f32; 4]>,
    /// Opacity logits; opacity is `sigmoid(logit)`.
    pub opacity_logits: Vec<f32>,
    /// SH coefficients, `len() * sh_coeff_count(sh_degree) * 3`, coefficient-major per Gaussian.
    pub sh: Vec<f32>,
}

/// Borrowed Gaussians: the plain slices the rasterizer reads.
#[derive(Clone, Copy, Debug)]
pub struct GaussiansView<'a> {
    /// SH degree, 0..=3.
    pub sh_degree: u32,
    /// Means in world coordinates.
    pub means: &'a [[f32; 3]],
    /// Natural-log scales.
    pub log_scales: &'a [[f32; 3]],
    /// Raw quaternions `w, x, y, z`.
    pub rotations: &'a [[f32; 4]],
    /// Opacity logits.
    pub opacity_logits: &'a [f32],
    /// SH coefficients, coefficient-major per Gaussian.
    pub sh: &'a [f32],
}

impl Gaussians {
    /// An empty set of Gaussians at an SH degree.
    pub fn with_degree(sh_degree: u32) -> Self {
        Self {
            sh_degree,
            ..Self::default()
        }
    }

    /// Number of Gaussians.
    pub fn len(&self) -> usize {
        self.view().len()
    }

    /// True when there are no Gaussians.
    pub fn is_empty(&self) -> bool {
        self.view().is_empty()
    }

    /// Floats of SH per Gaussian: `sh_coeff_count(sh_degree) * 3`.
    pub fn sh_stride(&self) -> usize {
        self.view().sh_stride()
    }

    /// Borrow as slices.
    pub fn view(&self) -> GaussiansView<'_> {
        GaussiansView {
            sh_degree: self.sh_degree,
            means: &self.means,
            log_scales: &self.log_scales,
            rotations: &self.rotations,
            opacity_logits: &self.opacity_logits,
            sh: &self.sh,
        }
    }
}

impl GaussiansView<'_> {
    /// Number of Gaussians.
    pub fn len(&self) -> usize {
        self.means.len()
    }

    /// True when there are no Gaussians.
    pub fn is_empty(&self) -> bool {
        self.means.is_empty()
    }

    /// Floats of SH per Gaussian.
    pub fn sh_stride(&self) -> usize {
        sh_coeff_count(self.sh_degree) * 3
    }

    /// Checks that every array has the length the means imply and the degree is 0..=3.
    pub fn check_lengths(&self) -> Result<(), ShapeError> {
        let n = self.len();
        if self.sh_degree > 3 {
            return Err(ShapeError::ShDegree(self.sh_degree));
        }
        let checks = [
            ("log_scales", self.log_scales.len(), n),
            ("rotations", self.rotations.len(), n),
            ("opacity_logits", self.opacity_logits.len(), n),
            ("sh", self.sh.len(), n * self.sh_stride()),
        ];
        for (field, got, expected) in checks {
            if got != expected {
                return Err(ShapeError::Length {
                    field,
                    got,
                    expected,
                });
            }
        }
        Ok(())
    }
}

/// Loss gradients with respect to every raw Gaussian parameter (zero for culled Gaussians), and
/// to the projected means. Gradients only: the screen radii are the rasterizer's forward
/// output, the count of zeroed Gaussians its backward output (`splat-raster`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GaussianGrads {
    /// dL/d mean.
    pub means: Vec<[f32; 3]>,
    /// dL/d log-scale.
    pub log_scales: Vec<[f32; 3]>,
    /// dL/d raw (unnormalised) quaternion `w, x, y, z`.
    pub rotations: Vec<[f32; 4]>,
    /// dL/d opacity logit.
    pub opacity_logits: Vec<f32>,
    /// dL/d SH coefficients, same layout as the input (zero outside the active bands).
    pub sh: Vec<f32>,
    /// dL/d projected mean `(u, v)`, in pixels (densification statistic, with
    /// the screen radii of the forward pass).
    pub means2d: Vec<[f32; 2]>,
}
