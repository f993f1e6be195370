//! The wgpu backend: [`WgpuRasterizer`] runs the forward and backward passes of DESIGN §3 in WGSL
//! compute kernels and gives the results of [`crate::CpuRasterizer`] (same culling and
//! [`CullStats`](crate::CullStats), same opacity-aware tile test, compositing constants, depth
//! convention and [`GaussianGrads`](crate::GaussianGrads) fields), to f32 rounding.
//!
//! Pipeline (kernels in `shaders/`):
//! 1. `project` (one thread per Gaussian): culling in the CPU's order, counted per reason with
//!    atomics; the compositing record, screen radius, number of touched tiles, depth key;
//! 2. depth sort ([`gpu_core::RadixSorter`], 32-bit keys `z.to_bits()`, values the Gaussian index);
//! 3. tile counts gathered in depth order and scanned ([`gpu_core::PrefixSum`], the backend's one
//!    prefix sum, also the sort's); the total number of
//!    (tile, Gaussian) pairs is read back (4 bytes, with the 32 bytes of cull counts) to size
//!    the intersection buffers;
//! 4. `emit`: each Gaussian writes its pairs at its scanned offset, so pairs are in depth order;
//!    a stable sort by tile id (only `ceil(log2(tiles))` key bits) then leaves every tile's list
//!    in depth order with ties broken by index, exactly the CPU's order; `tile_ranges`;
//! 5. `rasterize`: one 16×16 workgroup per tile, lists loaded into shared memory in batches of
//!    128; per pixel the CPU's loop (bounding box, σ cut-off, 0.99 cap, stop before `T < 1e-4`),
//!    keeping the final `T` and the last contributor per pixel, and the work counters per tile;
//! 6. `rasterize_backward`: per tile back to front from the largest last contributor, `T`
//!    recovered by division; per-pixel contributions added into 10 floats per Gaussian with
//!    native `atomic<f32>` adds where the adapter offers `SHADER_FLOAT32_ATOMIC`, otherwise a
//!    compare-exchange loop on `atomic<u32>` bit patterns ([`AtomicMode`], chosen when the
//!    pipelines are built);
//! 7. `project_backward` (one thread per Gaussian): the chain to means (SH view-direction path
//!    included), log-scales, raw quaternions, opacity logits and SH; means2d in pixels.
//!
//! Why two sorts rather than one with packed `tile | depth` keys: the sorter's keys are 32 bits,
//! and a packed key would have to cut the depth to `32 - log2(tiles)` bits, which reorders
//! Gaussians at close depths relative to the CPU backend; the depth sort keeps all 32 bits (the
//! bit pattern of a positive f32 orders like the number) and the stable tile sort is short.
//!
//! Precision: per-Gaussian geometry runs in f32 (the CPU uses f64). `det(Σ2d)` is formed without
//! cancellation (`Σ2d = T Tᵀ + 0.3 I`, `T = J W R S`, and `det(T Tᵀ)` as the sum of the squared
//! 2×2 minors of `T`, Cauchy–Binet), with `T` scaled by its largest entry so that squared scales
//! are never formed, and quaternions and means are scaled before squaring; needle-thin and huge
//! Gaussians therefore project as on the CPU. Known limits of f32: scales above `e^88`
//! (`exp` overflows) are culled as degenerate where the CPU's f64 still draws them as a flat
//! wash up to about `e^150`, and their gradients (meaningless in either precision) may be zeroed
//! as non-finite on the GPU. Conversely, for Gaussians much longer than `e^8` along the view ray
//! the CPU's f64 `det(Σ2d) = AC - B²` loses digits (beyond about `e^12` it cancels to zero or
//! below and the CPU culls them as degenerate), while the GPU's determinant has no cancellation. Discrete decisions at a
//! threshold (a bounding-box edge, `α = 1/255`, `T = 1e-4`) may flip between f32 and f64
//! geometry: on the 100K-Gaussian bench scene 2 of 817,880 tile pairs and 4 of 640,000 pixels
//! (colour off by at most 5e-4) differ.
//!
//! What crosses between CPU and GPU per call (d = SH degree, k = 3(d+1)² SH floats):
//! - forward: upload `4·(11 + k)` bytes per Gaussian (raw parameters) and a 160-byte uniform
//!   twice (before and after the pair count is known); read back 36 bytes mid-pass (cull counts,
//!   pair count), then 20 bytes per pixel (colour, alpha, depth), 4 bytes per Gaussian (radius)
//!   and 8 bytes per tile (work counters);
//! - backward: upload a 160-byte uniform, 12 bytes per pixel (the
//!   [`PixelGrads`](crate::PixelGrads) colour) plus 4 per pixel for each of its alpha and depth
//!   given (a 64-byte placeholder for each not given); read back `4·(14 + k)` bytes per Gaussian
//!   (gradients, means2d, a non-finite flag). The compositing record, tile lists, per-pixel `T`
//!   and last contributor stay on the device between forward and backward (in the
//!   [`ForwardOutput`]).
//!
//! Besides these, each sort pass and scan level uploads a small parameter record. Every upload,
//! read-back, submit, wait, dispatch, buffer and bind group is counted on the context
//! ([`GpuContext::traffic`], [`crate::Rasterizer::traffic`]); a test checks the counts against
//! this list.
//!
//! Buffers come from the context's pool ([`gpu_core::pool`]): a buffer nobody holds any more is
//! handed out again (cleared on the device where the kernels need zeros, as a new one is), and
//! a forward output holds the buffers its backward pass reads, so none of them is reused while
//! it lives. Once warm, a forward and backward create only the sort's and the scan's five small
//! parameter buffers (a test counts them).
//!
//! Not (yet) done here: bind groups kept between calls (made per call), the sort's and scan's
//! parameter records in a ring, subgroup or workgroup reductions before the gradient atomics.

