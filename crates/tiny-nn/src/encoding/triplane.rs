//! Tri-plane encoder (K-Planes), and with a time axis the HexPlane of 4DGaussians.
//!
//! Positions are normalised by the box to `q = 2 (p - min) / (max - min) - 1` and clamped to
//! `[-1, 1]` (a clamped coordinate has zero gradient). Without a time axis the input rows are
//! `(x, y, z)` and there are three planes of `C` channels, XY, XZ and YZ, at every scale. With a
//! [`TimeAxis`] the rows are `(x, y, z, t)`, `t` is normalised the same way by the axis' `[min,
//! max]`, and there are six planes in 4DGaussians' order (`itertools.combinations(range(4), 2)`):
//! XY, XZ, XT, YZ, YT, ZT.
//!
//! A plane over axes (a, b) has `R_a × R_b` texels: a space axis has the scale's resolution `R`
//! (from [`TriPlaneConfig::resolutions`], one per scale, each >= 2), the time axis the same
//! [`TimeAxis::resolution`] at every scale (4DGaussians multiplies only the space resolutions by
//! its `multires`). The plane is sampled bilinearly at `((q_a + 1)/2 · (R_a-1), (q_b + 1)/2 ·
//! (R_b-1))` (texel centres on the corners of the box, `align_corners = True`, border padding);
//! the cell index is clamped to `R-2` so the upper border uses the last cell with weight 1.
//!
//! Combination, selectable: [`PlaneCombine::Concat`] gives per scale the planes' features one
//! after the other (`3C` or `6C` values); [`PlaneCombine::Product`] gives their element-wise
//! product (`C` values, K-Planes and HexPlane). Scales follow one another in the output row.
//!
//! Parameters: per scale, per plane in the order above, row-major `[R_b][R_a][C]` (the layout of
//! a PyTorch `[1, C, R_b, R_a]` grid, channel-last). Space planes start uniform in
//! [`TriPlaneConfig::init_range`], space-time planes at [`TimeAxis::init`] (4DGaussians: 1).
//!
//! Regularisers of the planes ([`TriPlane::regularise`], value and gradient): 4DGaussians'
//! smoothness (mean squared second difference along a plane's second axis `b`) on the space
//! planes or on the space-time planes, and its L1 distance of space-time planes from 1.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use strum::{Display, EnumString, IntoStaticStr, VariantNames};

use crate::reduce::{add_into, fold_in_order};

use super::{ENC_ROWS, dot};
use crate::error::{NnError, check_len};
use crate::precision::{Precision, Store, StoreMut, StoreRef};

/// How the planes of one scale are combined.
///
/// Spelled `concat` / `product` on the command line (`FromStr`, `Display`, derived with `strum`)
/// and, with the `serde` feature, in files.
#[derive(EnumString, Display, IntoStaticStr, VariantNames)]
#[strum(serialize_all = "lowercase", parse_err_ty = PlaneCombineParseError, parse_err_fn = PlaneCombineParseError::new)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(rename_all = "lowercase")
)]
pub enum PlaneCombine {
    /// Concatenate the planes' features (3C or 6C per scale).
    Concat,
    /// Multiply the planes' features element-wise (C per scale).
    Product,
}

/// A plane-combination spelling other than `concat` and `product`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown value `{0}`; expected one of {expected}", expected = PlaneCombine::VARIANTS.join(", "))]
pub struct PlaneCombineParseError(pub String);

impl PlaneCombineParseError {
    fn new(value: &str) -> Self {
        Self(value.to_string())
    }
}

/// Bits per axis of the cells of [`TriPlane::spatial_order`].
const ORDER_BITS: usize = 4;
/// Cells per axis of [`TriPlane::spatial_order`] (16: 4 × 4 texels of a 64² plane per cell).
const ORDER_CELLS: usize = 1 << ORDER_BITS;

