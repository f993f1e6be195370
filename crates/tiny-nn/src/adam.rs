//! Adam with per-group learning rates, the 3DGS exponential schedule, and per-row moment edits.
//!
//! A group is one parameter buffer (a network's flat parameters, or a per-Gaussian array of
//! `rows × row_width` values). Its first and second moments are plain `Vec<f32>` of the same
//! length, public so another crate can permute them when rows are added or removed; the helpers
//! [`Adam::reset_rows`] and [`Adam::remap_rows`] cover the usual cases.
//!
//! The update is PyTorch's `torch.optim.Adam` (no weight decay, no amsgrad):
//! `m ← β1 m + (1-β1) g`, `v ← β2 v + (1-β2) g²`, `θ ← θ - lr · m̂ / (√v̂ + ε)` with
//! `m̂ = m / (1-β1^t)`, `v̂ = v / (1-β2^t)`, and `t` the group's step count. Parameters in f16
//! storage are updated in f32 and rounded back (saturating, counted): updates smaller than half an
//! f16 ulp of a weight are lost, as with any pure-f16 storage.

use half::f16;
use rayon::prelude::*;

use crate::error::{NnError, check_len};
use crate::precision::{F16_MAX, StoreMut};
use crate::simd::{Kernel, vectorised};

/// Values per parallel task of an Adam step.
const STEP_CHUNK: usize = 1 << 14;

/// A learning rate as a function of the step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LrSchedule {
    /// The same rate at every step.
    Constant(f32),
    /// 3DGS's `get_expon_lr_func`.
    Exponential(ExponentialLr),
}

/// 3DGS's `get_expon_lr_func(lr_init, lr_final, lr_delay_steps, lr_delay_mult, max_steps)`:
/// `lr(s) = delay(s) · exp((1-τ) ln lr_init + τ ln lr_final)`, `τ = clamp(s / max_steps, 0, 1)`,
/// `delay(s) = delay_mult + (1 - delay_mult) · sin(π/2 · clamp(s / delay_steps, 0, 1))` when
/// `delay_steps > 0`, else 1. Negative steps, or `lr_init = lr_final = 0`, give 0.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExponentialLr {
    /// Rate at step 0.
    pub lr_init: f32,
    /// Rate at `max_steps` and after.
    pub lr_final: f32,
    /// Length of the delay ramp (0: none).
    pub delay_steps: u64,
    /// Multiplier at step 0 of the ramp.
    pub delay_mult: f32,
    /// Steps of the log-linear decay.
    pub max_steps: u64,
}

impl ExponentialLr {
    /// Rate at `step`.
    pub fn at(&self, step: i64) -> f32 {
        if step < 0 || (self.lr_init == 0.0 && self.lr_final == 0.0) {
            return 0.0;
        }
        let s = step as f64;
        let delay = if self.delay_steps > 0 {
            let r = (s / self.delay_steps as f64).clamp(0.0, 1.0);
            let m = self.delay_mult as f64;
            m + (1.0 - m) * (0.5 * std::f64::consts::PI * r).sin()
        } else {
            1.0
        };
        let t = if self.max_steps == 0 {
            1.0
        } else {
            (s / self.max_steps as f64).clamp(0.0, 1.0)
        };
        let log_lerp =
            ((self.lr_init as f64).ln() * (1.0 - t) + (self.lr_final as f64).ln() * t).exp();
        (delay * log_lerp) as f32
    }
}

impl LrSchedule {
    /// Rate at `step`.
    pub fn at(&self, step: i64) -> f32 {
        match self {
            LrSchedule::Constant(lr) => *lr,
            LrSchedule::Exponential(e) => e.at(step),
        }
    }
}

/// Index of a group in an [`Adam`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct GroupId(pub usize);

/// One parameter group's state.
#[derive(Clone, Debug, PartialEq)]
pub struct AdamGroup {
    /// Name (for messages and files).
    pub name: String,
    /// Values per row (1 for an unstructured buffer).
    pub row_width: usize,
    /// Learning-rate schedule, evaluated at `iteration` (see [`Adam::step`]).
    pub schedule: LrSchedule,
    /// Number of updates applied (the `t` of bias correction).
    pub step: u64,
    /// First moments, one per parameter.
    pub m: Vec<f32>,
    /// Second moments, one per parameter.
    pub v: Vec<f32>,
}

