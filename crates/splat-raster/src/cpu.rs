//! The CPU backend: per-Gaussian work and per-tile compositing in parallel with rayon.
//!
//! Determinism: the forward image does not depend on the thread count (each tile is composited
//! by one thread in a fixed order), and neither do the gradients: each tile writes its per-entry
//! gradients into its own slots, which are then summed per Gaussian in tile order.

use std::sync::Arc;

use rayon::prelude::*;

use crate::Rasterizer;
use crate::camera::Camera;
use crate::composite::{self, Counters, LANES, PixelGrads, TileOut};
use crate::error::RasterError;
use crate::gaussians::GaussiansView;
use crate::options::{CullStats, RenderOptions};
use crate::output::{BackendState, BackwardState, CpuState, ForwardOutput, Gradients};
use crate::project::{self, CullReason, Frame, Splat, SplatGrad, TILE};
use crate::tiles;
use crate::validate::{validate, validate_backward};

/// The CPU rasterizer. By default it runs on rayon's global pool.
#[derive(Clone, Debug, Default)]
pub struct CpuRasterizer {
    pool: Option<Arc<rayon::ThreadPool>>,
}

impl CpuRasterizer {
    /// A rasterizer on rayon's global thread pool.
    pub fn new() -> Self {
        Self::default()
    }

    /// A rasterizer on its own pool of `threads` threads.
    pub fn with_threads(threads: usize) -> Result<Self, RasterError> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| RasterError::ThreadPool {
                threads,
                message: e.to_string(),
            })?;
        Ok(Self {
            pool: Some(Arc::new(pool)),
        })
    }

    fn install<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        match &self.pool {
            Some(pool) => pool.install(f),
            None => f(),
        }
    }
}

fn count(stats: &mut CullStats, reason: CullReason) {
    match reason {
        CullReason::NonFinite => stats.non_finite += 1,
        CullReason::ZeroQuaternion => stats.zero_quaternion += 1,
        CullReason::LowOpacity => stats.low_opacity += 1,
        CullReason::BehindNearPlane => stats.behind_near_plane += 1,
        CullReason::DegenerateCovariance => stats.degenerate_covariance += 1,
        CullReason::OffScreen => stats.off_screen += 1,
    }
}

/// Row-major pixel index → (tile, lane).
fn tile_lane(frame: &Frame, x: usize, y: usize) -> (usize, usize) {
    let t = TILE as usize;
    (
        (y / t) * frame.tiles_x as usize + x / t,
        (y % t) * t + x % t,
    )
}

impl CpuRasterizer {
    fn forward_impl(
        &self,
        g: GaussiansView<'_>,
        cam: &Camera,
        opts: &RenderOptions,
    ) -> Result<ForwardOutput, RasterError> {
        let active = validate(&g, cam, opts)?;
        let frame = Frame::new(cam);
        let n = g.len();
        let projected: Vec<Result<project::Projected, CullReason>> = (0..n)
            .into_par_iter()
            .map(|i| project::project(&frame, &g, active, i))
            .collect();
        let mut stats = CullStats {
            total: n,
            ..CullStats::default()
        };
        let mut splats = vec![Splat::default(); n];
        let mut rects = vec![None; n];
        let mut depth = vec![0.0f32; n];
        let mut radii = vec![0.0f32; n];
        for (i, p) in projected.into_iter().enumerate() {
            match p {
                Ok(p) => {
                    stats.drawn += 1;
                    splats[i] = p.splat;
                    rects[i] = Some(p.tiles);
                    depth[i] = p.splat.z;
                    radii[i] = p.radius;
                }
                Err(reason) => count(&mut stats, reason),
            }
        }
        let lists = tiles::bin(
            &rects,
            &depth,
            frame.tiles_x,
            frame.tiles_y,
            |id, tx, ty| splats[id as usize].touches_tile(&frame, tx, ty),
        );
        let n_tiles = frame.tiles_x as usize * frame.tiles_y as usize;
        let mut color_t = vec![[0.0f32; 3]; n_tiles * LANES];
        let mut depth_t = vec![0.0f32; n_tiles * LANES];
        let mut final_t = vec![0.0f32; n_tiles * LANES];
        let mut last = vec![0u32; n_tiles * LANES];
        let counters = color_t
            .par_chunks_mut(LANES)
            .zip(depth_t.par_chunks_mut(LANES))
            .zip(final_t.par_chunks_mut(LANES))
            .zip(last.par_chunks_mut(LANES))
            .enumerate()
            .map(|(tile, (((color, depth), final_t), last))| {
                composite::forward_tile(
                    &frame,
                    tile,
                    lists.tile(tile),
                    &splats,
                    opts.background,
                    TileOut {
                        color,
                        depth,
                        final_t,
                        last,
                    },
                )
            })
            .reduce(Counters::default, |a, b| Counters {
                evaluations: a.evaluations + b.evaluations,
                blended: a.blended + b.blended,
            });
        let (w, h) = (cam.width as usize, cam.height as usize);
        let mut color = Vec::with_capacity(w * h);
        let mut alpha = Vec::with_capacity(w * h);
        let mut depth_img = Vec::with_capacity(w * h);
        for y in 0..h {
            for x in 0..w {
                let (t, l) = tile_lane(&frame, x, y);
                let k = t * LANES + l;
                color.push(color_t[k]);
                alpha.push(1.0 - final_t[k]);
                depth_img.push(depth_t[k]);
            }
        }
        Ok(ForwardOutput {
            width: cam.width,
            height: cam.height,
            color,
            alpha,
            depth: depth_img,
            stats,
            state: BackwardState {
                n_gaussians: n,
                sh_degree: g.sh_degree,
                active_degree: active,
                background: opts.background,
                radii,
                counters,
                tile_pairs: lists.ids.len(),
                backend: BackendState::Cpu(CpuState {
                    splats,
                    lists,
                    final_t,
                    last,
                }),
            },
        })
    }

