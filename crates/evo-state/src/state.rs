//! [`EvoState`]: the per-Gaussian evolution state of DESIGN §4, its forward pass, commit and row
//! maintenance (the backward pass is in [`crate::backward`], the per-row arithmetic in the
//! private `kernel` module).

use rayon::prelude::*;

use crate::buffer::{FrameRef, StateBuffer};
use crate::config::{Component, EvoConfig, Gain, HistoryMode};
use crate::error::EvoError;
use crate::frames::{Frames, History};
use crate::gain::GainNet;
use crate::kernel::{PSI_INPUT_CLAMP, RowContext, fin};
use crate::norm::InputNorm;
use crate::step::{Gains, Stats, Step};
use splat_core::RowPlan;

/// Rows per parallel task.
pub(crate) const CHUNK: usize = 1024;
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
    /// Residual memory `M[k]`, per frame, in the buffer's storage; present with evolution on
    /// (with either history mode: the memory is not part of the "buffer" ablation).
    pub(crate) memory: Option<StateBuffer>,
    pub(crate) psi: GainNet,
    /// Running RMS of Ψ's inputs.
    pub(crate) psi_norm: InputNorm,
    pub(crate) saturations: u64,
}

impl EvoState {
    /// A fresh state: no valid frame, zero memory, no input statistics, Ψ initialised from
    /// `seed`.
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
        let memory = config
            .evolution
            .then(|| StateBuffer::new(config.storage, frames.len(), rows, dim));
        Ok(Self {
            valid: vec![false; frames.len()],
            memory,
            psi: GainNet::new(dim + 3, seed)?,
            psi_norm: InputNorm::new(dim + 2),
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

    /// The residual memory `M[k]` of every frame (evolution on): frame k holds the m committed
    /// with frame k's latest training step (zero where that step had no prior, or none was
    /// taken).
    pub fn memory(&self) -> Option<&StateBuffer> {
        self.memory.as_ref()
    }

    /// The running RMS of Ψ's inputs (DESIGN §4.9; see [`crate::norm`]).
    pub fn input_norm(&self) -> &InputNorm {
        &self.psi_norm
    }

    /// The buffer of corrected states (evolution on, history from the buffer).
    pub fn buffer(&self) -> Option<&StateBuffer> {
        self.buffer.as_ref()
    }

    /// Bytes held by the buffer (0 without one).
    pub fn buffer_bytes(&self) -> usize {
        self.buffer.as_ref().map_or(0, StateBuffer::byte_len)
    }

    /// Bytes held by the residual memory (0 with evolution off).
    pub fn memory_bytes(&self) -> usize {
        self.memory.as_ref().map_or(0, StateBuffer::byte_len)
    }

    /// Bytes of per-Gaussian state: buffer plus memory.
    pub fn state_bytes(&self) -> usize {
        self.buffer_bytes() + self.memory_bytes()
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

    pub(crate) fn check_len(
        what: &'static str,
        data: &[f32],
        expected: usize,
    ) -> Result<(), EvoError> {
        if data.len() != expected {
            return Err(EvoError::Length {
                what,
                expected,
                actual: data.len(),
            });
        }
        Ok(())
    }

    pub(crate) fn check_finite(
        what: &'static str,
        data: &[f32],
        stride: usize,
    ) -> Result<(), EvoError> {
        // A branch-free (vectorised) scan per chunk; only a chunk with a bad value is searched.
        const SCAN: usize = 1 << 14;
        let bad_chunk = data
            .par_chunks(SCAN)
            .position_first(|c| !c.iter().fold(true, |ok, v| ok & v.is_finite()));
        let Some(c) = bad_chunk else { return Ok(()) };
        let p = c * SCAN
            + data[c * SCAN..]
                .iter()
                .position(|v| !v.is_finite())
                .unwrap_or(0);
        Err(EvoError::NonFinite {
            what,
            row: p / stride,
            component: p % stride,
            value: data[p],
        })
    }

    /// Forward pass for a query at time `t` with observations `z` (N × D). Read-only: use it
    /// for training steps (then [`EvoState::commit`]) and for evaluation at any time.
    /// History mode `Requery` needs [`EvoState::forward_with`].
    pub fn forward(&self, t: f32, z: &[f32]) -> Result<Step, EvoError> {
        let mut step = Step::empty();
        self.forward_into(t, z, None, &mut step)?;
        Ok(step)
    }

    /// Forward pass with an observation source for history mode `Requery` (ignored with the
    /// buffer).
    pub fn forward_with(
        &self,
        t: f32,
        z: &[f32],
        source: &mut dyn ObservationSource,
    ) -> Result<Step, EvoError> {
        let mut step = Step::empty();
        self.forward_into(t, z, Some(source), &mut step)?;
        Ok(step)
    }

    /// The forward pass into an existing [`Step`], reusing its buffers (a training loop that
    /// keeps one step avoids reallocating, and page-faulting, tens of MB per step). On error
    /// the step is left empty and cannot be committed.
    pub fn forward_into(
        &self,
        t: f32,
        z: &[f32],
        source: Option<&mut dyn ObservationSource>,
        step: &mut Step,
    ) -> Result<(), EvoError> {
        // Until this pass succeeds, the step belongs to no frame and no generation.
        step.frame = None;
        step.generation = u64::MAX;
        step.rows = 0;
        let mut corrected = std::mem::take(&mut step.corrected);
        let mut prior = step.prior.take().unwrap_or_default();
        let mut memory_next = step.memory_next.take().unwrap_or_default();
        let mut stats = step.stats.take().unwrap_or_default();
        let mut psi_cache = step.psi_cache.take().unwrap_or_default();
        let mut inputs = std::mem::take(&mut step.scratch);
        step.gains = Gains::Observation;
        step.input_mean_sq = None;
        step.requeried = false;
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
        let finish = |step: &mut Step| {
            step.time = t;
            step.frame = frame;
            step.history = history;
            step.rows = n;
            step.generation = self.generation;
        };
        if history.len <= 1 {
            corrected.clear();
            corrected.extend_from_slice(z);
            step.corrected = corrected;
            finish(step);
            return Ok(());
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
            floor: self.config.motion_floor as f64 * self.config.extent as f64,
            memory: self.memory.as_ref().map(|m| m.frame(k1)),
        };

        let width = dim + 3;
        // Every element of these is written below; resizing only sets the length.
        prior.resize(n * dim, 0.0);
        memory_next.resize(n * dim, 0.0);
        let full = history.len == 3;
        let stats_rows = if full { n } else { 0 };
        stats.resize(stats_rows, Stats::default());
        inputs.resize(stats_rows * width, 0.0);
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

        let mean_sq = full.then(|| self.normalise_inputs(&mut inputs, n, width));

        let mut used_psi = false;
        let gains = match (history.len, self.config.gain) {
            (2, _) => Gains::Uniform(WARMUP_GAIN),
            (_, Gain::Fixed(k)) => Gains::Uniform(k),
            (_, Gain::Learned) => {
                used_psi = true;
                Gains::Learned(self.psi.forward_into(&inputs, n, &mut psi_cache)?)
            }
        };

        corrected.resize(n * dim, 0.0);
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
        step.stats = full.then_some(stats);
        step.psi_cache = used_psi.then_some(psi_cache);
        step.scratch = inputs;
        step.gains = gains;
        step.input_mean_sq = mean_sq;
        step.prior_scale = s;
        step.requeried = self.config.history == HistoryMode::Requery;
        finish(step);
        Ok(())
    }

    /// Commits a training step at frame k: writes d̃ to `B[k]`, marks the frame valid, writes the
    /// step's residual memory m to `M[k]` (zero when the step had no prior, h < 2) and folds the
    /// step's Ψ-input mean squares into the running RMS (h = 3). Never called for evaluation.
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
        if let Some(memory) = &mut self.memory {
            match &step.memory_next {
                Some(m) => self.saturations += memory.write_frame(k, m),
                None => memory.clear_frame(k),
            }
        }
        if let Some(mean_sq) = &step.input_mean_sq
            && step.rows > 0
        {
            self.psi_norm.update(mean_sq);
        }
        Ok(())
    }

    /// Applies a row plan (prune, clone, split): kept rows stay, new rows copy their parent's
    /// buffer rows and memory rows (all frames). Steps computed before become stale.
    pub fn apply_rows(&mut self, plan: &RowPlan) -> Result<(), EvoError> {
        plan.validate(self.rows)?;
        if let Some(buffer) = &mut self.buffer {
            buffer.apply_rows(plan)?;
        }
        if let Some(memory) = &mut self.memory {
            memory.apply_rows(plan)?;
        }
        self.rows = plan.new_len();
        self.generation += 1;
        Ok(())
    }

    /// Divides Ψ's raw inputs (`rows` × `width`, width = D + 3) by the running RMS of each of
    /// the first D + 2 features (the batch's own RMS before the first training step; at least
    /// the feature's floor, [`crate::norm::rms_floors`]), clamps
    /// them to ±[`PSI_INPUT_CLAMP`], and returns the batch's per-feature mean squares (for the
    /// commit).
    fn normalise_inputs(&self, inputs: &mut [f32], rows: usize, width: usize) -> Vec<f64> {
        let features = width - 1;
        // Per-chunk sums in parallel, then added in chunk order: the same bits for any thread
        // count (rayon's `reduce` would add them in a tree shaped by its splitting).
        let partial: Vec<Vec<f64>> = inputs
            .par_chunks(CHUNK * width)
            .map(|chunk| {
                let mut acc = vec![0.0f64; features];
                for row in chunk.chunks_exact(width) {
                    for (a, &x) in acc.iter_mut().zip(row) {
                        *a += x as f64 * x as f64;
                    }
                }
                acc
            })
            .collect();
        let mut sums = vec![0.0f64; features];
        for acc in &partial {
            for (s, a) in sums.iter_mut().zip(acc) {
                *s += a;
            }
        }
        let mean_sq: Vec<f64> = sums.iter().map(|s| s / rows.max(1) as f64).collect();
        let floors = crate::norm::rms_floors(
            self.dim(),
            self.config.layout.range(Component::Position),
            self.config.motion_floor as f64,
            self.config.extent as f64,
        );
        let factors = self.psi_norm.factors(&mean_sq, &floors);
        let limit = PSI_INPUT_CLAMP as f64;
        inputs.par_chunks_mut(CHUNK * width).for_each(|chunk| {
            for row in chunk.chunks_exact_mut(width) {
                for (x, f) in row.iter_mut().zip(&factors) {
                    *x = (*x as f64 * f).clamp(-limit, limit) as f32;
                }
            }
        });
        mean_sq
    }
}

impl splat_core::FollowsRowPlan for EvoState {
    fn label(&self) -> String {
        "evolution state".into()
    }

    fn row_count(&self) -> usize {
        self.rows()
    }

    fn follow(&mut self, plan: &RowPlan) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        Ok(self.apply_rows(plan)?)
    }
}
