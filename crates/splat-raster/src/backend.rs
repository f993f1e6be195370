//! Choosing a rasterizer backend at run time: `cpu`, `wgpu` or `auto`.
//!
//! `auto` runs on wgpu when the default adapter is a hardware GPU and on the CPU otherwise (no
//! adapter, or a software one such as Mesa's lavapipe, which is slower than the CPU backend);
//! [`BackendInfo`] says what was chosen and why, naming the adapter. `wgpu` runs on whatever
//! adapter there is, software included, and without one is an error, never a panic.

use std::fmt;

use serde::{Deserialize, Serialize};
use splat_core::one_word::{OneWord, unknown_message};

use crate::Rasterizer;
use crate::cpu::CpuRasterizer;
use crate::error::RasterError;

/// A rasterizer usable from any thread, as [`select_rasterizer`] returns it.
pub type DynRasterizer = Box<dyn Rasterizer + Send + Sync>;

/// The backend a user asks for, spelled `cpu`, `wgpu` or `auto`.
#[derive(strum::Display, strum::EnumString, strum::IntoStaticStr, strum::VariantNames)]
#[strum(serialize_all = "lowercase", parse_err_ty = RasterError, parse_err_fn = unknown_backend)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BackendChoice {
    /// [`CpuRasterizer`] (deterministic; the default).
    #[default]
    Cpu,
    /// `WgpuRasterizer` on the default adapter, whatever it is.
    Wgpu,
    /// wgpu on a hardware adapter, the CPU otherwise.
    Auto,
}

/// [`RasterError::UnknownBackend`] for `name`: the error of [`BackendChoice`]'s `from_str`.
fn unknown_backend(name: &str) -> RasterError {
    RasterError::UnknownBackend {
        name: name.to_string(),
        message: unknown_message::<BackendChoice>(name),
    }
}

/// The noun of [`RasterError::UnknownBackend`]'s message.
impl OneWord for BackendChoice {
    const FIELD: &'static str = "backend";
}

impl BackendChoice {
    /// Every choice.
    pub const ALL: [BackendChoice; 3] = [Self::Cpu, Self::Wgpu, Self::Auto];

    /// Its name on the command line and in files.
    pub fn name(self) -> &'static str {
        self.into()
    }
}

/// The backend that runs ([`Display`](fmt::Display): `cpu` or `wgpu`).
#[derive(strum::Display)]
#[strum(serialize_all = "lowercase")]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BackendKind {
    /// The CPU backend.
    Cpu,
    /// The wgpu backend.
    Wgpu,
}

/// What [`select_rasterizer`] chose, on which adapter, and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BackendInfo {
    /// What was asked for.
    pub choice: BackendChoice,
    /// What runs.
    pub kind: BackendKind,
    /// The wgpu adapter looked at, as `name (backend, hardware|software, ...)`, when one was.
    pub adapter: Option<String>,
    /// Why this backend (e.g. `auto: adapter llvmpipe is a software rasterizer`).
    pub reason: String,
}

impl fmt::Display for BackendInfo {
    /// One line, e.g. `backend: wgpu on NVIDIA H100 (Vulkan, hardware, f32 atomics) (asked: wgpu)`
    /// or `backend: cpu (auto: adapter llvmpipe ... is software)`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (self.kind, &self.adapter) {
            (BackendKind::Wgpu, Some(adapter)) => {
                write!(f, "backend: wgpu on {adapter} ({})", self.reason)
            }
            (kind, _) => write!(f, "backend: {kind} ({})", self.reason),
        }
    }
}

fn cpu(
    choice: BackendChoice,
    adapter: Option<String>,
    reason: String,
) -> (DynRasterizer, BackendInfo) {
    (
        Box::new(CpuRasterizer::new()),
        BackendInfo {
            choice,
            kind: BackendKind::Cpu,
            adapter,
            reason,
        },
    )
}

/// The rasterizer for `choice` and what it is. `wgpu` without a usable adapter (or in a build
/// without the `wgpu` feature) is [`RasterError::Gpu`]; `auto` then falls back to the CPU.
pub fn select_rasterizer(
    choice: BackendChoice,
) -> Result<(DynRasterizer, BackendInfo), RasterError> {
    match choice {
        BackendChoice::Cpu => Ok(cpu(choice, None, "asked: cpu".to_string())),
        BackendChoice::Wgpu => wgpu_rasterizer(choice),
        BackendChoice::Auto => Ok(auto(choice)),
    }
}

#[cfg(feature = "wgpu")]
fn wgpu_rasterizer(choice: BackendChoice) -> Result<(DynRasterizer, BackendInfo), RasterError> {
    let raster = crate::gpu::WgpuRasterizer::new()?;
    let adapter = raster.adapter().to_string();
    Ok((
        Box::new(raster),
        BackendInfo {
            choice,
            kind: BackendKind::Wgpu,
            adapter: Some(adapter),
            reason: "asked: wgpu".to_string(),
        },
    ))
}

#[cfg(not(feature = "wgpu"))]
fn wgpu_rasterizer(_choice: BackendChoice) -> Result<(DynRasterizer, BackendInfo), RasterError> {
    Err(RasterError::Gpu {
        stage: "adapter",
        message: "this build of splat-raster has no wgpu backend (cargo feature `wgpu` off)"
            .to_string(),
    })
}

#[cfg(feature = "wgpu")]
fn auto(choice: BackendChoice) -> (DynRasterizer, BackendInfo) {
    use std::sync::Arc;

    use crate::gpu::{AtomicMode, GpuContext, WgpuRasterizer};

    let ctx = match GpuContext::new() {
        Ok(ctx) => Arc::new(ctx),
        Err(e) => return cpu(choice, None, format!("auto: {e}")),
    };
    let summary = ctx.adapter().clone();
    if !summary.hardware {
        return cpu(
            choice,
            Some(summary.to_string()),
            format!(
                "auto: adapter {} is a software rasterizer, slower than the CPU backend",
                summary.name
            ),
        );
    }
    let atomics = if summary.float32_atomics {
        AtomicMode::NativeF32
    } else {
        AtomicMode::CompareExchange
    };
    match WgpuRasterizer::with_context(ctx, atomics) {
        Ok(raster) => (
            Box::new(raster),
            BackendInfo {
                choice,
                kind: BackendKind::Wgpu,
                adapter: Some(summary.to_string()),
                reason: "auto: hardware adapter".to_string(),
            },
        ),
        Err(e) => cpu(choice, Some(summary.to_string()), format!("auto: {e}")),
    }
}

#[cfg(not(feature = "wgpu"))]
fn auto(choice: BackendChoice) -> (DynRasterizer, BackendInfo) {
    cpu(
        choice,
        None,
        "auto: built without the wgpu backend (cargo feature `wgpu` off)".to_string(),
    )
}
