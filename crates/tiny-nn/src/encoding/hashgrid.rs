//! Multi-resolution hash-grid encoder (Instant-NGP), with the conventions Grid4D's encoder uses.
//!
//! What it is: `L` levels of a regular grid over a `D`-dimensional box (`1 ≤ D ≤ 4`), each grid
//! vertex owning `F` learnable features in a table of at most `T = 2^log2_T` entries per level.
//! An input row is mapped into the unit box, every level interpolates the features of the `2^D`
//! vertices of the cell around it, and the output row is the levels' `F` features one after the
//! other (`L · F` values, level-major). Gradients flow to the tables and to the inputs.
//! What it is not: a network (compose it with [`crate::Mlp`]), or a GPU kernel.
//!
//! # Geometry of a level (Müller et al. 2022, as Grid4D's `hashencoder` computes it)
//!
//! - Growth per level, per axis: `b_d = (N_max,d / N_min,d)^(1/(L-1))` (`b = 1` for one level),
//!   where `N_min` is the base resolution and `N_max` the finest.
//! - Level `l`: `scale_d = N_min,d · b_d^l − 1` and `res_d = ⌈scale_d⌉ + 1` vertices along
//!   axis `d`; the unit coordinate `u_d` sits at `u_d · scale_d` in vertex units (no half-vertex
//!   offset; the vertex 0 is on the box's lower wall). The cell is `⌊u_d · scale_d⌋`, clamped to
//!   `res_d − 2` so that the upper wall uses the last cell with weight 1.
//! - Table: a level with `Π res_d ≤ T` vertices is *dense*: vertex `v` is entry
//!   `v_0 + res_0 · (v_1 + res_1 · (v_2 + …))` of a table of exactly `Π res_d` entries (no
//!   collisions). Otherwise the level is *hashed* into `T` entries:
//!   `(v_0·π_0 ⊕ v_1·π_1 ⊕ v_2·π_2 ⊕ v_3·π_3) mod T` in wrapping 32-bit arithmetic, with
//!   Instant-NGP's primes [`PRIMES`] (`π_0 = 1` keeps neighbouring x in neighbouring entries).
//! - Interpolation weights per axis: `w_1 = S(f)`, `w_0 = 1 − S(f)` with `f` the position inside
//!   the cell and `S(f) = f` ([`Interpolation::Linear`], Instant-NGP) or `S(f) = f²(3 − 2f)`
//!   ([`Interpolation::Smoothstep`], what Grid4D's CUDA kernel applies); a corner's weight is
//!   the product over axes.
//!
//! # Inputs outside the box
//!
//! `u_d = (x_d − min_d) / (max_d − min_d)`. [`Outside::Clamp`] clamps `u` into `[0, 1]` (the
//! clamped axis gets a zero input gradient); [`Outside::Zero`] gives the whole row zero features
//! and zero gradients as soon as one coordinate is outside (Grid4D's kernel). Non-finite inputs
//! are errors.
//!
//! # Precision and determinism
//!
//! Tables are stored in f32 or f16 ([`Precision`]); lookups widen each entry to f32 and every sum
//! is f32. Table gradients are f32 and are scattered level by level: levels own disjoint ranges
//! of the table, each level is one parallel task that visits the rows in input order, so every
//! table entry's gradient is a sum in row order — bit-identical for any thread count, with no
//! atomics and no per-thread copies of the table. Input gradients are summed over the levels in
//! level order.

use half::f16;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::ENC_ROWS;
use crate::error::{NnError, check_len};
use crate::precision::{Precision, Store, StoreMut, StoreRef};

/// Most input dimensions an encoder takes.
pub const MAX_DIMS: usize = 4;
/// Corners of a cell in [`MAX_DIMS`] dimensions.
const MAX_CORNERS: usize = 1 << MAX_DIMS;
/// Instant-NGP's (tiny-cuda-nn's) spatial-hash primes, also those of Grid4D's `fast_hash`.
pub const PRIMES: [u32; MAX_DIMS] = [1, 2_654_435_761, 805_459_861, 3_674_653_429];
/// Largest `log2_T` accepted (entry indices stay in 32 bits).
pub const MAX_LOG2_TABLE: u32 = 30;
/// Rows per chunk of the backward pass: each level keeps `chunk × D` input-gradient values
/// between the parallel scatter and the level-ordered sum.
const BACKWARD_ROWS: usize = 1 << 15;

