//! Invariants: culled Gaussians change nothing, input order changes nothing, and the thread count
//! changes nothing (forward bit-identical, gradients identical).

use crate::common;

use rand::RngExt;
use splat_raster::{
    Camera, CpuRasterizer, GaussianGrads, Gaussians, PixelGrads, Rasterizer, RenderOptions,
};

/// One way of making a Gaussian culled.
type Edit = Box<dyn Fn(&mut Gaussians)>;

fn setup(seed: u64, n: usize) -> (Camera, Gaussians, RenderOptions) {
    let mut rng = common::rng(seed);
    let cam = common::random_camera(&mut rng, 45, 37);
    let g = common::random_gaussians(&mut rng, n, 2, 1.2);
    let opts = RenderOptions {
        background: [0.1, 0.7, 0.3],
        sh_degree: None,
    };
    (cam, g, opts)
}

fn d_images(npix: usize, seed: u64) -> (Vec<[f32; 3]>, Vec<f32>, Vec<f32>) {
    let mut rng = common::rng(seed);
    (
        (0..npix)
            .map(|_| std::array::from_fn(|_| rng.random_range(-1.0f32..1.0)))
            .collect(),
        (0..npix).map(|_| rng.random_range(-1.0f32..1.0)).collect(),
        (0..npix).map(|_| rng.random_range(-1.0f32..1.0)).collect(),
    )
}

fn run(
    r: &CpuRasterizer,
    g: &Gaussians,
    cam: &Camera,
    opts: &RenderOptions,
) -> (splat_raster::ForwardOutput, GaussianGrads) {
    let fwd = r.forward(g.view(), cam, opts).unwrap();
    let (dc, da, dd) = d_images(cam.pixel_count(), 7);
    let grads = r
        .backward(
            g.view(),
            cam,
            opts,
            &fwd,
            PixelGrads::from_color(&dc).with_alpha(&da).with_depth(&dd),
        )
        .unwrap()
        .grads;
    (fwd, grads)
}

/// Inserts Gaussian `src` of `extra` into `g` at position `at`.
fn insert(g: &mut Gaussians, at: usize, extra: &Gaussians, src: usize) {
    let stride = g.sh_stride();
    g.means.insert(at, extra.means[src]);
    g.log_scales.insert(at, extra.log_scales[src]);
    g.rotations.insert(at, extra.rotations[src]);
    g.opacity_logits.insert(at, extra.opacity_logits[src]);
    let sh = extra.sh[src * stride..(src + 1) * stride].to_vec();
    g.sh.splice(at * stride..at * stride, sh);
}

fn remove_row<T: Clone>(v: &[T], at: usize, stride: usize) -> Vec<T> {
    let mut out = v[..at * stride].to_vec();
    out.extend_from_slice(&v[(at + 1) * stride..]);
    out
}

#[test]
fn culled_gaussians_change_nothing() {
    let (cam, g, opts) = setup(11, 30);
    let r = CpuRasterizer::new();
    let (base, base_grads) = run(&r, &g, &cam, &opts);
    // One Gaussian per culling reason, built from a drawn one.
    let mut bad = Gaussians::with_degree(g.sh_degree);
    let behind = (cam.center() - (cam.rotation.transpose() * glam::Vec3::Z)).to_array();
    let off =
        (cam.center() + cam.rotation.transpose() * glam::Vec3::new(40.0, 0.0, 4.0)).to_array();
    let cases: [(&str, Edit); 6] = [
        (
            "non_finite",
            Box::new(|b: &mut Gaussians| b.log_scales[0][1] = f32::NAN),
        ),
        (
            "zero_quaternion",
            Box::new(|b: &mut Gaussians| b.rotations[0] = [0.0; 4]),
        ),
        (
            "low_opacity",
            Box::new(|b: &mut Gaussians| b.opacity_logits[0] = -8.0),
        ),
        (
            "behind",
            Box::new(move |b: &mut Gaussians| b.means[0] = behind),
        ),
        (
            "degenerate",
            Box::new(|b: &mut Gaussians| b.log_scales[0] = [400.0; 3]),
        ),
        (
            "off_screen",
            Box::new(move |b: &mut Gaussians| b.means[0] = off),
        ),
    ];
    for (_, make) in &cases {
        let mut one = Gaussians::with_degree(g.sh_degree);
        insert(&mut one, 0, &g, 3);
        make(&mut one);
        let at = bad.len();
        insert(&mut bad, at, &one, 0);
    }
    let mut with = g.clone();
    let positions = [0, 5, 9, 17, 25, 33];
    for (k, &at) in positions.iter().enumerate() {
        insert(&mut with, at, &bad, k);
    }
    let (out, grads) = run(&r, &with, &cam, &opts);
    assert_eq!(out.stats.drawn, base.stats.drawn);
    assert_eq!(out.stats.total, base.stats.total + 6);
    let s = out.stats;
    assert_eq!(
        [
            s.non_finite,
            s.zero_quaternion,
            s.low_opacity,
            s.behind_near_plane,
            s.degenerate_covariance,
            s.off_screen - base.stats.off_screen
        ],
        [1; 6],
        "{s}"
    );
    assert_eq!(out.color, base.color);
    assert_eq!(out.alpha, base.alpha);
    assert_eq!(out.depth, base.depth);
    // Gradients of the original Gaussians are unchanged; the culled ones get zero.
    let mut means = grads.means.clone();
    let mut sh = grads.sh.clone();
    let mut logits = grads.opacity_logits.clone();
    for &at in positions.iter().rev() {
        assert_eq!(grads.means[at], [0.0; 3]);
        assert_eq!(grads.opacity_logits[at], 0.0);
        assert_eq!(out.radii()[at], 0.0);
        means = remove_row(&means, at, 1);
        logits = remove_row(&logits, at, 1);
        sh = remove_row(&sh, at, g.sh_stride());
    }
    assert_eq!(means, base_grads.means);
    assert_eq!(logits, base_grads.opacity_logits);
    assert_eq!(sh, base_grads.sh);
}

