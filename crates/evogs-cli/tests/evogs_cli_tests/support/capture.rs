//! A procedural capture for `evogs prepare`: a textured room (floor and three walls of random
//! colour tiles, SIFT-friendly) with a striped ball bobbing in it, filmed by one camera moving
//! along a 60° arc (a monocular video), rendered with the CPU rasterizer.

#![allow(dead_code)]

use std::path::Path;

use evogs_io::{ImageRgb, save_png};
use glam::Vec3;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use splat_core::sh::dc_from_rgb;
use splat_raster::{Camera, CpuRasterizer, Gaussians, RenderOptions};

/// Image side in pixels.
pub const SIZE: u32 = 256;
/// Half the room's width (floor x, y in [−HALF, HALF]); walls are WALL high.
pub const HALF: f32 = 3.0;
const WALL: f32 = 2.5;
/// Spacing of the surface Gaussians.
const STEP: f32 = 0.06;
/// Tile size of the colour texture.
const TILE: f32 = 0.3;

/// The static room: (means, colours, log-scales).
fn room(rng: &mut ChaCha8Rng) -> Vec<([f32; 3], Vec3, [f32; 3])> {
    let mut out = Vec::new();
    let n = (2.0 * HALF / STEP) as i32;
    let h = (WALL / STEP) as i32;
    let s = (0.6 * STEP).ln();
    let thin = 0.004f32.ln();
    // One random colour per tile, shared by its Gaussians, plus a little per-Gaussian noise.
    let mut tiles = std::collections::HashMap::new();
    let mut colour = |key: (i32, i32, i32), rng: &mut ChaCha8Rng| -> Vec3 {
        let base = *tiles.entry(key).or_insert_with(|| {
            Vec3::new(
                rng.random::<f32>(),
                rng.random::<f32>(),
                rng.random::<f32>(),
            )
        });
        (base + Vec3::splat(0.08 * (rng.random::<f32>() - 0.5))).clamp(Vec3::ZERO, Vec3::ONE)
    };
    let tile = |v: f32| (v / TILE).floor() as i32;
    for i in 0..n {
        let a = -HALF + (i as f32 + 0.5) * STEP;
        for j in 0..n {
            let b = -HALF + (j as f32 + 0.5) * STEP;
            out.push((
                [a, b, 0.0],
                colour((0, tile(a), tile(b)), rng),
                [s, s, thin],
            ));
        }
        for k in 0..h {
            let z = (k as f32 + 0.5) * STEP;
            // Back wall (y = HALF), left (x = −HALF), right (x = HALF).
            out.push((
                [a, HALF, z],
                colour((1, tile(a), tile(z)), rng),
                [s, thin, s],
            ));
            out.push((
                [-HALF, a, z],
                colour((2, tile(a), tile(z)), rng),
                [thin, s, s],
            ));
            out.push((
                [HALF, a, z],
                colour((3, tile(a), tile(z)), rng),
                [thin, s, s],
            ));
        }
    }
    out
}

/// The ball's centre at time `t` in [0, 1]: it bobs up and down once.
pub fn ball_centre(t: f32) -> Vec3 {
    Vec3::new(0.0, 0.8, 0.55 + 0.35 * (std::f32::consts::TAU * t).sin())
}

/// The scene at time `t`.
pub fn scene(t: f32) -> Gaussians {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut parts = room(&mut rng);
    // The ball: Fibonacci sphere, horizontal stripes.
    let count = 1500;
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    let centre = ball_centre(t);
    for i in 0..count {
        let z = 1.0 - 2.0 * (i as f32 + 0.5) / count as f32;
        let r = (1.0 - z * z).sqrt();
        let a = i as f32 * golden;
        let n = Vec3::new(r * a.cos(), r * a.sin(), z);
        let stripe = ((z * 4.0).floor() as i32).rem_euclid(2) == 0;
        let c = if stripe {
            Vec3::new(0.95, 0.85, 0.1)
        } else {
            Vec3::new(0.1, 0.2, 0.8)
        };
        parts.push(((centre + 0.35 * n).to_array(), c, [0.03f32.ln(); 3]));
    }
    let mut g = Gaussians::with_degree(0);
    for (mean, colour, scale) in parts {
        g.means.push(mean);
        g.log_scales.push(scale);
        g.rotations.push([1.0, 0.0, 0.0, 0.0]);
        g.opacity_logits.push(5.0);
        g.sh.extend(colour.to_array().map(dc_from_rgb));
    }
    g
}