/// Most input axes (x, y, z, t).
const MAX_AXES: usize = 4;
/// Most planes per scale.
const MAX_PLANES: usize = 6;
/// The planes' axes (a, b) without a time axis: XY, XZ, YZ.
const TRI_AXES: [(usize, usize); 3] = [(0, 1), (0, 2), (1, 2)];
/// The planes' axes (a, b) with a time axis (3 = t), in 4DGaussians' order: XY, XZ, XT, YZ, YT,
/// ZT.
const HEX_AXES: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];

/// The time axis of a HexPlane.
#[derive(Clone, Debug, PartialEq)]
pub struct TimeAxis {
    /// Texels along t in every space-time plane (>= 2), the same at every scale.
    pub resolution: usize,
    /// Time mapped to -1.
    pub min: f32,
    /// Time mapped to +1.
    pub max: f32,
    /// Initial value of every space-time texel (4DGaussians: 1, so that a product starts as the
    /// product of the space planes).
    pub init: f32,
}

impl TimeAxis {
    /// `resolution` texels over `[min, max]`, space-time texels initialised to 1.
    pub fn new(resolution: usize, min: f32, max: f32) -> Self {
        Self {
            resolution,
            min,
            max,
            init: 1.0,
        }
    }
}

/// Which regulariser [`TriPlane::regularise`] evaluates (4DGaussians' `compute_regulation`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PlaneRegulariser {
    /// Mean squared second difference along axis b of each space plane (XY along y, XZ and YZ
    /// along z), summed over planes and scales: 4DGaussians' `_plane_regulation`, weighted by
    /// its `plane_tv_weight`.
    SpaceSmoothness,
    /// The same on the space-time planes, along t: `_time_regulation`, weighted by
    /// `time_smoothness_weight`.
    TimeSmoothness,
    /// Mean `|1 - texel|` of each space-time plane, summed: `_l1_regulation`, weighted by
    /// `l1_time_planes`.
    TimeL1,
}

/// Settings of a [`TriPlane`].
#[derive(Clone, Debug, PartialEq)]
pub struct TriPlaneConfig {
    /// Channels per plane.
    pub channels: usize,
    /// Space resolution of each scale (each >= 2).
    pub resolutions: Vec<usize>,
    /// Combination of the planes.
    pub combine: PlaneCombine,
    /// Lower corner of the box mapped to -1.
    pub box_min: [f32; 3],
    /// Upper corner of the box mapped to +1.
    pub box_max: [f32; 3],
    /// Initial values of the space planes are uniform in this range: (0.1, 0.5) for products
    /// (K-Planes, 4DGaussians), (-0.1, 0.1) for concatenation by default.
    pub init_range: (f32, f32),
    /// The time axis: `Some` makes the encoder a HexPlane over `(x, y, z, t)`.
    pub time: Option<TimeAxis>,
    /// Storage precision of the planes.
    pub precision: Precision,
    /// Seed of the initialisation.
    pub seed: u64,
}

