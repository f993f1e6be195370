//! The CPU backend: per-Gaussian work and per-tile compositing in parallel with rayon.
//!
//! - `project`: per-Gaussian projection (f64) and its backward pass;
//! - `tiles`: binning of drawn Gaussians into depth-ordered tile lists;
//! - `composite`: per-tile front-to-back compositing and its backward, as plain reference kernels
//!   (`scalar`) and eight-pixel SIMD kernels (`lanes`) over the lane builds of `simd`.
//!
//! Determinism: the forward image does not depend on the thread count (each tile is composited
//! by one thread in a fixed order), and neither do the gradients: each tile writes its per-entry
//! gradients into its own slots, which are then summed per Gaussian in tile order.

mod composite;
mod project;
mod simd;
mod tiles;

use std::sync::Arc;

use rayon::prelude::*;

use self::composite::{LANES, TileOut, lanes, scalar};
use self::project::{CullReason, Splat, SplatGrads};
use self::simd::Isa;
use self::tiles::TileLists;
use crate::Rasterizer;
use crate::camera::Camera;
use crate::constants::TILE;
use crate::error::RasterError;
use crate::frame::Frame;
use crate::gaussians::GaussiansView;
use crate::options::{CullStats, RenderOptions};
use crate::output::{
    BackendState, BackwardOutput, BackwardState, Counters, ForwardOutput, GaussianGrads, PixelGrads,
};
use crate::validate::{validate, validate_backward};

/// Which compositing kernels [`CpuRasterizer`] runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum CpuKernel {
    /// Eight pixels at a time with a vectorised `exp`, compiled for AVX2 + FMA when the CPU has
    /// them (chosen at run time) and for the baseline target otherwise, with identical results.
    #[default]
    Simd,
    /// The plain reference kernels, one pixel at a time with the standard library's `exp`: the
    /// CPU backend's kernels before the SIMD ones, kept to check and to measure those against.
    Scalar,
}

/// The kernels that run: the scalar ones with an `exp`, or the SIMD ones built for an
/// instruction set.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Kernels {
    Scalar { exp: fn(f32) -> f32 },
    Lanes(Isa),
}

impl Kernels {
    fn of(kernel: CpuKernel) -> Self {
        match kernel {
            CpuKernel::Simd => Kernels::Lanes(Isa::best()),
            CpuKernel::Scalar => Kernels::Scalar { exp: f32::exp },
        }
    }
}

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

