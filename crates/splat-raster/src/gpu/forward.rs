//! The forward pass on the GPU: projection, depth sort, tile counts and their prefix sum
//! (the backend's one scan, [`gpu_core::PrefixSum`]),
//! intersection emission, sort by tile, tile ranges, compositing; then the read-back of the
//! images, radii and counters (a resident pass keeps the images on the device and reads back
//! the radii and counters only).

use crate::camera::Camera;
use crate::error::RasterError;
use crate::gaussians::GaussiansView;
use crate::options::{CullStats, RenderOptions};
use crate::output::{BackendState, BackwardState, Counters, ForwardOutput};
use crate::validate::validate;

use super::WgpuRasterizer;
use super::frame::{FrameUniform, pack_params};
use super::state::GpuState;
use gpu_core::buffers::{pooled_storage, pooled_storage_init, pooled_uniform, read_back};
use gpu_core::encode::{bind, dispatch, groups_1d};
use gpu_core::level_lengths;

/// The label of the forward pass's GPU timestamp spans (both stages).
pub const SPAN_FORWARD: &str = "raster forward";

/// Bytes of one WGSL `Splat` record.
pub(crate) const SPLAT_BYTES: u64 = 64;

/// Index of each outcome in the projection's cull counts: the `CULL_*` codes of common.wgsl (0:
/// drawn). A test in `gpu/layout_tests.rs` checks them against the WGSL constants.
pub(crate) mod cull {
    /// Drawn (no cull reason).
    pub(crate) const DRAWN: usize = 0;
    /// `CULL_NON_FINITE`.
    pub(crate) const NON_FINITE: usize = 1;
    /// `CULL_ZERO_QUATERNION`.
    pub(crate) const ZERO_QUATERNION: usize = 2;
    /// `CULL_LOW_OPACITY`.
    pub(crate) const LOW_OPACITY: usize = 3;
    /// `CULL_BEHIND_NEAR_PLANE`.
    pub(crate) const BEHIND_NEAR_PLANE: usize = 4;
    /// `CULL_DEGENERATE`.
    pub(crate) const DEGENERATE: usize = 5;
    /// `CULL_OFF_SCREEN`.
    pub(crate) const OFF_SCREEN: usize = 6;
}

fn u32s(bytes: &[u8]) -> Vec<u32> {
    bytemuck::pod_collect_to_vec(bytes)
}

fn f32s(bytes: &[u8]) -> Vec<f32> {
    bytemuck::pod_collect_to_vec(bytes)
}

