//! `evo-state`: the EvoGS deformation evolution state machine (DESIGN §4 in the repository's `docs/DESIGN.md`), usable with any renderer.
//!
//! What it is: per-Gaussian persistent deformation states over the training frames — the buffer
//! of corrected states `B[k][i] ∈ R^D` and beside it the per-frame residual memory `M[k][i]`
//! (both f32 or f16), the second-order time-scaled prior, the motion statistics, the gain `K`
//! (warm-up rules, or the network Ψ, a [`tiny_nn::Mlp`], on inputs divided by their running RMS),
//! the correction `d̃ = (1-K) d̂ + K z`, the losses `L_sup`, `L_prior` with their gradients to the
//! observation `z`, to Ψ and (history re-queried from Φ) to the observations at the history
//! times, committing training steps, row maintenance for densification ([`RowPlan`] of
//! `splat-core`, shared by every per-Gaussian array), and saving/loading the whole state as safetensors,
//! bit-exact.
//!
//! What it is not: the observation network Φ (the caller produces `z`, N × D, with any network),
//! a renderer, or an optimiser (the caller steps Ψ's parameters, e.g. with `tiny_nn::Adam`).
//!
//! # Walk-through
//!
//! ```
//! use evo_state::{EvoConfig, EvoState, Frames, RowPlan};
//!
//! // Training frames (sorted distinct timestamps; not necessarily uniform).
//! let frames = Frames::from_timestamps([0.0, 0.1, 0.25, 0.3, 0.5])?;
//! let config = EvoConfig::default(); // position + rotation + scale: D = 10, learned gain
//! let (n, d) = (4, config.dim());
//! let mut state = EvoState::new(config, frames, n, 7)?;
//!
//! for k in 0..5 {
//!     let t = state.frames().times()[k];
//!     let z = vec![t; n * d]; // Φ's observations at time t (here: anything finite)
//!     let step = state.forward(t, &z)?; // prior, statistics, gain, corrected d̃
//!     let deformation = step.corrected(); // add to the canonical raw parameters, render
//!     assert_eq!(deformation.len(), n * d);
//!     let dl_dd = vec![0.0; n * d]; // dL_render/dd̃ from the renderer's backward
//!     let opacity = vec![1.0; n]; // activated opacities, used as constants (sg)
//!     let grads = state.backward(&step, &z, &dl_dd, &opacity)?;
//!     // grads.dz goes back into Φ; grads.dpsi (from the 4th frame on) into Ψ's optimiser.
//!     assert_eq!(grads.dpsi.is_some(), k >= 3);
//!     // training steps only: writes B[k] and M[k], sets valid[k], updates Ψ's input RMS
//!     state.commit(&step)?;
//! }
//!
//! // A training loop can keep one Step and one Backward and reuse their buffers with
//! // `forward_into` / `backward_into` (same results, no per-step allocation).
//!
//! // Evaluation at any time (between or beyond frames) never writes.
//! let step = state.forward(0.4, &vec![0.0; n * d])?;
//! assert_eq!(step.history().frames(), &[3, 2, 1]);
//!
//! // Densification: keep rows 0, 2, 3; split row 1 into two children.
//! state.apply_rows(&RowPlan { kept: vec![0, 2, 3], parent_from_new: vec![1, 1] })?;
//! assert_eq!(state.rows(), 5);
//!
//! let dir = tempfile::tempdir()?;
//! let path = dir.path().join("evo.safetensors");
//! state.save(&path)?;
//! assert_eq!(EvoState::load(&path)?, state);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Choices beyond the paper (DESIGN §4)
//!
//! - **History window.** A query at time t sits at frame position p = #{k : t_k < t}; k1 is the
//!   latest valid frame with p - k1 <= `max_gap`, k2 the latest valid with k1 - k2 <= `max_gap`,
//!   and so on. A query beyond the last frame extrapolates from the last frames.
//! - **Residual memory.** Defined where a prior exists (h >= 2): `m = β M[k1] + (1-β)(z - d̂)`
//!   (the paper's `m^t = β m^{t-1} + (1-β) r^t`, with the history frame k1 as t-1). Ψ sees this m
//!   as a constant; a commit writes it to `M[k]`, or zero when the step had no prior (h < 2).
//! - **Statistics.** `v1 = (x_k1 - x_k2)/(k1 - k2)`, `v2 = (x_k2 - x_k3)/(k2 - k3)` (per frame
//!   spacing); with the position component disabled, speeds are 0 and θ = 0.
//! - **Ψ inputs** `[m, |v2|, |v1|, θ]`: m and the speeds are divided per feature by their running
//!   RMS ([`norm`]; θ, in radians, as it is); all are clamped to ±1e4.
//! - **Fixed gain** replaces only the learned stage (h = 3); the warm-up (h <= 1: d̃ = z,
//!   h = 2: K = 0.5) is kept, as in the paper's ablation ("all other settings unchanged").
//! - **History re-query** ("without buffer"): no buffer is stored and every frame before the
//!   query counts as available; the caller's [`ObservationSource`] gives z at those times, and
//!   the backward pass returns dL/dz at the history times k1, k2 ([`Backward::history`]) for the
//!   caller to pass back through Φ. The residual memory is kept per frame as with the buffer.
//! - **Evolution off:** d̃ = z, no buffer, no memory, EvoGS losses 0, dL/dz = dL_render/dd̃.
//! - **Numerics.** Per-element arithmetic is f64 and results saturate into the f32 range; f16
//!   storage saturates at ±65504 and counts saturations; non-finite z, dL/dd̃ or opacities are
//!   rejected naming the Gaussian (row) and component.

pub mod backward;
pub mod buffer;
pub mod config;
pub mod error;
pub mod frames;
pub mod gain;
mod kernel;
pub mod norm;
pub mod persist;
pub mod state;
pub mod step;

pub use buffer::StateBuffer;
pub use config::{Component, EvoConfig, Gain, HistoryMode, Layout, ParseError, Storage};
pub use error::EvoError;
pub use frames::{Frames, History};
pub use gain::GainNet;
pub use kernel::PSI_INPUT_CLAMP;
pub use norm::InputNorm;
pub use splat_core::{NewRows, RowPlan, RowPlanError};
pub use state::{EvoState, ObservationSource, WARMUP_GAIN};
pub use step::{Backward, Gains, HistoryGrads, Losses, Stats, Step};
