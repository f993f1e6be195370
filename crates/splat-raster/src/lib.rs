//! `splat-raster`: a differentiable 3D Gaussian Splatting rasterizer.
//!
//! What it is: the forward pass (projection, tiling, depth sort, front-to-back compositing) and the
//! backward pass (gradients to every raw Gaussian parameter) of 3DGS, exactly as pinned in the
//! repository's docs/DESIGN.md §3, over plain structure-of-arrays inputs ([`GaussiansView`]) and an OpenCV-axes
//! pinhole [`Camera`]. The [`Rasterizer`] trait is the backend interface; [`CpuRasterizer`] is the
//! rayon-parallel CPU backend, and `WgpuRasterizer` (cargo feature `wgpu`, off by default; `evogs-cli` turns it on) the
//! GPU backend with WGSL compute kernels, checked against the CPU one; [`select_rasterizer`] picks
//! one at run time from a [`BackendChoice`] (`cpu`, `wgpu`, `auto`).
//!
//! Conventions beyond DESIGN §3, fixed here:
//! - depth output is the un-normalised expected depth `Σ z·α·T` (camera-space z); divide by the
//!   alpha output for a normalised depth;
//! - `d = pixel centre − projected mean` in `σ`; the 2D-mean gradient is dL/d(u, v) in pixels;
//! - the 0.99 alpha cap and the `max(·, 0)` colour clamp pass zero gradient where active;
//! - the screen radius is `3·sqrt(λ_max(Σ2d))` pixels (3DGS convention);
//! - per-Gaussian geometry (covariance, Jacobian, `Σ2d`, conic) and its backward run in f64 on
//!   the CPU, since `det(Σ2d)` of thin Gaussians cancels badly in f32 (the wgpu backend runs it in
//!   f32 in cancellation-free forms instead, see its module doc); per-pixel work runs in f32;
//! - a pixel's loop stops at the first Gaussian that would take `T` below `1e-4` (not blended);
//! - tiles are 16×16; a Gaussian is listed in a tile only if its opacity-aware ellipse
//!   (`σ <= ln(255·o)`, with a small safety margin) reaches a pixel centre of the tile, and only
//!   the pixels of its bounding box are visited, so results equal the per-pixel definition.
//!
//! Memory of the backward pass is bounded as in 3DGS: per pixel the final transmittance and the
//! position of the last contributor, per tile the depth-sorted list; the backward walks each
//! pixel back to front recovering `T` by division. Results do not depend on the thread count:
//! tiles are composited independently, and per-entry gradients are reduced in a fixed order.
//!
//! What it is not: a trainer, an optimiser, a file reader or a deformation model. Those live in
//! other crates of the workspace and hand this crate slices.

mod backend;
mod constants;
mod cpu;
mod error;
mod frame;
#[cfg(feature = "wgpu")]
mod gpu;
mod options;
mod output;
pub mod sh;
mod validate;

pub use backend::{BackendChoice, BackendInfo, BackendKind, DynRasterizer, select_rasterizer};
pub use constants::{
    ALPHA_MAX, ALPHA_MIN, DILATION, MAX_COLOR, NEAR_PLANE, QUAT_NORM2_MIN, T_MIN, TILE,
};
pub use cpu::{CpuKernel, CpuRasterizer};
pub use error::RasterError;
#[cfg(feature = "wgpu")]
pub use gpu::{
    AdapterSummary, AtomicMode, GpuContext, SPAN_BACKWARD, SPAN_FORWARD, WgpuRasterizer,
};
pub use gpu_core::{Traffic, TrafficRate};
pub use options::{CullStats, RenderOptions};
pub use output::{BackwardOutput, ForwardOutput, GaussianGrads, PixelGrads};
/// The plain types of `splat-core` the rasterizer reads, re-exported for convenience (defined
/// there, once).
pub use splat_core::{Camera, Gaussians, GaussiansView, camera, gaussians, sh_coeff_count};

/// A rasterizer backend: [`CpuRasterizer`], or `WgpuRasterizer` (feature `wgpu`).
pub trait Rasterizer {
    /// Renders colour, alpha and expected depth, keeping what the backward pass needs.
    fn forward(
        &self,
        g: GaussiansView<'_>,
        cam: &Camera,
        opts: &RenderOptions,
    ) -> Result<ForwardOutput, RasterError>;

