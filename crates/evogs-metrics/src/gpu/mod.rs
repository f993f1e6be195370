//! The training loss `0.8·L1 + 0.2·(1 − SSIM)` and its gradient on the GPU (cargo feature
//! `wgpu`, issue W): the WGSL twin of [`LossWorkspace`](crate::LossWorkspace), checked against
//! it and against the plain [`photometric_loss`](crate::photometric_loss) by this crate's
//! `gpu_loss` tests.
//!
//! Five passes over interleaved RGB f32 images (`loss.wgsl`), one invocation per element:
//! horizontal sums of the five moments, vertical sums with the SSIM map and its three
//! sensitivities, their horizontal sums, then the vertical sums with the gradient; a fifth pass
//! adds the SSIM map, `|x − y|` and `(x − y)²` per workgroup in a fixed order (each invocation
//! 16 elements, then a tree), and the host adds the workgroups' partial sums in order in f64, so
//! a run repeats itself bit for bit. The window's taps are the CPU's ([`ssim_kernel`] in f64,
//! rounded to f32).
//!
//! [`GpuLoss::encode`] records the passes on buffers already on the device (a resident
//! iteration renders into one and keeps its targets in others); [`GpuLoss::compute`] uploads
//! two images, runs them and reads the loss and gradient back.
//!
//! Precision: f32 throughout, as the CPU's f32 training loss; the sums of the window run in
//! another order than the CPU's (vertical then horizontal there), so values differ by f32
//! rounding (the tests' tolerances say how much).
//!
//! [`GpuLoss::finish`] submits and reads the terms only, the gradient staying on the device: the
//! trainer's resident loss (`evogs-train`, with the rasterizer on wgpu).
//!
//! What it is not: the loss's reference (that is [`photometric_loss`](crate::photometric_loss)).

use gpu_core::buffers::{read_back, storage, storage_init, uniform};
use gpu_core::encode::{bind, dispatch, groups_1d};
use gpu_core::{GpuContext, GpuError, wgsl_mirror};

use crate::loss::{L1_WEIGHT, SSIM_WEIGHT};
use crate::ssim::{SSIM_C1, SSIM_C2};
use crate::{ImageSize, LossValues, ssim_kernel};

const LOSS_WGSL: &str = include_str!("loss.wgsl");
/// The label of the loss's GPU timestamp span ([`gpu_core::timestamps`]).
pub const SPAN: &str = "loss";
/// Elements one workgroup of `reduce` adds (`WORKGROUP · PER_THREAD` of loss.wgsl).
const REDUCE_BLOCK: u32 = 256 * 16;

wgsl_mirror! {
    /// Mirror of `Params` in `loss.wgsl` (a test checks names, types, offsets and size).
    #[repr(C)]
    #[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
    pub(crate) struct LossParams {
        pub width: u32,
        pub height: u32,
        pub count: u32,
        pub row_stride: u32,
        pub l1_step: f32,
        pub ssim_step: f32,
        pub c1: f32,
        pub c2: f32,
        pub reduce_groups: u32,
        pub pad0: u32,
        pub pad1: u32,
        pub pad2: u32,
    }
}

/// The loss's compute pipelines, compiled once per device.
#[derive(Debug)]
pub struct GpuLoss {
    blur_moments_h: wgpu::ComputePipeline,
    ssim_map: wgpu::ComputePipeline,
    blur_sensitivities_h: wgpu::ComputePipeline,
    gradient: wgpu::ComputePipeline,
    reduce: wgpu::ComputePipeline,
}

/// The device buffers of one image size: the window's taps, the scratch planes, the gradient
/// and the workgroups' partial sums. Made once per size and reused.
#[derive(Debug)]
pub struct LossBuffers {
    size: ImageSize,
    params: wgpu::Buffer,
    taps: wgpu::Buffer,
    h: wgpu::Buffer,
    v: wgpu::Buffer,
    /// `∂loss/∂rendered`, interleaved RGB f32 like the images.
    pub gradient: wgpu::Buffer,
    /// Three f32 per workgroup of the reduction: sums of the SSIM map, `|x − y|`, `(x − y)²`.
    pub partials: wgpu::Buffer,
    groups: (u32, u32),
    reduce_groups: u32,
}

