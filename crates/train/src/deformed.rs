//! Adding a backbone's deformation to canonical Gaussians: mean + Δposition, raw quaternion +
//! Δrotation, log-scale + Δscale (D-3DGS adds `d_rotation` to the raw quaternion and `d_scaling`
//! to the raw scale before activation, `gaussian_renderer/__init__.py`). Opacity and SH are the
//! canonical ones.

use splat_raster::{Gaussians, GaussiansView};

use crate::backbone::DEFORM_DIM;

/// The deformed geometric parameters of every Gaussian.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DeformedGeometry {
    /// Means.
    pub means: Vec<[f32; 3]>,
    /// Log-scales.
    pub log_scales: Vec<[f32; 3]>,
    /// Raw quaternions.
    pub rotations: Vec<[f32; 4]>,
}

impl DeformedGeometry {
    /// Canonical + `d` (N × [`DEFORM_DIM`]); `None` leaves the canonical geometry.
    pub fn new(canonical: &Gaussians, d: Option<&[f32]>) -> Self {
        let Some(d) = d else {
            return Self {
                means: canonical.means.clone(),
                log_scales: canonical.log_scales.clone(),
                rotations: canonical.rotations.clone(),
            };
        };
        let rows = d.chunks_exact(DEFORM_DIM);
        let mut out = Self {
            means: Vec::with_capacity(canonical.len()),
            log_scales: Vec::with_capacity(canonical.len()),
            rotations: Vec::with_capacity(canonical.len()),
        };
        for (i, r) in rows.enumerate() {
            let (m, q, s) = (
                canonical.means[i],
                canonical.rotations[i],
                canonical.log_scales[i],
            );
            out.means.push([m[0] + r[0], m[1] + r[1], m[2] + r[2]]);
            out.rotations
                .push([q[0] + r[3], q[1] + r[4], q[2] + r[5], q[3] + r[6]]);
            out.log_scales.push([s[0] + r[7], s[1] + r[8], s[2] + r[9]]);
        }
        out
    }

    /// The deformed Gaussians as the rasterizer reads them (opacity and SH from `canonical`).
    pub fn view<'a>(&'a self, canonical: &'a Gaussians) -> GaussiansView<'a> {
        GaussiansView {
            sh_degree: canonical.sh_degree,
            means: &self.means,
            log_scales: &self.log_scales,
            rotations: &self.rotations,
            opacity_logits: &canonical.opacity_logits,
            sh: &canonical.sh,
        }
    }

    /// Owned deformed Gaussians (for export).
    pub fn into_gaussians(self, canonical: &Gaussians) -> Gaussians {
        Gaussians {
            sh_degree: canonical.sh_degree,
            means: self.means,
            log_scales: self.log_scales,
            rotations: self.rotations,
            opacity_logits: canonical.opacity_logits.clone(),
            sh: canonical.sh.clone(),
        }
    }
}

/// dL/d(deformation) rows from the rasterizer's gradients of the deformed mean, quaternion and
/// log-scale (the deformation is added, so these are the same gradients).
pub fn deformation_gradient(
    means: &[[f32; 3]],
    rotations: &[[f32; 4]],
    log_scales: &[[f32; 3]],
) -> Vec<f32> {
    let mut out = Vec::with_capacity(means.len() * DEFORM_DIM);
    for ((m, q), s) in means.iter().zip(rotations).zip(log_scales) {
        out.extend_from_slice(m);
        out.extend_from_slice(q);
        out.extend_from_slice(s);
    }
    out
}
