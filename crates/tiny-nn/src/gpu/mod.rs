//! Networks and the optimiser on the GPU (cargo feature `wgpu`, issue W): WGSL twins of
//! [`Mlp`](crate::Mlp)'s forward and backward ([`GpuMlp`]), of D-3DGS's
//! [`DeformNet`](crate::DeformNet) with its sinusoidal encoding ([`GpuDeformNet`]) and of
//! [`Adam`](crate::Adam)'s step ([`GpuAdam`]), on buffers that stay on the device, each checked against its CPU
//! implementation by this crate's `gpu_*` tests (on lavapipe in CI). [`DeformRunner`] runs the
//! deformation network for a caller whose inputs and outputs are on the host (the trainer's
//! D-3DGS backbone), keeping the device's buffers between calls, and can keep the parameters,
//! their gradient and Adam's moments there (resident), read back only when the host asks.
//!
//! Precision: f32 storage and arithmetic, as the CPU's f32 path; sums run in other orders than
//! the CPU's gemm, so values differ by f32 rounding (the tests state how much). Every sum has a
//! fixed order: a run on one device repeats itself bit for bit.
//!
//! What it is not: the reference (that is the CPU code beside it), f16 storage, or the other
//! encoders (tri-plane, B-spline, hash grid) and networks (EvoGS's Φ, HexPlane, Grid4D), which
//! stay on the CPU for now.

mod adam;
mod deform;
mod mlp;

pub use adam::{AdamBuffers, AdamLayout, GpuAdam};
pub use deform::{DeformRunner, DeformWorkspace, DeviceDeformNet, GpuDeformNet};
pub use mlp::{CHUNK_ROWS, DeviceMlp, GpuMlp, MlpKernels, MlpWorkspace};