impl AdamGroup {
    /// Counts one more update and returns its constants at `iteration`.
    fn advance(&mut self, b1: f32, b2: f32, eps: f32, iteration: i64) -> AdamUpdate {
        self.step += 1;
        let lr = self.schedule.at(iteration);
        let t = self.step.min(i32::MAX as u64) as i32;
        let bc1 = 1.0 - (b1 as f64).powi(t);
        let bc2 = 1.0 - (b2 as f64).powi(t);
        AdamUpdate {
            b1,
            b2,
            eps,
            step_size: (lr as f64 / bc1) as f32,
            bc2_sqrt: bc2.sqrt() as f32,
        }
    }
}

/// The Adam optimiser over any number of groups.
#[derive(Clone, Debug, PartialEq)]
pub struct Adam {
    /// β1 (default 0.9).
    pub beta1: f32,
    /// β2 (default 0.999).
    pub beta2: f32,
    /// ε (default 1e-15, as 3DGS and D-3DGS use).
    pub eps: f32,
    groups: Vec<AdamGroup>,
}

impl Default for Adam {
    fn default() -> Self {
        Self::new()
    }
}

impl Adam {
    /// β1 = 0.9, β2 = 0.999, ε = 1e-15 and no groups.
    pub fn new() -> Self {
        Self {
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-15,
            groups: Vec::new(),
        }
    }

    /// Adds a group of `len` parameters in rows of `row_width`, with zero moments.
    pub fn add_group(
        &mut self,
        name: &str,
        len: usize,
        row_width: usize,
        schedule: LrSchedule,
    ) -> Result<GroupId, NnError> {
        if row_width == 0 || !len.is_multiple_of(row_width) {
            return Err(NnError::Config(format!(
                "Adam group `{name}`: length {len} is not a multiple of row width {row_width}"
            )));
        }
        self.groups.push(AdamGroup {
            name: name.to_string(),
            row_width,
            schedule,
            step: 0,
            m: vec![0.0; len],
            v: vec![0.0; len],
        });
        Ok(GroupId(self.groups.len() - 1))
    }

    /// The groups.
    pub fn groups(&self) -> &[AdamGroup] {
        &self.groups
    }

    /// The groups, mutable (moments, schedules, steps), in the order they were added.
    pub fn groups_mut(&mut self) -> &mut [AdamGroup] {
        &mut self.groups
    }

    fn checked_group(&mut self, id: GroupId) -> Result<&mut AdamGroup, NnError> {
        self.groups
            .get_mut(id.0)
            .ok_or_else(|| NnError::Config(format!("no Adam group {}", id.0)))
    }

    /// One group.
    ///
    /// # Panics
    /// Panics when `id` does not come from this optimiser's [`Adam::add_group`].
    pub fn group(&self, id: GroupId) -> &AdamGroup {
        &self.groups[id.0]
    }

    /// One group, mutable (moments, schedule, step).
    ///
    /// # Panics
    /// Panics when `id` does not come from this optimiser's [`Adam::add_group`].
    pub fn group_mut(&mut self, id: GroupId) -> &mut AdamGroup {
        &mut self.groups[id.0]
    }

    /// Counts one more update of group `id` and returns its constants at `iteration`, without
    /// touching parameters or moments: for a step applied elsewhere (on the GPU, where the
    /// moments live in device buffers and this optimiser keeps the schedule and the step count).
    /// [`Adam::step`] is this plus the element-wise update on the host.
    pub fn next_update(&mut self, id: GroupId, iteration: i64) -> Result<AdamUpdate, NnError> {
        let (b1, b2, eps) = (self.beta1, self.beta2, self.eps);
        Ok(self.checked_group(id)?.advance(b1, b2, eps, iteration))
    }

    /// The learning rate group `id` would use at `iteration`.
    pub fn lr(&self, id: GroupId, iteration: i64) -> f32 {
        self.groups[id.0].schedule.at(iteration)
    }

