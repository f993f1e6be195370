//! Uniform cubic B-spline temporal encoder with `M` learnable control vectors of width `E`.
//!
//! With `S = M - 3` segments (knot spacing `1/S`), time `t ∈ [0, 1]` maps to `s = t · S`, the
//! segment `k = min(⌊s⌋, S - 1)` and `u = s - k ∈ [0, 1]`; so `t = 0` gives `k = 0, u = 0` and
//! `t = 1` lands in the last segment with `u = 1` (never past the last control vector). The output
//! is `Σ_{j=0..3} B_j(u) · P[k + j]` with `B0 = (1-u)³/6`, `B1 = (3u³ - 6u² + 4)/6`,
//! `B2 = (-3u³ + 3u² + 3u + 1)/6`, `B3 = u³/6`. Times outside [0, 1] are clamped (zero gradient
//! to t there); non-finite times are errors.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use crate::reduce::{add_into, fold_in_order};

use super::{ENC_ROWS, dot};
use crate::error::{NnError, check_len};
use crate::precision::{Precision, Store, StoreMut, StoreRef};

/// Settings of a [`BSplineTime`].
#[derive(Clone, Debug, PartialEq)]
pub struct BSplineConfig {
    /// Number of control vectors `M` (>= 4).
    pub controls: usize,
    /// Width `E` of each control vector (the output width).
    pub width: usize,
    /// Initial control values are uniform in `[-init_scale, init_scale]`.
    pub init_scale: f32,
    /// Storage precision of the control vectors.
    pub precision: Precision,
    /// Seed of the initialisation.
    pub seed: u64,
}

impl BSplineConfig {
    /// `controls` control vectors of width `width`, init scale 0.1, f32, seed 0.
    pub fn new(controls: usize, width: usize) -> Self {
        Self {
            controls,
            width,
            init_scale: 0.1,
            precision: Precision::F32,
            seed: 0,
        }
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
    /// Sets the initialisation scale.
    #[must_use]
    pub fn init_scale(mut self, s: f32) -> Self {
        self.init_scale = s;
        self
    }
    /// Builds the encoder.
    pub fn build(self) -> Result<BSplineTime, NnError> {
        BSplineTime::new(self)
    }

    /// The parameters the encoder will have (`M · E`), without allocating them (an overflow is
    /// an error).
    pub fn param_count(&self) -> Result<usize, NnError> {
        self.controls
            .checked_mul(self.width)
            .ok_or_else(|| NnError::Config("B-spline parameter count overflows".into()))
    }
}

/// The B-spline encoder.
#[derive(Clone, Debug)]
pub struct BSplineTime {
    config: BSplineConfig,
    params: Store,
}

/// What [`BSplineTime::forward`] keeps: the times.
#[derive(Clone, Debug)]
pub struct BSplineCache {
    times: Vec<f32>,
}

/// Gradients from [`BSplineTime::backward`].
#[derive(Clone, Debug, PartialEq)]
pub struct BSplineGrads {
    /// dL/d(control vectors), M × E.
    pub params: Vec<f32>,
    /// dL/dt per row (when asked for).
    pub times: Option<Vec<f32>>,
}

/// The four basis values at `u`.
#[inline(always)]
pub fn basis(u: f32) -> [f32; 4] {
    let (u2, u3) = (u * u, u * u * u);
    let v = 1.0 - u;
    [
        v * v * v / 6.0,
        (3.0 * u3 - 6.0 * u2 + 4.0) / 6.0,
        (-3.0 * u3 + 3.0 * u2 + 3.0 * u + 1.0) / 6.0,
        u3 / 6.0,
    ]
}

/// The four basis derivatives d/du at `u`.
#[inline(always)]
pub fn basis_derivative(u: f32) -> [f32; 4] {
    let v = 1.0 - u;
    [
        -0.5 * v * v,
        1.5 * u * u - 2.0 * u,
        -1.5 * u * u + u + 0.5,
        0.5 * u * u,
    ]
}

impl BSplineTime {
    /// Builds and initialises the encoder.
    pub fn new(config: BSplineConfig) -> Result<Self, NnError> {
        if config.controls < 4 || config.width == 0 {
            return Err(NnError::Config(format!(
                "B-spline needs >= 4 control vectors of width > 0, got {} of width {}",
                config.controls, config.width
            )));
        }
        let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
        let s = config.init_scale.abs();
        let values: Vec<f32> = (0..config.param_count()?)
            .map(|_| {
                if s > 0.0 {
                    rng.random_range(-s..s)
                } else {
                    0.0
                }
            })
            .collect();
        let (params, _) = Store::from_f32(config.precision, &values);
        Ok(Self { config, params })
    }

    /// The configuration.
    pub fn config(&self) -> &BSplineConfig {
        &self.config
    }
    /// Output width `E`.
    pub fn output_width(&self) -> usize {
        self.config.width
    }
    /// Number of parameters `M · E`.
    pub fn param_count(&self) -> usize {
        self.params.len()
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
        check_len("B-spline parameters", self.params.len(), values.len())?;
        Ok(self.params.as_mut().write_from(values))
    }

