//! [`EvoState`]: the per-Gaussian evolution state and the forward, backward and commit steps of
//! SPEC §4.

use rayon::prelude::*;

use crate::buffer::{FrameRef, StateBuffer};
use crate::config::{Component, EvoConfig, Gain, HistoryMode};
use crate::error::EvoError;
use crate::frames::{Frames, History};
use crate::gain::GainNet;
use crate::rows::{NewRows, RowPlan};
use crate::step::{Backward, Gains, Losses, Stats, Step};

/// Rows per parallel task.
const CHUNK: usize = 1024;
/// Ψ's inputs are clamped to ±this after normalisation, so Ψ stays finite for any finite input.
pub const PSI_INPUT_CLAMP: f32 = 1e4;
/// ε in θ's denominator (the paper's 1e-6).
const THETA_EPS: f64 = 1e-6;
/// The gain of the h = 2 warm-up stage.
pub const WARMUP_GAIN: f32 = 0.5;

/// Supplies observations of the network Φ at other times ("without buffer" ablation).
pub trait ObservationSource {
    /// Writes z(t) for every Gaussian (N × D, row-major) into `out`.
    fn observe(
        &mut self,
        t: f32,
        out: &mut [f32],
    ) -> Result<(), Box<dyn std::error::Error + Send + Sync>>;
}

impl<F> ObservationSource for F
where
    F: FnMut(f32, &mut [f32]) -> Result<(), Box<dyn std::error::Error + Send + Sync>>,
{
    fn observe(
        &mut self,
        t: f32,
        out: &mut [f32],
    ) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        self(t, out)
    }
}

/// The EvoGS evolution state of N Gaussians over T frames.
#[derive(Debug, Clone, PartialEq)]
pub struct EvoState {
    pub(crate) config: EvoConfig,
    pub(crate) frames: Frames,
    pub(crate) rows: usize,
    pub(crate) generation: u64,
    /// Present with evolution on and history from the buffer.
    pub(crate) buffer: Option<StateBuffer>,
    pub(crate) valid: Vec<bool>,
    /// Residual memory m, N × D (f32).
    pub(crate) memory: Vec<f32>,
    pub(crate) psi: GainNet,
    pub(crate) saturations: u64,
}

/// Saturates an f64 into the finite f32 range.
#[inline]
fn fin(x: f64) -> f32 {
    x.clamp(-(f32::MAX as f64), f32::MAX as f64) as f32
}

/// Everything a row of the forward pass reads.
struct RowContext<'a> {
    history: &'a [FrameRef<'a>],
    frames: [usize; 3],
    s: f64,
    beta: f64,
    dim: usize,
    position: Option<std::ops::Range<usize>>,
    extent: f64,
    floor: f64,
    memory: &'a [f32],
}