#[test]
fn input_order_changes_nothing() {
    let (cam, g, opts) = setup(12, 40);
    let r = CpuRasterizer::new();
    let (base, base_grads) = run(&r, &g, &cam, &opts);
    // A fixed shuffle (random depths have no exact ties).
    let mut rng = common::rng(99);
    let mut perm: Vec<usize> = (0..g.len()).collect();
    for i in (1..perm.len()).rev() {
        perm.swap(i, rng.random_range(0..=i));
    }
    let stride = g.sh_stride();
    let mut p = Gaussians::with_degree(g.sh_degree);
    for &i in &perm {
        p.means.push(g.means[i]);
        p.log_scales.push(g.log_scales[i]);
        p.rotations.push(g.rotations[i]);
        p.opacity_logits.push(g.opacity_logits[i]);
        p.sh.extend_from_slice(&g.sh[i * stride..(i + 1) * stride]);
    }
    let (out, grads) = run(&r, &p, &cam, &opts);
    assert_eq!(out.color, base.color);
    assert_eq!(out.alpha, base.alpha);
    assert_eq!(out.depth, base.depth);
    for (k, &i) in perm.iter().enumerate() {
        assert_eq!(grads.means[k], base_grads.means[i]);
        assert_eq!(grads.log_scales[k], base_grads.log_scales[i]);
        assert_eq!(grads.rotations[k], base_grads.rotations[i]);
        assert_eq!(grads.means2d[k], base_grads.means2d[i]);
        assert_eq!(
            grads.sh[k * stride..(k + 1) * stride],
            base_grads.sh[i * stride..(i + 1) * stride]
        );
    }
}

#[test]
fn thread_count_changes_nothing() {
    let (cam, g, opts) = setup(13, 300);
    let cam = Camera {
        width: 83,
        height: 71,
        ..cam
    };
    let results: Vec<_> = [1, 2, 3]
        .iter()
        .map(|&t| run(&CpuRasterizer::with_threads(t).unwrap(), &g, &cam, &opts))
        .collect();
    let (f1, g1) = &results[0];
    assert!(f1.stats.drawn > 100);
    for (f, gr) in &results[1..] {
        let bits = |v: &[[f32; 3]]| {
            v.iter()
                .flat_map(|c| c.map(f32::to_bits))
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(&f.color), bits(&f1.color));
        assert_eq!(f.alpha, f1.alpha);
        assert_eq!(f.depth, f1.depth);
        assert_eq!(gr, g1);
    }
}

#[test]
fn inactive_sh_bands_get_zero_gradient_and_change_nothing() {
    let (cam, g, _) = setup(14, 30);
    let r = CpuRasterizer::new();
    let opts = RenderOptions {
        background: [0.5; 3],
        sh_degree: Some(1),
    };
    let (fwd, grads) = run(&r, &g, &cam, &opts);
    let stride = g.sh_stride();
    for i in 0..g.len() {
        let row = &grads.sh[i * stride..(i + 1) * stride];
        assert!(
            row[12..].iter().all(|&v| v == 0.0),
            "Gaussian {i}: bands above 1 must be 0"
        );
    }
    assert!(grads.sh.iter().any(|&v| v != 0.0));
    // Changing the inactive coefficients changes nothing.
    let mut h = g.clone();
    for i in 0..h.len() {
        for v in &mut h.sh[i * stride + 12..(i + 1) * stride] {
            *v += 0.7;
        }
    }
    let (fwd2, _) = run(&r, &h, &cam, &opts);
    assert_eq!(fwd.color, fwd2.color);
}
