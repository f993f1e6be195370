//! Tri-plane spatial encoder (K-Planes / HexPlane style, space planes only).
//!
//! Positions are normalised by the box to `q = 2 (p - min) / (max - min) - 1` and clamped to
//! `[-1, 1]` (a clamped coordinate has zero gradient). Three planes of `C` channels, XY, XZ and
//! YZ, exist at every resolution `R` (R × R texels, `R >= 2`). A plane over axes (a, b) is sampled
//! bilinearly at `((q_a + 1)/2 ·, (q_b + 1)/2 · )` (texel centres on the corners of the
//! box, `align_corners = True`); the cell index is clamped to `R-2` so the upper border uses the
//! last cell with weight 1.
//!
//! Combination, selectable: [`PlaneCombine::Concat`] gives per resolution `[f_XY, f_XZ, f_YZ]`
//! (`3C` values); [`PlaneCombine::Product`] gives the element-wise product `f_XY ⊙ f_XZ ⊙ f_YZ`
//! (`C` values, K-Planes). Resolutions follow one another in the output row.
//!
//! Parameters: per resolution, per plane (XY, XZ, YZ), row-major `[R (b)][R (a)][C]`.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use crate::reduce::{add_into, fold_in_order};

use super::{ENC_ROWS, dot};
use crate::error::{NnError, check_len};
use crate::precision::{Precision, Store, StoreMut, StoreRef};

/// How the three planes of one resolution are combined.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PlaneCombine {
    /// Concatenate the three planes' features (3C per resolution).
    Concat,
    /// Multiply the three planes' features element-wise (C per resolution).
    Product,
}

/// Bits per axis of the cells of [`TriPlane::spatial_order`].
const ORDER_BITS: usize = 4;
/// Cells per axis of [`TriPlane::spatial_order`] (16: 4 × 4 texels of a 64² plane per cell).
const ORDER_CELLS: usize = 1 << ORDER_BITS;

/// The planes' axes (a, b): XY, XZ, YZ.
const PLANE_AXES: [(usize, usize); 3] = [(0, 1), (0, 2), (1, 2)];

/// Settings of a [`TriPlane`].
#[derive(Clone, Debug, PartialEq)]
pub struct TriPlaneConfig {
    /// Channels per plane.
    pub channels: usize,
    /// Plane resolutions (each >= 2).
    pub resolutions: Vec<usize>,
    /// Combination of the planes.
    pub combine: PlaneCombine,
    /// Lower corner of the box mapped to -1.
    pub box_min: [f32; 3],
    /// Upper corner of the box mapped to +1.
    pub box_max: [f32; 3],
    /// Initial values are uniform in this range: (0.1, 0.5) for products (K-Planes), (-0.1, 0.1)
    /// for concatenation by default.
    pub init_range: (f32, f32),
    /// Storage precision of the planes.
    pub precision: Precision,
    /// Seed of the initialisation.
    pub seed: u64,
}

impl TriPlaneConfig {
    /// `channels` channels at the given resolutions over the box `[-1, 1]³`, f32, seed 0.
    pub fn new(channels: usize, resolutions: &[usize], combine: PlaneCombine) -> Self {
        Self {
            channels,
            resolutions: resolutions.to_vec(),
            combine,
            box_min: [-1.0; 3],
            box_max: [1.0; 3],
            init_range: match combine {
                PlaneCombine::Product => (0.1, 0.5),
                PlaneCombine::Concat => (-0.1, 0.1),
            },
            precision: Precision::F32,
            seed: 0,
        }
    }
    /// Sets the normalisation box.
    pub fn bounds(mut self, min: [f32; 3], max: [f32; 3]) -> Self {
        self.box_min = min;
        self.box_max = max;
        self
    }
    /// Sets the storage precision.
    pub fn precision(mut self, p: Precision) -> Self {
        self.precision = p;
        self
    }
    /// Sets the seed.
    pub fn seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }
    /// Sets the initialisation range.
    pub fn init_range(mut self, lo: f32, hi: f32) -> Self {
        self.init_range = (lo, hi);
        self
    }
    /// Builds the encoder.
    pub fn build(self) -> Result<TriPlane, NnError> {
        TriPlane::new(self)
    }
}