/// How a level interpolates between the vertices of a cell.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Interpolation {
    /// Multilinear weights (Instant-NGP).
    Linear,
    /// Weights through `S(f) = f²(3 − 2f)` (Grid4D's kernel): C¹ across cell walls, and a zero
    /// input gradient on the walls themselves.
    Smoothstep,
}

impl Interpolation {
    /// `S(f)` and `S'(f)`.
    #[inline(always)]
    fn weight(self, f: f32) -> (f32, f32) {
        match self {
            Interpolation::Linear => (f, 1.0),
            Interpolation::Smoothstep => (f * f * (3.0 - 2.0 * f), 6.0 * f * (1.0 - f)),
        }
    }
}

/// What happens to inputs outside the box.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Outside {
    /// Clamp each coordinate into the box (zero gradient along a clamped axis).
    Clamp,
    /// The whole row encodes to zeros with zero gradients (Grid4D).
    Zero,
}

/// Settings of a [`HashGrid`].
#[derive(Clone, Debug, PartialEq)]
pub struct HashGridConfig {
    /// Input dimensions `D` (1..=4).
    pub dims: usize,
    /// Levels `L` (>= 1).
    pub levels: usize,
    /// Features per level `F` (>= 1).
    pub features: usize,
    /// `log2` of the most entries a level's table has (1..=[`MAX_LOG2_TABLE`]).
    pub log2_table: u32,
    /// Base resolution `N_min` per axis (>= 2).
    pub base_resolution: Vec<f32>,
    /// Finest resolution `N_max` per axis (>= the base).
    pub finest_resolution: Vec<f32>,
    /// Lower corner of the box mapped to `u = 0`, per axis.
    pub box_min: Vec<f32>,
    /// Upper corner of the box mapped to `u = 1`, per axis.
    pub box_max: Vec<f32>,
    /// Interpolation inside a cell.
    pub interpolation: Interpolation,
    /// Inputs outside the box.
    pub outside: Outside,
    /// Initial entries are uniform in this range (Grid4D and Instant-NGP: ±1e-4).
    pub init_range: (f32, f32),
    /// Storage precision of the tables.
    pub precision: Precision,
    /// Seed of the initialisation.
    pub seed: u64,
}

