//! Applying deformation rows to canonical Gaussians, and the way back: the rows' gradient from
//! the gradients of the deformed parameters.
//!
//! A row holds the components of its [`Layout`], in [`Component`] order; each is added to a raw
//! parameter (DESIGN §4.1): mean + Δposition, raw quaternion + Δrotation, log-scale + Δscale,
//! opacity logit + Δopacity and SH DC + Δcolour. A component the layout leaves out is read from
//! the canonical Gaussians; appearance that is not deformed is never copied. Since every
//! component is added, dL/d(row) is the gradient of the deformed parameters themselves, gathered
//! in the row's order ([`deformation_gradient_into`]).
//!
//! D-3DGS adds `d_rotation` to the *normalised* quaternion and `d_scaling` to the *activated*
//! scale (`gaussian_renderer/__init__.py`: `pc.get_rotation + d_rotation`,
//! `pc.get_scaling + d_scaling`). Here both are added to the raw parameters, for every backbone
//! alike (DESIGN §11): a scale offset then stays relative and can never make a scale negative.

use rayon::prelude::*;

use crate::deform::{Component, Layout};
use crate::gaussians::{GaussianGrads, Gaussians, GaussiansView};

/// Rows per parallel task when rows are applied or gathered.
const ROWS_PER_TASK: usize = 1024;

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

/// Where each component sits in a row of a layout (`None` when it is left out).
#[derive(Clone, Copy)]
struct Offsets {
    position: Option<usize>,
    rotation: Option<usize>,
    scale: Option<usize>,
    opacity: Option<usize>,
    colour: Option<usize>,
}

impl Offsets {
    fn of(layout: Layout) -> Self {
        Self {
            position: layout.offset(Component::Position),
            rotation: layout.offset(Component::Rotation),
            scale: layout.offset(Component::Scale),
            opacity: layout.offset(Component::Opacity),
            colour: layout.offset(Component::Colour),
        }
    }
}

/// `base` plus the `K` values of `row` from `offset`, or `base` when the component is left out.
fn add<const K: usize>(base: [f32; K], row: &[f32], offset: Option<usize>) -> [f32; K] {
    match offset {
        Some(o) => std::array::from_fn(|k| base[k] + row[o + k]),
        None => base,
    }
}

impl DeformedGeometry {
    /// Canonical + `rows` (`canonical.len()` rows of `layout.dim()` values, in `layout`'s
    /// order); `None` leaves the canonical Gaussians.
    ///
    /// # Panics
    /// When `rows` does not hold `canonical.len() × layout.dim()` values.
    pub fn new(canonical: &Gaussians, rows: Option<&[f32]>, layout: Layout) -> Self {
        let mut out = Self::default();
        out.assign(canonical, rows, layout);
        out
    }

