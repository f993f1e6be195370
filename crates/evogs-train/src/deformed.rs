//! Adding a backbone's deformation to canonical Gaussians: mean + Δposition, raw quaternion +
//! Δrotation, log-scale + Δscale (DESIGN §4.1), and, where the backbone
//! deforms appearance (EvoGS's optional components, DESIGN §4.1), opacity logit + Δopacity and SH DC
//! + Δcolour. Appearance that is not deformed is read from the canonical Gaussians, never copied.
//!
//! D-3DGS adds `d_rotation` to the *normalised* quaternion and `d_scaling` to the *activated*
//! scale (`gaussian_renderer/__init__.py`: `pc.get_rotation + d_rotation`,
//! `pc.get_scaling + d_scaling`). Here both are added to the raw parameters, for every backbone
//! alike (DESIGN §11): a scale offset then stays relative and can never make a scale negative.

use rayon::prelude::*;
use splat_raster::{GaussianGrads, Gaussians, GaussiansView};

use evogs_backbones::{Appearance, COLOUR_COLUMN, DEFORM_DIM, OPACITY_COLUMN};

/// The deformed parameters of every Gaussian.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DeformedGeometry {
    /// Means.
    pub means: Vec<[f32; 3]>,
    /// Log-scales.
    pub log_scales: Vec<[f32; 3]>,
    /// Raw quaternions.
    pub rotations: Vec<[f32; 4]>,
    /// Opacity logits, when the opacity is deformed (else the canonical ones are used).
    pub opacity_logits: Option<Vec<f32>>,
    /// SH coefficients, when the colour (SH DC) is deformed (else the canonical ones are used).
    pub sh: Option<Vec<f32>>,
}

impl DeformedGeometry {
    /// Canonical + `d` (N × [`DEFORM_DIM`]; the appearance columns only where `appearance` says);
    /// `None` leaves the canonical Gaussians.
    pub fn new(canonical: &Gaussians, d: Option<&[f32]>, appearance: Appearance) -> Self {
        let mut out = Self::default();
        out.assign(canonical, d, appearance);
        out
    }

    /// [`DeformedGeometry::new`] into `self`, reusing its buffers: the same values, with no
    /// allocation once the buffers have held as many Gaussians (the trainer keeps one across
    /// iterations, so it allocates only when densification grows the count).
    pub fn assign(&mut self, canonical: &Gaussians, d: Option<&[f32]>, appearance: Appearance) {
        let Some(d) = d else {
            self.means.clear();
            self.log_scales.clear();
            self.rotations.clear();
            self.means.extend_from_slice(&canonical.means);
            self.log_scales.extend_from_slice(&canonical.log_scales);
            self.rotations.extend_from_slice(&canonical.rotations);
            self.opacity_logits = None;
            self.sh = None;
            return;
        };
        // Every row is written below, in parallel.
        let n = d.len() / DEFORM_DIM;
        self.means.resize(n, [0.0; 3]);
        self.rotations.resize(n, [0.0; 4]);
        self.log_scales.resize(n, [0.0; 3]);
        self.means
            .par_iter_mut()
            .zip(self.rotations.par_iter_mut())
            .zip(self.log_scales.par_iter_mut())
            .zip(d.par_chunks_exact(DEFORM_DIM))
            .enumerate()
            .with_min_len(ROWS_PER_TASK)
            .for_each(|(i, (((mean, rotation), log_scale), r))| {
                let (m, q, s) = (
                    canonical.means[i],
                    canonical.rotations[i],
                    canonical.log_scales[i],
                );
                *mean = [m[0] + r[0], m[1] + r[1], m[2] + r[2]];
                *rotation = [q[0] + r[3], q[1] + r[4], q[2] + r[5], q[3] + r[6]];
                *log_scale = [s[0] + r[7], s[1] + r[8], s[2] + r[9]];
            });
        let mut opacity = self.opacity_logits.take().unwrap_or_default();
        if appearance.opacity {
            opacity.clear();
            opacity.extend(
                canonical
                    .opacity_logits
                    .iter()
                    .zip(d.chunks_exact(DEFORM_DIM))
                    .map(|(o, r)| o + r[OPACITY_COLUMN]),
            );
            self.opacity_logits = Some(opacity);
        }
        let mut sh = self.sh.take().unwrap_or_default();
        if appearance.colour {
            let stride = canonical.sh_stride();
            sh.clear();
            sh.extend_from_slice(&canonical.sh);
            for (row, r) in sh.chunks_exact_mut(stride).zip(d.chunks_exact(DEFORM_DIM)) {
                for c in 0..3 {
                    row[c] += r[COLOUR_COLUMN + c];
                }
            }
            self.sh = Some(sh);
        }
    }

