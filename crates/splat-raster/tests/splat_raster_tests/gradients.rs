//! Analytic f32 gradients against central finite differences of the f64 reference renderer, for
//! every parameter kind, through colour, alpha and depth, on scenes kept away from the kinks of
//! the piecewise definition (thresholds, caps, clamps).

use crate::common;

use glam::Vec3;
use rand::RngExt;
use splat_raster::{
    Camera, CpuRasterizer, Gaussians, PixelGrads, Rasterizer, RenderOptions, sh_coeff_count,
};
use splat_reference::{Params, RefCam};

/// Loss weights per pixel for colour, alpha and depth.
struct Weights {
    color: Vec<[f32; 3]>,
    alpha: Vec<f32>,
    depth: Vec<f32>,
}

fn loss(w: &Weights, img: &splat_reference::RefImage) -> f64 {
    let mut l = 0.0;
    for p in 0..img.color.len() {
        for ch in 0..3 {
            l += f64::from(w.color[p][ch]) * img.color[p][ch];
        }
        l += f64::from(w.alpha[p]) * img.alpha[p] + f64::from(w.depth[p]) * img.depth[p];
    }
    l
}

/// Adds a Gaussian whose centre lies outside the Jacobian clamp range (x/z = 1.1) but which is
/// large enough to reach into the image, so the clamped-Jacobian path is exercised.
fn add_clamped(g: &mut Gaussians, cam: &Camera) {
    let z = 3.0;
    let p_cam = Vec3::new(1.1 * z, 0.1 * z, z);
    let world = cam.rotation.transpose() * (p_cam - cam.translation);
    g.means.push(world.to_array());
    g.log_scales.push([0.1f32.ln(), 0.9f32.ln(), 0.2f32.ln()]);
    g.rotations.push([0.9, 0.1, -0.2, 0.3]);
    g.opacity_logits.push(1.0);
    let k = sh_coeff_count(g.sh_degree);
    g.sh.extend((0..3 * k).map(|i| if i < 3 { 0.4 } else { 0.05 }));
}

/// What a test scene stresses beyond random small Gaussians.
#[derive(Clone, Copy, PartialEq)]
enum Extra {
    None,
    /// One Gaussian outside the Jacobian clamp range.
    Clamp,
    /// Many overlapping, fairly opaque Gaussians: pixels stop at T < 1e-4.
    Dense,
    /// Needle- and disc-like Gaussians (scale ratios up to ~100).
    Anisotropic,
}

/// Finds a scene (by seed) with every kink at least `margin` away.
fn scene(
    seed0: u64,
    width: u32,
    height: u32,
    degree: u32,
    n: usize,
    extra: Extra,
) -> (u64, Camera, Gaussians) {
    let dense = extra == Extra::Dense;
    for seed in seed0..seed0 + 200 {
        let mut rng = common::rng(seed);
        let cam = common::random_camera(&mut rng, width, height);
        let mut g = common::random_gaussians(&mut rng, n, degree, if dense { 0.35 } else { 1.0 });
        // Opacity at most ~0.9 keeps every Gaussian far from the 0.99 cap.
        if dense {
            for l in &mut g.opacity_logits {
                *l = rng.random_range(1.0f32..2.2);
            }
        }
        if extra == Extra::Clamp {
            add_clamped(&mut g, &cam);
        }
        if extra == Extra::Anisotropic {
            for s in &mut g.log_scales {
                *s = [
                    rng.random_range(-5.0f32..-3.5),
                    rng.random_range(-1.5f32..-0.8),
                    rng.random_range(-3.5f32..-2.0),
                ];
            }
        }
        let img = splat_reference::render(
            &Params::from(&g),
            &RefCam::from(&cam),
            [0.3, 0.2, 0.1],
            degree,
        );
        // A dense scene must exercise the early stop at T < 1e-4.
        if img.margin > 1e-3 && img.drawn == g.len() && (!dense || img.stopped > 0) {
            return (seed, cam, g);
        }
    }
    panic!("no scene away from kinks near seed {seed0}");
}