/// The tri-plane encoder.
#[derive(Clone, Debug)]
pub struct TriPlane {
    config: TriPlaneConfig,
    /// Offset of plane `k` of resolution `r` at `offsets[3r + k]`.
    offsets: Vec<usize>,
    params: Store,
}

/// What [`TriPlane::forward`] keeps for backward: the positions.
#[derive(Clone, Debug)]
pub struct TriPlaneCache {
    rows: usize,
    positions: Vec<f32>,
}

/// Gradients from [`TriPlane::backward`].
#[derive(Clone, Debug, PartialEq)]
pub struct TriPlaneGrads {
    /// dL/d(planes), laid out as the parameter buffer.
    pub params: Vec<f32>,
    /// dL/d(positions), rows × 3 (when asked for).
    pub positions: Option<Vec<f32>>,
}

/// One bilinear lookup: the four texel offsets (in values) and the weights, plus the derivative
/// factors of the weights along a and b.
struct Lookup {
    idx: [usize; 4],
    w: [f32; 4],
    /// d(weights)/d(q_a) and d(weights)/d(q_b).
    dwa: [f32; 4],
    dwb: [f32; 4],
}

impl TriPlane {
    /// Builds and initialises the encoder.
    pub fn new(config: TriPlaneConfig) -> Result<Self, NnError> {
        if config.channels == 0 || config.resolutions.is_empty() {
            return Err(NnError::Config(
                "tri-plane needs channels > 0 and a resolution".into(),
            ));
        }
        if let Some(r) = config.resolutions.iter().find(|&&r| r < 2) {
            return Err(NnError::Config(format!("tri-plane resolution {r} < 2")));
        }
        for a in 0..3 {
            let (lo, hi) = (config.box_min[a], config.box_max[a]);
            if !(lo.is_finite() && hi.is_finite() && hi > lo) {
                return Err(NnError::Config(format!(
                    "tri-plane box axis {a}: [{lo}, {hi}] is not a finite non-empty interval"
                )));
            }
        }
        let mut offsets = Vec::new();
        let mut total = 0;
        for &r in &config.resolutions {
            for _ in 0..3 {
                offsets.push(total);
                total += r * r * config.channels;
            }
        }
        let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
        let (lo, hi) = config.init_range;
        let values: Vec<f32> = (0..total)
            .map(|_| {
                if hi > lo {
                    rng.random_range(lo..hi)
                } else {
                    lo
                }
            })
            .collect();
        let (params, _) = Store::from_f32(config.precision, &values);
        Ok(Self {
            config,
            offsets,
            params,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &TriPlaneConfig {
        &self.config
    }
    /// Features per row.
    pub fn output_width(&self) -> usize {
        let per = match self.config.combine {
            PlaneCombine::Concat => 3 * self.config.channels,
            PlaneCombine::Product => self.config.channels,
        };
        per * self.config.resolutions.len()
    }
    /// Number of parameters.
    pub fn param_count(&self) -> usize {
        self.params.len()
    }
    /// Offset of plane `plane` (0 = XY, 1 = XZ, 2 = YZ) of resolution index `res`.
    pub fn plane_offset(&self, res: usize, plane: usize) -> usize {
        self.offsets[3 * res + plane]
    }
    /// The parameters (read-only).
    pub fn params(&self) -> StoreRef<'_> {
        self.params.as_ref()
    }
    /// The parameters, for an optimiser step.
    pub fn params_mut(&mut self) -> StoreMut<'_> {
        self.params.as_mut()
    }
    /// Replaces the parameters from f32 values; returns the saturation count.
    pub fn set_params(&mut self, values: &[f32]) -> Result<u64, NnError> {
        check_len("tri-plane parameters", self.params.len(), values.len())?;
        Ok(self.params.as_mut().write_from(values))
    }

    /// Normalised, clamped coordinates and whether each axis was inside the box.
    #[inline(always)]
    fn normalise(&self, p: &[f32]) -> ([f32; 3], [f32; 3]) {
        let mut q = [0f32; 3];
        let mut dq = [0f32; 3];
        for a in 0..3 {
            let (lo, hi) = (self.config.box_min[a], self.config.box_max[a]);
            let s = 2.0 / (hi - lo);
            let v = (p[a] - lo) * s - 1.0;
            if (-1.0..=1.0).contains(&v) {
                q[a] = v;
                dq[a] = s;
            } else {
                q[a] = v.clamp(-1.0, 1.0);
            }
        }
        (q, dq)
    }

    #[inline(always)]
    fn lookup(res: usize, c: usize, qa: f32, qb: f32) -> Lookup {
        let half = 0.5 * (res - 1) as f32;
        let fa = (qa + 1.0) * half;
        let fb = (qb + 1.0) * half;
        let ia = (fa.floor() as usize).min(res - 2);
        let ib = (fb.floor() as usize).min(res - 2);
        let (ua, ub) = (fa - ia as f32, fb - ib as f32);
        let base = (ib * res + ia) * c;
        Lookup {
            idx: [base, base + c, base + res * c, base + (res + 1) * c],
            w: [
                (1.0 - ua) * (1.0 - ub),
                ua * (1.0 - ub),
                (1.0 - ua) * ub,
                ua * ub,
            ],
            dwa: [-(1.0 - ub) * half, (1.0 - ub) * half, -ub * half, ub * half],
            dwb: [-(1.0 - ua) * half, -ua * half, (1.0 - ua) * half, ua * half],
        }
    }

    /// Writes into `order` a permutation of the rows of `positions` (rows × 3, already checked)
    /// that visits them in space-filling-curve order: the normalised box is cut into
    /// [`ORDER_CELLS`]³ cells, cells are taken in Morton (Z) order, and rows inside a cell keep
    /// their input order (a stable counting sort, so the order is a function of the positions
    /// alone). Rows that follow one another then sample nearby texels in all three planes, so
    /// a block of rows reuses the texels (and their gradients) it brings into cache.
    pub(crate) fn spatial_order(&self, positions: &[f32], order: &mut Vec<usize>) {
        let rows = positions.len() / 3;
        let cell_from_q =
            |v: f32| (((v + 1.0) * 0.5 * ORDER_CELLS as f32) as usize).min(ORDER_CELLS - 1);
        let keys: Vec<u16> = positions
            .chunks_exact(3)
            .map(|p| {
                let (q, _) = self.normalise(p);
                let mut key = 0u16;
                for (axis, &v) in q.iter().enumerate() {
                    let cell = cell_from_q(v);
                    for bit in 0..ORDER_BITS {
                        key |= (((cell >> bit) & 1) as u16) << (3 * bit + axis);
                    }
                }
                key
            })
            .collect();
        let mut start_from_key = vec![0usize; ORDER_CELLS.pow(3) + 1];
        for &k in &keys {
            start_from_key[k as usize + 1] += 1;
        }
        for k in 1..start_from_key.len() {
            start_from_key[k] += start_from_key[k - 1];
        }
        order.clear();
        order.resize(rows, 0);
        for (r, &k) in keys.iter().enumerate() {
            let slot = &mut start_from_key[k as usize];
            order[*slot] = r;
            *slot += 1;
        }
    }

    /// Checks shapes and finiteness of positions.
    pub(crate) fn check_positions(&self, positions: &[f32], rows: usize) -> Result<(), NnError> {
        check_len("tri-plane positions", rows * 3, positions.len())?;
        if let Some(i) = positions.iter().position(|v| !v.is_finite()) {
            return Err(NnError::Config(format!(
                "tri-plane positions: row {} has a non-finite coordinate",
                i / 3
            )));
        }
        Ok(())
    }

    /// The planes as f32 (a copy; f16 storage is widened once per pass).
    pub(crate) fn planes_f32(&self) -> std::borrow::Cow<'_, [f32]> {
        self.params.as_f32()
    }

