//! `evogs-backbones`: the deformation backbones of the evogs trainer.
//!
//! What it is: the [`Backbone`] trait (forward, backward, parameters, weights) with its optional
//! per-Gaussian part ([`PerGaussianState`]), and the backbones on it:
//!
//! - [`backbone`]: the traits; each backbone hands back its deformation rows in its own
//!   [`Layout`] (the row is defined once, in `splat_core::deform`);
//! - [`d3dgs`]: the D-3DGS deformation MLP ([`D3dgsBackbone`], shaped by [`NetSettings`]);
//! - [`hex_backbone`]: 4DGaussians' HexPlane field ([`HexBackbone`], `--backbone 4dgs`);
//! - [`grid4d_backbone`]: Grid4D's hash-grid field ([`Grid4dBackbone`], `--backbone grid4d`);
//!   [`grid4d_phi`]: the same field as EvoGS's Φ ([`Grid4dPhi`]);
//! - [`evo_backbone`], [`evo_settings`]: EvoGS (Φ + evo-state + Ψ, [`EvoBackbone`]) and its
//!   switches ([`EvoSettings`]), recorded in a run's `config.json`;
//! - [`scgs`]: SC-GS's sparse control points ([`ScgsBackbone`], `--backbone scgs`): a network
//!   on a few hundred control points, linear blend skinning of each Gaussian by its nearest ones,
//!   and the ARAP loss on their trajectories ([`ScgsSettings`]); EvoGS on it with the state on
//!   every Gaussian ([`EvoBackbone`] of `scgs::phi::ScgsPhi`) or on the control points
//!   ([`ScgsControlEvo`], [`EvolutionOn`]);
//! - [`observer`]: what a field implements to be Φ ([`Observer`]); [`hex_phi`]: 4DGaussians'
//!   field as Φ ([`HexPhi`]);
//! - [`one_word`]: settings spelled by one word and the one message for an unknown word;
//! - `Backbone::use_device` (cargo feature `wgpu`): a backbone's network on a wgpu device
//!   (D-3DGS's, through `tiny_nn::gpu::DeformRunner`; the others answer that they have no
//!   device form yet);
//! - `cli` (cargo feature `clap`): EvoGS's switches as command-line flags (`EvoArgs`), each
//!   default read from [`EvoSettings::default`], and the parser of one-word settings.
//!
//! - [`choice`]: the method and backbone a run names ([`Method`], [`BackboneKind`]) and the one
//!   function that builds it ([`make_backbone`], from a [`BackboneRun`]).
//!
//! A new backbone is a module here implementing [`Backbone`] (and [`PerGaussianState`] only when
//! it keeps rows of its own per Gaussian), a [`BackboneKind`] variant and its arm in
//! [`make_backbone`]; the trainer names no backbone (ARCHITECTURE.md §5).
//!
//! What it is not: the trainer (Gaussians, Adam, densification, the loop, checkpoints: that is
//! `evogs-train`, which owns the run's whole config), the deformation row and its application to
//! Gaussians (`splat-core`'s `Layout` and `DeformedGeometry`), a network library (`tiny-nn`) or
//! the evolution state (`evo-state`). It does not depend on the rasterizer.
//!
//! Deliberate deviation from the paper (DESIGN §4.7): EvoGS's motion floor is 1e-3 of the scene
//! extent per frame spacing, not 1e-6 (evo-state keeps 1e-6; the trainer sets its own,
//! `--motion-floor`). Below it θ is measurement noise that would block the uncertainty trigger
//! everywhere; see [`evo_settings::TRAINER_MOTION_FLOOR`] for the measurement and the reasoning.

pub mod backbone;
pub mod choice;
#[cfg(feature = "clap")]
pub mod cli;
pub mod d3dgs;
pub mod error;
pub mod evo_backbone;
pub mod evo_settings;
pub mod grid4d_backbone;
pub mod grid4d_phi;
pub mod hex_backbone;
pub mod hex_phi;
pub mod observer;
pub mod one_word;
pub mod scgs;
pub mod working_memory;

pub use backbone::{Backbone, DensifyCues, GainStats, PerGaussianState};
pub use choice::{
    BackboneKind, BackboneRun, BackboneSettings, Method, make_backbone, parameter_count,
};
pub use d3dgs::{D3dgsBackbone, NetInit, NetSettings};
pub use error::BackboneError;
pub use evo_backbone::EvoBackbone;
pub use evo_settings::{
    DensifyPolicy, EvoConfig, EvoSettings, Gain, HistoryMode, Layout, PlaneCombine, Precision,
    Storage,
};
pub use grid4d_backbone::{Grid4dBackbone, Grid4dLr, Grid4dRun};
pub use grid4d_phi::Grid4dPhi;
pub use hex_backbone::HexBackbone;
pub use hex_phi::HexPhi;
pub use observer::Observer;
pub use one_word::{OneWord, unknown_message};
pub use scgs::control_evo::ScgsControlEvo;
pub use scgs::{EvolutionOn, Placement, ScgsBackbone, ScgsSettings};
pub use working_memory::WorkingBytes;