    /// One Adam update of group `id` with the rate of its schedule at `iteration`. Returns how
    /// many updated f16 parameters saturated at ±65504 (0 for f32).
    pub fn step(
        &mut self,
        id: GroupId,
        iteration: i64,
        params: StoreMut<'_>,
        grads: &[f32],
    ) -> Result<u64, NnError> {
        let (b1, b2, eps) = (self.beta1, self.beta2, self.eps);
        let g = self.checked_group(id)?;
        // The messages are built only for a mismatch: a step allocates nothing.
        for (what, len) in [("parameters", params.len()), ("gradients", grads.len())] {
            if len != g.m.len() {
                check_len(&format!("Adam group `{}` {what}", g.name), g.m.len(), len)?;
            }
        }
        let k = g.advance(b1, b2, eps, iteration);
        let update = |m: &mut f32, v: &mut f32, gr: f32| k.update(m, v, gr);
        // Element by element, so chunks in parallel give the same values for any thread count.
        let sat = match params {
            StoreMut::F32(p) => {
                p.par_chunks_mut(STEP_CHUNK)
                    .zip(g.m.par_chunks_mut(STEP_CHUNK))
                    .zip(g.v.par_chunks_mut(STEP_CHUNK))
                    .zip(grads.par_chunks(STEP_CHUNK))
                    .for_each(|(((p, m), v), grads)| {
                        vectorised(UpdateF32 { p, m, v, grads, k });
                    });
                0
            }
            StoreMut::F16(p) => p
                .par_chunks_mut(STEP_CHUNK)
                .zip(g.m.par_chunks_mut(STEP_CHUNK))
                .zip(g.v.par_chunks_mut(STEP_CHUNK))
                .zip(grads.par_chunks(STEP_CHUNK))
                .map(|(((p, m), v), grads)| {
                    let mut sat = 0;
                    for (((p, m), v), &gr) in p.iter_mut().zip(m).zip(v).zip(grads) {
                        let x = p.to_f32() - update(m, v, gr);
                        if x.abs() > F16_MAX {
                            sat += 1;
                        }
                        *p = f16::from_f32(x.clamp(-F16_MAX, F16_MAX));
                    }
                    sat
                })
                .sum(),
        };
        Ok(sat)
    }

    /// One Adam update of group `id`, as [`Adam::step`], of the columns `cols` of rows that are
    /// `stride` values long: `params` and `grads` hold `rows × stride` values, the group's
    /// moments `rows × cols.len()` (its rows). So one group can update a column range of a wider
    /// per-row array in place (3DGS's `f_dc` and `f_rest` are two column ranges of the SH rows)
    /// without copying it out and back. The values are those of [`Adam::step`] on the columns
    /// copied out, bit for bit.
    pub fn step_columns(
        &mut self,
        id: GroupId,
        iteration: i64,
        params: &mut [f32],
        grads: &[f32],
        stride: usize,
        cols: std::ops::Range<usize>,
    ) -> Result<(), NnError> {
        let (b1, b2, eps) = (self.beta1, self.beta2, self.eps);
        let g = self.checked_group(id)?;
        let w = cols.len();
        // No columns fit a group that holds no value (3DGS's `f_rest` at SH degree 0).
        let fits = cols.end <= stride
            && if w == 0 {
                g.m.is_empty()
            } else {
                w == g.row_width
            };
        if !fits {
            return Err(NnError::Config(format!(
                "Adam group `{}`: columns {cols:?} of rows of {stride} do not give its rows of {}",
                g.name, g.row_width
            )));
        }
        let rows =
            g.m.len()
                .checked_div(w)
                .unwrap_or(params.len() / stride.max(1));
        for (what, len) in [("parameters", params.len()), ("gradients", grads.len())] {
            if len != rows * stride {
                check_len(
                    &format!("Adam group `{}` {what}", g.name),
                    rows * stride,
                    len,
                )?;
            }
        }
        let k = g.advance(b1, b2, eps, iteration);
        if w == 0 {
            return Ok(());
        }
        // Rows per parallel task: about as many values as a task of `step`.
        let chunk = (STEP_CHUNK / stride).max(1);
        params
            .par_chunks_mut(chunk * stride)
            .zip(grads.par_chunks(chunk * stride))
            .zip(g.m.par_chunks_mut(chunk * w))
            .zip(g.v.par_chunks_mut(chunk * w))
            .for_each(|(((p, grads), m), v)| {
                vectorised(UpdateColumnsF32 {
                    p,
                    m,
                    v,
                    grads,
                    stride,
                    cols: cols.clone(),
                    k,
                });
            });
        Ok(())
    }

    /// Zeroes both moments of the given rows of group `id` (3DGS does this for the opacity of
    /// every Gaussian at an opacity reset).
    pub fn reset_rows(&mut self, id: GroupId, rows: &[usize]) -> Result<(), NnError> {
        let g = self.checked_group(id)?;
        let n_rows = g.m.len() / g.row_width;
        for &r in rows {
            if r >= n_rows {
                return Err(NnError::Config(format!(
                    "Adam group `{}`: row {r} out of range ({n_rows} rows)",
                    g.name
                )));
            }
            let s = r * g.row_width..(r + 1) * g.row_width;
            g.m[s.clone()].fill(0.0);
            g.v[s].fill(0.0);
        }
        Ok(())
    }