impl HashGridConfig {
    /// `levels × features` over `dims` axes, tables of at most `2^log2_table` entries, resolutions
    /// growing from `base` to `finest` on every axis; unit box, linear weights, clamping, entries
    /// uniform in ±1e-4, f32, seed 0.
    pub fn new(
        dims: usize,
        levels: usize,
        features: usize,
        log2_table: u32,
        base: f32,
        finest: f32,
    ) -> Self {
        Self {
            dims,
            levels,
            features,
            log2_table,
            base_resolution: vec![base; dims],
            finest_resolution: vec![finest; dims],
            box_min: vec![0.0; dims],
            box_max: vec![1.0; dims],
            interpolation: Interpolation::Linear,
            outside: Outside::Clamp,
            init_range: (-1e-4, 1e-4),
            precision: Precision::F32,
            seed: 0,
        }
    }
    /// Sets per-axis base and finest resolutions.
    #[must_use]
    pub fn resolutions(mut self, base: &[f32], finest: &[f32]) -> Self {
        self.base_resolution = base.to_vec();
        self.finest_resolution = finest.to_vec();
        self
    }
    /// Sets the box.
    #[must_use]
    pub fn bounds(mut self, min: &[f32], max: &[f32]) -> Self {
        self.box_min = min.to_vec();
        self.box_max = max.to_vec();
        self
    }
    /// Sets the interpolation.
    #[must_use]
    pub fn interpolation(mut self, i: Interpolation) -> Self {
        self.interpolation = i;
        self
    }
    /// Sets the handling of inputs outside the box.
    #[must_use]
    pub fn outside(mut self, o: Outside) -> Self {
        self.outside = o;
        self
    }
    /// Sets the initialisation range.
    #[must_use]
    pub fn init_range(mut self, lo: f32, hi: f32) -> Self {
        self.init_range = (lo, hi);
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
    /// Builds the encoder.
    pub fn build(self) -> Result<HashGrid, NnError> {
        HashGrid::new(self)
    }

    /// Features per row, `L · F` (what [`HashGrid::output_width`] returns once built).
    pub fn output_width(&self) -> usize {
        self.levels * self.features
    }

    /// The parameters the grid will have (table entries × F), without allocating them. Expects
    /// a configuration [`HashGrid::new`] accepts (the sizes are checked there first).
    pub fn param_count(&self) -> Result<usize, NnError> {
        let (_, entries) = self.level_layout()?;
        entries
            .checked_mul(self.features)
            .ok_or_else(|| NnError::Config("hash grid: parameter count overflows".into()))
    }

    /// Each level's resolution and place in the table, and the table's entries in all.
    fn level_layout(&self) -> Result<(Vec<HashLevel>, usize), NnError> {
        let config = self;
        let d = config.dims.min(MAX_DIMS);
        let bad = |m: String| Err(NnError::Config(format!("hash grid: {m}")));
        if config.base_resolution.len() < d || config.finest_resolution.len() < d {
            return bad(format!("resolutions for fewer than {d} dims"));
        }
        if !(1..=MAX_LOG2_TABLE).contains(&config.log2_table) {
            return bad(format!(
                "log2_table {} is not in 1..={MAX_LOG2_TABLE}",
                config.log2_table
            ));
        }
        let table = 1usize << config.log2_table;
        let mut levels = Vec::with_capacity(config.levels.min(64));
        let mut offset = 0usize;
        for l in 0..config.levels {
            let mut scale = [0f32; MAX_DIMS];
            let mut resolution = [1u32; MAX_DIMS];
            let mut vertices = 1u64;
            for a in 0..d {
                let (n0, n1) = (
                    config.base_resolution[a] as f64,
                    config.finest_resolution[a] as f64,
                );
                let log2_growth = if config.levels > 1 {
                    (n1 / n0).log2() / (config.levels - 1) as f64
                } else {
                    0.0
                };
                let s = (n0 * (l as f64 * log2_growth).exp2() - 1.0) as f32;
                let r = s.ceil() as f64 + 1.0;
                if r > u32::MAX as f64 {
                    return bad(format!("level {l} axis {a}: resolution {r} is too large"));
                }
                scale[a] = s;
                resolution[a] = r as u32;
                vertices = vertices.saturating_mul(resolution[a] as u64);
            }
            let dense = vertices <= table as u64;
            let entries = if dense { vertices as usize } else { table };
            levels.push(HashLevel {
                scale,
                resolution,
                offset,
                entries,
                dense,
            });
            offset = match offset.checked_add(entries) {
                Some(o) => o,
                None => return bad("parameter count overflows".into()),
            };
        }
        Ok((levels, offset))
    }
}

/// One level's grid and its part of the table.
#[derive(Clone, Debug, PartialEq)]
pub struct HashLevel {
    /// `scale_d`: the unit coordinate `u_d` lies at `u_d · scale_d` vertices (axes >= D are 0).
    pub scale: [f32; MAX_DIMS],
    /// Vertices per axis, `⌈scale_d⌉ + 1` (axes >= D are 1).
    pub resolution: [u32; MAX_DIMS],
    /// First entry of the level in the table.
    pub offset: usize,
    /// Entries of the level: `Π res_d` when dense, else `T`.
    pub entries: usize,
    /// Whether vertices index the table directly (no hashing, no collisions).
    pub dense: bool,
}

impl HashLevel {
    /// Entry (within the level) of the vertex `v` (`dims` coordinates, each below the
    /// resolution).
    #[inline(always)]
    pub fn index(&self, dims: usize, v: &[u32]) -> usize {
        if self.dense {
            let mut idx = 0usize;
            let mut stride = 1usize;
            for (&vd, &rd) in v[..dims].iter().zip(&self.resolution) {
                idx += vd as usize * stride;
                stride *= rd as usize;
            }
            idx
        } else {
            let mut h = 0u32;
            for (&vd, &pd) in v[..dims].iter().zip(&PRIMES) {
                h ^= vd.wrapping_mul(pd);
            }
            h as usize & (self.entries - 1)
        }
    }
}

/// The hash-grid encoder.
#[derive(Clone, Debug)]
pub struct HashGrid {
    config: HashGridConfig,
    levels: Vec<HashLevel>,
    /// `1 / (max_d − min_d)`.
    inv_extent: [f32; MAX_DIMS],
    params: Store,
}

/// What [`HashGrid::forward`] keeps for backward: the inputs.
#[derive(Clone, Debug)]
pub struct HashGridCache {
    rows: usize,
    inputs: Vec<f32>,
}

/// Gradients from [`HashGrid::backward`].
#[derive(Clone, Debug, PartialEq)]
pub struct HashGridGrads {
    /// dL/d(table), laid out as the parameters.
    pub params: Vec<f32>,
    /// dL/d(inputs), rows × D (when asked for).
    pub inputs: Option<Vec<f32>>,
}

/// A cell's corners at one level: entry indices within the level and weights, and, when asked,
/// the derivatives of the weights along each axis of `u`.
struct Cell {
    entry: [u32; MAX_CORNERS],
    w: [f32; MAX_CORNERS],
    dw: [[f32; MAX_CORNERS]; MAX_DIMS],
}

/// A table element widened to f32 on read.
trait Entry: Copy + Send + Sync {
    fn widen(self) -> f32;
}
impl Entry for f32 {
    #[inline(always)]
    fn widen(self) -> f32 {
        self
    }
}
impl Entry for f16 {
    #[inline(always)]
    fn widen(self) -> f32 {
        self.to_f32()
    }
}

impl HashGrid {
    /// Checks the configuration, lays out the levels and initialises the table.
    pub fn new(config: HashGridConfig) -> Result<Self, NnError> {
        let d = config.dims;
        let bad = |m: String| Err(NnError::Config(format!("hash grid: {m}")));
        if !(1..=MAX_DIMS).contains(&d) {
            return bad(format!("dims {d} is not in 1..={MAX_DIMS}"));
        }
        if config.levels == 0 || config.features == 0 {
            return bad("needs at least one level and one feature".into());
        }
        for (what, v) in [
            ("base_resolution", &config.base_resolution),
            ("finest_resolution", &config.finest_resolution),
            ("box_min", &config.box_min),
            ("box_max", &config.box_max),
        ] {
            if v.len() != d {
                return bad(format!("{what} has {} values for {d} dims", v.len()));
            }
        }
        let mut inv_extent = [0f32; MAX_DIMS];
        for (a, inv) in inv_extent.iter_mut().enumerate().take(d) {
            let (n0, n1) = (config.base_resolution[a], config.finest_resolution[a]);
            if !(n0.is_finite() && n1.is_finite() && n0 >= 2.0 && n1 >= n0) {
                return bad(format!(
                    "axis {a}: resolutions {n0} -> {n1} need 2 <= base <= finest"
                ));
            }
            let (lo, hi) = (config.box_min[a], config.box_max[a]);
            if !(lo.is_finite() && hi.is_finite() && hi > lo) {
                return bad(format!(
                    "box axis {a}: [{lo}, {hi}] is not a finite non-empty interval"
                ));
            }
            *inv = 1.0 / (hi - lo);
        }
        let (levels, offset) = config.level_layout()?;
        let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
        let (lo, hi) = config.init_range;
        let values: Vec<f32> = (0..offset
            .checked_mul(config.features)
            .ok_or_else(|| NnError::Config("hash grid: parameter count overflows".into()))?)
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
            levels,
            inv_extent,
            params,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &HashGridConfig {
        &self.config
    }
    /// The levels.
    pub fn levels(&self) -> &[HashLevel] {
        &self.levels
    }
    /// Input dimensions `D`.
    pub fn dims(&self) -> usize {
        self.config.dims
    }
    /// Features per row, `L · F`.
    pub fn output_width(&self) -> usize {
        self.config.output_width()
    }
    /// Number of parameters (table entries × F).
    pub fn param_count(&self) -> usize {
        self.params.len()
    }
    /// The table (read-only): entry `e` of level `l` holds values
    /// `(levels[l].offset + e) · F .. + F`.
    pub fn params(&self) -> StoreRef<'_> {
        self.params.as_ref()
    }
    /// The table, for an optimiser step.
    pub fn params_mut(&mut self) -> StoreMut<'_> {
        self.params.as_mut()
    }
    /// Replaces the table from f32 values; returns the number of values saturated in f16.
    pub fn set_params(&mut self, values: &[f32]) -> Result<u64, NnError> {
        check_len("hash-grid table", self.params.len(), values.len())?;
        Ok(self.params.as_mut().write_from(values))
    }

