//! The GPU backend's part of what a forward pass returns: the device buffers it keeps for its
//! backward pass. [`crate::output`] holds it (in `BackendState::Gpu`); the passes of
//! [`crate::gpu`] fill and read it.

use super::frame::FrameUniform;

/// Device buffers a GPU forward pass keeps for its backward pass.
#[derive(Clone, Debug)]
pub(crate) struct GpuState {
    pub context_id: u64,
    pub frame: FrameUniform,
    pub params: wgpu::Buffer,
    pub splats: wgpu::Buffer,
    pub isect_ids: wgpu::Buffer,
    pub ranges: wgpu::Buffer,
    pub final_t: wgpu::Buffer,
    pub last: wgpu::Buffer,
}
