//! The CPU backend: per-Gaussian work and per-tile compositing in parallel with rayon.
//!
//! - `project`: per-Gaussian projection (f64) and its backward pass;
//! - `tiles`: binning of drawn Gaussians into depth-ordered tile lists;
//! - `composite`: per-tile front-to-back compositing and its backward, as plain reference kernels
//!   (`scalar`) and eight-pixel SIMD kernels (`lanes`) over the lane builds of `simd`, and the
//!   choice between them ([`CpuKernel`]);
//! - `state`: what a forward pass keeps for its backward pass, and the buffers the passes reuse
//!   (held by [`ForwardOutput`] and [`BackwardOutput`]).
//!
//! Determinism: the forward image does not depend on the thread count (each tile is composited
//! by one thread in a fixed order), and neither do the gradients: each tile writes its per-entry
//! gradients into its own slots, which are then summed per Gaussian in tile order.

mod composite;
mod project;
mod simd;
pub(crate) mod state;
mod tiles;

use std::sync::Arc;

use rayon::prelude::*;

pub use self::composite::CpuKernel;
use self::composite::{Kernels, LANES, TileOut, lanes, scalar};
use self::project::{CullReason, Splat, SplatGrads};
use self::state::{BackwardScratch, CpuState, Scratch};
use self::tiles::TileLists;
use crate::Rasterizer;
use crate::camera::Camera;
use crate::constants::TILE;
use crate::error::RasterError;
use crate::frame::Frame;
use crate::gaussians::GaussiansView;
use crate::options::{CullStats, RenderOptions};
use crate::output::{BackendState, BackwardOutput, Counters, ForwardOutput, PixelGrads};
use crate::validate::{validate, validate_backward};

/// The CPU rasterizer. By default it runs the SIMD kernels on rayon's global pool.
#[derive(Clone, Debug)]
pub struct CpuRasterizer {
    pool: Option<Arc<rayon::ThreadPool>>,
    kernels: Kernels,
}

impl Default for CpuRasterizer {
    fn default() -> Self {
        Self {
            pool: None,
            kernels: Kernels::of(CpuKernel::Simd),
        }
    }
}

impl CpuRasterizer {
    /// A rasterizer on rayon's global thread pool.
    pub fn new() -> Self {
        Self::default()
    }

    /// The same rasterizer running `kernel`. A backward pass runs the kernels its forward pass
    /// ran, whatever this says.
    #[must_use]
    pub fn with_kernel(self, kernel: CpuKernel) -> Self {
        Self {
            kernels: Kernels::of(kernel),
            ..self
        }
    }

    /// The same rasterizer running `kernels` (tests of each build against the reference).
    #[cfg(test)]
    pub(crate) fn with_kernels(self, kernels: Kernels) -> Self {
        Self { kernels, ..self }
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
            ..Self::default()
        })
    }

    fn install<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        match &self.pool {
            Some(pool) => pool.install(f),
            None => f(),
        }
    }
}

/// Gaussians per task of the projection (fixed, so the work split does not depend on the
/// thread count; the counts summed never do).
const PROJECT_CHUNK: usize = 256;