    /// Rebuilds the moments of group `id` for a new row set: new row `i` takes the moments of old
    /// row `old_from_new[i]`, or zeros for `None` (a row with no history).
    pub fn remap_rows(
        &mut self,
        id: GroupId,
        old_from_new: &[Option<usize>],
    ) -> Result<(), NnError> {
        let g = self.checked_group(id)?;
        let w = g.row_width;
        let n_old = g.m.len() / w;
        let mut m = vec![0f32; old_from_new.len() * w];
        let mut v = vec![0f32; old_from_new.len() * w];
        for (new, old) in old_from_new.iter().enumerate() {
            if let Some(old) = *old {
                if old >= n_old {
                    return Err(NnError::Config(format!(
                        "Adam group `{}`: source row {old} out of range ({n_old} rows)",
                        g.name
                    )));
                }
                m[new * w..(new + 1) * w].copy_from_slice(&g.m[old * w..(old + 1) * w]);
                v[new * w..(new + 1) * w].copy_from_slice(&g.v[old * w..(old + 1) * w]);
            }
        }
        g.m = m;
        g.v = v;
        Ok(())
    }
}

/// The constants of one Adam update of a group, made by [`Adam::next_update`] (which counts
/// the update): what a kernel outside this crate (the GPU step of [`crate::gpu`]) needs to apply
/// the same update as [`Adam::step`], per element
/// `m ← b1 m + (1 − b1) g`, `v ← b2 v + (1 − b2) g²`, `θ ← θ − step_size · m / (√v / bc2_sqrt + eps)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdamUpdate {
    /// β1.
    pub b1: f32,
    /// β2.
    pub b2: f32,
    /// ε.
    pub eps: f32,
    /// The rate over the first moment's bias correction, `lr / (1 − β1^t)`.
    pub step_size: f32,
    /// The square root of the second moment's bias correction, `√(1 − β2^t)`.
    pub bc2_sqrt: f32,
}

impl AdamUpdate {
    /// Updates the moments `m` and `v` with the gradient `gr`; returns the step to subtract.
    #[inline(always)]
    pub fn update(self, m: &mut f32, v: &mut f32, gr: f32) -> f32 {
        *m = self.b1 * *m + (1.0 - self.b1) * gr;
        *v = self.b2 * *v + (1.0 - self.b2) * gr * gr;
        self.step_size * *m / (v.sqrt() / self.bc2_sqrt + self.eps)
    }
}

/// One chunk of an f32 group's update, compiled 8 lanes wide where the CPU has AVX2
/// ([`vectorised`]): the same operations per element (no fused multiply-add), so the same bits
/// in every build.
struct UpdateF32<'a> {
    p: &'a mut [f32],
    m: &'a mut [f32],
    v: &'a mut [f32],
    grads: &'a [f32],
    k: AdamUpdate,
}

impl Kernel for UpdateF32<'_> {
    type Output = ();
    #[inline(always)]
    fn run(self) {
        let k = self.k;
        for (((p, m), v), &gr) in self.p.iter_mut().zip(self.m).zip(self.v).zip(self.grads) {
            *p -= k.update(m, v, gr);
        }
    }
}

/// [`UpdateF32`] on the columns `cols` of each `stride`-long row of `p` and `grads`, the moments
/// holding `cols.len()` values per row.
struct UpdateColumnsF32<'a> {
    p: &'a mut [f32],
    m: &'a mut [f32],
    v: &'a mut [f32],
    grads: &'a [f32],
    stride: usize,
    cols: std::ops::Range<usize>,
    k: AdamUpdate,
}