impl TriPlaneConfig {
    /// `channels` channels at the given resolutions over the box `[-1, 1]³`, no time axis, f32,
    /// seed 0.
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
            time: None,
            precision: Precision::F32,
            seed: 0,
        }
    }
    /// Sets the normalisation box.
    #[must_use]
    pub fn bounds(mut self, min: [f32; 3], max: [f32; 3]) -> Self {
        self.box_min = min;
        self.box_max = max;
        self
    }
    /// Adds a time axis (a HexPlane).
    #[must_use]
    pub fn time(mut self, axis: TimeAxis) -> Self {
        self.time = Some(axis);
        self
    }
    /// Sets the storage precision.
    #[must_use]
    pub fn precision(mut self, p: Precision) -> Self {
        self.precision = p;
        self
    }
    /// Sets the seed.
    #[must_use]
    pub fn seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }
    /// Sets the initialisation range.
    #[must_use]
    pub fn init_range(mut self, lo: f32, hi: f32) -> Self {
        self.init_range = (lo, hi);
        self
    }
    /// Builds the encoder.
    pub fn build(self) -> Result<TriPlane, NnError> {
        TriPlane::new(self)
    }

    /// The planes' axes of one scale: the three space planes, or with a time axis the six
    /// planes of a HexPlane.
    fn axes(&self) -> &'static [(usize, usize)] {
        if self.time.is_some() {
            &HEX_AXES
        } else {
            &TRI_AXES
        }
    }

    /// Features per row (what [`TriPlane::output_width`] returns once built).
    pub fn output_width(&self) -> usize {
        let per = match self.combine {
            PlaneCombine::Concat => self.axes().len() * self.channels,
            PlaneCombine::Product => self.channels,
        };
        per * self.resolutions.len()
    }

    /// The parameters the encoder will have, without allocating them (checked arithmetic: an
    /// overflow is an error).
    pub fn param_count(&self) -> Result<usize, NnError> {
        Ok(self.plane_layout()?.1)
    }

    /// Each plane's offset in the parameter buffer (scale by scale, planes in the order of
    /// [`TriPlane::plane_axes`]) and the buffer's length.
    fn plane_layout(&self) -> Result<(Vec<usize>, usize), NnError> {
        let too_large = || NnError::Config("tri-plane parameter count overflows".into());
        let time_res = self.time.as_ref().map_or(0, |t| t.resolution);
        let mut offsets = Vec::with_capacity(self.resolutions.len() * self.axes().len());
        let mut total: usize = 0;
        for &r in &self.resolutions {
            for &(a, b) in self.axes() {
                let res = |axis: usize| if axis == 3 { time_res } else { r };
                offsets.push(total);
                let n = res(a)
                    .checked_mul(res(b))
                    .and_then(|n| n.checked_mul(self.channels))
                    .ok_or_else(too_large)?;
                total = total.checked_add(n).ok_or_else(too_large)?;
            }
        }
        Ok((offsets, total))
    }
}

/// The tri-plane (or, with a time axis, HexPlane) encoder.
#[derive(Clone, Debug)]
pub struct TriPlane {
    config: TriPlaneConfig,
    /// The planes' axes of one scale.
    axes: &'static [(usize, usize)],
    /// Lower end and `2 / (max - min)` of each input axis.
    lo: [f32; MAX_AXES],
    scale: [f32; MAX_AXES],
    /// Offset of plane `k` of scale `r` at `offsets[planes · r + k]`.
    offsets: Vec<usize>,
    params: Store,
}

/// What [`TriPlane::forward`] keeps for backward: the inputs.
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
    /// dL/d(inputs), rows × 3 (rows × 4 with a time axis), when asked for.
    pub positions: Option<Vec<f32>>,
}