    /// Segment `k`, local `u`, and `ds/dt` (0 where t was clamped).
    #[inline(always)]
    pub fn segment(&self, t: f32) -> (usize, f32, f32) {
        let segs = (self.config.controls - 3) as f32;
        let inside = (0.0..=1.0).contains(&t);
        let s = t.clamp(0.0, 1.0) * segs;
        let k = (s.floor() as usize).min(self.config.controls - 4);
        (k, s - k as f32, if inside { segs } else { 0.0 })
    }

    /// The control vectors as f32.
    pub(crate) fn controls_f32(&self) -> std::borrow::Cow<'_, [f32]> {
        self.params.as_f32()
    }

    /// Checks that every time is finite.
    pub(crate) fn check_times(times: &[f32]) -> Result<(), NnError> {
        match times.iter().position(|t| !t.is_finite()) {
            Some(i) => Err(NnError::Config(format!(
                "B-spline times: row {i} is not finite"
            ))),
            None => Ok(()),
        }
    }

    /// Encodes one time into `out` (E values).
    #[inline(always)]
    pub(crate) fn encode_row_into(&self, ctrl: &[f32], t: f32, out: &mut [f32]) {
        let e = self.config.width;
        let (k, u, _) = self.segment(t);
        let b = basis(u);
        out.fill(0.0);
        for (j, bj) in b.iter().enumerate() {
            let c = &ctrl[(k + j) * e..(k + j + 1) * e];
            out.iter_mut().zip(c).for_each(|(o, c)| *o += bj * c);
        }
    }

    /// Backward of one row: adds dL/d(controls) into `acc`, returns dL/dt.
    #[inline(always)]
    pub(crate) fn backward_row_into(
        &self,
        ctrl: &[f32],
        t: f32,
        go: &[f32],
        acc: &mut [f32],
    ) -> f32 {
        let e = self.config.width;
        let (k, u, ds) = self.segment(t);
        let (b, db) = (basis(u), basis_derivative(u));
        let mut gt = 0f32;
        for j in 0..4 {
            let off = (k + j) * e;
            for (a, &g) in acc[off..off + e].iter_mut().zip(go) {
                *a += b[j] * g;
            }
            gt += db[j] * dot(go, &ctrl[off..off + e]);
        }
        gt * ds
    }

    /// Encodes one time per row. Errors on non-finite times.
    pub fn forward(&self, times: &[f32]) -> Result<(Vec<f32>, BSplineCache), NnError> {
        Self::check_times(times)?;
        let e = self.config.width;
        let p = self.controls_f32();
        let mut out = vec![0f32; times.len() * e];
        out.par_chunks_mut(ENC_ROWS * e)
            .zip(times.par_chunks(ENC_ROWS))
            .for_each(|(o, ts)| {
                for (orow, &t) in o.chunks_exact_mut(e).zip(ts) {
                    self.encode_row_into(&p, t, orow);
                }
            });
        Ok((
            out,
            BSplineCache {
                times: times.to_vec(),
            },
        ))
    }

    /// Backward: `d_out` is dL/d(output) (rows × E).
    pub fn backward(
        &self,
        cache: &BSplineCache,
        d_out: &[f32],
        want_time_grad: bool,
    ) -> Result<BSplineGrads, NnError> {
        let e = self.config.width;
        let rows = cache.times.len();
        check_len("B-spline output gradient", rows * e, d_out.len())?;
        let p = self.controls_f32();
        let n_params = p.len();
        let mut d_t = want_time_grad.then(|| vec![0f32; rows]);
        let n_blocks = rows.div_ceil(ENC_ROWS);
        let blocks: Vec<Option<&mut [f32]>> = match d_t.as_mut() {
            Some(v) => v.chunks_mut(ENC_ROWS).map(Some).collect(),
            None => (0..n_blocks).map(|_| None).collect(),
        };
        let params = fold_in_order(
            blocks,
            || vec![0f32; n_params],
            |mut acc, (blk, mut dt)| {
                let r0 = blk * ENC_ROWS;
                for i in 0..ENC_ROWS.min(rows - r0) {
                    let row = r0 + i;
                    let g = &d_out[row * e..(row + 1) * e];
                    let gt = self.backward_row_into(&p, cache.times[row], g, &mut acc);
                    if let Some(dt) = dt.as_mut() {
                        dt[i] = gt;
                    }
                }
                acc
            },
            add_into,
        );
        Ok(BSplineGrads { params, times: d_t })
    }
}

impl crate::weights::Parameters for BSplineTime {
    fn named_params(&self) -> Vec<(String, StoreRef<'_>)> {
        vec![("controls".to_string(), self.params.as_ref())]
    }
    fn named_params_mut(&mut self) -> Vec<(String, StoreMut<'_>)> {
        vec![("controls".to_string(), self.params.as_mut())]
    }
}