    /// Unit coordinates of an input row and `du/dx` per axis (0 where clamped), or `None` when
    /// the row is outside under [`Outside::Zero`].
    #[inline(always)]
    fn normalise(&self, x: &[f32]) -> Option<([f32; MAX_DIMS], [f32; MAX_DIMS])> {
        let mut u = [0f32; MAX_DIMS];
        let mut du = [0f32; MAX_DIMS];
        for a in 0..self.config.dims {
            let v = (x[a] - self.config.box_min[a]) * self.inv_extent[a];
            if (0.0..=1.0).contains(&v) {
                u[a] = v;
                du[a] = self.inv_extent[a];
            } else if self.config.outside == Outside::Zero {
                return None;
            } else {
                u[a] = v.clamp(0.0, 1.0);
            }
        }
        Some((u, du))
    }

    /// The cell of unit coordinates `u` at `level` in `D` dimensions; the weight derivatives
    /// only when `grad`. A corner's entry combines per-axis terms of its two candidate vertices:
    /// `v_d · stride_d` summed (dense) or `v_d · π_d` xor-ed (hashed), as [`HashLevel::index`].
    #[inline(always)]
    fn cell<const D: usize>(&self, level: &HashLevel, u: &[f32; MAX_DIMS], grad: bool) -> Cell {
        let mut lo = [0u32; MAX_DIMS];
        let mut hi = [0u32; MAX_DIMS];
        let mut w0 = [0f32; MAX_DIMS];
        let mut w1 = [0f32; MAX_DIMS];
        let mut dw1 = [0f32; MAX_DIMS];
        let mut stride = 1u32;
        for a in 0..D {
            let p = u[a] * level.scale[a];
            let c = (p.floor().max(0.0) as u32).min(level.resolution[a] - 2);
            let (s, ds) = self.config.interpolation.weight(p - c as f32);
            w0[a] = 1.0 - s;
            w1[a] = s;
            dw1[a] = ds * level.scale[a];
            if level.dense {
                lo[a] = c * stride;
                hi[a] = lo[a] + stride;
                stride *= level.resolution[a];
            } else {
                lo[a] = c.wrapping_mul(PRIMES[a]);
                hi[a] = (c + 1).wrapping_mul(PRIMES[a]);
            }
        }
        let mask = (level.entries - 1) as u32;
        let mut cell = Cell {
            entry: [0; MAX_CORNERS],
            w: [0.0; MAX_CORNERS],
            dw: [[0.0; MAX_CORNERS]; MAX_DIMS],
        };
        for k in 0..1usize << D {
            let bit = |a: usize| (k >> a) & 1 == 1;
            let mut idx = 0u32;
            let mut w = 1f32;
            for a in 0..D {
                let v = if bit(a) { hi[a] } else { lo[a] };
                idx = if level.dense { idx + v } else { idx ^ v };
                w *= if bit(a) { w1[a] } else { w0[a] };
            }
            cell.entry[k] = if level.dense { idx } else { idx & mask };
            cell.w[k] = w;
            if grad {
                for (g, &dwg) in dw1.iter().enumerate().take(D) {
                    let mut dw = if bit(g) { dwg } else { -dwg };
                    for a in 0..D {
                        if a != g {
                            dw *= if bit(a) { w1[a] } else { w0[a] };
                        }
                    }
                    cell.dw[g][k] = dw;
                }
            }
        }
        cell
    }

