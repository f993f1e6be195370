//! `evogs-synth`: procedural dynamic scenes with exact ground truth (DESIGN §10), and the demo's
//! embedded scene.
//!
//! A scene is an object — a checkered *body* sphere and a small *satellite* cube beside it — made
//! of SH-degree-0 Gaussians, moved by only the effects its [`SceneSpec`] enables (each an
//! `Option`; an effect that is `None` adds no Gaussians, no computation and no stored data):
//!
//! | effect | what moves | stored ground truth it adds |
//! |---|---|---|
//! | [`RigidMotion`] | body + satellite rotate about the origin and translate | rotations |
//! | [`Wave`] | the body bends: a travelling wave displaces it along +z (non-rigid) | — |
//! | [`LargeMotion`] | body + satellite travel along an arc larger than the object | — |
//! | [`Jump`] | the satellite teleports at a time between two training frames and then moves with a new velocity | — |
//! | [`AppearanceChange`] | the body's colour blends towards a tint and back | per-frame SH DC |
//! | [`Occlusion`] | an extra panel of Gaussians orbits the object, passing in front of every camera | rotations, the panel's Gaussians |
//!
//! Positions are always stored. [`generate`] renders every frame with `splat-raster` from the
//! cameras of the scene's capture [`Protocol`]: `dnerf` (a seeded random camera on a sphere per
//! frame, train times uniform in [0, 1], test and val at held-out times and cameras) or
//! `monocular` (one camera along a short arc, test and val at training times from rig cameras,
//! plus a fixed-camera sequence), with optional [`CaptureNoise`]; [`write_dnerf`] writes the
//! D-NeRF layout plus the ground truth (see [`write`](write_dnerf) for the files). Generation is
//! deterministic for a seed. [`embedded_scene`] is a small scene built in memory, with no files.
//!
//! Motion of Gaussian `i` at time `t` (canonical mean `p`, quaternion `q`):
//! `local = p + wave(p, t) [body] + jump(t) [satellite]`,
//! `x(t) = R(t)·local + T_rigid(t) + T_large(t)`, `q(t) = q_R(t) ⊗ q`; the occluder follows its
//! own orbit. See [`MotionModel`].
//!
//! What it is not: a trainer or a dataset reader (those are `evogs-train` and `evogs-io`; the
//! written scenes load with `evogs_io::read_dnerf_split` like any D-NeRF scene).

mod cameras;
mod effects;
mod embedded;
mod error;
mod ground_truth;
mod motion;
mod object;
mod preset;
mod protocol;
mod scene;
mod summary;
mod write;

pub use effects::{AppearanceChange, Jump, LargeMotion, Occlusion, RigidMotion, Wave};
pub use embedded::embedded_scene;
pub use error::SynthError;
pub use ground_truth::read_ground_truth;
pub use motion::{MotionModel, Part};
pub use preset::{Preset, SceneSpec};
pub use protocol::{CaptureNoise, MONOCULAR_ARC, MONOCULAR_BOB, Protocol, RIG_OFFSET};
pub use scene::{FIXED_SPLIT, SynthFrame, SyntheticScene, Trajectories, generate};
pub use summary::{SceneSummary, SplitSummary};
pub use write::{FIXED_DIR, GROUND_TRUTH_FILE, PLY_FILE, SCENE_FILE, write_dnerf};