    /// The deformed Gaussians as the rasterizer reads them (undeformed appearance from
    /// `canonical`).
    pub fn view<'a>(&'a self, canonical: &'a Gaussians) -> GaussiansView<'a> {
        GaussiansView {
            sh_degree: canonical.sh_degree,
            means: &self.means,
            log_scales: &self.log_scales,
            rotations: &self.rotations,
            opacity_logits: self
                .opacity_logits
                .as_deref()
                .unwrap_or(&canonical.opacity_logits),
            sh: self.sh.as_deref().unwrap_or(&canonical.sh),
        }
    }

    /// Owned deformed Gaussians (for export).
    pub fn into_gaussians(self, canonical: &Gaussians) -> Gaussians {
        Gaussians {
            sh_degree: canonical.sh_degree,
            means: self.means,
            log_scales: self.log_scales,
            rotations: self.rotations,
            opacity_logits: self
                .opacity_logits
                .unwrap_or_else(|| canonical.opacity_logits.clone()),
            sh: self.sh.unwrap_or_else(|| canonical.sh.clone()),
        }
    }
}

/// dL/d(deformation) rows (N × [`DEFORM_DIM`]) from the rasterizer's gradients of the deformed
/// parameters (the deformation is added, so these are the same gradients): mean, quaternion,
/// log-scale, opacity logit and the SH DC coefficients (`sh_stride` values per Gaussian).
pub fn deformation_gradient(grads: &GaussianGrads, sh_stride: usize) -> Vec<f32> {
    let mut out = Vec::new();
    deformation_gradient_into(grads, sh_stride, &mut out);
    out
}

/// [`deformation_gradient`] into `out` (cleared first; no allocation once it has held as many
/// rows).
pub fn deformation_gradient_into(grads: &GaussianGrads, sh_stride: usize, out: &mut Vec<f32>) {
    let n = grads.means.len();
    // Every value of every row is written below.
    out.resize(n * DEFORM_DIM, 0.0);
    out.par_chunks_mut(DEFORM_DIM)
        .enumerate()
        .with_min_len(ROWS_PER_TASK)
        .for_each(|(i, row)| {
            let dc = grads.sh.get(i * sh_stride..i * sh_stride + 3);
            let dc = dc.unwrap_or(&[0.0; 3]);
            let opacity = grads.opacity_logits.get(i).copied().unwrap_or(0.0);
            let parts: [&[f32]; 5] = [
                &grads.means[i],
                &grads.rotations[i],
                &grads.log_scales[i],
                &[opacity],
                dc,
            ];
            for (dst, &v) in row.iter_mut().zip(parts.into_iter().flatten()) {
                *dst = v;
            }
        });
}