/// One bilinear lookup: the four texel offsets (in values) and the weights, plus the derivative
/// factors of the weights along a and b.
#[derive(Clone, Copy, Default)]
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
        let mut lo = [0f32; MAX_AXES];
        let mut scale = [0f32; MAX_AXES];
        let mut interval = |a: usize, min: f32, max: f32, name: &str| {
            if !(min.is_finite() && max.is_finite() && max > min) {
                return Err(NnError::Config(format!(
                    "tri-plane {name}: [{min}, {max}] is not a finite non-empty interval"
                )));
            }
            lo[a] = min;
            scale[a] = 2.0 / (max - min);
            Ok(())
        };
        for a in 0..3 {
            interval(
                a,
                config.box_min[a],
                config.box_max[a],
                &format!("box axis {a}"),
            )?;
        }
        if let Some(t) = &config.time {
            if t.resolution < 2 || !t.init.is_finite() {
                return Err(NnError::Config(format!(
                    "tri-plane time axis: resolution {} < 2 or initial value {} not finite",
                    t.resolution, t.init
                )));
            }
            interval(3, t.min, t.max, "time axis")?;
        }
        let axes = config.axes();
        let (offsets, total) = config.plane_layout()?;
        // Whether each value belongs to a plane with a time axis (those start at the time
        // axis's initial value).
        let mut is_time = Vec::with_capacity(total);
        for (k, &start) in offsets.iter().enumerate() {
            let end = offsets.get(k + 1).copied().unwrap_or(total);
            is_time.extend(std::iter::repeat_n(
                axes[k % axes.len()].1 == 3,
                end - start,
            ));
        }
        let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
        let (lo_init, hi_init) = config.init_range;
        let time_init = config.time.as_ref().map_or(0.0, |t| t.init);
        let values: Vec<f32> = is_time
            .iter()
            .map(|&t| {
                if t {
                    time_init
                } else if hi_init > lo_init {
                    rng.random_range(lo_init..hi_init)
                } else {
                    lo_init
                }
            })
            .collect();
        let (params, _) = Store::from_f32(config.precision, &values);
        Ok(Self {
            config,
            axes,
            lo,
            scale,
            offsets,
            params,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &TriPlaneConfig {
        &self.config
    }
    /// Values per input row: 3, or 4 with a time axis.
    pub fn dims(&self) -> usize {
        if self.config.time.is_some() { 4 } else { 3 }
    }
    /// Planes per scale: 3, or 6 with a time axis.
    pub fn planes_per_scale(&self) -> usize {
        self.axes.len()
    }
    /// The axes (a, b) of plane `plane` (0, 1, 2 = x, y, z; 3 = t).
    pub fn plane_axes(&self, plane: usize) -> (usize, usize) {
        self.axes[plane]
    }
    /// Features per row.
    pub fn output_width(&self) -> usize {
        self.config.output_width()
    }
    /// Number of parameters.
    pub fn param_count(&self) -> usize {
        self.params.len()
    }
    /// Offset of plane `plane` (in the order of [`TriPlane::plane_axes`]) of scale `res`.
    pub fn plane_offset(&self, res: usize, plane: usize) -> usize {
        self.offsets[self.axes.len() * res + plane]
    }
    /// Texels along axis `axis` at scale `res`.
    pub fn axis_resolution(&self, res: usize, axis: usize) -> usize {
        match (&self.config.time, axis) {
            (Some(t), 3) => t.resolution,
            _ => self.config.resolutions[res],
        }
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

    /// Normalised, clamped coordinates and `dq/dp` per axis (0 where clamped).
    #[inline(always)]
    fn normalise(&self, p: &[f32]) -> ([f32; MAX_AXES], [f32; MAX_AXES]) {
        let mut q = [0f32; MAX_AXES];
        let mut dq = [0f32; MAX_AXES];
        for a in 0..self.dims() {
            let s = self.scale[a];
            let v = (p[a] - self.lo[a]) * s - 1.0;
            if (-1.0..=1.0).contains(&v) {
                q[a] = v;
                dq[a] = s;
            } else {
                q[a] = v.clamp(-1.0, 1.0);
            }
        }
        (q, dq)
    }

    /// The bilinear lookup at `(qa, qb)` in a plane of `ra × rb` texels of `c` channels.
    #[inline(always)]
    fn lookup(ra: usize, rb: usize, c: usize, qa: f32, qb: f32) -> Lookup {
        let half_a = 0.5 * (ra - 1) as f32;
        let half_b = 0.5 * (rb - 1) as f32;
        let fa = (qa + 1.0) * half_a;
        let fb = (qb + 1.0) * half_b;
        let ia = (fa.floor() as usize).min(ra - 2);
        let ib = (fb.floor() as usize).min(rb - 2);
        let (ua, ub) = (fa - ia as f32, fb - ib as f32);
        let base = (ib * ra + ia) * c;
        Lookup {
            idx: [base, base + c, base + ra * c, base + (ra + 1) * c],
            w: [
                (1.0 - ua) * (1.0 - ub),
                ua * (1.0 - ub),
                (1.0 - ua) * ub,
                ua * ub,
            ],
            dwa: [
                -(1.0 - ub) * half_a,
                (1.0 - ub) * half_a,
                -ub * half_a,
                ub * half_a,
            ],
            dwb: [
                -(1.0 - ua) * half_b,
                -ua * half_b,
                (1.0 - ua) * half_b,
                ua * half_b,
            ],
        }
    }

    /// The lookups of the `P` planes of scale `r` at `q`.
    #[inline(always)]
    fn lookups<const P: usize>(&self, r: usize, q: &[f32; MAX_AXES]) -> [Lookup; P] {
        let c = self.config.channels;
        // A plain loop, not `std::array::from_fn`: its closure was not inlined into the AVX2
        // build of the row kernels, so every lookup ran as a call compiled for SSE2, its `floor`
        // a libm call (5.6 % of an EvoGS iteration's CPU time on lego, perf).
        let mut out = [Lookup::default(); P];
        for (k, o) in out.iter_mut().enumerate() {
            let (a, b) = self.axes[k];
            *o = Self::lookup(
                self.axis_resolution(r, a),
                self.axis_resolution(r, b),
                c,
                q[a],
                q[b],
            );
        }
        out
    }

    /// Writes into `order` a permutation of the rows of `positions` (rows × [`TriPlane::dims`],
    /// already checked) that visits them in space-filling-curve order: the normalised box is cut
    /// into [`ORDER_CELLS`]³ cells, cells are taken in Morton (Z) order, and rows inside a cell
    /// keep their input order (a stable counting sort, so the order is a function of the
    /// positions alone). Rows that follow one another then sample nearby texels in all three
    /// space planes, so a block of rows reuses the texels (and their gradients) it brings into
    /// cache.
    pub(crate) fn spatial_order(&self, positions: &[f32], order: &mut Vec<usize>) {
        let dims = self.dims();
        let rows = positions.len() / dims;
        let cell_from_q =
            |v: f32| (((v + 1.0) * 0.5 * ORDER_CELLS as f32) as usize).min(ORDER_CELLS - 1);
        let keys: Vec<u16> = positions
            .par_chunks_exact(dims)
            .with_min_len(1024)
            .map(|p| {
                let (q, _) = self.normalise(p);
                let mut key = 0u16;
                for (axis, &v) in q[..3].iter().enumerate() {
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

    /// Checks shapes and finiteness of the input rows.
    pub(crate) fn check_positions(&self, positions: &[f32], rows: usize) -> Result<(), NnError> {
        let dims = self.dims();
        check_len("tri-plane positions", rows * dims, positions.len())?;
        if let Some(i) = positions.iter().position(|v| !v.is_finite()) {
            return Err(NnError::Config(format!(
                "tri-plane positions: row {} has a non-finite coordinate",
                i / dims
            )));
        }
        Ok(())
    }

    /// The planes as f32 (a copy; f16 storage is widened once per pass).
    pub(crate) fn planes_f32(&self) -> std::borrow::Cow<'_, [f32]> {
        self.params.as_f32()
    }

    /// Encodes one input row `p` ([`TriPlane::dims`] values) into `out` (output width); `feat`
    /// is scratch of `planes_per_scale · C`.
    #[inline(always)]
    pub(crate) fn encode_row_into(
        &self,
        planes: &[f32],
        p: &[f32],
        out: &mut [f32],
        feat: &mut [f32],
    ) {
        match self.axes.len() {
            3 => self.encode_row_p::<3>(planes, p, out, feat),
            _ => self.encode_row_p::<MAX_PLANES>(planes, p, out, feat),
        }
    }

    #[inline(always)]
    fn encode_row_p<const P: usize>(
        &self,
        planes: &[f32],
        p: &[f32],
        out: &mut [f32],
        feat: &mut [f32],
    ) {
        let c = self.config.channels;
        let (q, _) = self.normalise(p);
        for r in 0..self.config.resolutions.len() {
            let lks = self.lookups::<P>(r, &q);
            for (k, lk) in lks.iter().enumerate() {
                let off = self.offsets[P * r + k];
                sample(planes, off, lk, &mut feat[k * c..(k + 1) * c]);
            }
            match self.config.combine {
                PlaneCombine::Concat => {
                    out[r * P * c..(r + 1) * P * c].copy_from_slice(&feat[..P * c]);
                }
                PlaneCombine::Product => {
                    for (ch, o) in out[r * c..(r + 1) * c].iter_mut().enumerate() {
                        let mut v = feat[ch];
                        for k in 1..P {
                            v *= feat[k * c + ch];
                        }
                        *o = v;
                    }
                }
            }
        }
    }

    /// Backward of one row: adds dL/d(planes) into `acc` and writes dL/d(input row) into `d_in`
    /// ([`TriPlane::dims`] values). `go` is the row's output gradient; `feat` and `dfeat` are
    /// scratch of `planes_per_scale · C`.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn backward_row_into(
        &self,
        planes: &[f32],
        p: &[f32],
        go: &[f32],
        acc: &mut [f32],
        feat: &mut [f32],
        dfeat: &mut [f32],
        d_in: &mut [f32],
    ) {
        match self.axes.len() {
            3 => self.backward_row_p::<3>(planes, p, go, acc, feat, dfeat, d_in),
            _ => self.backward_row_p::<MAX_PLANES>(planes, p, go, acc, feat, dfeat, d_in),
        }
    }

    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn backward_row_p<const P: usize>(
        &self,
        planes: &[f32],
        p: &[f32],
        go: &[f32],
        acc: &mut [f32],
        feat: &mut [f32],
        dfeat: &mut [f32],
        d_in: &mut [f32],
    ) {
        let c = self.config.channels;
        let (q, dq) = self.normalise(p);
        let mut gq = [0f32; MAX_AXES];
        for r in 0..self.config.resolutions.len() {
            let lks = self.lookups::<P>(r, &q);
            match self.config.combine {
                PlaneCombine::Concat => {
                    dfeat[..P * c].copy_from_slice(&go[r * P * c..(r + 1) * P * c]);
                }
                PlaneCombine::Product => {
                    for (k, lk) in lks.iter().enumerate() {
                        let off = self.offsets[P * r + k];
                        sample(planes, off, lk, &mut feat[k * c..(k + 1) * c]);
                    }
                    for ch in 0..c {
                        let g = go[r * c + ch];
                        for k in 0..P {
                            let mut v = g;
                            for j in (0..P).filter(|&j| j != k) {
                                v *= feat[j * c + ch];
                            }
                            dfeat[k * c + ch] = v;
                        }
                    }
                }
            }
            for (k, lk) in lks.iter().enumerate() {
                let off = self.offsets[P * r + k];
                let df = &dfeat[k * c..(k + 1) * c];
                let (a, b) = self.axes[k];
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
        for (a, g) in d_in.iter_mut().enumerate() {
            *g = gq[a] * dq[a];
        }
    }

    /// Encodes `rows` input rows (rows × [`TriPlane::dims`]). Errors on non-finite values.
    pub fn forward(
        &self,
        positions: &[f32],
        rows: usize,
    ) -> Result<(Vec<f32>, TriPlaneCache), NnError> {
        self.check_positions(positions, rows)?;
        let (w, dims) = (self.output_width(), self.dims());
        let planes = self.planes_f32();
        let mut out = vec![0f32; rows * w];
        out.par_chunks_mut(ENC_ROWS * w)
            .zip(positions.par_chunks(ENC_ROWS * dims))
            .for_each(|(o, ps)| {
                let mut feat = vec![0f32; self.axes.len() * self.config.channels];
                for (orow, p) in o.chunks_exact_mut(w).zip(ps.chunks_exact(dims)) {
                    self.encode_row_into(&planes, p, orow, &mut feat);
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
        let (w, dims) = (self.output_width(), self.dims());
        check_len("tri-plane output gradient", rows * w, d_out.len())?;
        let scratch = self.axes.len() * self.config.channels;
        let planes = self.planes_f32();
        let n_params = self.params.len();
        let mut d_pos = want_position_grad.then(|| vec![0f32; rows * dims]);
        let n_blocks = rows.div_ceil(ENC_ROWS);
        let dp_blocks: Vec<Option<&mut [f32]>> = match d_pos.as_mut() {
            Some(v) => v.chunks_mut(ENC_ROWS * dims).map(Some).collect(),
            None => (0..n_blocks).map(|_| None).collect(),
        };
        let params = fold_in_order(
            dp_blocks,
            || vec![0f32; n_params],
            |mut acc, (blk, mut dp)| {
                let r0 = blk * ENC_ROWS;
                let nr = ENC_ROWS.min(rows - r0);
                let mut feat = vec![0f32; scratch];
                let mut dfeat = vec![0f32; scratch];
                let mut g = [0f32; MAX_AXES];
                for i in 0..nr {
                    let row = r0 + i;
                    self.backward_row_into(
                        &planes,
                        &cache.positions[row * dims..(row + 1) * dims],
                        &d_out[row * w..(row + 1) * w],
                        &mut acc,
                        &mut feat,
                        &mut dfeat,
                        &mut g[..dims],
                    );
                    if let Some(dp) = dp.as_mut() {
                        dp[i * dims..(i + 1) * dims].copy_from_slice(&g[..dims]);
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

    /// Evaluates the regulariser `which` times `weight` and adds its gradient with respect to
    /// the planes into `grad` (laid out as the parameters). Returns the weighted value. A
    /// regulariser of the space-time planes is 0 without a time axis; a plane with fewer than
    /// 3 texels along b has no second difference and adds nothing.
    pub fn regularise(
        &self,
        which: PlaneRegulariser,
        weight: f32,
        grad: &mut [f32],
    ) -> Result<f64, NnError> {
        check_len(
            "tri-plane regulariser gradient",
            self.params.len(),
            grad.len(),
        )?;
        let planes = self.planes_f32();
        let c = self.config.channels;
        let mut total = 0f64;
        for r in 0..self.config.resolutions.len() {
            for (k, &(a, b)) in self.axes.iter().enumerate() {
                let time_plane = b == 3;
                let wanted = match which {
                    PlaneRegulariser::SpaceSmoothness => !time_plane,
                    PlaneRegulariser::TimeSmoothness | PlaneRegulariser::TimeL1 => time_plane,
                };
                if !wanted {
                    continue;
                }
                let (ra, rb) = (self.axis_resolution(r, a), self.axis_resolution(r, b));
                let off = self.plane_offset(r, k);
                let n = ra * rb * c;
                let (plane, g) = (&planes[off..off + n], &mut grad[off..off + n]);
                match which {
                    PlaneRegulariser::TimeL1 => {
                        let scale = weight / n as f32;
                        let mut sum = 0f64;
                        for (v, gv) in plane.iter().zip(g.iter_mut()) {
                            let d = 1.0 - v;
                            sum += d.abs() as f64;
                            // d|1 - v|/dv = -sign(1 - v), 0 at v = 1 (PyTorch's abs).
                            if d != 0.0 {
                                *gv -= scale * d.signum();
                            }
                        }
                        total += weight as f64 * sum / n as f64;
                    }
                    _ => {
                        if rb < 3 {
                            continue;
                        }
                        let count = (rb - 2) * ra * c;
                        let scale = 2.0 * weight / count as f32;
                        let row = ra * c;
                        let mut sum = 0f64;
                        for ib in 0..rb - 2 {
                            for j in 0..row {
                                let (i0, i1, i2) =
                                    (ib * row + j, (ib + 1) * row + j, (ib + 2) * row + j);
                                let d2 = plane[i2] - 2.0 * plane[i1] + plane[i0];
                                sum += (d2 as f64) * (d2 as f64);
                                let s = scale * d2;
                                g[i0] += s;
                                g[i1] -= 2.0 * s;
                                g[i2] += s;
                            }
                        }
                        total += weight as f64 * sum / count as f64;
                    }
                }
            }
        }
        Ok(total)
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
