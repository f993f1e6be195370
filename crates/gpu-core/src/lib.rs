//! `gpu-core`: the wgpu building blocks the workspace's GPU code shares.
//!
//! What it is: with the cargo feature `wgpu`, a device context ([`GpuContext`]: adapter, device,
//! queue, what the adapter offers, and the host–device [`Traffic`] recorded on it), buffer and
//! binding helpers that count what they move ([`buffers`]), dispatch helpers ([`encode`]), a
//! stable radix sort of `u32` keys with `u32` values ([`RadixSorter`]) and the device-wide prefix
//! sum it runs ([`PrefixSum`]), GPU timestamps of labelled spans where the adapter has them
//! ([`timestamps`]), and [`wgsl_mirror!`] for uniforms mirrored between Rust and WGSL. Always (no GPU needed): [`Traffic`] and [`TrafficRate`], and [`wgsl_text`], which reads
//! constants and struct layouts out of WGSL sources for the tests that keep a kernel and its
//! Rust side in step.
//!
//! What it is not: a kernel library for splatting or networks. Those keep a `gpu` module beside
//! their CPU code in their own crates (`splat-raster`'s rasterizer is the first) and build on
//! this one. Buffers a backend needs on every call come from the context's [`pool`], which hands
//! back those nobody holds any more; not a sub-allocator.

mod error;
mod traffic;
pub mod wgsl_text;

pub use error::GpuError;
pub use traffic::{Traffic, TrafficRate};

#[cfg(feature = "wgpu")]
pub mod buffers;
#[cfg(feature = "wgpu")]
mod context;
#[cfg(feature = "wgpu")]
pub mod encode;
// Textually before the modules that declare mirrors: they use its macro without a path.
#[cfg(feature = "wgpu")]
#[macro_use]
mod layout;
#[cfg(all(feature = "wgpu", test))]
mod layout_tests;
#[cfg(feature = "wgpu")]
pub mod pool;
#[cfg(feature = "wgpu")]
mod scan;
#[cfg(feature = "wgpu")]
mod sort;
#[cfg(feature = "wgpu")]
pub mod timestamps;

#[cfg(feature = "wgpu")]
pub use context::{AdapterSummary, GpuContext, TrafficCounter};
#[cfg(feature = "wgpu")]
pub use scan::{PrefixSum, ScanPlan, level_lengths};
#[cfg(feature = "wgpu")]
pub use sort::{RadixSorter, SortRecord};

/// Hooks for this crate's own benches, not part of the API: compiled only with the cargo
/// feature `test-support`, which only the crate's dev-dependency on itself turns on.
#[cfg(all(feature = "wgpu", feature = "test-support"))]
#[doc(hidden)]
pub mod test_support {
    pub use crate::sort::SortHarness;
}