/// The counts of `a` and `b` added (their `total`s included).
fn sum_culls(a: CullStats, b: CullStats) -> CullStats {
    CullStats {
        total: a.total + b.total,
        drawn: a.drawn + b.drawn,
        non_finite: a.non_finite + b.non_finite,
        zero_quaternion: a.zero_quaternion + b.zero_quaternion,
        low_opacity: a.low_opacity + b.low_opacity,
        behind_near_plane: a.behind_near_plane + b.behind_near_plane,
        degenerate_covariance: a.degenerate_covariance + b.degenerate_covariance,
        off_screen: a.off_screen + b.off_screen,
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

/// What the backward pass made of one Gaussian.
enum Outcome {
    /// Culled in the forward pass: zero gradient.
    Culled,
    /// Its gradient overflowed `f32`: set to zero and counted.
    Zeroed,
    /// Its raw-parameter gradient and dL/d(u, v).
    Drawn(project::RawGrads, [f32; 2]),
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
    /// The forward pass into `out`, reusing the buffers of its CPU state (when it holds one)
    /// and of its images: nothing is allocated once they are large enough. The values written
    /// do not depend on what `out` held.
    fn forward_into_impl(
        &self,
        g: GaussiansView<'_>,
        cam: &Camera,
        opts: &RenderOptions,
        out: &mut ForwardOutput,
    ) -> Result<(), RasterError> {
        let active = validate(&g, cam, opts)?;
        let frame = Frame::new(cam);
        let n = g.len();
        // The previous pass's CPU buffers (borrowed in place: a pass allocates no state), or
        // fresh ones.
        if !matches!(out.state.backend, BackendState::Cpu(_)) {
            out.state.backend = BackendState::Cpu(Box::default());
        }
        #[allow(unreachable_patterns)]
        let cpu = match &mut out.state.backend {
            BackendState::Cpu(cpu) => &mut **cpu,
            _ => {
                return Err(RasterError::ForwardMismatch(
                    "the output holds another backend's state".into(),
                ));
            }
        };
        cpu.kernels = self.kernels;
        let CpuState {
            splats: sorted,
            lists,
            final_t,
            last,
            scratch,
            ..
        } = cpu;
        let Scratch {
            splats,
            rects,
            depth,
            color_t,
            depth_t,
            bin,
        } = scratch;
        // Per Gaussian, in parallel: its record, tile rectangle, depth and screen radius (the
        // defaults when culled), and the cull counts summed. Every row is written, so the
        // buffers are only resized.
        let radii = &mut out.state.radii;
        splats.resize(n, Splat::default());
        rects.resize(n, None);
        depth.resize(n, 0.0);
        radii.resize(n, 0.0);
        let culls = splats
            .par_iter_mut()
            .zip(rects.par_iter_mut())
            .zip(depth.par_iter_mut())
            .zip(radii.par_iter_mut())
            .enumerate()
            .with_min_len(PROJECT_CHUNK)
            .fold(
                CullStats::default,
                |mut stats, (i, (((splat, rect), z), radius))| {
                    match project::project(&frame, &g, active, i) {
                        Ok(p) => {
                            stats.drawn += 1;
                            (*splat, *rect, *z, *radius) =
                                (p.splat, Some(p.tiles), p.splat.z, p.radius);
                        }
                        Err(reason) => {
                            count(&mut stats, reason);
                            (*splat, *rect, *z, *radius) = (Splat::default(), None, 0.0, 0.0);
                        }
                    }
                    stats
                },
            )
            .reduce(CullStats::default, sum_culls);
        let stats = CullStats { total: n, ..culls };
        tiles::bin_into(
            rects,
            depth,
            frame.tiles_x,
            frame.tiles_y,
            |id, rect, tiles| {
                splats[id as usize].for_each_touched_tile(&frame, rect, |tx, ty| {
                    tiles.push(ty * frame.tiles_x + tx);
                });
            },
            lists,
            bin,
        );
        // The records in depth order, as the tile lists index them.
        sorted.clear();
        sorted.par_extend(lists.order.par_iter().map(|&i| splats[i as usize]));
        let n_tiles = frame.tiles_x as usize * frame.tiles_y as usize;
        // Every tile writes all its lanes: the values left from before are overwritten, so
        // the buffers are only resized.
        color_t.resize(n_tiles * LANES, [0.0; 3]);
        depth_t.resize(n_tiles * LANES, 0.0);
        final_t.resize(n_tiles * LANES, 0.0);
        last.resize(n_tiles * LANES, 0);
        let (lists, sorted) = (&*lists, &*sorted);
        let counters = color_t
            .par_chunks_mut(LANES)
            .zip(depth_t.par_chunks_mut(LANES))
            .zip(final_t.par_chunks_mut(LANES))
            .zip(last.par_chunks_mut(LANES))
            .enumerate()
            .map(|(tile, (((color, depth), final_t), last))| {
                let out = TileOut {
                    color,
                    depth,
                    final_t,
                    last,
                };
                let (ids, background) = (lists.tile(tile), opts.background);
                match self.kernels {
                    Kernels::Scalar { exp } => {
                        scalar::forward_tile_into(&frame, tile, ids, sorted, background, out, exp)
                    }
                    Kernels::Lanes(isa) => simd::dispatch(
                        isa,
                        lanes::Forward {
                            frame: &frame,
                            tile,
                            ids,
                            splats: sorted,
                            background,
                            out,
                        },
                    ),
                }
            })
            .reduce(Counters::default, |a, b| Counters {
                evaluations: a.evaluations + b.evaluations,
                blended: a.blended + b.blended,
            });
        // Every pixel is written below: the images are only resized.
        let (w, h) = (cam.width as usize, cam.height as usize);
        out.alpha.resize(w * h, 0.0);
        out.depth.resize(w * h, 0.0);
        out.color.resize(w * h, [0.0; 3]);
        let (color_t, depth_t, final_t) = (&*color_t, &*depth_t, &*final_t);
        out.color
            .par_chunks_mut(w)
            .zip(out.alpha.par_chunks_mut(w))
            .zip(out.depth.par_chunks_mut(w))
            .enumerate()
            .for_each(|(y, ((color, alpha), depth))| {
                for x in 0..w {
                    let (t, l) = tile_lane(&frame, x, y);
                    let k = t * LANES + l;
                    color[x] = color_t[k];
                    alpha[x] = 1.0 - final_t[k];
                    depth[x] = depth_t[k];
                }
            });
        let tile_pairs = lists.ids.len();
        out.width = cam.width;
        out.height = cam.height;
        out.stats = stats;
        let st = &mut out.state;
        st.n_gaussians = n;
        st.sh_degree = g.sh_degree;
        st.active_degree = active;
        st.background = opts.background;
        st.counters = counters;
        st.tile_pairs = tile_pairs;
        Ok(())
    }

    /// The backward pass into `out`, reusing its gradient arrays and its per-entry scratch:
    /// nothing is allocated once they are large enough. Every value of `out` is written, so the
    /// result does not depend on what it held.
    fn backward_into_impl(
        &self,
        g: GaussiansView<'_>,
        cam: &Camera,
        opts: &RenderOptions,
        fwd: &ForwardOutput,
        pixel_grads: PixelGrads<'_>,
        out: &mut BackwardOutput,
    ) -> Result<(), RasterError> {
        let active = validate_backward(&g, cam, opts, fwd, pixel_grads)?;
        let st = &fwd.state;
        let mismatch = |what: &str| Err(RasterError::ForwardMismatch(what.into()));
        #[allow(unreachable_patterns)]
        let cpu = match &st.backend {
            BackendState::Cpu(cpu) => cpu,
            _ => return mismatch("the forward pass ran on another backend"),
        };
        let frame = Frame::new(cam);

        // Per list entry gradients, each tile writing its own slots (all of them: the kernels
        // write the entries before the tile's last contributor, the tile zeroes the rest first).
        let lists = &cpu.lists;
        let entries = &mut out.scratch.entries;
        entries.resize(lists.ids.len(), SplatGrads::default());
        let tile_pass = |tile: usize, slots: &mut [SplatGrads]| {
            slots.fill(SplatGrads::default());
            let range = tile * LANES..(tile + 1) * LANES;
            let (final_t, last) = (&cpu.final_t[range.clone()], &cpu.last[range]);
            let ids = lists.tile(tile);
            match cpu.kernels {
                Kernels::Scalar { exp } => scalar::backward_tile_into(
                    &frame,
                    tile,
                    ids,
                    &cpu.splats,
                    st.background,
                    final_t,
                    last,
                    pixel_grads,
                    slots,
                    exp,
                ),
                Kernels::Lanes(isa) => simd::dispatch(
                    isa,
                    lanes::Backward {
                        frame: &frame,
                        tile,
                        ids,
                        splats: &cpu.splats,
                        background: st.background,
                        final_t,
                        last,
                        grads: pixel_grads,
                        out: slots,
                    },
                ),
            }
        };
        each_tile(
            &lists.offsets,
            0..lists.offsets.len() - 1,
            entries,
            &tile_pass,
        );
        // Per Gaussian, its entries summed in tile order (a fixed order), then chained to the
        // raw parameters; every row of every array is written.
        let n = g.len();
        let stride = g.sh_stride();
        let grads = &mut out.grads;
        for v in [&mut grads.means, &mut grads.log_scales] {
            v.resize(n, [0.0; 3]);
        }
        grads.rotations.resize(n, [0.0; 4]);
        grads.opacity_logits.resize(n, 0.0);
        grads.sh.resize(n * stride, 0.0);
        grads.means2d.resize(n, [0.0; 2]);
        let entries = &*entries;
        let zeroed = grads
            .sh
            .par_chunks_mut(stride)
            .zip(grads.means.par_iter_mut())
            .zip(grads.log_scales.par_iter_mut())
            .zip(grads.rotations.par_iter_mut())
            .zip(grads.opacity_logits.par_iter_mut())
            .zip(grads.means2d.par_iter_mut())
            .enumerate()
            .map(
                |(i, (((((sh_out, mean), log_scale), rotation), logit), uv))| {
                    sh_out.fill(0.0);
                    let outcome = backward_gaussian(&frame, &g, active, lists, entries, i, sh_out);
                    let (raw, d_uv, zeroed) = match outcome {
                        Outcome::Drawn(raw, d_uv) => (raw, d_uv, 0),
                        Outcome::Culled => (project::RawGrads::default(), [0.0; 2], 0),
                        Outcome::Zeroed => (project::RawGrads::default(), [0.0; 2], 1),
                    };
                    *mean = raw.mean;
                    *log_scale = raw.log_scale;
                    *rotation = raw.q;
                    *logit = raw.logit;
                    *uv = d_uv;
                    zeroed
                },
            )
            .sum();
        out.zeroed_non_finite = zeroed;
        Ok(())
    }
}

/// Runs `pass(tile, slots)` for every tile of `tiles` in parallel, each on its own slots of
/// `entries` (which start at `offsets[tiles.start]`), splitting the range in halves: no list of
/// slots is built.
fn each_tile<F>(
    offsets: &[usize],
    tiles: std::ops::Range<usize>,
    entries: &mut [SplatGrads],
    pass: &F,
) where
    F: Fn(usize, &mut [SplatGrads]) + Sync,
{
    match tiles.len() {
        0 => {}
        1 => pass(tiles.start, entries),
        len => {
            let mid = tiles.start + len / 2;
            let (head, tail) = entries.split_at_mut(offsets[mid] - offsets[tiles.start]);
            rayon::join(
                || each_tile(offsets, tiles.start..mid, head, pass),
                || each_tile(offsets, mid..tiles.end, tail, pass),
            );
        }
    }
}

/// Gaussian `i`'s entries summed in tile order and chained to its raw parameters (its SH
/// gradient into `sh_out`, which holds zeros).
fn backward_gaussian(
    frame: &Frame,
    g: &GaussiansView<'_>,
    active: u32,
    lists: &TileLists,
    entries: &[SplatGrads],
    i: usize,
    sh_out: &mut [f32],
) -> Outcome {
    // Culled in the forward pass (off screen included; a drawn Gaussian touches a tile): zero
    // gradient.
    if lists.entries_of(i).is_empty() {
        return Outcome::Culled;
    }
    let mut d = SplatGrads::default();
    for &e in lists.entries_of(i) {
        d.add(&entries[e as usize]);
    }
    let Some(grad) = project::project_backward_into(frame, g, active, i, &d, sh_out) else {
        return Outcome::Culled;
    };
    let finite = grad.mean.iter().all(|v| v.is_finite())
        && grad.log_scale.iter().all(|v| v.is_finite())
        && grad.q.iter().all(|v| v.is_finite())
        && grad.logit.is_finite()
        && sh_out.iter().all(|v| v.is_finite())
        && d.u.is_finite()
        && d.v.is_finite();
    if finite {
        Outcome::Drawn(grad, [d.u, d.v])
    } else {
        sh_out.fill(0.0);
        Outcome::Zeroed
    }
}

impl Rasterizer for CpuRasterizer {
    fn forward(
        &self,
        g: GaussiansView<'_>,
        cam: &Camera,
        opts: &RenderOptions,
    ) -> Result<ForwardOutput, RasterError> {
        let mut out = ForwardOutput::default();
        self.install(|| self.forward_into_impl(g, cam, opts, &mut out))?;
        // A lone pass keeps only what its backward needs.
        #[allow(irrefutable_let_patterns)]
        if let BackendState::Cpu(cpu) = &mut out.state.backend {
            cpu.scratch = Scratch::default();
        }
        Ok(out)
    }

    fn forward_into(
        &self,
        g: GaussiansView<'_>,
        cam: &Camera,
        opts: &RenderOptions,
        out: &mut ForwardOutput,
    ) -> Result<(), RasterError> {
        self.install(|| self.forward_into_impl(g, cam, opts, out))
    }

    fn backward(
        &self,
        g: GaussiansView<'_>,
        cam: &Camera,
        opts: &RenderOptions,
        fwd: &ForwardOutput,
        d: PixelGrads<'_>,
    ) -> Result<BackwardOutput, RasterError> {
        let mut out = BackwardOutput::default();
        self.install(|| self.backward_into_impl(g, cam, opts, fwd, d, &mut out))?;
        // A lone pass keeps only the gradients.
        out.scratch = BackwardScratch::default();
        Ok(out)
    }

    fn backward_into(
        &self,
        g: GaussiansView<'_>,
        cam: &Camera,
        opts: &RenderOptions,
        fwd: &ForwardOutput,
        d: PixelGrads<'_>,
        out: &mut BackwardOutput,
    ) -> Result<(), RasterError> {
        self.install(|| self.backward_into_impl(g, cam, opts, fwd, d, out))
    }
}

#[cfg(test)]
mod tests {
    use glam::{Mat3, Vec3};
    use proptest::prelude::*;

    use super::simd::{F8, Isa, Portable, Simd, dispatch};
    use super::*;
    use crate::gaussians::Gaussians;
    use crate::output::GaussianGrads;

    /// The vectorised `exp` on one value (the same value in any build).
    fn approx_exp(x: f32) -> f32 {
        super::simd::exp(Portable, F8([x; 8])).0[0]
    }

    /// The CPU backend's state of a forward pass on the CPU.
    fn cpu_state(f: &ForwardOutput) -> &CpuState {
        #[allow(unreachable_patterns)]
        match &f.state.backend {
            BackendState::Cpu(s) => s,
            _ => unreachable!("a CPU forward pass"),
        }
    }

    fn isas() -> Vec<Isa> {
        let mut v = vec![Isa::Portable];
        if Isa::best() != Isa::Portable {
            v.push(Isa::best());
        }
        v
    }

    /// Raw parameters of one Gaussian: mean (z in front of the camera), log-scales, quaternion,
    /// opacity logit, three SH DC values.
    type Raw = ([f32; 3], [f32; 3], [f32; 4], f32, [f32; 3]);

    fn gaussian() -> impl Strategy<Value = Raw> {
        (
            (-1.5f32..1.5, -1.2f32..1.2, 2.0f32..5.0),
            prop_oneof![
                3 => (-3.5f32..-1.5, -3.5f32..-1.5, -3.5f32..-1.5),
                1 => (-7.0f32..-4.0, -1.5f32..0.5, -3.0f32..-1.0),
                1 => (-0.5f32..1.5, -0.5f32..1.5, -0.5f32..1.5),
            ],
            (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0, 0.1f32..1.0),
            prop_oneof![2 => -2.0f32..3.0, 1 => 4.0f32..9.0],
            (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0),
        )
            .prop_map(|(m, s, q, o, c)| {
                (
                    [m.0, m.1, m.2],
                    [s.0, s.1, s.2],
                    [q.3, q.0, q.1, q.2],
                    o,
                    [c.0, c.1, c.2],
                )
            })
    }

    fn scene(parts: &[Raw]) -> Gaussians {
        let mut g = Gaussians::with_degree(0);
        for &(m, s, q, o, c) in parts {
            g.means.push(m);
            g.log_scales.push(s);
            g.rotations.push(q);
            g.opacity_logits.push(o);
            g.sh.extend(c);
        }
        g
    }

    fn assert_close(what: &str, fast: &[f32], reference: &[f32]) {
        let scale = reference.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        for (k, (a, b)) in fast.iter().zip(reference).enumerate() {
            let tol = 1e-4 * b.abs() + 2e-5 * scale + 1e-30;
            assert!(
                (a - b).abs() <= tol,
                "{what}[{k}]: {a} vs {b} (scale {scale})"
            );
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

        /// The SIMD kernels against the scalar reference kernels with the same `exp`: the
        /// forward pass bit for bit, the gradients within rounding of their sums; and the
        /// builds of the SIMD kernels against each other, bit for bit.
        #[test]
        fn simd_kernels_match_the_scalar_reference(
            parts in proptest::collection::vec(gaussian(), 1..60),
            width in 1u32..50,
            height in 1u32..40,
            background in (-0.5f32..1.5, -0.5f32..1.5, -0.5f32..1.5),
        ) {
            let g = scene(&parts);
            let cam = Camera::from_center(
                width, height, 30.0, 28.0, 0.45 * width as f32, 0.55 * height as f32,
                Mat3::IDENTITY, Vec3::ZERO,
            );
            let opts = RenderOptions { background: [background.0, background.1, background.2], sh_degree: None };
            let npix = cam.pixel_count();
            let dc: Vec<[f32; 3]> = (0..npix).map(|p| [0.3, -0.7, 0.5].map(|v: f32| v * ((p % 5) as f32 - 1.7))).collect();
            let da: Vec<f32> = (0..npix).map(|p| 0.2 * ((p % 3) as f32 - 1.1)).collect();
            let dd: Vec<f32> = (0..npix).map(|p| 0.05 * ((p % 7) as f32 - 3.2)).collect();
            let run = |kernels: Kernels| {
                let r = CpuRasterizer::new().with_kernels(kernels);
                let fwd = r.forward(g.view(), &cam, &opts).unwrap();
                let d = PixelGrads::from_color(&dc).with_alpha(&da).with_depth(&dd);
                let grads = r.backward(g.view(), &cam, &opts, &fwd, d).unwrap().grads;
                (fwd, grads)
            };
            let (rf, rg) = run(Kernels::Scalar { exp: approx_exp });
            let rs = cpu_state(&rf);
            let mut first: Option<GaussianGrads> = None;
            for isa in isas() {
                let (f, gr) = run(Kernels::Lanes(isa));
                let fs = cpu_state(&f);
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                prop_assert_eq!(bits(f.color.as_flattened()), bits(rf.color.as_flattened()));
                prop_assert_eq!(bits(&f.alpha), bits(&rf.alpha));
                prop_assert_eq!(bits(&f.depth), bits(&rf.depth));
                prop_assert_eq!(&fs.last, &rs.last);
                prop_assert_eq!(f.state.counters, rf.state.counters);
                assert_close("means", gr.means.as_flattened(), rg.means.as_flattened());
                assert_close("log_scales", gr.log_scales.as_flattened(), rg.log_scales.as_flattened());
                assert_close("rotations", gr.rotations.as_flattened(), rg.rotations.as_flattened());
                assert_close("opacity_logits", &gr.opacity_logits, &rg.opacity_logits);
                assert_close("sh", &gr.sh, &rg.sh);
                assert_close("means2d", gr.means2d.as_flattened(), rg.means2d.as_flattened());
                if let Some(first) = &first {
                    prop_assert_eq!(first, &gr);
                }
                first = Some(gr);
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

        /// `forward_into` an output that held another render (more or fewer Gaussians, a larger
        /// or smaller image, another background) gives what `forward` gives, bit for bit: the
        /// images, the statistics, the radii, the backward state, and so the gradients.
        #[test]
        fn forward_into_a_used_output_equals_a_fresh_forward(
            before in proptest::collection::vec(gaussian(), 0..80),
            parts in proptest::collection::vec(gaussian(), 1..60),
            sizes in ((1u32..50, 1u32..40), (1u32..50, 1u32..40)),
        ) {
            let cam = |(width, height): (u32, u32)| Camera::from_center(
                width, height, 30.0, 28.0, 0.45 * width as f32, 0.55 * height as f32,
                Mat3::IDENTITY, Vec3::ZERO,
            );
            let (cam_before, cam) = (cam(sizes.0), cam(sizes.1));
            let opts = RenderOptions { background: [0.2, 0.5, 0.9], sh_degree: None };
            let r = CpuRasterizer::new();
            let g = scene(&parts);
            let fresh = r.forward(g.view(), &cam, &opts).unwrap();
            let mut out = ForwardOutput::default();
            let other = RenderOptions { background: [1.0; 3], sh_degree: None };
            r.forward_into(scene(&before).view(), &cam_before, &other, &mut out).unwrap();
            r.forward_into(g.view(), &cam, &opts, &mut out).unwrap();
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            prop_assert_eq!((out.width, out.height), (fresh.width, fresh.height));
            prop_assert_eq!(bits(out.color.as_flattened()), bits(fresh.color.as_flattened()));
            prop_assert_eq!(bits(&out.alpha), bits(&fresh.alpha));
            prop_assert_eq!(bits(&out.depth), bits(&fresh.depth));
            prop_assert_eq!(bits(out.radii()), bits(fresh.radii()));
            prop_assert_eq!(out.stats, fresh.stats);
            prop_assert_eq!(out.state.counters, fresh.state.counters);
            prop_assert_eq!(out.tile_pairs(), fresh.tile_pairs());
            let (a, b) = (cpu_state(&out), cpu_state(&fresh));
            prop_assert_eq!(&a.splats, &b.splats);
            prop_assert_eq!(&a.lists, &b.lists);
            prop_assert_eq!(bits(&a.final_t), bits(&b.final_t));
            prop_assert_eq!(&a.last, &b.last);
            let npix = cam.pixel_count();
            let dc: Vec<[f32; 3]> = (0..npix).map(|p| [0.3, -0.7, 0.5].map(|v: f32| v * ((p % 5) as f32 - 1.7))).collect();
            let d = PixelGrads::from_color(&dc);
            let grads = |f: &ForwardOutput| r.backward(g.view(), &cam, &opts, f, d).unwrap().grads;
            prop_assert_eq!(grads(&out), grads(&fresh));
        }

        /// `backward_into` an output that held another scene's gradients (more or fewer
        /// Gaussians, another image) gives what `backward` gives, bit for bit.
        #[test]
        fn backward_into_a_used_output_equals_a_fresh_backward(
            before in proptest::collection::vec(gaussian(), 0..80),
            parts in proptest::collection::vec(gaussian(), 1..60),
            sizes in ((1u32..50, 1u32..40), (1u32..50, 1u32..40)),
            degree in 0u32..=3,
        ) {
            let cam = |(width, height): (u32, u32)| Camera::from_center(
                width, height, 30.0, 28.0, 0.45 * width as f32, 0.55 * height as f32,
                Mat3::IDENTITY, Vec3::ZERO,
            );
            let (cam_before, cam) = (cam(sizes.0), cam(sizes.1));
            let opts = RenderOptions { background: [0.2, 0.5, 0.9], sh_degree: None };
            let r = CpuRasterizer::new();
            // The earlier scene at SH degree 0 and this one at `degree`: the SH stride changes too.
            let g_before = scene(&before);
            let mut g = scene(&parts);
            g.sh = g.sh.chunks_exact(3)
                .flat_map(|dc| {
                    let mut row = vec![0.1f32; crate::sh_coeff_count(degree) * 3];
                    row[..3].copy_from_slice(dc);
                    row
                })
                .collect();
            g.sh_degree = degree;
            let pixel_grads = |cam: &Camera| -> Vec<[f32; 3]> {
                (0..cam.pixel_count()).map(|p| [0.3, -0.7, 0.5].map(|v: f32| v * ((p % 5) as f32 - 1.7))).collect()
            };
            let mut out = BackwardOutput::default();
            let (dc_before, dc) = (pixel_grads(&cam_before), pixel_grads(&cam));
            let f_before = r.forward(g_before.view(), &cam_before, &opts).unwrap();
            r.backward_into(g_before.view(), &cam_before, &opts, &f_before, PixelGrads::from_color(&dc_before), &mut out).unwrap();
            let f = r.forward(g.view(), &cam, &opts).unwrap();
            let fresh = r.backward(g.view(), &cam, &opts, &f, PixelGrads::from_color(&dc)).unwrap();
            r.backward_into(g.view(), &cam, &opts, &f, PixelGrads::from_color(&dc), &mut out).unwrap();
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            let (a, b) = (&out.grads, &fresh.grads);
            prop_assert_eq!(bits(a.means.as_flattened()), bits(b.means.as_flattened()));
            prop_assert_eq!(bits(a.log_scales.as_flattened()), bits(b.log_scales.as_flattened()));
            prop_assert_eq!(bits(a.rotations.as_flattened()), bits(b.rotations.as_flattened()));
            prop_assert_eq!(bits(&a.opacity_logits), bits(&b.opacity_logits));
            prop_assert_eq!(bits(&a.sh), bits(&b.sh));
            prop_assert_eq!(bits(a.means2d.as_flattened()), bits(b.means2d.as_flattened()));
            prop_assert_eq!(out.zeroed_non_finite, fresh.zeroed_non_finite);
        }
    }

    #[test]
    fn dispatch_runs_every_available_build() {
        struct Sum(Vec<f32>);
        impl super::simd::Kernel for Sum {
            type Output = f32;
            #[inline(always)]
            fn run<S: Simd>(self, s: S) -> f32 {
                self.0.iter().sum::<f32>() + s.sum(s.splat(0.0))
            }
        }
        for isa in isas() {
            assert_eq!(dispatch(isa, Sum(vec![1.0, 2.5, 3.0])), 6.5);
        }
    }
}