/// Rows per parallel task of [`deformation_gradient_into`].
const ROWS_PER_TASK: usize = 1024;

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The deformation is added to the raw parameters, so for any per-parameter gradient G the
        /// first-order change of `Σ G·params` under a deformation δ is `deformation_gradient(G)·δ`:
        /// both functions must agree on the order of the 14 components (SH degree 1: only the DC
        /// coefficients are deformed).
        #[test]
        fn gradient_rows_match_the_order_of_the_deformation(
            n in 1usize..6,
            seed in any::<u64>(),
            opacity in any::<bool>(),
            colour in any::<bool>(),
        ) {
            use rand::{RngExt, SeedableRng};
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let mut r = || rng.random_range(-1.0f32..1.0);
            let canonical = Gaussians {
                sh_degree: 1,
                means: (0..n).map(|_| [r(), r(), r()]).collect(),
                log_scales: (0..n).map(|_| [r(), r(), r()]).collect(),
                rotations: (0..n).map(|_| [r(), r(), r(), r()]).collect(),
                opacity_logits: (0..n).map(|_| r()).collect(),
                sh: (0..n * 12).map(|_| r()).collect(),
            };
            let appearance = Appearance { opacity, colour };
            let mut delta: Vec<f32> = (0..n * DEFORM_DIM).map(|_| r()).collect();
            // Columns of components that are off do nothing: zero them for the prediction.
            for row in delta.chunks_exact_mut(DEFORM_DIM) {
                if !opacity { row[OPACITY_COLUMN] = 0.0; }
                if !colour { row[COLOUR_COLUMN..].fill(0.0); }
            }
            let grads = GaussianGrads {
                means: (0..n).map(|_| [r(), r(), r()]).collect(),
                rotations: (0..n).map(|_| [r(), r(), r(), r()]).collect(),
                log_scales: (0..n).map(|_| [r(), r(), r()]).collect(),
                opacity_logits: (0..n).map(|_| r()).collect(),
                sh: (0..n * 12).map(|_| r()).collect(),
                ..GaussianGrads::default()
            };
            let deformed = DeformedGeometry::new(&canonical, Some(&delta), appearance);
            let view = deformed.view(&canonical);
            let dot = |a: &[f32], b: &[f32], c: &[f32]| -> f64 {
                a.iter().zip(b).zip(c).map(|((g, x), y)| f64::from(*g) * f64::from(x - y)).sum()
            };
            let change = dot(grads.means.as_flattened(), view.means.as_flattened(), canonical.means.as_flattened())
                + dot(grads.rotations.as_flattened(), view.rotations.as_flattened(), canonical.rotations.as_flattened())
                + dot(grads.log_scales.as_flattened(), view.log_scales.as_flattened(), canonical.log_scales.as_flattened())
                + dot(&grads.opacity_logits, view.opacity_logits, &canonical.opacity_logits)
                + dot(&grads.sh, view.sh, &canonical.sh);
            let rows = deformation_gradient(&grads, canonical.sh_stride());
            // Into buffers that held twice as many Gaussians, every component deformed: the same.
            let twice = Gaussians {
                sh_degree: 1,
                means: canonical.means.repeat(2),
                log_scales: canonical.log_scales.repeat(2),
                rotations: canonical.rotations.repeat(2),
                opacity_logits: canonical.opacity_logits.repeat(2),
                sh: canonical.sh.repeat(2),
            };
            let every = Appearance { opacity: true, colour: true };
            let mut reused = DeformedGeometry::new(&twice, Some(&delta.repeat(2)), every);
            reused.assign(&canonical, Some(&delta), appearance);
            prop_assert_eq!(&reused, &deformed);
            let mut into = vec![7.0; 2 * rows.len()];
            deformation_gradient_into(&grads, canonical.sh_stride(), &mut into);
            prop_assert_eq!(&into, &rows);
            let predicted: f64 = rows.iter().zip(&delta).map(|(g, d)| f64::from(*g) * f64::from(*d)).sum();
            prop_assert!((change - predicted).abs() < 1e-4, "{change} vs {predicted}");
            prop_assert_eq!(deformed.opacity_logits.is_some(), opacity);
            prop_assert_eq!(deformed.sh.is_some(), colour);
            // Higher SH bands are never deformed.
            for (a, b) in view.sh.chunks_exact(12).zip(canonical.sh.chunks_exact(12)) {
                prop_assert_eq!(&a[3..], &b[3..]);
            }
            let none = DeformedGeometry::new(&canonical, None, appearance);
            prop_assert_eq!(none.view(&canonical).means, &canonical.means[..]);
            prop_assert_eq!(none.into_gaussians(&canonical), canonical.clone());
        }
    }
}