/// The bounding-box diagonal of the static room (the scene extent).
pub fn extent() -> f32 {
    Vec3::new(2.0 * HALF, 2.0 * HALF, WALL).length()
}

/// The camera of frame `k` of `frames`: on a 60° arc of radius 2.4 at height 1.3, looking at
/// the middle of the room.
pub fn camera(k: usize, frames: usize) -> Camera {
    let u = k as f32 / (frames - 1) as f32;
    let angle = (-120.0 + 60.0 * u).to_radians();
    let eye = Vec3::new(2.4 * angle.cos(), 2.4 * angle.sin(), 1.3);
    Camera::look_at(
        SIZE,
        SIZE,
        65f32.to_radians(),
        eye,
        Vec3::new(0.0, 0.6, 0.6),
        Vec3::Z,
    )
}

/// Renders `frames` frames into `dir/f_NNN.png`.
pub fn render_frames(dir: &Path, frames: usize) {
    std::fs::create_dir_all(dir).unwrap();
    let raster = CpuRasterizer::new();
    let opts = RenderOptions {
        background: [0.5; 3],
        sh_degree: None,
    };
    for k in 0..frames {
        let t = k as f32 / (frames - 1) as f32;
        let g = scene(t);
        let out = splat_raster::Rasterizer::forward(&raster, g.view(), &camera(k, frames), &opts)
            .unwrap();
        let image = ImageRgb {
            width: SIZE,
            height: SIZE,
            pixels: out.color,
        };
        save_png(&dir.join(format!("f_{k:03}.png")), &image).unwrap();
    }
}

/// Encodes `dir/f_NNN.png` into an H.264 mp4 at 12 frames per second.
pub fn encode_mp4(dir: &Path, clip: &Path) {
    let status = std::process::Command::new("ffmpeg")
        .args(["-nostdin", "-v", "error", "-y", "-framerate", "12", "-i"])
        .arg(dir.join("f_%03d.png"))
        .args(["-c:v", "libx264", "-crf", "14", "-pix_fmt", "yuv420p"])
        .arg(clip)
        .status()
        .expect("ffmpeg (scripts/test installs it)");
    assert!(status.success());
}

/// Similarity alignment (Umeyama 1991) of `from` onto `to`: `to ≈ s R from + t`. Returns the
/// aligned points.
pub fn align_similarity(from: &[Vec3], to: &[Vec3]) -> Vec<Vec3> {
    use nalgebra::{Matrix3, Vector3};
    let n = from.len() as f64;
    let v = |p: &Vec3| Vector3::new(p.x as f64, p.y as f64, p.z as f64);
    let mean = |ps: &[Vec3]| ps.iter().map(v).sum::<Vector3<f64>>() / n;
    let (mf, mt) = (mean(from), mean(to));
    let mut cov = Matrix3::zeros();
    let mut var = 0.0;
    for (a, b) in from.iter().zip(to) {
        let (da, db) = (v(a) - mf, v(b) - mt);
        cov += db * da.transpose();
        var += da.norm_squared();
    }
    cov /= n;
    var /= n;
    let svd = cov.svd(true, true);
    let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
    let mut d = Matrix3::identity();
    if (u.determinant() * vt.determinant()) < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = u * d * vt;
    let s = (svd.singular_values.component_mul(&d.diagonal())).sum() / var;
    let t = mt - s * r * mf;
    from.iter()
        .map(|p| {
            let q = s * r * v(p) + t;
            Vec3::new(q.x as f32, q.y as f32, q.z as f32)
        })
        .collect()
}

/// A uniform grey PNG (nothing for SIFT to find).
pub fn render_blank(path: &Path, grey: f32) {
    save_png(path, &ImageRgb::filled(64, 64, [grey; 3])).unwrap();
}