    /// Checks the shape and finiteness of inputs.
    fn check_inputs(&self, inputs: &[f32], rows: usize) -> Result<(), NnError> {
        check_len("hash-grid inputs", rows * self.config.dims, inputs.len())?;
        if let Some(i) = inputs.iter().position(|v| !v.is_finite()) {
            return Err(NnError::Config(format!(
                "hash-grid inputs: row {} has a non-finite coordinate",
                i / self.config.dims
            )));
        }
        Ok(())
    }

    /// Encodes `rows` input rows (rows × D). Errors on non-finite inputs.
    pub fn forward(
        &self,
        inputs: &[f32],
        rows: usize,
    ) -> Result<(Vec<f32>, HashGridCache), NnError> {
        self.check_inputs(inputs, rows)?;
        let mut out = vec![0f32; rows * self.output_width()];
        match &self.params {
            Store::F32(t) => self.dispatch(Forward {
                table: t,
                inputs,
                out: &mut out,
            }),
            Store::F16(t) => self.dispatch(Forward {
                table: t,
                inputs,
                out: &mut out,
            }),
        }
        Ok((
            out,
            HashGridCache {
                rows,
                inputs: inputs.to_vec(),
            },
        ))
    }

    /// Backward: `d_out` is dL/d(features) (rows × L · F). Input gradients (rows × D) only when
    /// asked for.
    pub fn backward(
        &self,
        cache: &HashGridCache,
        d_out: &[f32],
        want_input_grad: bool,
    ) -> Result<HashGridGrads, NnError> {
        let rows = cache.rows;
        check_len(
            "hash-grid output gradient",
            rows * self.output_width(),
            d_out.len(),
        )?;
        let mut params = vec![0f32; self.params.len()];
        let mut d_in = want_input_grad.then(|| vec![0f32; rows * self.config.dims]);
        match &self.params {
            Store::F32(t) => self.dispatch(Backward {
                table: t,
                cache,
                d_out,
                grads: &mut params,
                d_in: d_in.as_deref_mut(),
            }),
            Store::F16(t) => self.dispatch(Backward {
                table: t,
                cache,
                d_out,
                grads: &mut params,
                d_in: d_in.as_deref_mut(),
            }),
        }
        Ok(HashGridGrads {
            params,
            inputs: d_in,
        })
    }