impl LossBuffers {
    /// Buffers for `size` images on `ctx`.
    pub fn new(ctx: &GpuContext, size: ImageSize) -> Result<Self, GpuError> {
        let count = u32::try_from(3 * size.pixels())
            .map_err(|_| GpuError::new("buffers", format!("{size:?}: too many pixels")))?;
        let max_dim = ctx.device.limits().max_compute_workgroups_per_dimension;
        let groups = groups_1d(count, max_dim);
        let reduce_groups = count.div_ceil(REDUCE_BLOCK).max(1);
        let params = LossParams {
            width: size.width as u32,
            height: size.height as u32,
            count,
            row_stride: groups.0 * 256,
            l1_step: (L1_WEIGHT / f64::from(count)) as f32,
            ssim_step: (SSIM_WEIGHT / f64::from(count)) as f32,
            c1: SSIM_C1 as f32,
            c2: SSIM_C2 as f32,
            reduce_groups,
            ..LossParams::default()
        };
        let taps = ssim_kernel().map(|t| t as f32);
        let plane = 4 * u64::from(count);
        Ok(Self {
            size,
            params: uniform(ctx, "loss params", bytemuck::bytes_of(&params)),
            taps: storage_init(ctx, "ssim taps", bytemuck::cast_slice(&taps))?,
            h: storage(ctx, "loss moments", 5 * plane)?,
            v: storage(ctx, "loss map", 4 * plane)?,
            gradient: storage(ctx, "loss gradient", plane)?,
            partials: storage(ctx, "loss partial sums", 12 * u64::from(reduce_groups))?,
            groups,
            reduce_groups,
        })
    }

    /// The image size these buffers are for.
    pub fn size(&self) -> ImageSize {
        self.size
    }
}