mod backward;
mod forward;
mod frame;
#[cfg(test)]
mod layout_tests;
mod pipelines;
pub(crate) mod state;

use std::sync::Arc;

pub use backward::SPAN_BACKWARD;
pub use forward::SPAN_FORWARD;
pub use gpu_core::{AdapterSummary, GpuContext};
pub use pipelines::AtomicMode;

use crate::Rasterizer;
use crate::camera::Camera;
use crate::error::RasterError;
use crate::gaussians::GaussiansView;
use crate::options::RenderOptions;
use crate::output::{BackwardOutput, ForwardOutput, PixelGrads};

use backward::PixelSource;
use gpu_core::RadixSorter;
use pipelines::Pipelines;

/// The GPU rasterizer (wgpu compute kernels). Same interface and results as
/// [`crate::CpuRasterizer`].
pub struct WgpuRasterizer {
    ctx: Arc<GpuContext>,
    pipelines: Pipelines,
    sorter: RadixSorter,
    atomics: AtomicMode,
}

impl std::fmt::Debug for WgpuRasterizer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WgpuRasterizer")
            .field("adapter", self.ctx.adapter())
            .field("atomics", &self.atomics)
            .finish_non_exhaustive()
    }
}

impl WgpuRasterizer {
    /// A rasterizer on the default adapter, with native f32 atomics when it offers them.
    /// No adapter is an error ([`RasterError::Gpu`]), not a panic.
    pub fn new() -> Result<Self, RasterError> {
        let ctx = Arc::new(GpuContext::new()?);
        let mode = if ctx.adapter().float32_atomics {
            AtomicMode::NativeF32
        } else {
            AtomicMode::CompareExchange
        };
        Self::with_context(ctx, mode)
    }

    /// A rasterizer on an existing context with a chosen gradient accumulation. Asking for
    /// [`AtomicMode::NativeF32`] on an adapter without f32 atomics is an error.
    pub fn with_context(ctx: Arc<GpuContext>, atomics: AtomicMode) -> Result<Self, RasterError> {
        if atomics == AtomicMode::NativeF32 && !ctx.adapter().float32_atomics {
            return Err(RasterError::Gpu {
                stage: "pipelines",
                message: format!(
                    "adapter {} does not offer SHADER_FLOAT32_ATOMIC",
                    ctx.adapter().name
                ),
            });
        }
        let pipelines = Pipelines::new(&ctx.device, atomics)?;
        let sorter = RadixSorter::new(&ctx.device);
        Ok(Self {
            ctx,
            pipelines,
            sorter,
            atomics,
        })
    }

    /// The device context (shareable between rasterizers).
    pub fn context(&self) -> &Arc<GpuContext> {
        &self.ctx
    }

    /// What the adapter is (name, backend, hardware or software, f32 atomics).
    pub fn adapter(&self) -> &AdapterSummary {
        self.ctx.adapter()
    }

    /// How the backward pass accumulates gradients.
    pub fn atomics(&self) -> AtomicMode {
        self.atomics
    }
}

impl WgpuRasterizer {
    /// Runs `f` with wgpu's validation and out-of-memory errors captured (instead of wgpu's
    /// default of panicking) and returned as [`RasterError::Gpu`].
    fn checked<R>(&self, f: impl FnOnce() -> Result<R, RasterError>) -> Result<R, RasterError> {
        let device = &self.ctx.device;
        let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let out = f();
        let errors = [
            pollster::block_on(validation.pop()),
            pollster::block_on(oom.pop()),
        ];
        if let Some(err) = errors.into_iter().flatten().next() {
            return Err(RasterError::Gpu {
                stage: "device",
                message: err.to_string(),
            });
        }
        out
    }
}

impl Rasterizer for WgpuRasterizer {
    fn forward(
        &self,
        g: GaussiansView<'_>,
        cam: &Camera,
        opts: &RenderOptions,
    ) -> Result<ForwardOutput, RasterError> {
        self.checked(|| self.forward_impl(g, cam, opts, false))
    }

    fn backward(
        &self,
        g: GaussiansView<'_>,
        cam: &Camera,
        opts: &RenderOptions,
        fwd: &ForwardOutput,
        d: PixelGrads<'_>,
    ) -> Result<BackwardOutput, RasterError> {
        self.checked(|| self.backward_impl(g, cam, opts, fwd, PixelSource::Host(d)))
    }

    fn forward_resident(
        &self,
        g: GaussiansView<'_>,
        cam: &Camera,
        opts: &RenderOptions,
        out: &mut ForwardOutput,
    ) -> Result<(), RasterError> {
        *out = self.checked(|| self.forward_impl(g, cam, opts, true))?;
        Ok(())
    }

    fn backward_resident(
        &self,
        g: GaussiansView<'_>,
        cam: &Camera,
        opts: &RenderOptions,
        fwd: &ForwardOutput,
        d_color: &wgpu::Buffer,
        out: &mut BackwardOutput,
    ) -> Result<(), RasterError> {
        *out =
            self.checked(|| self.backward_impl(g, cam, opts, fwd, PixelSource::Device(d_color)))?;
        Ok(())
    }

    fn traffic(&self) -> Option<crate::Traffic> {
        Some(self.ctx.traffic())
    }

    fn device(&self) -> Option<Arc<GpuContext>> {
        Some(Arc::clone(&self.ctx))
    }
}