    /// Runs `pass` compiled for this grid's `D`, and for `F = 2` (Grid4D's, Instant-NGP's) or any
    /// `F`.
    fn dispatch<P: Pass>(&self, pass: P) {
        let f2 = self.config.features == 2;
        match (self.config.dims, f2) {
            (1, true) => pass.run::<1, 2>(self),
            (2, true) => pass.run::<2, 2>(self),
            (3, true) => pass.run::<3, 2>(self),
            (4, true) => pass.run::<4, 2>(self),
            (1, false) => pass.run::<1, 0>(self),
            (2, false) => pass.run::<2, 0>(self),
            (3, false) => pass.run::<3, 0>(self),
            _ => pass.run::<4, 0>(self),
        }
    }

    /// Features per level: `FF` when it is not 0 (a compile-time constant), else the setting.
    #[inline(always)]
    fn features<const FF: usize>(&self) -> usize {
        if FF > 0 { FF } else { self.config.features }
    }

    /// Forward over all rows: blocks of rows in parallel; inside a block, level after level, so
    /// that one level's table is read by the whole block before the next (cache locality).
    fn forward_rows<T: Entry, const D: usize, const FF: usize>(
        &self,
        table: &[T],
        inputs: &[f32],
        out: &mut [f32],
    ) {
        let (f, w) = (self.features::<FF>(), self.output_width());
        out.par_chunks_mut(ENC_ROWS * w)
            .zip(inputs.par_chunks(ENC_ROWS * D))
            .for_each(|(o, xs)| {
                let us: Vec<Option<[f32; MAX_DIMS]>> = xs
                    .chunks_exact(D)
                    .map(|x| self.normalise(x).map(|(u, _)| u))
                    .collect();
                for (l, level) in self.levels.iter().enumerate() {
                    let t = &table[level.offset * f..(level.offset + level.entries) * f];
                    for (orow, u) in o.chunks_exact_mut(w).zip(&us) {
                        let Some(u) = u else { continue };
                        let cell = self.cell::<D>(level, u, false);
                        let ol = &mut orow[l * f..(l + 1) * f];
                        for k in 0..1usize << D {
                            let at = cell.entry[k] as usize * f;
                            for (ov, tv) in ol.iter_mut().zip(&t[at..at + f]) {
                                *ov += cell.w[k] * tv.widen();
                            }
                        }
                    }
                }
            });
    }