impl GpuLoss {
    /// Compiles the loss's kernels on `ctx`'s device.
    pub fn new(ctx: &GpuContext) -> Result<Self, GpuError> {
        let device = &ctx.device;
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("photometric loss"),
            source: wgpu::ShaderSource::Wgsl(LOSS_WGSL.into()),
        });
        let pipeline = |entry: &str| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: None,
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        let loss = Self {
            blur_moments_h: pipeline("blur_moments_h"),
            ssim_map: pipeline("ssim_map"),
            blur_sensitivities_h: pipeline("blur_sensitivities_h"),
            gradient: pipeline("gradient"),
            reduce: pipeline("reduce"),
        };
        if let Some(err) = pollster::block_on(scope.pop()) {
            return Err(GpuError::new("pipelines", err.to_string()));
        }
        Ok(loss)
    }

    /// Records the five passes: the loss of `rendered` against `target` (interleaved RGB f32 of
    /// `bufs.size()`, on the device) into `bufs.gradient` and `bufs.partials`, in a GPU
    /// timestamp span labelled [`SPAN`] where the adapter has timestamps.
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        rendered: &wgpu::Buffer,
        target: &wgpu::Buffer,
        bufs: &LossBuffers,
    ) {
        let span = ctx.span_begin(encoder, SPAN);
        let b = bufs;
        let group = |pipeline, entries: &[(u32, &wgpu::Buffer)]| bind(ctx, pipeline, entries);
        let passes = [
            (
                &self.blur_moments_h,
                group(
                    &self.blur_moments_h,
                    &[
                        (0, &b.params),
                        (1, &b.taps),
                        (2, rendered),
                        (3, target),
                        (4, &b.h),
                    ],
                ),
            ),
            (
                &self.ssim_map,
                group(
                    &self.ssim_map,
                    &[(0, &b.params), (1, &b.taps), (4, &b.h), (5, &b.v)],
                ),
            ),
            (
                &self.blur_sensitivities_h,
                group(
                    &self.blur_sensitivities_h,
                    &[(0, &b.params), (1, &b.taps), (4, &b.h), (5, &b.v)],
                ),
            ),
            (
                &self.gradient,
                group(
                    &self.gradient,
                    &[
                        (0, &b.params),
                        (1, &b.taps),
                        (2, rendered),
                        (3, target),
                        (4, &b.h),
                        (6, &b.gradient),
                    ],
                ),
            ),
        ];
        for (pipeline, bind_group) in &passes {
            dispatch(ctx, encoder, pipeline, bind_group, b.groups);
        }
        let max_dim = ctx.device.limits().max_compute_workgroups_per_dimension;
        let reduce = group(
            &self.reduce,
            &[
                (0, &b.params),
                (2, rendered),
                (3, target),
                (5, &b.v),
                (6, &b.partials),
            ],
        );
        dispatch(
            ctx,
            encoder,
            &self.reduce,
            &reduce,
            split_groups(b.reduce_groups, max_dim),
        );
        ctx.span_end(encoder, span);
    }

    /// Submits `encoder` (holding the passes [`encode`](Self::encode) recorded on `bufs`) and
    /// reads back the loss's terms only: `12` bytes per workgroup of the reduction (118 at
    /// 400 × 400), added on the host in order, in f64. The gradient stays on the device in
    /// `bufs.gradient`, for a backward pass there.
    pub fn finish(
        &self,
        ctx: &GpuContext,
        encoder: wgpu::CommandEncoder,
        bufs: &LossBuffers,
    ) -> Result<LossValues, GpuError> {
        let bytes = 12 * u64::from(bufs.reduce_groups);
        let back = read_back(ctx, encoder, &[(&bufs.partials, 0, bytes)])?;
        let partials: Vec<f32> = bytemuck::pod_collect_to_vec(&back[0]);
        Ok(values(&partials, 3.0 * bufs.size.pixels() as f64))
    }

    /// The loss of `rendered` against `target` (`size` images), its terms and its gradient:
    /// uploads both, runs [`encode`](Self::encode) and reads back.
    pub fn compute(
        &self,
        ctx: &GpuContext,
        size: ImageSize,
        rendered: &[[f32; 3]],
        target: &[[f32; 3]],
    ) -> Result<(LossValues, Vec<[f32; 3]>), GpuError> {
        for (name, image) in [("rendered", rendered), ("target", target)] {
            if image.len() != size.pixels() {
                return Err(GpuError::new(
                    "buffers",
                    format!(
                        "{name}: {} pixels for a {}×{} image",
                        image.len(),
                        size.width,
                        size.height
                    ),
                ));
            }
        }
        let bufs = LossBuffers::new(ctx, size)?;
        let x = storage_init(ctx, "rendered", bytemuck::cast_slice(rendered))?;
        let y = storage_init(ctx, "target", bytemuck::cast_slice(target))?;
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        self.encode(ctx, &mut encoder, &x, &y, &bufs);
        let count = 3 * size.pixels() as u64;
        let back = read_back(
            ctx,
            encoder,
            &[
                (&bufs.gradient, 0, 4 * count),
                (&bufs.partials, 0, 12 * u64::from(bufs.reduce_groups)),
            ],
        )?;
        let gradient: Vec<f32> = bytemuck::pod_collect_to_vec(&back[0]);
        let partials: Vec<f32> = bytemuck::pod_collect_to_vec(&back[1]);
        Ok((
            values(&partials, count as f64),
            gradient
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect(),
        ))
    }
}

/// The loss's terms from the workgroups' partial sums (added in order, in f64).
fn values(partials: &[f32], count: f64) -> LossValues {
    let mut sums = [0.0f64; 3];
    for chunk in partials.chunks_exact(3) {
        for (s, &p) in sums.iter_mut().zip(chunk) {
            *s += f64::from(p);
        }
    }
    let [ssim, l1, mse] = sums.map(|s| s / count);
    LossValues {
        loss: L1_WEIGHT * l1 + SSIM_WEIGHT * (1.0 - ssim),
        l1,
        ssim,
        mse,
    }
}

/// `groups` workgroups on a grid at most `max_per_dim` wide (the kernel skips the extra ones).
fn split_groups(groups: u32, max_per_dim: u32) -> (u32, u32) {
    let x = groups.clamp(1, max_per_dim.max(1));
    (x, groups.div_ceil(x))
}

#[cfg(test)]
mod tests {
    use super::*;
    use gpu_core::wgsl_text::check_mirror;

    #[test]
    fn the_uniform_matches_its_wgsl_struct() {
        check_mirror(
            LossParams::FIELDS,
            size_of::<LossParams>(),
            LOSS_WGSL,
            "Params",
        );
    }

    #[test]
    fn grids_cover_every_workgroup() {
        for (groups, max) in [(1, 65535), (118, 65535), (70_000, 65535), (10, 3)] {
            let (x, y) = split_groups(groups, max);
            assert!(x <= max && u64::from(x) * u64::from(y) >= u64::from(groups));
        }
    }
}