impl WgpuRasterizer {
    /// The forward pass; `resident` leaves the colour, alpha and depth on the device (the
    /// output's image vectors empty, the colour held by its state) instead of reading them back.
    pub(crate) fn forward_impl(
        &self,
        g: GaussiansView<'_>,
        cam: &Camera,
        opts: &RenderOptions,
        resident: bool,
    ) -> Result<ForwardOutput, RasterError> {
        let active = validate(&g, cam, opts)?;
        let ctx = &*self.ctx;
        let device = &ctx.device;
        let queue = &ctx.queue;
        let max_dim = device.limits().max_compute_workgroups_per_dimension;
        let n = g.len();
        let n32 = u32::try_from(n).map_err(|_| RasterError::Gpu {
            stage: "buffers",
            message: format!("{n} Gaussians do not fit u32 indices"),
        })?;
        let mut frame = FrameUniform::new(cam, n, g.sh_stride(), active, opts.background);
        let n_tiles = frame.n_tiles();
        let npix = cam.pixel_count() as u64;

        // Every buffer comes from the context's pool and is held until the read-back that
        // ends its stage has waited (`pooled_*`'s contract); those the backward pass reads
        // stay held by the output.
        let mut enc = device.create_command_encoder(&Default::default());
        let span = ctx.span_begin(&mut enc, SPAN_FORWARD);
        let params = pooled_storage_init(
            ctx,
            &mut enc,
            "params",
            bytemuck::cast_slice(&pack_params(&g)),
        )?;
        let frame_buf = pooled_uniform(ctx, "frame", bytemuck::bytes_of(&frame));
        let n64 = n as u64;
        let mut storage = |label, bytes| pooled_storage(ctx, &mut enc, label, bytes);
        let splats = storage("splats", n64 * SPLAT_BYTES)?;
        let radii = storage("radii", n64 * 4)?;
        let depth_keys = storage("depth_keys", n64 * 4)?;
        let sort_ids = storage("sort_ids", n64 * 4)?;
        let tile_counts = storage("tile_counts", n64 * 4)?;
        let stats = storage("stats", 32)?;
        let offsets = storage("offsets", n64 * 4)?;
        // The scan's upper levels (chunk totals); the last one ends as the grand total.
        let scan_lens = level_lengths(n32);
        let scan_sums = scan_lens[1..]
            .iter()
            .map(|&len| storage("scan_sums", u64::from(len) * 4))
            .collect::<Result<Vec<_>, _>>()?;
        let total = scan_sums.last().expect("at least one upper level");

        // Stage 1: project, sort by depth, count tiles in depth order and scan the counts.
        let p = &self.pipelines;
        let per_gaussian = groups_1d(n32, max_dim);
        // The sort's and the scan's pooled parameter records, held until submitted.
        let mut held_stage1 = None;
        if n > 0 {
            let bg = bind(
                ctx,
                &p.project,
                &[
                    (0, &frame_buf),
                    (1, &params),
                    (2, &splats),
                    (3, &radii),
                    (4, &depth_keys),
                    (5, &sort_ids),
                    (6, &tile_counts),
                    (7, &stats),
                ],
            );
            dispatch(ctx, &mut enc, &p.project, &bg, per_gaussian);
            let depth_sort = self
                .sorter
                .encode(ctx, &mut enc, &depth_keys, &sort_ids, n32, 32);
            let bg = bind(
                ctx,
                &p.gather_counts,
                &[
                    (0, &frame_buf),
                    (3, &sort_ids),
                    (4, &tile_counts),
                    (5, &offsets),
                ],
            );
            dispatch(ctx, &mut enc, &p.gather_counts, &bg, per_gaussian);
            let scan = self.sorter.prefix_sum();
            let levels: Vec<&wgpu::Buffer> = std::iter::once(&*offsets)
                .chain(scan_sums.iter().map(|b| &**b))
                .collect();
            let plan = scan.plan(ctx, &levels, &scan_lens);
            let mut cpass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("tile count scan"),
                timestamp_writes: None,
            });
            scan.record(&ctx.traffic, &mut cpass, &plan);
            drop(cpass);
            held_stage1 = Some((depth_sort, plan));
        }
        ctx.span_end(&mut enc, span);
        let head = read_back(ctx, enc, &[(&stats, 0, 32), (&**total, 0, 4)])?;
        drop(held_stage1);
        let counts = u32s(&head[0]);
        let n_isect = if n > 0 { u32s(&head[1])[0] } else { 0 };
        let stats = CullStats {
            total: n,
            drawn: counts[cull::DRAWN] as usize,
            non_finite: counts[cull::NON_FINITE] as usize,
            zero_quaternion: counts[cull::ZERO_QUATERNION] as usize,
            low_opacity: counts[cull::LOW_OPACITY] as usize,
            behind_near_plane: counts[cull::BEHIND_NEAR_PLANE] as usize,
            degenerate_covariance: counts[cull::DEGENERATE] as usize,
            off_screen: counts[cull::OFF_SCREEN] as usize,
        };

        // Stage 2: emit the (tile, Gaussian) pairs in depth order, sort them stably by tile,
        // find each tile's range and composite.
        frame.n_isect = n_isect;
        ctx.traffic
            .upload(std::mem::size_of::<FrameUniform>() as u64);
        queue.write_buffer(&frame_buf, 0, bytemuck::bytes_of(&frame));
        let mut enc = device.create_command_encoder(&Default::default());
        let span = ctx.span_begin(&mut enc, SPAN_FORWARD);
        let mut storage = |label, bytes| pooled_storage(ctx, &mut enc, label, bytes);
        let isect_keys = storage("isect_keys", u64::from(n_isect) * 4)?;
        let isect_ids = storage("isect_ids", u64::from(n_isect) * 4)?;
        let ranges = storage("ranges", u64::from(n_tiles) * 8)?;
        let color = storage("color", npix * 12)?;
        let alpha = storage("alpha", npix * 4)?;
        let depth = storage("depth", npix * 4)?;
        let lanes = u64::from(n_tiles) * 256;
        let final_t = storage("final_t", lanes * 4)?;
        let last = storage("last", lanes * 4)?;
        let tile_counters = storage("tile_counters", u64::from(n_tiles) * 8)?;
        let mut tile_sort = None;
        if n_isect > 0 {
            let bg = bind(
                ctx,
                &p.emit,
                &[
                    (0, &frame_buf),
                    (2, &splats),
                    (3, &sort_ids),
                    (4, &tile_counts),
                    (5, &offsets),
                    (6, &isect_keys),
                    (7, &isect_ids),
                ],
            );
            dispatch(ctx, &mut enc, &p.emit, &bg, per_gaussian);
            let key_bits = (32 - (n_tiles.max(2) - 1).leading_zeros()).max(1);
            tile_sort =
                Some(
                    self.sorter
                        .encode(ctx, &mut enc, &isect_keys, &isect_ids, n_isect, key_bits),
                );
            let bg = bind(
                ctx,
                &p.tile_ranges,
                &[(0, &frame_buf), (2, &isect_keys), (3, &ranges)],
            );
            dispatch(
                ctx,
                &mut enc,
                &p.tile_ranges,
                &bg,
                groups_1d(n_isect, max_dim),
            );
        }
        let bg = bind(
            ctx,
            &p.rasterize,
            &[
                (0, &frame_buf),
                (2, &splats),
                (3, &isect_ids),
                (4, &ranges),
                (5, &color),
                (6, &alpha),
                (7, &depth),
                (8, &final_t),
                (9, &last),
                (10, &tile_counters),
            ],
        );
        dispatch(
            ctx,
            &mut enc,
            &p.rasterize,
            &bg,
            (frame.tiles_x, frame.tiles_y),
        );
        ctx.span_end(&mut enc, span);
        let n_pix = if resident { 0 } else { npix };
        let out = read_back(
            ctx,
            enc,
            &[
                (&radii, 0, n64 * 4),
                (&tile_counters, 0, u64::from(n_tiles) * 8),
                (&color, 0, n_pix * 12),
                (&alpha, 0, n_pix * 4),
                (&depth, 0, n_pix * 4),
            ],
        )?;
        drop(tile_sort);
        let per_tile = u32s(&out[1]);
        let counters = Counters {
            evaluations: per_tile.iter().step_by(2).map(|&v| u64::from(v)).sum(),
            blended: per_tile
                .iter()
                .skip(1)
                .step_by(2)
                .map(|&v| u64::from(v))
                .sum(),
        };
        Ok(ForwardOutput {
            width: cam.width,
            height: cam.height,
            color: f32s(&out[2])
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect(),
            alpha: f32s(&out[3]),
            depth: f32s(&out[4]),
            stats,
            state: BackwardState {
                n_gaussians: n,
                sh_degree: g.sh_degree,
                active_degree: active,
                background: opts.background,
                radii: f32s(&out[0]),
                counters,
                tile_pairs: n_isect as usize,
                backend: BackendState::Gpu(Box::new(GpuState {
                    context_id: self.ctx.id(),
                    frame,
                    params,
                    splats,
                    isect_ids,
                    ranges,
                    final_t,
                    last,
                    color: resident.then_some(color),
                })),
            },
        })
    }
}