    /// Backward over all rows, in chunks of rows; inside a chunk one parallel task per level
    /// scatters into the level's own range of `grads` in row order.
    fn backward_rows<T: Entry, const D: usize, const FF: usize>(
        &self,
        table: &[T],
        cache: &HashGridCache,
        d_out: &[f32],
        grads: &mut [f32],
        mut d_in: Option<&mut [f32]>,
    ) {
        let (f, w) = (self.features::<FF>(), self.output_width());
        // Disjoint gradient ranges, one per level.
        let mut level_grads: Vec<&mut [f32]> = Vec::with_capacity(self.levels.len());
        let mut rest = grads;
        for level in &self.levels {
            let (g, r) = std::mem::take(&mut rest).split_at_mut(level.entries * f);
            level_grads.push(g);
            rest = r;
        }
        let want = d_in.is_some();
        let mut r0 = 0;
        while r0 < cache.rows {
            let nr = BACKWARD_ROWS.min(cache.rows - r0);
            let inputs = &cache.inputs[r0 * D..(r0 + nr) * D];
            let go = &d_out[r0 * w..(r0 + nr) * w];
            let us: Vec<Option<[f32; MAX_DIMS]>> = inputs
                .par_chunks(ENC_ROWS * D)
                .flat_map_iter(|xs| {
                    xs.chunks_exact(D)
                        .map(|x| self.normalise(x).map(|(u, _)| u))
                        .collect::<Vec<_>>()
                })
                .collect();
            // One task per level: scatter into its own range in row order; its part of dL/du.
            let du_levels: Vec<Vec<f32>> = level_grads
                .par_iter_mut()
                .zip(self.levels.par_iter())
                .enumerate()
                .map(|(l, (g, level))| {
                    let t = &table[level.offset * f..(level.offset + level.entries) * f];
                    let mut du_l = if want { vec![0f32; nr * D] } else { Vec::new() };
                    for (i, u) in us.iter().enumerate() {
                        let Some(u) = u else { continue };
                        let gl = &go[i * w + l * f..i * w + (l + 1) * f];
                        let cell = self.cell::<D>(level, u, want);
                        for k in 0..1usize << D {
                            let at = cell.entry[k] as usize * f;
                            for (gv, &gi) in g[at..at + f].iter_mut().zip(gl) {
                                *gv += cell.w[k] * gi;
                            }
                            if want {
                                let mut s = 0f32;
                                for (tv, &gi) in t[at..at + f].iter().zip(gl) {
                                    s += tv.widen() * gi;
                                }
                                for a in 0..D {
                                    du_l[i * D + a] += cell.dw[a][k] * s;
                                }
                            }
                        }
                    }
                    du_l
                })
                .collect();
            if let Some(d_in) = d_in.as_deref_mut() {
                let out = &mut d_in[r0 * D..(r0 + nr) * D];
                for du_l in &du_levels {
                    out.iter_mut().zip(du_l).for_each(|(o, v)| *o += v);
                }
                for (o, x) in out.chunks_exact_mut(D).zip(inputs.chunks_exact(D)) {
                    match self.normalise(x) {
                        Some((_, du)) => o.iter_mut().zip(du).for_each(|(v, s)| *v *= s),
                        None => o.fill(0.0),
                    }
                }
            }
            r0 += nr;
        }
    }