impl Kernel for UpdateColumnsF32<'_> {
    type Output = ();
    #[inline(always)]
    fn run(self) {
        let (k, w) = (self.k, self.cols.len());
        let rows = self
            .p
            .chunks_exact_mut(self.stride)
            .zip(self.grads.chunks_exact(self.stride))
            .zip(self.m.chunks_exact_mut(w))
            .zip(self.v.chunks_exact_mut(w));
        for (((p, grads), m), v) in rows {
            let (p, grads) = (&mut p[self.cols.clone()], &grads[self.cols.clone()]);
            UpdateF32 { p, m, v, grads, k }.run();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{Adam, AdamUpdate, LrSchedule, UpdateF32};
    use crate::precision::StoreMut;
    use crate::simd::{Kernel, vectorised};

    /// The AVX2 build of the f32 update gives the bits of the baseline build.
    #[test]
    fn vectorised_update_gives_the_same_bits() {
        let n = 1_003;
        let value = |i: usize, s: f32| (i as f32 * s).sin() * 10f32.powi((i % 9) as i32 - 4);
        let grads: Vec<f32> = (0..n).map(|i| value(i, 0.37)).collect();
        let start = (
            (0..n).map(|i| value(i, 0.11)).collect::<Vec<f32>>(),
            (0..n).map(|i| value(i, 0.23) * 1e-2).collect::<Vec<f32>>(),
            (0..n).map(|i| value(i, 0.05).abs()).collect::<Vec<f32>>(),
        );
        let k = AdamUpdate {
            b1: 0.9,
            b2: 0.999,
            eps: 1e-15,
            step_size: 1.6e-4 / 0.1,
            bc2_sqrt: 0.001f32.sqrt(),
        };
        let run = |wide: bool| {
            let (mut p, mut m, mut v) = start.clone();
            let kernel = UpdateF32 {
                p: &mut p,
                m: &mut m,
                v: &mut v,
                grads: &grads,
                k,
            };
            if wide {
                vectorised(kernel);
            } else {
                kernel.run();
            }
            let bits = |x: &[f32]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            (bits(&p), bits(&m), bits(&v))
        };
        assert_eq!(run(true), run(false));
    }

    /// `step_columns` on two column ranges of wide rows gives, bit for bit, what `step` gives
    /// on the columns copied out (3DGS's SH split), over several steps, and refuses columns that
    /// do not match the group's rows.
    #[test]
    fn step_columns_equals_step_on_the_columns_copied_out() {
        let (rows, stride) = (1_500, 12);
        let value = |i: usize, s: f32| (i as f32 * s).sin() * 10f32.powi((i % 7) as i32 - 3);
        let mut wide: Vec<f32> = (0..rows * stride).map(|i| value(i, 0.13)).collect();
        let split = |x: &[f32], cols: std::ops::Range<usize>| -> Vec<f32> {
            x.chunks_exact(stride)
                .flat_map(|r| r[cols.clone()].to_vec())
                .collect()
        };
        let (mut dc, mut rest) = (split(&wide, 0..3), split(&wide, 3..stride));
        let adam = || {
            let mut a = Adam::new();
            let dc = a
                .add_group("dc", rows * 3, 3, LrSchedule::Constant(2.5e-3))
                .unwrap();
            let rest = a
                .add_group("rest", rows * 9, 9, LrSchedule::Constant(1.25e-4))
                .unwrap();
            (a, dc, rest)
        };
        let (mut a, a_dc, a_rest) = adam();
        let (mut b, b_dc, b_rest) = adam();
        for step in 0..3 {
            let grads: Vec<f32> = (0..rows * stride).map(|i| value(i + step, 0.41)).collect();
            a.step_columns(a_dc, 0, &mut wide, &grads, stride, 0..3)
                .unwrap();
            a.step_columns(a_rest, 0, &mut wide, &grads, stride, 3..stride)
                .unwrap();
            b.step(b_dc, 0, StoreMut::F32(&mut dc), &split(&grads, 0..3))
                .unwrap();
            b.step(
                b_rest,
                0,
                StoreMut::F32(&mut rest),
                &split(&grads, 3..stride),
            )
            .unwrap();
        }
        let bits = |x: &[f32]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&split(&wide, 0..3)), bits(&dc));
        assert_eq!(bits(&split(&wide, 3..stride)), bits(&rest));
        assert_eq!(a.groups(), b.groups());
        let grads = vec![0.0; rows * stride];
        assert!(
            a.step_columns(a_dc, 0, &mut wide, &grads, stride, 0..4)
                .is_err()
        );
        assert!(
            a.step_columns(a_dc, 0, &mut wide, &grads[1..], stride, 0..3)
                .is_err()
        );
        // No columns of a group with no values (`f_rest` at SH degree 0): the step is counted.
        let empty = a
            .add_group("empty", 0, 1, LrSchedule::Constant(1e-3))
            .unwrap();
        let (mut dc_only, zeros) = (vec![0.5f32; rows * 3], vec![0.0f32; rows * 3]);
        a.step_columns(empty, 0, &mut dc_only, &zeros, 3, 3..3)
            .unwrap();
        assert_eq!((a.group(empty).step, dc_only[0]), (1, 0.5));
        assert!(
            a.step_columns(a_dc, 0, &mut wide, &grads, stride, 3..3)
                .is_err()
        );
    }
}