    /// Encodes one position `p` (3 values) into `out` (output width); `feat` is scratch of `3C`.
    #[inline(always)]
    pub(crate) fn encode_row(&self, planes: &[f32], p: &[f32], out: &mut [f32], feat: &mut [f32]) {
        let c = self.config.channels;
        let (q, _) = self.normalise(p);
        for (r, &res) in self.config.resolutions.iter().enumerate() {
            for (k, &(a, b)) in PLANE_AXES.iter().enumerate() {
                let lk = Self::lookup(res, c, q[a], q[b]);
                let off = self.offsets[3 * r + k];
                sample(planes, off, &lk, &mut feat[k * c..(k + 1) * c]);
            }
            match self.config.combine {
                PlaneCombine::Concat => out[r * 3 * c..(r + 1) * 3 * c].copy_from_slice(feat),
                PlaneCombine::Product => {
                    let (f0, rest) = feat.split_at(c);
                    let (f1, f2) = rest.split_at(c);
                    for (ch, o) in out[r * c..(r + 1) * c].iter_mut().enumerate() {
                        *o = f0[ch] * f1[ch] * f2[ch];
                    }
                }
            }
        }
    }

    /// Backward of one row: adds dL/d(planes) into `acc` and returns dL/d(position). `go` is the
    /// row's output gradient; `feat` and `dfeat` are scratch of `3C`.
    #[inline(always)]
    pub(crate) fn backward_row(
        &self,
        planes: &[f32],
        p: &[f32],
        go: &[f32],
        acc: &mut [f32],
        feat: &mut [f32],
        dfeat: &mut [f32],
    ) -> [f32; 3] {
        let c = self.config.channels;
        let (q, dq) = self.normalise(p);
        let mut gq = [0f32; 3];
        for (r, &res) in self.config.resolutions.iter().enumerate() {
            let lks: [Lookup; 3] = std::array::from_fn(|k| {
                let (a, b) = PLANE_AXES[k];
                Self::lookup(res, c, q[a], q[b])
            });
            match self.config.combine {
                PlaneCombine::Concat => {
                    dfeat.copy_from_slice(&go[r * 3 * c..(r + 1) * 3 * c]);
                }
                PlaneCombine::Product => {
                    for (k, lk) in lks.iter().enumerate() {
                        let off = self.offsets[3 * r + k];
                        sample(planes, off, lk, &mut feat[k * c..(k + 1) * c]);
                    }
                    for ch in 0..c {
                        let g = go[r * c + ch];
                        let (f0, f1, f2) = (feat[ch], feat[c + ch], feat[2 * c + ch]);
                        dfeat[ch] = g * f1 * f2;
                        dfeat[c + ch] = g * f0 * f2;
                        dfeat[2 * c + ch] = g * f0 * f1;
                    }
                }
            }
            for (k, lk) in lks.iter().enumerate() {
                let off = self.offsets[3 * r + k];
                let df = &dfeat[k * c..(k + 1) * c];
                let (a, b) = PLANE_AXES[k];
                for corner in 0..4 {
                    let base = off + lk.idx[corner];
                    let wt = lk.w[corner];
                    for (ac, &d) in acc[base..base + c].iter_mut().zip(df) {
                        *ac += wt * d;
                    }
                    let dot = dot(&planes[base..base + c], df);
                    gq[a] += lk.dwa[corner] * dot;
                    gq[b] += lk.dwb[corner] * dot;
                }
            }
        }
        [gq[0] * dq[0], gq[1] * dq[1], gq[2] * dq[2]]
    }