    /// The plain reference (f64, one corner at a time, no caching), for tests: the encoding of
    /// one input row `x` with the table `table` (laid out as the parameters).
    pub fn reference_encode(&self, table: &[f64], x: &[f64]) -> Vec<f64> {
        let (dims, f) = (self.config.dims, self.config.features);
        let mut out = vec![0f64; self.output_width()];
        let mut u = [0f64; MAX_DIMS];
        for a in 0..dims {
            let (lo, hi) = (self.config.box_min[a] as f64, self.config.box_max[a] as f64);
            let v = (x[a] - lo) / (hi - lo);
            if !(0.0..=1.0).contains(&v) && self.config.outside == Outside::Zero {
                return out;
            }
            u[a] = v.clamp(0.0, 1.0);
        }
        let s = |t: f64| match self.config.interpolation {
            Interpolation::Linear => t,
            Interpolation::Smoothstep => t * t * (3.0 - 2.0 * t),
        };
        for (l, level) in self.levels.iter().enumerate() {
            let mut cell = [0u32; MAX_DIMS];
            let mut frac = [0f64; MAX_DIMS];
            for a in 0..dims {
                let p = u[a] * level.scale[a] as f64;
                let c = (p.floor() as u32).min(level.resolution[a] - 2);
                cell[a] = c;
                frac[a] = s(p - c as f64);
            }
            for k in 0..1usize << dims {
                let mut v = [0u32; MAX_DIMS];
                let mut wk = 1f64;
                for a in 0..dims {
                    let hi = (k >> a) & 1;
                    v[a] = cell[a] + hi as u32;
                    wk *= if hi == 1 { frac[a] } else { 1.0 - frac[a] };
                }
                let at = (level.offset + level.index(dims, &v)) * f;
                for c in 0..f {
                    out[l * f + c] += wk * table[at + c];
                }
            }
        }
        out
    }
}

/// A pass over the rows, compiled for a dimension `D` and a feature count (`FF`, 0 = any).
trait Pass {
    fn run<const D: usize, const FF: usize>(self, grid: &HashGrid);
}

struct Forward<'a, T> {
    table: &'a [T],
    inputs: &'a [f32],
    out: &'a mut [f32],
}

impl<T: Entry> Pass for Forward<'_, T> {
    fn run<const D: usize, const FF: usize>(self, grid: &HashGrid) {
        grid.forward_rows::<T, D, FF>(self.table, self.inputs, self.out);
    }
}

struct Backward<'a, T> {
    table: &'a [T],
    cache: &'a HashGridCache,
    d_out: &'a [f32],
    grads: &'a mut [f32],
    d_in: Option<&'a mut [f32]>,
}

impl<T: Entry> Pass for Backward<'_, T> {
    fn run<const D: usize, const FF: usize>(self, grid: &HashGrid) {
        grid.backward_rows::<T, D, FF>(self.table, self.cache, self.d_out, self.grads, self.d_in);
    }
}

impl crate::weights::Parameters for HashGrid {
    fn named_params(&self) -> Vec<(String, StoreRef<'_>)> {
        vec![("table".to_string(), self.params.as_ref())]
    }
    fn named_params_mut(&mut self) -> Vec<(String, StoreMut<'_>)> {
        vec![("table".to_string(), self.params.as_mut())]
    }
}