impl EvoState {
    /// A fresh state: no valid frame, zero memory, Ψ initialised from `seed`.
    pub fn new(
        config: EvoConfig,
        frames: Frames,
        rows: usize,
        seed: u64,
    ) -> Result<Self, EvoError> {
        config.validate()?;
        let dim = config.dim();
        let buffer = (config.evolution && config.history == HistoryMode::Buffer)
            .then(|| StateBuffer::new(config.storage, frames.len(), rows, dim));
        Ok(Self {
            valid: vec![false; frames.len()],
            memory: vec![0.0; rows * dim],
            psi: GainNet::new(dim + 3, seed)?,
            config,
            frames,
            rows,
            generation: 0,
            buffer,
            saturations: 0,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &EvoConfig {
        &self.config
    }

    /// The frames.
    pub fn frames(&self) -> &Frames {
        &self.frames
    }

    /// N, the number of Gaussians.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// D, the deformation dimension.
    pub fn dim(&self) -> usize {
        self.config.dim()
    }

    /// Which frames have been committed.
    pub fn valid(&self) -> &[bool] {
        &self.valid
    }

    /// Residual memory m, N × D.
    pub fn memory(&self) -> &[f32] {
        &self.memory
    }

    /// The buffer of corrected states (evolution on, history from the buffer).
    pub fn buffer(&self) -> Option<&StateBuffer> {
        self.buffer.as_ref()
    }

    /// Bytes held by the buffer (0 without one).
    pub fn buffer_bytes(&self) -> usize {
        self.buffer.as_ref().map_or(0, StateBuffer::byte_len)
    }

    /// The gain network Ψ.
    pub fn psi(&self) -> &GainNet {
        &self.psi
    }

    /// The gain network Ψ, for an optimiser step.
    pub fn psi_mut(&mut self) -> &mut GainNet {
        &mut self.psi
    }

    /// Number of values saturated at ±65504 by f16 storage so far.
    pub fn saturations(&self) -> u64 {
        self.saturations
    }

    /// The history a query at `t` would use.
    pub fn history(&self, t: f32) -> History {
        match self.config.history {
            HistoryMode::Buffer => self
                .frames
                .history(t, self.config.max_gap, |k| self.valid[k]),
            HistoryMode::Requery => self.frames.history(t, self.config.max_gap, |_| true),
        }
    }

    fn check_len(what: &'static str, data: &[f32], expected: usize) -> Result<(), EvoError> {
        if data.len() != expected {
            return Err(EvoError::Length {
                what,
                expected,
                actual: data.len(),
            });
        }
        Ok(())
    }

    fn check_finite(what: &'static str, data: &[f32], stride: usize) -> Result<(), EvoError> {
        match data.par_iter().position_first(|v| !v.is_finite()) {
            None => Ok(()),
            Some(p) => Err(EvoError::NonFinite {
                what,
                row: p / stride,
                component: p % stride,
                value: data[p],
            }),
        }
    }

    /// Forward pass for a query at time `t` with observations `z` (N × D). Read-only: use it
    /// for training steps (then [`EvoState::commit`]) and for evaluation at any time.
    /// History mode `Requery` needs [`EvoState::forward_with`].
    pub fn forward(&self, t: f32, z: &[f32]) -> Result<Step, EvoError> {
        self.forward_impl(t, z, None)
    }

    /// Forward pass with an observation source for history mode `Requery` (ignored with the
    /// buffer).
    pub fn forward_with(
        &self,
        t: f32,
        z: &[f32],
        source: &mut dyn ObservationSource,
    ) -> Result<Step, EvoError> {
        self.forward_impl(t, z, Some(source))
    }

    fn forward_impl(
        &self,
        t: f32,
        z: &[f32],
        source: Option<&mut dyn ObservationSource>,
    ) -> Result<Step, EvoError> {
        let dim = self.dim();
        let n = self.rows;
        if !t.is_finite() {
            return Err(EvoError::NonFiniteTime(t));
        }
        Self::check_len("observation z", z, n * dim)?;
        Self::check_finite("observation z", z, dim)?;
        let frame = self.frames.frame_of(t);
        let history = if self.config.evolution {
            self.history(t)
        } else {
            History {
                frames: [0; 3],
                len: 0,
            }
        };
        let mut step = Step {
            time: t,
            frame,
            history,
            rows: n,
            generation: self.generation,
            corrected: Vec::new(),
            prior: None,
            gains: Gains::Observation,
            stats: None,
            psi_cache: None,
            memory_next: None,
        };
        if history.len <= 1 {
            step.corrected = z.to_vec();
            return Ok(step);
        }

        // History blocks: from the buffer, or re-queried.
        let requeried: Vec<Vec<f32>> = match (self.config.history, source) {
            (HistoryMode::Buffer, _) => Vec::new(),
            (HistoryMode::Requery, None) => return Err(EvoError::NeedsObservationSource),
            (HistoryMode::Requery, Some(source)) => {
                let mut out = Vec::with_capacity(history.len);
                for &k in history.frames() {
                    let time = self.frames.times()[k];
                    let mut block = vec![0.0f32; n * dim];
                    source
                        .observe(time, &mut block)
                        .map_err(|source| EvoError::Source { time, source })?;
                    Self::check_finite("re-queried history observation", &block, dim)?;
                    out.push(block);
                }
                out
            }
        };
        let blocks: Vec<FrameRef<'_>> = match &self.buffer {
            Some(buffer) => history.frames().iter().map(|&k| buffer.frame(k)).collect(),
            None => requeried.iter().map(|b| FrameRef::F32(b)).collect(),
        };
        let times = self.frames.times();
        let [k1, k2, _] = history.frames;
        let s = (t as f64 - times[k1] as f64) / (times[k1] as f64 - times[k2] as f64);
        let ctx = RowContext {
            history: &blocks,
            frames: history.frames,
            s,
            beta: self.config.beta as f64,
            dim,
            position: self.config.layout.range(Component::Position),
            extent: self.config.extent as f64,
            floor: self.config.motion_floor as f64 * self.config.extent as f64,
            memory: &self.memory,
        };

        let width = dim + 3;
        let mut prior = vec![0.0f32; n * dim];
        let mut memory_next = vec![0.0f32; n * dim];
        let full = history.len == 3;
        let stats_rows = if full { n } else { 0 };
        let mut stats = vec![Stats::default(); stats_rows];
        let mut inputs = vec![0.0f32; stats_rows * width];
        if full {
            prior
                .par_chunks_mut(CHUNK * dim)
                .zip(memory_next.par_chunks_mut(CHUNK * dim))
                .zip(stats.par_chunks_mut(CHUNK))
                .zip(inputs.par_chunks_mut(CHUNK * width))
                .enumerate()
                .for_each(|(c, (((p, m), s), x))| {
                    for r in 0..s.len() {
                        let i = c * CHUNK + r;
                        let rows = r * dim..(r + 1) * dim;
                        ctx.row(
                            i,
                            &z[i * dim..(i + 1) * dim],
                            &mut p[rows.clone()],
                            &mut m[rows],
                            Some((&mut s[r], &mut x[r * width..(r + 1) * width])),
                        );
                    }
                });
        } else {
            prior
                .par_chunks_mut(CHUNK * dim)
                .zip(memory_next.par_chunks_mut(CHUNK * dim))
                .enumerate()
                .for_each(|(c, (p, m))| {
                    for r in 0..p.len() / dim {
                        let i = c * CHUNK + r;
                        let rows = r * dim..(r + 1) * dim;
                        ctx.row(
                            i,
                            &z[i * dim..(i + 1) * dim],
                            &mut p[rows.clone()],
                            &mut m[rows],
                            None,
                        );
                    }
                });
        }

        let mut psi_cache = None;
        let gains = match (history.len, self.config.gain) {
            (2, _) => Gains::Uniform(WARMUP_GAIN),
            (_, Gain::Fixed(k)) => Gains::Uniform(k),
            (_, Gain::Learned) => {
                let (k, cache) = self.psi.forward(&inputs, n)?;
                psi_cache = Some(cache);
                Gains::Learned(k)
            }
        };

        let mut corrected = vec![0.0f32; n * dim];
        corrected
            .par_chunks_mut(CHUNK * dim)
            .zip(prior.par_chunks(CHUNK * dim))
            .zip(z.par_chunks(CHUNK * dim))
            .enumerate()
            .for_each(|(c, ((out, p), z))| {
                for (r, ((out, p), z)) in out
                    .chunks_mut(dim)
                    .zip(p.chunks(dim))
                    .zip(z.chunks(dim))
                    .enumerate()
                {
                    let k = gains.at(c * CHUNK + r) as f64;
                    for ((o, &p), &z) in out.iter_mut().zip(p).zip(z) {
                        *o = fin((1.0 - k) * p as f64 + k * z as f64);
                    }
                }
            });

        step.corrected = corrected;
        step.prior = Some(prior);
        step.memory_next = Some(memory_next);
        if full {
            step.stats = Some(stats);
        }
        step.psi_cache = psi_cache;
        step.gains = gains;
        Ok(step)
    }

    /// Backward pass: from dL_render/dd̃ (`dl_dd`, N × D) and the (stop-gradient) opacities
    /// (N, activated), the gradients of `L_render + λ1 L_sup + λ2 L_prior` with respect to z
    /// and to Ψ's parameters. d̂ and Ψ's inputs are constants.
    pub fn backward(
        &self,
        step: &Step,
        z: &[f32],
        dl_dd: &[f32],
        opacity: &[f32],
    ) -> Result<Backward, EvoError> {
        let dim = self.dim();
        let n = step.rows;
        Self::check_len("observation z", z, n * dim)?;
        Self::check_len("render gradient dL/dd", dl_dd, n * dim)?;
        Self::check_len("opacity", opacity, n)?;
        Self::check_finite("observation z", z, dim)?;
        Self::check_finite("render gradient dL/dd", dl_dd, dim)?;
        Self::check_finite("opacity", opacity, 1)?;
        let Some(prior) = step.prior.as_deref() else {
            // d̃ = z: no EvoGS loss, identity Jacobian.
            return Ok(Backward {
                dz: dl_dd.to_vec(),
                dpsi: None,
                losses: Losses::default(),
            });
        };
        let inv_n = 1.0 / n.max(1) as f64;
        let l1 = self.config.lambda_sup as f64;
        let l2 = self.config.lambda_prior as f64;
        let learned = matches!(step.gains, Gains::Learned(_));
        let mut dz = vec![0.0f32; n * dim];
        let mut dk = vec![0.0f32; if learned { n } else { 0 }];
        let dk_chunks: Vec<&mut [f32]> = if learned {
            dk.chunks_mut(CHUNK).collect()
        } else {
            Vec::new()
        };
        let mut dk_iter = dk_chunks.into_iter();
        let chunk_count = n.div_ceil(CHUNK);
        let dk_slots: Vec<Option<&mut [f32]>> = (0..chunk_count).map(|_| dk_iter.next()).collect();
        let partial: Vec<(f64, f64)> = dz
            .par_chunks_mut(CHUNK * dim)
            .zip(dk_slots.into_par_iter())
            .enumerate()
            .map(|(c, (dz, mut dk))| {
                let (mut sup, mut pri) = (0.0f64, 0.0f64);
                for r in 0..dz.len() / dim {
                    let i = c * CHUNK + r;
                    let k = step.gains.at(i) as f64;
                    let op = opacity[i] as f64;
                    let mut dki = 0.0f64;
                    for j in 0..dim {
                        let e = i * dim + j;
                        let (zv, pv, dv) = (z[e] as f64, prior[e] as f64, step.corrected[e] as f64);
                        let res = dv - zv;
                        sup += res * res;
                        pri += op * (pv - zv) * (pv - zv);
                        let g = dl_dd[e] as f64 + l1 * 2.0 * inv_n * res;
                        dz[r * dim + j] =
                            fin(g * k - l1 * 2.0 * inv_n * res + l2 * 2.0 * inv_n * op * (zv - pv));
                        dki += g * (zv - pv);
                    }
                    if let Some(dk) = dk.as_deref_mut() {
                        dk[r] = fin(dki);
                    }
                }
                (sup, pri)
            })
            .collect();
        let (sup, pri) = partial
            .iter()
            .fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
        let losses = Losses {
            sup: sup * inv_n,
            prior: pri * inv_n,
        };
        let dpsi = match (learned, &step.psi_cache) {
            (true, Some(cache)) => Some(self.psi.backward(cache, &dk)?),
            _ => None,
        };
        Ok(Backward { dz, dpsi, losses })
    }

    /// Commits a training step at a frame time: writes d̃ to the frame's buffer block, marks
    /// the frame valid and updates the residual memory (h >= 2). Never called for evaluation.
    pub fn commit(&mut self, step: &Step) -> Result<(), EvoError> {
        let k = step.frame.ok_or(EvoError::NotAFrame(step.time))?;
        if step.rows != self.rows || step.generation != self.generation {
            return Err(EvoError::StaleStep {
                step_rows: step.rows,
                step_generation: step.generation,
                rows: self.rows,
                generation: self.generation,
            });
        }
        if !self.config.evolution {
            return Ok(());
        }
        if let Some(buffer) = &mut self.buffer {
            self.saturations += buffer.write_frame(k, &step.corrected);
        }
        self.valid[k] = true;
        if let Some(m) = &step.memory_next {
            self.memory.copy_from_slice(m);
        }
        Ok(())
    }

    /// Applies a row plan (prune, clone, split): kept rows stay, new rows copy their parent's
    /// buffer rows (all frames) and memory. Steps computed before become stale.
    pub fn apply_rows(&mut self, plan: &RowPlan) -> Result<(), EvoError> {
        plan.validate(self.rows)?;
        let dim = self.dim();
        if let Some(buffer) = &mut self.buffer {
            buffer.apply_rows(plan)?;
        }
        plan.apply(&mut self.memory, dim, NewRows::CopyParent)?;
        self.rows = plan.new_len();
        self.generation += 1;
        Ok(())
    }
}

impl RowContext<'_> {
    /// Prior, next memory and (h = 3) statistics and Ψ inputs of row `i`.
    #[inline]
    fn row(
        &self,
        i: usize,
        z: &[f32],
        prior: &mut [f32],
        memory_next: &mut [f32],
        full: Option<(&mut Stats, &mut [f32])>,
    ) {
        const MAX_DIM: usize = 14;
        let d = self.dim;
        let mut h = [[0.0f64; MAX_DIM]; 3];
        for (slot, block) in h.iter_mut().zip(self.history) {
            block.read_row(i, &mut slot[..d]);
        }
        let m_old = &self.memory[i * d..(i + 1) * d];
        for j in 0..d {
            let p = fin(h[0][j] + self.s * (h[0][j] - h[1][j]));
            prior[j] = p;
            memory_next[j] =
                fin(self.beta * m_old[j] as f64 + (1.0 - self.beta) * (z[j] as f64 - p as f64));
        }
        let Some((stats, inputs)) = full else { return };
        let [k1, k2, k3] = self.frames;
        let (mut n1, mut n2, mut dot) = (0.0f64, 0.0f64, 0.0f64);
        if let Some(pos) = &self.position {
            for j in pos.clone() {
                let v1 = (h[0][j] - h[1][j]) / (k1 - k2) as f64;
                let v2 = (h[1][j] - h[2][j]) / (k2 - k3) as f64;
                n1 += v1 * v1;
                n2 += v2 * v2;
                dot += v1 * v2;
            }
        }
        let (n1, n2) = (n1.sqrt(), n2.sqrt());
        let theta = if n1 < self.floor || n2 < self.floor || !(n1 * n2).is_finite() {
            // Below the motion floor a Gaussian moves consistently; beyond f64 range (only with
            // absurd states) the angle is not measurable and counts as consistent too.
            0.0
        } else {
            (dot / (n1 * n2 + THETA_EPS)).clamp(-1.0, 1.0).acos()
        };
        *stats = Stats {
            speed_prev: fin(n2),
            speed_last: fin(n1),
            theta: theta as f32,
        };
        let clamp = |x: f64| (x.clamp(-(PSI_INPUT_CLAMP as f64), PSI_INPUT_CLAMP as f64)) as f32;
        for j in 0..d {
            let in_scene_units = self.position.as_ref().is_some_and(|p| p.contains(&j));
            let scale = if in_scene_units {
                1.0 / self.extent
            } else {
                1.0
            };
            inputs[j] = clamp(memory_next[j] as f64 * scale);
        }
        inputs[d] = clamp(n2 / self.extent);
        inputs[d + 1] = clamp(n1 / self.extent);
        inputs[d + 2] = theta as f32;
    }
}
