//! The CPU backend's part of what the passes return: the state a forward pass keeps for its
//! backward pass (with the buffers the next forward pass reuses), and the backward pass's own
//! buffers. [`crate::output`] holds them (in `BackendState::Cpu` and `BackwardOutput`); the
//! passes of [`crate::cpu`] fill and read them.
//!
//! What it is not: the passes themselves.

use super::composite::{CpuKernel, Kernels};
use super::project::{Splat, SplatGrads};
use super::tiles::{BinScratch, TileLists};

/// The CPU backend's backward state, and the buffers a forward pass reuses.
#[derive(Clone, Debug)]
pub(crate) struct CpuState {
    /// The kernels the forward pass ran (the backward pass runs the same).
    pub kernels: Kernels,
    /// The drawn Gaussians' records in depth order (indexed by the lists' ranks).
    pub splats: Vec<Splat>,
    pub lists: TileLists,
    /// Tile-major (tile, lane) final transmittance.
    pub final_t: Vec<f32>,
    /// Tile-major one-past-last contributor position in the tile list.
    pub last: Vec<u32>,
    /// Buffers only the forward pass uses, kept for the next one by
    /// [`Rasterizer::forward_into`](crate::Rasterizer::forward_into) (empty after
    /// [`Rasterizer::forward`](crate::Rasterizer::forward)).
    pub scratch: Scratch,
}

impl Default for CpuState {
    fn default() -> Self {
        Self {
            kernels: Kernels::of(CpuKernel::Simd),
            splats: Vec::new(),
            lists: TileLists::default(),
            final_t: Vec::new(),
            last: Vec::new(),
            scratch: Scratch::default(),
        }
    }
}

/// The forward pass's own buffers (only their capacity outlives a pass).
#[derive(Clone, Debug, Default)]
pub(crate) struct Scratch {
    /// Per Gaussian (by index), its record (default when culled).
    pub splats: Vec<Splat>,
    /// Per Gaussian, its tile rectangle (None when culled).
    pub rects: Vec<Option<[u32; 4]>>,
    /// Per Gaussian, its camera z (0 when culled).
    pub depth: Vec<f32>,
    /// Tile-major (tile, lane) colour and un-normalised depth.
    pub color_t: Vec<[f32; 3]>,
    pub depth_t: Vec<f32>,
    /// The binning's buffers.
    pub bin: BinScratch,
}

/// The CPU backward pass's own buffers (only their capacity outlives a pass).
#[derive(Clone, Debug, Default)]
pub(crate) struct BackwardScratch {
    /// Per tile-list entry, its gradient (tile-major, as the lists).
    pub entries: Vec<SplatGrads>,
}

impl PartialEq for BackwardScratch {
    /// Scratch holds no result: any two are equal.
    fn eq(&self, _: &Self) -> bool {
        true
    }
}
