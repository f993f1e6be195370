//! Test support: one-Gaussian builders and deterministic random scenes. The exact f64 reference
//! renderer of DESIGN §3 is the crate `splat-reference`, which the tests use directly (as does
//! the CLI's agreement test); there is no other copy.
#![allow(dead_code)]

use glam::Vec3;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use splat_raster::{Camera, Gaussians, sh_coeff_count};

/// The identity quaternion `w, x, y, z`.
pub const Q: [f32; 4] = [1.0, 0.0, 0.0, 0.0];

/// One Gaussian with the given raw parameters and fixed, distinct SH coefficients.
pub fn one(mean: [f32; 3], log_scale: [f32; 3], q: [f32; 4], logit: f32, degree: u32) -> Gaussians {
    let k = sh_coeff_count(degree);
    Gaussians {
        sh_degree: degree,
        means: vec![mean],
        log_scales: vec![log_scale],
        rotations: vec![q],
        opacity_logits: vec![logit],
        sh: (0..3 * k).map(|i| 0.3 - 0.05 * i as f32).collect(),
    }
}

/// The Gaussians of `parts` in order, as one set (all of `parts[0]`'s SH degree).
pub fn concat(parts: &[Gaussians]) -> Gaussians {
    let mut g = Gaussians::with_degree(parts[0].sh_degree);
    for p in parts {
        g.means.extend_from_slice(&p.means);
        g.log_scales.extend_from_slice(&p.log_scales);
        g.rotations.extend_from_slice(&p.rotations);
        g.opacity_logits.extend_from_slice(&p.opacity_logits);
        g.sh.extend_from_slice(&p.sh);
    }
    g
}

/// 15 copies of the one-Gaussian set `good` (SH degree 3), each with NaN, +Inf or -Inf in one of
/// its fields: mean, log-scale, quaternion, opacity logit, SH.
pub fn poisoned_copies(good: &Gaussians) -> Vec<Gaussians> {
    let mut parts = Vec::new();
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        for field in 0..5 {
            let mut g = good.clone();
            match field {
                0 => g.means[0][1] = bad,
                1 => g.log_scales[0][2] = bad,
                2 => g.rotations[0][3] = bad,
                3 => g.opacity_logits[0] = bad,
                _ => g.sh[40] = bad,
            }
            parts.push(g);
        }
    }
    parts
}

/// A random camera looking at the origin from distance ~4, with fx != fy and an off-centre
/// principal point.
pub fn random_camera(rng: &mut ChaCha8Rng, width: u32, height: u32) -> Camera {
    let theta: f32 = rng.random_range(0.0..std::f32::consts::TAU);
    let phi: f32 = rng.random_range(-0.8..0.8);
    let eye = Vec3::new(theta.cos() * phi.cos(), theta.sin() * phi.cos(), phi.sin()) * 4.0;
    let mut cam = Camera::look_at(width, height, 0.9, eye, Vec3::ZERO, Vec3::Z);
    cam.fy = cam.fx * rng.random_range(0.8..1.2);
    cam.cx += rng.random_range(-0.15..0.15) * width as f32;
    cam.cy += rng.random_range(-0.15..0.15) * height as f32;
    cam
}

/// `n` random Gaussians around the origin, sized to cover a few to tens of pixels at distance 4.
pub fn random_gaussians(rng: &mut ChaCha8Rng, n: usize, degree: u32, spread: f32) -> Gaussians {
    let mut g = Gaussians::with_degree(degree);
    let k = sh_coeff_count(degree);
    for _ in 0..n {
        g.means
            .push(std::array::from_fn(|_| rng.random_range(-spread..spread)));
        g.log_scales
            .push(std::array::from_fn(|_| rng.random_range(-3.0f32..-1.2)));
        g.rotations
            .push(std::array::from_fn(|_| rng.random_range(-1.0f32..1.0)));
        g.opacity_logits.push(rng.random_range(-2.0f32..2.0));
        for c in 0..k {
            let amp = if c == 0 { 1.0 } else { 0.3 };
            for _ in 0..3 {
                g.sh.push(rng.random_range(-amp..amp));
            }
        }
    }
    g
}

pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}