    /// [`forward`](Self::forward) into `out` (start from [`ForwardOutput::default`]), reusing
    /// its buffers where the backend can: the CPU backend reuses every buffer of the pass, so a
    /// caller rendering view after view (the viewer) allocates nothing once the sizes stop
    /// growing. `out` ends equal to what `forward` returns, whatever it held before; on an error
    /// its content is unspecified. The default implementation calls `forward`.
    fn forward_into(
        &self,
        g: GaussiansView<'_>,
        cam: &Camera,
        opts: &RenderOptions,
        out: &mut ForwardOutput,
    ) -> Result<(), RasterError> {
        *out = self.forward(g, cam, opts)?;
        Ok(())
    }

    /// Gradients of a loss with respect to every raw parameter, given the loss gradients of the
    /// forward outputs (`d.alpha`, `d.depth` may be omitted when the loss does not use them).
    /// `fwd` must be the output of `forward` on the same inputs.
    fn backward(
        &self,
        g: GaussiansView<'_>,
        cam: &Camera,
        opts: &RenderOptions,
        fwd: &ForwardOutput,
        d: PixelGrads<'_>,
    ) -> Result<BackwardOutput, RasterError>;

    /// [`backward`](Self::backward) into `out` (start from [`BackwardOutput::default`]),
    /// reusing its buffers where the backend can: the CPU backend reuses its gradient arrays and
    /// the per-entry buffer of the pass, so a training loop allocates nothing once the sizes stop
    /// growing. `out` ends equal to what `backward` returns, whatever it held before; on an error
    /// its content is unspecified. The default implementation calls `backward`.
    fn backward_into(
        &self,
        g: GaussiansView<'_>,
        cam: &Camera,
        opts: &RenderOptions,
        fwd: &ForwardOutput,
        d: PixelGrads<'_>,
        out: &mut BackwardOutput,
    ) -> Result<(), RasterError> {
        *out = self.backward(g, cam, opts, fwd, d)?;
        Ok(())
    }

    /// The host–device [`Traffic`] recorded on this backend's device since it was made, or
    /// `None` for a backend that moves nothing between devices (the CPU one, the default).
    fn traffic(&self) -> Option<Traffic> {
        None
    }

    /// The device this backend renders on, for other work to share it (the trainer puts the
    /// deformation network there), or `None` for a backend without one (the CPU one, the
    /// default).
    #[cfg(feature = "wgpu")]
    fn device(&self) -> Option<std::sync::Arc<GpuContext>> {
        None
    }

    /// [`forward_into`](Self::forward_into) with the images left on the backend's device, for
    /// a loss there to read (the trainer's resident loss): `out.color`, `out.alpha` and
    /// `out.depth` stay empty and [`ForwardOutput::device_color`] is the colour; the radii,
    /// statistics and counters are read back as by `forward_into`. A backend without a device
    /// (the CPU one, the default) refuses.
    #[cfg(feature = "wgpu")]
    fn forward_resident(
        &self,
        g: GaussiansView<'_>,
        cam: &Camera,
        opts: &RenderOptions,
        out: &mut ForwardOutput,
    ) -> Result<(), RasterError> {
        let _ = (g, cam, opts, out);
        Err(no_device("forward_resident"))
    }

    /// [`backward_into`](Self::backward_into) after [`forward_resident`](Self::forward_resident),
    /// with `∂loss/∂colour` in `d_color`, a buffer of the backend's device (interleaved RGB f32,
    /// one triple per pixel; no alpha or depth gradient). Unlike the host's, its values are not
    /// checked for non-finite ones (they never reach the host): whoever makes them on the
    /// device answers for them. A backend without a device (the default) refuses.
    #[cfg(feature = "wgpu")]
    fn backward_resident(
        &self,
        g: GaussiansView<'_>,
        cam: &Camera,
        opts: &RenderOptions,
        fwd: &ForwardOutput,
        d_color: &wgpu::Buffer,
        out: &mut BackwardOutput,
    ) -> Result<(), RasterError> {
        let _ = (g, cam, opts, fwd, d_color, out);
        Err(no_device("backward_resident"))
    }
}

/// The error of a resident pass asked of a backend without a device.
#[cfg(feature = "wgpu")]
fn no_device(pass: &str) -> RasterError {
    RasterError::Gpu {
        stage: "resident",
        message: format!("{pass}: this backend has no device to keep the images on"),
    }
}
