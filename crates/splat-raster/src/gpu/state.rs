//! The GPU backend's part of what a forward pass returns: the device buffers it keeps for its
//! backward pass. [`crate::output`] holds it (in `BackendState::Gpu`); the passes of
//! [`crate::gpu`] fill and read it.

use std::sync::Arc;

use super::frame::FrameUniform;

/// Device buffers a GPU forward pass keeps for its backward pass (from the context's pool:
/// held here, none is handed to another call until the output is dropped).
#[derive(Clone, Debug)]
pub(crate) struct GpuState {
    pub context_id: u64,
    pub frame: FrameUniform,
    pub params: Arc<wgpu::Buffer>,
    pub splats: Arc<wgpu::Buffer>,
    pub isect_ids: Arc<wgpu::Buffer>,
    pub ranges: Arc<wgpu::Buffer>,
    pub final_t: Arc<wgpu::Buffer>,
    pub last: Arc<wgpu::Buffer>,
    /// The colour, kept on the device by a resident forward pass (not read back).
    pub color: Option<Arc<wgpu::Buffer>>,
}