    /// Encodes `rows` positions (rows × 3). Errors on non-finite positions.
    pub fn forward(
        &self,
        positions: &[f32],
        rows: usize,
    ) -> Result<(Vec<f32>, TriPlaneCache), NnError> {
        self.check_positions(positions, rows)?;
        let w = self.output_width();
        let planes = self.planes_f32();
        let mut out = vec![0f32; rows * w];
        out.par_chunks_mut(ENC_ROWS * w)
            .zip(positions.par_chunks(ENC_ROWS * 3))
            .for_each(|(o, ps)| {
                let mut feat = vec![0f32; 3 * self.config.channels];
                for (orow, p) in o.chunks_exact_mut(w).zip(ps.chunks_exact(3)) {
                    self.encode_row(&planes, p, orow, &mut feat);
                }
            });
        Ok((
            out,
            TriPlaneCache {
                rows,
                positions: positions.to_vec(),
            },
        ))
    }

    /// Backward: `d_out` is dL/d(features) (rows × output width).
    pub fn backward(
        &self,
        cache: &TriPlaneCache,
        d_out: &[f32],
        want_position_grad: bool,
    ) -> Result<TriPlaneGrads, NnError> {
        let rows = cache.rows;
        let w = self.output_width();
        check_len("tri-plane output gradient", rows * w, d_out.len())?;
        let c = self.config.channels;
        let planes = self.planes_f32();
        let n_params = self.params.len();
        let mut d_pos = want_position_grad.then(|| vec![0f32; rows * 3]);
        let n_blocks = rows.div_ceil(ENC_ROWS);
        let dp_blocks: Vec<Option<&mut [f32]>> = match d_pos.as_mut() {
            Some(v) => v.chunks_mut(ENC_ROWS * 3).map(Some).collect(),
            None => (0..n_blocks).map(|_| None).collect(),
        };
        let params = fold_in_order(
            dp_blocks,
            || vec![0f32; n_params],
            |mut acc, (blk, mut dp)| {
                let r0 = blk * ENC_ROWS;
                let nr = ENC_ROWS.min(rows - r0);
                let mut feat = vec![0f32; 3 * c];
                let mut dfeat = vec![0f32; 3 * c];
                for i in 0..nr {
                    let row = r0 + i;
                    let g = self.backward_row(
                        &planes,
                        &cache.positions[row * 3..row * 3 + 3],
                        &d_out[row * w..(row + 1) * w],
                        &mut acc,
                        &mut feat,
                        &mut dfeat,
                    );
                    if let Some(dp) = dp.as_mut() {
                        dp[i * 3..i * 3 + 3].copy_from_slice(&g);
                    }
                }
                acc
            },
            add_into,
        );
        Ok(TriPlaneGrads {
            params,
            positions: d_pos,
        })
    }
}