    /// [`DeformedGeometry::new`] into `self`, reusing its buffers: the same values, with no
    /// allocation once the buffers have held as many Gaussians (the trainer keeps one across
    /// iterations, so it allocates only when densification grows the count).
    ///
    /// # Panics
    /// When `rows` does not hold `canonical.len() × layout.dim()` values.
    pub fn assign(&mut self, canonical: &Gaussians, rows: Option<&[f32]>, layout: Layout) {
        let Some(d) = rows else {
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
        let n = canonical.len();
        let dim = layout.dim();
        assert_eq!(
            d.len(),
            n * dim,
            "deformation rows: {} values for {n} Gaussians of {dim} (`{layout}`)",
            d.len()
        );
        let at = Offsets::of(layout);
        // Every row is written below, in parallel (a layout without geometry has empty rows).
        self.means.resize(n, [0.0; 3]);
        self.rotations.resize(n, [0.0; 4]);
        self.log_scales.resize(n, [0.0; 3]);
        self.means
            .par_iter_mut()
            .zip(self.rotations.par_iter_mut())
            .zip(self.log_scales.par_iter_mut())
            .enumerate()
            .with_min_len(ROWS_PER_TASK)
            .for_each(|(i, ((mean, rotation), log_scale))| {
                let r = &d[i * dim..(i + 1) * dim];
                *mean = add(canonical.means[i], r, at.position);
                *rotation = add(canonical.rotations[i], r, at.rotation);
                *log_scale = add(canonical.log_scales[i], r, at.scale);
            });
        let mut opacity = self.opacity_logits.take().unwrap_or_default();
        if let Some(o) = at.opacity {
            opacity.clear();
            opacity.extend(
                canonical
                    .opacity_logits
                    .iter()
                    .zip(d.chunks_exact(dim))
                    .map(|(v, r)| v + r[o]),
            );
            self.opacity_logits = Some(opacity);
        }
        let mut sh = self.sh.take().unwrap_or_default();
        if let Some(o) = at.colour {
            let stride = canonical.sh_stride();
            sh.clear();
            sh.extend_from_slice(&canonical.sh);
            for (coefficients, r) in sh.chunks_exact_mut(stride).zip(d.chunks_exact(dim)) {
                for c in 0..3 {
                    coefficients[c] += r[o + c];
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

/// dL/d(deformation) rows (N × `layout.dim()`, in `layout`'s order) from the rasterizer's
/// gradients of the deformed parameters (the deformation is added, so these are the same
/// gradients): mean, quaternion, log-scale, opacity logit and the SH DC coefficients
/// (`sh_stride` values per Gaussian), each where the layout holds it.
pub fn deformation_gradient(grads: &GaussianGrads, sh_stride: usize, layout: Layout) -> Vec<f32> {
    let mut out = Vec::new();
    deformation_gradient_into(grads, sh_stride, layout, &mut out);
    out
}

/// [`deformation_gradient`] into `out` (every value written; no allocation once it has held as
/// many rows).
pub fn deformation_gradient_into(
    grads: &GaussianGrads,
    sh_stride: usize,
    layout: Layout,
    out: &mut Vec<f32>,
) {
    let n = grads.means.len();
    let dim = layout.dim();
    out.clear();
    if dim == 0 {
        return;
    }
    // Every value of every row is written below.
    out.resize(n * dim, 0.0);
    out.par_chunks_mut(dim)
        .enumerate()
        .with_min_len(ROWS_PER_TASK)
        .for_each(|(i, row)| {
            let dc = grads.sh.get(i * sh_stride..i * sh_stride + 3);
            let dc = dc.unwrap_or(&[0.0; 3]);
            let opacity = grads.opacity_logits.get(i).copied().unwrap_or(0.0);
            let parts: [(bool, &[f32]); 5] = [
                (layout.position, &grads.means[i]),
                (layout.rotation, &grads.rotations[i]),
                (layout.scale, &grads.log_scales[i]),
                (layout.opacity, &[opacity]),
                (layout.colour, dc),
            ];
            let held = parts.into_iter().filter(|(on, _)| *on);
            for (dst, &v) in row.iter_mut().zip(held.flat_map(|(_, p)| p)) {
                *dst = v;
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The deformation is added to the raw parameters, so for any per-parameter gradient G the
        /// first-order change of `Σ G·params` under a deformation δ is `deformation_gradient(G)·δ`:
        /// both functions must agree on the order of the components of every layout (SH degree
        /// 1: only the DC coefficients are deformed).
        #[test]
        fn gradient_rows_match_the_order_of_the_deformation(
            n in 1usize..6,
            seed in any::<u64>(),
            bits in 1u8..32,
        ) {
            use rand::{RngExt, SeedableRng};
            let layout = Layout::from_bits(bits).unwrap();
            let dim = layout.dim();
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
            let delta: Vec<f32> = (0..n * dim).map(|_| r()).collect();
            let grads = GaussianGrads {
                means: (0..n).map(|_| [r(), r(), r()]).collect(),
                rotations: (0..n).map(|_| [r(), r(), r(), r()]).collect(),
                log_scales: (0..n).map(|_| [r(), r(), r()]).collect(),
                opacity_logits: (0..n).map(|_| r()).collect(),
                sh: (0..n * 12).map(|_| r()).collect(),
                ..GaussianGrads::default()
            };
            let deformed = DeformedGeometry::new(&canonical, Some(&delta), layout);
            let view = deformed.view(&canonical);
            let dot = |a: &[f32], b: &[f32], c: &[f32]| -> f64 {
                a.iter().zip(b).zip(c).map(|((g, x), y)| f64::from(*g) * f64::from(x - y)).sum()
            };
            let change = dot(grads.means.as_flattened(), view.means.as_flattened(), canonical.means.as_flattened())
                + dot(grads.rotations.as_flattened(), view.rotations.as_flattened(), canonical.rotations.as_flattened())
                + dot(grads.log_scales.as_flattened(), view.log_scales.as_flattened(), canonical.log_scales.as_flattened())
                + dot(&grads.opacity_logits, view.opacity_logits, &canonical.opacity_logits)
                + dot(&grads.sh, view.sh, &canonical.sh);
            let rows = deformation_gradient(&grads, canonical.sh_stride(), layout);
            prop_assert_eq!(rows.len(), n * dim);
            // Into buffers that held twice as many Gaussians of every component: the same.
            let twice = Gaussians {
                sh_degree: 1,
                means: canonical.means.repeat(2),
                log_scales: canonical.log_scales.repeat(2),
                rotations: canonical.rotations.repeat(2),
                opacity_logits: canonical.opacity_logits.repeat(2),
                sh: canonical.sh.repeat(2),
            };
            let wide: Vec<f32> = (0..2 * n * Layout::MAX_DIM).map(|_| r()).collect();
            let mut reused = DeformedGeometry::new(&twice, Some(&wide), Layout::ALL);
            reused.assign(&canonical, Some(&delta), layout);
            prop_assert_eq!(&reused, &deformed);
            let mut into = vec![7.0; 2 * n * Layout::MAX_DIM];
            deformation_gradient_into(&grads, canonical.sh_stride(), layout, &mut into);
            prop_assert_eq!(&into, &rows);
            let predicted: f64 = rows.iter().zip(&delta).map(|(g, d)| f64::from(*g) * f64::from(*d)).sum();
            prop_assert!((change - predicted).abs() < 1e-4, "{change} vs {predicted}");
            prop_assert_eq!(deformed.opacity_logits.is_some(), layout.opacity);
            prop_assert_eq!(deformed.sh.is_some(), layout.colour);
            // Components the layout leaves out are the canonical values, bit for bit.
            if !layout.position { prop_assert_eq!(view.means, &canonical.means[..]); }
            if !layout.rotation { prop_assert_eq!(view.rotations, &canonical.rotations[..]); }
            if !layout.scale { prop_assert_eq!(view.log_scales, &canonical.log_scales[..]); }
            // Higher SH bands are never deformed.
            for (a, b) in view.sh.chunks_exact(12).zip(canonical.sh.chunks_exact(12)) {
                prop_assert_eq!(&a[3..], &b[3..]);
            }
            let none = DeformedGeometry::new(&canonical, None, layout);
            prop_assert_eq!(none.view(&canonical).means, &canonical.means[..]);
            prop_assert_eq!(none.into_gaussians(&canonical), canonical.clone());
        }
    }

    #[test]
    #[should_panic(expected = "deformation rows")]
    fn rows_of_another_width_are_refused() {
        let g = Gaussians {
            sh_degree: 0,
            means: vec![[0.0; 3]],
            log_scales: vec![[0.0; 3]],
            rotations: vec![[1.0, 0.0, 0.0, 0.0]],
            opacity_logits: vec![0.0],
            sh: vec![0.0; 3],
        };
        DeformedGeometry::new(&g, Some(&[0.0; Layout::MAX_DIM]), Layout::GEOMETRY);
    }
}