/// The CPU backend's backward state.
#[derive(Clone, Debug)]
pub(crate) struct CpuState {
    /// The kernels the forward pass ran (the backward pass runs the same).
    pub kernels: Kernels,
    /// The drawn Gaussians' records in depth order (indexed by the lists' ranks).
    pub splats: Vec<Splat>,
    pub lists: TileLists,
    /// Tile-major (tile, lane) final transmittance.
    pub final_t: Vec<f32>,
    /// Tile-major one-past-last contributor position in the tile list.
    pub last: Vec<u32>,
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
        // The records in depth order, as the tile lists index them.
        let splats: Vec<Splat> = lists.order.iter().map(|&i| splats[i as usize]).collect();
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
                let out = TileOut {
                    color,
                    depth,
                    final_t,
                    last,
                };
                let (ids, background) = (lists.tile(tile), opts.background);
                match self.kernels {
                    Kernels::Scalar { exp } => {
                        scalar::forward_tile_into(&frame, tile, ids, &splats, background, out, exp)
                    }
                    Kernels::Lanes(isa) => simd::dispatch(
                        isa,
                        lanes::Forward {
                            frame: &frame,
                            tile,
                            ids,
                            splats: &splats,
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
        let (w, h) = (cam.width as usize, cam.height as usize);
        let mut color = vec![[0.0f32; 3]; w * h];
        let mut alpha = vec![0.0f32; w * h];
        let mut depth_img = vec![0.0f32; w * h];
        color
            .par_chunks_mut(w)
            .zip(alpha.par_chunks_mut(w))
            .zip(depth_img.par_chunks_mut(w))
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
                    kernels: self.kernels,
                    splats,
                    lists,
                    final_t,
                    last,
                }),
            },
        })
    }

    fn backward_impl(
        &self,
        g: GaussiansView<'_>,
        cam: &Camera,
        opts: &RenderOptions,
        fwd: &ForwardOutput,
        pixel_grads: PixelGrads<'_>,
    ) -> Result<BackwardOutput, RasterError> {
        let active = validate_backward(&g, cam, opts, fwd, pixel_grads)?;
        let st = &fwd.state;
        let mismatch = |what: &str| Err(RasterError::ForwardMismatch(what.into()));
        #[allow(unreachable_patterns)]
        let cpu = match &st.backend {
            BackendState::Cpu(cpu) => cpu,
            _ => return mismatch("the forward pass ran on another backend"),
        };
        let frame = Frame::new(cam);

        // Per list entry gradients, each tile writing its own slots.
        let lists = &cpu.lists;
        let mut entries = vec![SplatGrads::default(); lists.ids.len()];
        let mut slots: Vec<&mut [SplatGrads]> = Vec::with_capacity(lists.offsets.len());
        let mut rest = entries.as_mut_slice();
        for t in 0..lists.offsets.len() - 1 {
            let (head, tail) = rest.split_at_mut(lists.offsets[t + 1] - lists.offsets[t]);
            slots.push(head);
            rest = tail;
        }
        slots.into_par_iter().enumerate().for_each(|(tile, out)| {
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
                    out,
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
                        out,
                    },
                ),
            }
        });
        // Per Gaussian, its entries summed in tile order (a fixed order), then chained to the
        // raw parameters.
        let n = g.len();
        let stride = g.sh_stride();
        let mut sh = vec![0.0f32; n * stride];
        let outcomes: Vec<Outcome> = sh
            .par_chunks_mut(stride)
            .enumerate()
            .map(|(i, sh_out)| {
                // Culled in the forward pass (off screen included; a drawn Gaussian touches a
                // tile): zero gradient.
                if lists.entries_of(i).is_empty() {
                    return Outcome::Culled;
                }
                let mut d = SplatGrads::default();
                for &e in lists.entries_of(i) {
                    d.add(&entries[e as usize]);
                }
                let Some(grad) = project::project_backward_into(&frame, &g, active, i, &d, sh_out)
                else {
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
            })
            .collect();
        let mut out = BackwardOutput {
            grads: GaussianGrads {
                means: vec![[0.0; 3]; n],
                log_scales: vec![[0.0; 3]; n],
                rotations: vec![[0.0; 4]; n],
                opacity_logits: vec![0.0; n],
                sh,
                means2d: vec![[0.0; 2]; n],
            },
            zeroed_non_finite: 0,
        };
        let grads = &mut out.grads;
        for (i, outcome) in outcomes.into_iter().enumerate() {
            match outcome {
                Outcome::Culled => {}
                Outcome::Zeroed => out.zeroed_non_finite += 1,
                Outcome::Drawn(grad, uv) => {
                    grads.means[i] = grad.mean;
                    grads.log_scales[i] = grad.log_scale;
                    grads.rotations[i] = grad.q;
                    grads.opacity_logits[i] = grad.logit;
                    grads.means2d[i] = uv;
                }
            }
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
        d: PixelGrads<'_>,
    ) -> Result<BackwardOutput, RasterError> {
        self.install(|| self.backward_impl(g, cam, opts, fwd, d))
    }
}

#[cfg(test)]
mod tests {
    use glam::{Mat3, Vec3};
    use proptest::prelude::*;

    use super::simd::{F8, Portable, Simd, dispatch};
    use super::*;
    use crate::gaussians::Gaussians;

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