/// Bilinear sample of `c = out.len()` channels.
#[inline(always)]
fn sample(planes: &[f32], off: usize, lk: &Lookup, out: &mut [f32]) {
    out.fill(0.0);
    let c = out.len();
    for corner in 0..4 {
        let base = off + lk.idx[corner];
        let wt = lk.w[corner];
        for (o, &p) in out.iter_mut().zip(&planes[base..base + c]) {
            *o += wt * p;
        }
    }
}

impl crate::weights::Parameters for TriPlane {
    fn named_params(&self) -> Vec<(String, StoreRef<'_>)> {
        vec![("planes".to_string(), self.params.as_ref())]
    }
    fn named_params_mut(&mut self) -> Vec<(String, StoreMut<'_>)> {
        vec![("planes".to_string(), self.params.as_mut())]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn cell(v: f32) -> usize {
        (((v + 1.0) * 0.5 * ORDER_CELLS as f32) as usize).min(ORDER_CELLS - 1)
    }

    proptest! {
        /// The order is a permutation that never steps back along the Morton curve of cells and
        /// keeps input order inside a cell; positions outside the box fall in the border cells.
        #[test]
        fn spatial_order_is_a_stable_morton_sort(
            pts in proptest::collection::vec(-1.5f32..1.5, 0..600),
        ) {
            let tp = TriPlaneConfig::new(2, &[4], PlaneCombine::Concat).build().unwrap();
            let rows = pts.len() / 3;
            let positions = &pts[..rows * 3];
            let mut order = vec![7; 3];
            tp.spatial_order(positions, &mut order);
            let mut seen = order.clone();
            seen.sort_unstable();
            prop_assert_eq!(seen, (0..rows).collect::<Vec<_>>());
            // Morton key from the definition: bit b of axis a at position 3b + a.
            let key = |r: usize| {
                (0..3).map(|a| {
                    let c = cell(positions[r * 3 + a].clamp(-1.0, 1.0));
                    (0..ORDER_BITS).map(|b| ((c >> b) & 1) << (3 * b + a)).sum::<usize>()
                }).sum::<usize>()
            };
            for w in order.windows(2) {
                let (ka, kb) = (key(w[0]), key(w[1]));
                prop_assert!(ka < kb || (ka == kb && w[0] < w[1]), "{:?}", w);
            }
        }
    }
}
