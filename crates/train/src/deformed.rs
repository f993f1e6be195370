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

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The deformation is added to the raw parameters, so for any per-parameter gradient G the
        /// first-order change of `Σ G·params` under a deformation δ is `deformation_gradient(G)·δ`:
        /// both functions must agree on the order of the 10 components.
        #[test]
        fn gradient_rows_match_the_order_of_the_deformation(
            n in 1usize..6,
            seed in any::<u64>(),
        ) {
            use rand::{RngExt, SeedableRng};
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let mut r = || rng.random_range(-1.0f32..1.0);
            let canonical = Gaussians {
                sh_degree: 0,
                means: (0..n).map(|_| [r(), r(), r()]).collect(),
                log_scales: (0..n).map(|_| [r(), r(), r()]).collect(),
                rotations: (0..n).map(|_| [r(), r(), r(), r()]).collect(),
                opacity_logits: (0..n).map(|_| r()).collect(),
                sh: (0..n * 3).map(|_| r()).collect(),
            };
            let delta: Vec<f32> = (0..n * DEFORM_DIM).map(|_| r()).collect();
            let gm: Vec<[f32; 3]> = (0..n).map(|_| [r(), r(), r()]).collect();
            let gq: Vec<[f32; 4]> = (0..n).map(|_| [r(), r(), r(), r()]).collect();
            let gs: Vec<[f32; 3]> = (0..n).map(|_| [r(), r(), r()]).collect();
            let deformed = DeformedGeometry::new(&canonical, Some(&delta));
            let dot = |a: &[f32], b: &[f32], c: &[f32]| -> f64 {
                a.iter().zip(b).zip(c).map(|((g, x), y)| f64::from(*g) * f64::from(x - y)).sum()
            };
            let change = dot(gm.as_flattened(), deformed.means.as_flattened(), canonical.means.as_flattened())
                + dot(gq.as_flattened(), deformed.rotations.as_flattened(), canonical.rotations.as_flattened())
                + dot(gs.as_flattened(), deformed.log_scales.as_flattened(), canonical.log_scales.as_flattened());
            let rows = deformation_gradient(&gm, &gq, &gs);
            let predicted: f64 = rows.iter().zip(&delta).map(|(g, d)| f64::from(*g) * f64::from(*d)).sum();
            prop_assert!((change - predicted).abs() < 1e-4, "{change} vs {predicted}");
            let view = deformed.view(&canonical);
            prop_assert_eq!(view.opacity_logits, &canonical.opacity_logits[..]);
            prop_assert_eq!(DeformedGeometry::new(&canonical, None).means, canonical.means.clone());
        }
    }
}
