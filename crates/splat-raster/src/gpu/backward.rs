//! The backward pass on the GPU: upload the pixel gradients (or take them on the device, after
//! a resident forward pass), composite backward into per-Gaussian record gradients (atomics),
//! chain them through the projection, read back.

use crate::camera::Camera;
use crate::error::RasterError;
use crate::gaussians::GaussiansView;
use crate::options::RenderOptions;
use crate::output::{BackendState, BackwardOutput, ForwardOutput, GaussianGrads, PixelGrads};
use crate::validate::{validate_backward, validate_backward_state};

use super::WgpuRasterizer;
use gpu_core::buffers::{pooled_storage, pooled_storage_init, pooled_uniform, read_back};
use gpu_core::encode::{bind, dispatch, groups_1d};

/// The label of the backward pass's GPU timestamp span.
pub const SPAN_BACKWARD: &str = "raster backward";

/// Floats per Gaussian of the record gradient (u, v, a, b, c, opacity, r, g, b, z).
const RECORD_GRAD: u64 = 10;
/// Floats per Gaussian of the projection backward's output (see project_bwd.wgsl).
pub(crate) const OUT_STRIDE: usize = 14;

/// Where a backward pass's pixel gradients are.
#[derive(Clone, Copy)]
pub(crate) enum PixelSource<'a> {
    /// On the host, uploaded by the pass.
    Host(PixelGrads<'a>),
    /// `∂loss/∂colour` already on the device (interleaved RGB f32), no alpha or depth gradient.
    Device(&'a wgpu::Buffer),
}

impl WgpuRasterizer {
    pub(crate) fn backward_impl(
        &self,
        g: GaussiansView<'_>,
        cam: &Camera,
        opts: &RenderOptions,
        fwd: &ForwardOutput,
        d: PixelSource<'_>,
    ) -> Result<BackwardOutput, RasterError> {
        match d {
            PixelSource::Host(d) => validate_backward(&g, cam, opts, fwd, d)?,
            PixelSource::Device(buffer) => {
                let active = validate_backward_state(&g, cam, opts, fwd)?;
                let need = cam.pixel_count() as u64 * 12;
                if buffer.size() < need {
                    return Err(RasterError::Gpu {
                        stage: "buffers",
                        message: format!(
                            "d_color on the device holds {} bytes, the image needs {need}",
                            buffer.size()
                        ),
                    });
                }
                active
            }
        };
        let st = &fwd.state;
        let mismatch = |what: &str| Err(RasterError::ForwardMismatch(what.into()));
        let gpu = match &st.backend {
            BackendState::Gpu(gpu) if gpu.context_id == self.ctx.id() => gpu,
            BackendState::Gpu(_) => {
                return mismatch("the forward pass ran on another GPU context");
            }
            BackendState::Cpu(_) => {
                return mismatch("the forward pass ran on another backend");
            }
        };

        let ctx = &*self.ctx;
        let device = &ctx.device;
        let max_dim = device.limits().max_compute_workgroups_per_dimension;
        let n = g.len();
        let stride = g.sh_stride();
        let (d_alpha, d_depth) = match d {
            PixelSource::Host(d) => (d.alpha, d.depth),
            PixelSource::Device(_) => (None, None),
        };
        let mut frame = gpu.frame;
        frame.use_d_alpha = u32::from(d_alpha.is_some());
        frame.use_d_depth = u32::from(d_depth.is_some());
        // Pooled buffers, held until the read-back below has waited (`pooled_*`'s contract).
        let mut enc = device.create_command_encoder(&Default::default());
        let span = ctx.span_begin(&mut enc, SPAN_BACKWARD);
        let frame_buf = pooled_uniform(ctx, "frame", bytemuck::bytes_of(&frame));
        let mut upload = |label, data: &[u8]| pooled_storage_init(ctx, &mut enc, label, data);
        let uploaded;
        let d_color_buf: &wgpu::Buffer = match d {
            PixelSource::Host(d) => {
                uploaded = upload("d_color", bytemuck::cast_slice(d.color))?;
                &uploaded
            }
            PixelSource::Device(buffer) => buffer,
        };
        let d_alpha_buf = upload("d_alpha", bytemuck::cast_slice(d_alpha.unwrap_or(&[])))?;
        let d_depth_buf = upload("d_depth", bytemuck::cast_slice(d_depth.unwrap_or(&[])))?;
        let n64 = n as u64;
        let grads = pooled_storage(ctx, &mut enc, "record_grads", n64 * RECORD_GRAD * 4)?;
        let out = pooled_storage(ctx, &mut enc, "raw_grads", n64 * OUT_STRIDE as u64 * 4)?;
        let sh_out = pooled_storage(ctx, &mut enc, "sh_grads", n64 * stride as u64 * 4)?;

        let p = &self.pipelines;
        if n > 0 {
            let bg = bind(
                ctx,
                &p.rasterize_backward,
                &[
                    (0, &frame_buf),
                    (2, &gpu.splats),
                    (3, &gpu.isect_ids),
                    (4, &gpu.ranges),
                    (5, &gpu.final_t),
                    (6, &gpu.last),
                    (7, d_color_buf),
                    (8, &d_alpha_buf),
                    (9, &d_depth_buf),
                    (10, &grads),
                ],
            );
            dispatch(
                ctx,
                &mut enc,
                &p.rasterize_backward,
                &bg,
                (frame.tiles_x, frame.tiles_y),
            );
            let bg = bind(
                ctx,
                &p.project_backward,
                &[
                    (0, &frame_buf),
                    (1, &gpu.params),
                    (2, &gpu.splats),
                    (3, &grads),
                    (4, &out),
                    (5, &sh_out),
                ],
            );
            dispatch(
                ctx,
                &mut enc,
                &p.project_backward,
                &bg,
                groups_1d(n as u32, max_dim),
            );
        }
        ctx.span_end(&mut enc, span);
        let back = read_back(
            ctx,
            enc,
            &[
                (&out, 0, n64 * OUT_STRIDE as u64 * 4),
                (&sh_out, 0, n64 * stride as u64 * 4),
            ],
        )?;
        let raw: Vec<f32> = bytemuck::pod_collect_to_vec(&back[0]);
        let sh: Vec<f32> = bytemuck::pod_collect_to_vec(&back[1]);
        let mut grads = GaussianGrads {
            means: Vec::with_capacity(n),
            log_scales: Vec::with_capacity(n),
            rotations: Vec::with_capacity(n),
            opacity_logits: Vec::with_capacity(n),
            sh,
            means2d: Vec::with_capacity(n),
        };
        let mut zeroed_non_finite = 0;
        for r in raw.chunks_exact(OUT_STRIDE) {
            grads.means.push([r[0], r[1], r[2]]);
            grads.log_scales.push([r[3], r[4], r[5]]);
            grads.rotations.push([r[6], r[7], r[8], r[9]]);
            grads.opacity_logits.push(r[10]);
            grads.means2d.push([r[11], r[12]]);
            if r[13] != 0.0 {
                zeroed_non_finite += 1;
            }
        }
        Ok(BackwardOutput {
            grads,
            zeroed_non_finite,
            ..BackwardOutput::default()
        })
    }
}
