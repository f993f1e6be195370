//! The wgpu backend's building blocks.

pub(crate) mod sort;
