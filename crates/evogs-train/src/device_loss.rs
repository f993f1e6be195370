//! The training loss on the rasterizer's device (cargo feature `wgpu`, issue W): with the
//! rasterizer on wgpu and a fixed background, every training image is uploaded once, each
//! iteration renders into a device buffer ([`splat_raster::Rasterizer::forward_resident`]),
//! `evogs_metrics::gpu::GpuLoss` computes `0.8·L1 + 0.2·(1 − SSIM)` and its gradient there, and
//! the rasterizer's backward reads that gradient there
//! ([`splat_raster::Rasterizer::backward_resident`]). Of the images only the loss's partial sums
//! cross (12 bytes per 4 096 values), where the host path read back the colour, alpha and depth
//! (20 bytes a pixel) and uploaded the colour's gradient (12 bytes a pixel).
//!
//! Under a random background the target is the view's image with the iteration's background
//! showing through its transmittance, made on the host each iteration; that case keeps the
//! loss on the host (the [`Placement`](crate::trainer::Placement) line says so).
//!
//! What it is not: the loss's definition (`evogs_metrics::photometric_loss`) or its CPU form
//! (`evogs_metrics::LossWorkspace`, the trainer's loss on every other path).

use std::sync::Arc;

use evogs_metrics::gpu::{GpuLoss, LossBuffers};
use evogs_metrics::{ImageSize, LossValues};
use splat_raster::{GpuContext, RasterError};

use crate::data::SplitViews;
use crate::error::TrainError;

/// Bytes of training images the device loss keeps on the device (4 GiB: wgpu cannot ask a
/// device how much memory it has, so a fixed budget that a 8 GiB card holds beside a run's
/// Gaussians and buffers; D-NeRF's 100–200 views at 400 × 400 take 0.2–0.4 GiB). Above it the
/// loss stays on the host, and the `loss:` line says why.
pub(crate) const IMAGE_BUDGET: u64 = 4 << 30;

/// The loss's kernels, its buffers and the training images, on the rasterizer's device.
#[derive(Debug)]
pub(crate) struct DeviceLoss {
    ctx: Arc<GpuContext>,
    loss: GpuLoss,
    /// Per training view, its image (interleaved RGB f32), uploaded once.
    targets: Vec<wgpu::Buffer>,
    /// The buffers of the last image size (remade when a view of another size comes).
    bufs: Option<LossBuffers>,
}

impl DeviceLoss {
    /// Compiles the loss on `ctx` and uploads every training image (`train`'s, in order).
    pub(crate) fn new(ctx: Arc<GpuContext>, train: &SplitViews) -> Result<Self, TrainError> {
        let loss = GpuLoss::new(&ctx).map_err(RasterError::from)?;
        let targets = train
            .views
            .iter()
            .map(|v| {
                let bytes = bytemuck::cast_slice(&v.image.pixels);
                gpu_core::buffers::storage_init(&ctx, "training image", bytes)
            })
            .collect::<Result<Vec<_>, _>>()
            .map_err(RasterError::from)?;
        // The buffers of the first view's size (a dataset's views share one), made here so
        // that an ordinary iteration uploads nothing of the loss's.
        let bufs = match train.views.first() {
            Some(v) => {
                let size = ImageSize::new(v.image.width as usize, v.image.height as usize);
                Some(LossBuffers::new(&ctx, size).map_err(RasterError::from)?)
            }
            None => None,
        };
        Ok(Self {
            ctx,
            loss,
            targets,
            bufs,
        })
    }

    /// Bytes the training images hold on the device.
    pub(crate) fn image_bytes(&self) -> u64 {
        self.targets.iter().map(wgpu::Buffer::size).sum()
    }

    /// The loss of `rendered` (on the device, `size`) against training view `view`'s image:
    /// its terms, read back, and its gradient `∂loss/∂rendered`, left on the device.
    pub(crate) fn compute(
        &mut self,
        view: usize,
        size: ImageSize,
        rendered: &wgpu::Buffer,
    ) -> Result<(LossValues, &wgpu::Buffer), TrainError> {
        let ctx = &*self.ctx;
        if self.bufs.as_ref().is_none_or(|b| b.size() != size) {
            self.bufs = Some(LossBuffers::new(ctx, size).map_err(RasterError::from)?);
        }
        let bufs = self.bufs.as_ref().expect("made above");
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        self.loss
            .encode(ctx, &mut encoder, rendered, &self.targets[view], bufs);
        let values = self
            .loss
            .finish(ctx, encoder, bufs)
            .map_err(RasterError::from)?;
        Ok((values, &bufs.gradient))
    }
}
