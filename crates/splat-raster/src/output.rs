//! What the passes return: the rendered images with the state the backward pass needs, and the
//! gradients of every raw parameter. The backends' own parts of that state are defined with
//! their backends (`cpu::state`, `gpu::state`) and only held here.

use crate::cpu::state::{BackwardScratch, CpuState};
#[cfg(feature = "wgpu")]
use crate::gpu::state::GpuState;
use crate::options::CullStats;
pub use splat_core::GaussianGrads;

/// A rendered image and the state its backward pass needs.
///
/// Images are row-major (`index = y * width + x`). `depth` is the un-normalised expected depth
/// `Σ z·α·T` over the blended Gaussians (camera-space z); divide by `alpha` for the normalised
/// one. The backward state is bounded as in 3DGS: per pixel the final transmittance and the
/// position of the last contributor, per tile the depth-sorted Gaussian list, per Gaussian its
/// compositing record — no per-(Gaussian, pixel) state.
#[derive(Clone, Debug)]
pub struct ForwardOutput {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Composited colour, background included.
    pub color: Vec<[f32; 3]>,
    /// Accumulated opacity `1 - T_final`.
    pub alpha: Vec<f32>,
    /// Un-normalised expected depth `Σ z·α·T`.
    pub depth: Vec<f32>,
    /// Culling statistics.
    pub stats: CullStats,
    pub(crate) state: BackwardState,
}

impl Default for ForwardOutput {
    /// An empty output (a 0×0 image), for [`Rasterizer::forward_into`](crate::Rasterizer::forward_into)
    /// to render into.
    fn default() -> Self {
        Self {
            width: 0,
            height: 0,
            color: Vec::new(),
            alpha: Vec::new(),
            depth: Vec::new(),
            stats: CullStats::default(),
            state: BackwardState {
                n_gaussians: 0,
                sh_degree: 0,
                active_degree: 0,
                background: [0.0; 3],
                radii: Vec::new(),
                counters: Counters::default(),
                tile_pairs: 0,
                backend: BackendState::Cpu(Box::default()),
            },
        }
    }
}

/// Per-frame state kept for the backward pass: what every backend records, and the backend's
/// own state (the GPU backend keeps its buffers on the device).
#[derive(Clone, Debug)]
pub(crate) struct BackwardState {
    pub n_gaussians: usize,
    pub sh_degree: u32,
    pub active_degree: u32,
    pub background: [f32; 3],
    pub radii: Vec<f32>,
    pub counters: Counters,
    /// Gaussian-tile pairs (total length of the per-tile lists).
    pub tile_pairs: usize,
    pub backend: BackendState,
}

/// The backend-specific part of [`BackwardState`].
#[derive(Clone, Debug)]
pub(crate) enum BackendState {
    /// Boxed: the CPU state (with its reused buffers) is far larger than the GPU's handle.
    Cpu(Box<CpuState>),
    #[cfg(feature = "wgpu")]
    Gpu(Box<GpuState>),
}

/// Work counters of a forward pass.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Counters {
    /// Gaussian-pixel pairs the inner loop visited: for each list entry processed, the pixels of
    /// its bounding box inside the tile.
    pub evaluations: u64,
    /// Gaussian-pixel pairs actually blended.
    pub blended: u64,
}

impl ForwardOutput {
    /// Gaussian-pixel pairs the compositing loop visited: for every tile, the list entries it
    /// processed before all its pixels stopped, times the tile's pixels inside the image.
    pub fn pair_evaluations(&self) -> u64 {
        self.state.counters.evaluations
    }

    /// Mean number of Gaussians blended into a pixel.
    pub fn mean_contributors(&self) -> f64 {
        self.state.counters.blended as f64 / self.color.len().max(1) as f64
    }

    /// The colour on the device after a
    /// [`forward_resident`](crate::Rasterizer::forward_resident) (interleaved RGB f32, one
    /// triple per pixel, background included; `color` is then empty), or `None` after any
    /// other forward pass.
    #[cfg(feature = "wgpu")]
    pub fn device_color(&self) -> Option<&wgpu::Buffer> {
        match &self.state.backend {
            BackendState::Gpu(gpu) => gpu.color.as_deref(),
            BackendState::Cpu(_) => None,
        }
    }

    /// Per-Gaussian screen radius in pixels (3σ of the major axis of Σ2d; 0 when culled).
    pub fn radii(&self) -> &[f32] {
        &self.state.radii
    }

    /// Total length of the per-tile Gaussian lists (Gaussian-tile pairs).
    pub fn tile_pairs(&self) -> usize {
        self.state.tile_pairs
    }
}

/// The loss gradients of a forward pass's per-pixel outputs, row-major as its images, as
/// [`Rasterizer::backward`](crate::Rasterizer::backward) takes them. `alpha` and `depth` are
/// `None` when the loss does not use those outputs (the same as all zeros, without the work).
#[derive(Clone, Copy, Debug)]
pub struct PixelGrads<'a> {
    /// dL/d colour, one RGB triple per pixel.
    pub color: &'a [[f32; 3]],
    /// dL/d alpha (accumulated opacity), one per pixel.
    pub alpha: Option<&'a [f32]>,
    /// dL/d depth (the un-normalised expected depth), one per pixel.
    pub depth: Option<&'a [f32]>,
}

impl<'a> PixelGrads<'a> {
    /// Gradients of the colour only.
    pub fn from_color(color: &'a [[f32; 3]]) -> Self {
        Self {
            color,
            alpha: None,
            depth: None,
        }
    }

    /// The same with dL/d alpha.
    #[must_use]
    pub fn with_alpha(self, alpha: &'a [f32]) -> Self {
        Self {
            alpha: Some(alpha),
            ..self
        }
    }

    /// The same with dL/d depth.
    #[must_use]
    pub fn with_depth(self, depth: &'a [f32]) -> Self {
        Self {
            depth: Some(depth),
            ..self
        }
    }
}

/// What a backward pass returns: the gradients and what became of them.
///
/// Equality compares the gradients and the count, never the scratch buffers
/// [`Rasterizer::backward_into`](crate::Rasterizer::backward_into) keeps in it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BackwardOutput {
    /// The gradients.
    pub grads: GaussianGrads,
    /// Gaussians whose gradient overflowed `f32` and was set to zero instead of NaN/Inf.
    pub zeroed_non_finite: usize,
    /// Buffers only the backward pass uses, kept for the next one by
    /// [`Rasterizer::backward_into`](crate::Rasterizer::backward_into) (empty after
    /// [`Rasterizer::backward`](crate::Rasterizer::backward)).
    pub(crate) scratch: BackwardScratch,
}