    #[allow(clippy::too_many_arguments)]
    fn backward_impl(
        &self,
        g: GaussiansView<'_>,
        cam: &Camera,
        opts: &RenderOptions,
        fwd: &ForwardOutput,
        d_color: &[[f32; 3]],
        d_alpha: Option<&[f32]>,
        d_depth: Option<&[f32]>,
    ) -> Result<Gradients, RasterError> {
        let active = validate_backward(&g, cam, opts, fwd, d_color, d_alpha, d_depth)?;
        let st = &fwd.state;
        let mismatch = |what: &str| Err(RasterError::ForwardMismatch(what.into()));
        #[allow(unreachable_patterns)]
        let cpu = match &st.backend {
            BackendState::Cpu(cpu) => cpu,
            _ => return mismatch("the forward pass ran on another backend"),
        };
        let frame = Frame::new(cam);
        let pixel_grads = PixelGrads {
            color: d_color,
            alpha: d_alpha,
            depth: d_depth,
        };

        // Per list entry gradients, each tile writing its own slots.
        let lists = &cpu.lists;
        let mut entries = vec![SplatGrad::default(); lists.ids.len()];
        let mut slots: Vec<&mut [SplatGrad]> = Vec::with_capacity(lists.offsets.len());
        let mut rest = entries.as_mut_slice();
        for t in 0..lists.offsets.len() - 1 {
            let (head, tail) = rest.split_at_mut(lists.offsets[t + 1] - lists.offsets[t]);
            slots.push(head);
            rest = tail;
        }
        slots.into_par_iter().enumerate().for_each(|(tile, out)| {
            let lanes = tile * LANES..(tile + 1) * LANES;
            composite::backward_tile(
                &frame,
                tile,
                lists.tile(tile),
                &cpu.splats,
                st.background,
                &cpu.final_t[lanes.clone()],
                &cpu.last[lanes],
                pixel_grads,
                out,
            );
        });
        // Fixed-order reduction per Gaussian.
        let n = g.len();
        let mut per_gaussian = vec![SplatGrad::default(); n];
        for (entry, &id) in entries.iter().zip(&lists.ids) {
            per_gaussian[id as usize].add(entry);
        }

        let stride = g.sh_stride();
        let mut sh = vec![0.0f32; n * stride];
        let raw: Vec<Option<project::RawGrad>> = sh
            .par_chunks_mut(stride)
            .enumerate()
            .map(|(i, sh_out)| {
                // Culled in the forward pass (off screen included): zero gradient.
                if cpu.splats[i].opacity <= 0.0 {
                    return None;
                }
                let grad =
                    project::project_backward(&frame, &g, active, i, &per_gaussian[i], sh_out)?;
                let finite = grad.mean.iter().all(|v| v.is_finite())
                    && grad.log_scale.iter().all(|v| v.is_finite())
                    && grad.q.iter().all(|v| v.is_finite())
                    && grad.logit.is_finite()
                    && sh_out.iter().all(|v| v.is_finite())
                    && per_gaussian[i].u.is_finite()
                    && per_gaussian[i].v.is_finite();
                if finite {
                    Some(grad)
                } else {
                    sh_out.fill(0.0);
                    Some(project::RawGrad {
                        logit: f32::NAN,
                        ..project::RawGrad::default()
                    })
                }
            })
            .collect();
        let mut out = Gradients {
            means: vec![[0.0; 3]; n],
            log_scales: vec![[0.0; 3]; n],
            rotations: vec![[0.0; 4]; n],
            opacity_logits: vec![0.0; n],
            sh,
            means2d: vec![[0.0; 2]; n],
            radii: st.radii.clone(),
            zeroed_non_finite: 0,
        };
        for (i, grad) in raw.into_iter().enumerate() {
            let Some(grad) = grad else { continue };
            if grad.logit.is_nan() {
                out.zeroed_non_finite += 1;
                continue;
            }
            out.means[i] = grad.mean;
            out.log_scales[i] = grad.log_scale;
            out.rotations[i] = grad.q;
            out.opacity_logits[i] = grad.logit;
            out.means2d[i] = [per_gaussian[i].u, per_gaussian[i].v];
        }
        Ok(out)
    }
}

impl Rasterizer for CpuRasterizer {
    fn forward(
        &self,
        g: GaussiansView<'_>,
        cam: &Camera,
        opts: &RenderOptions,
    ) -> Result<ForwardOutput, RasterError> {
        self.install(|| self.forward_impl(g, cam, opts))
    }

    fn backward(
        &self,
        g: GaussiansView<'_>,
        cam: &Camera,
        opts: &RenderOptions,
        fwd: &ForwardOutput,
        d_color: &[[f32; 3]],
        d_alpha: Option<&[f32]>,
        d_depth: Option<&[f32]>,
    ) -> Result<Gradients, RasterError> {
        self.install(|| self.backward_impl(g, cam, opts, fwd, d_color, d_alpha, d_depth))
    }
}