fn check_gradients(seed0: u64, width: u32, height: u32, degree: u32, n: usize, extra: Extra) {
    let (seed, cam, g) = scene(seed0, width, height, degree, n, extra);
    let mut rng = common::rng(seed ^ 0xabcdef);
    let npix = cam.pixel_count();
    let w = Weights {
        color: (0..npix)
            .map(|_| std::array::from_fn(|_| rng.random_range(-1.0f32..1.0)))
            .collect(),
        alpha: (0..npix).map(|_| rng.random_range(-1.0f32..1.0)).collect(),
        depth: (0..npix).map(|_| rng.random_range(-0.3f32..0.3)).collect(),
    };
    let background = [0.3f32, 0.2, 0.1];
    let opts = RenderOptions {
        background,
        sh_degree: None,
    };
    let r = CpuRasterizer::new();
    let fwd = r.forward(g.view(), &cam, &opts).unwrap();
    assert_eq!(
        fwd.stats.drawn,
        g.len(),
        "seed {seed}: every Gaussian is drawn"
    );
    let grads = r
        .backward(
            g.view(),
            &cam,
            &opts,
            &fwd,
            PixelGrads::from_color(&w.color)
                .with_alpha(&w.alpha)
                .with_depth(&w.depth),
        )
        .unwrap()
        .grads;
    let params = Params::from(&g);
    let rcam = RefCam::from(&cam);
    let bg = background.map(f64::from);
    let analytic: [(&str, Vec<f32>); 6] = [
        ("means", grads.means.as_flattened().to_vec()),
        ("log_scales", grads.log_scales.as_flattened().to_vec()),
        ("rotations", grads.rotations.as_flattened().to_vec()),
        ("opacity_logits", grads.opacity_logits.clone()),
        ("sh", grads.sh.clone()),
        ("means2d", grads.means2d.as_flattened().to_vec()),
    ];
    let h = 1e-6;
    for (kind, an) in analytic {
        let mut p = params.clone();
        let len = p.kind_mut(kind).len();
        assert_eq!(an.len(), len, "{kind}: gradient length");
        let fd: Vec<f64> = (0..len)
            .map(|k| {
                let x = p.kind_mut(kind)[k];
                p.kind_mut(kind)[k] = x + h;
                let lp = loss(&w, &splat_reference::render(&p, &rcam, bg, degree));
                p.kind_mut(kind)[k] = x - h;
                let lm = loss(&w, &splat_reference::render(&p, &rcam, bg, degree));
                p.kind_mut(kind)[k] = x;
                (lp - lm) / (2.0 * h)
            })
            .collect();
        let scale = fd.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(
            scale > 1e-3,
            "seed {seed} {kind}: gradients vanish (scale {scale})"
        );
        for k in 0..len {
            let a = f64::from(an[k]);
            let tol = 2e-3 * fd[k].abs() + 2e-4 * scale;
            assert!(
                (a - fd[k]).abs() <= tol,
                "seed {seed} degree {degree} {kind}[{k}] (Gaussian {}): analytic {a} vs finite difference {} (scale {scale})",
                k / (len / g.len()),
                fd[k]
            );
        }
    }
}

#[test]
fn gradients_match_finite_differences_sh_degree_0() {
    check_gradients(1000, 29, 23, 0, 8, Extra::Clamp);
}

#[test]
fn gradients_match_finite_differences_sh_degree_1() {
    check_gradients(2000, 31, 17, 1, 8, Extra::Clamp);
}

#[test]
fn gradients_match_finite_differences_sh_degree_2() {
    check_gradients(3000, 24, 30, 2, 8, Extra::None);
}

#[test]
fn gradients_match_finite_differences_sh_degree_3() {
    check_gradients(4000, 33, 21, 3, 8, Extra::Clamp);
}

#[test]
fn gradients_match_finite_differences_dense_scene() {
    // Dense enough that pixels stop early at T < 1e-4, so the stop path is differentiated too.
    check_gradients(5000, 20, 18, 1, 30, Extra::Dense);
}

#[test]
fn gradients_match_finite_differences_anisotropic() {
    check_gradients(6000, 30, 26, 2, 8, Extra::Anisotropic);
}
