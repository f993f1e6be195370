//! `evogs render` agrees with the exact per-pixel f64 reference of DESIGN §3 (crate
//! `splat-reference`, written independently of the rasterizer) to within 8-bit rounding (±1
//! level), on random small scenes with SH degrees 0–3, an off-centre principal point and hard
//! cases (behind the camera, zero quaternion, NaN).

use crate::support;

use std::path::Path;

use evogs_io::{CameraInfo, read_nerfies_camera, write_nerfies_camera, write_ply};
use glam::Vec3;
use proptest::prelude::*;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use splat_raster::{Camera, Gaussians};
use splat_reference::{Params, RefCam};
use support::s;

type V3 = [f64; 3];

/// A random scene in front of the camera, with hard cases mixed in.
fn random_scene(seed: u64, degree: u32, eye: Vec3) -> Gaussians {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut g = Gaussians::with_degree(degree);
    let stride = g.sh_stride();
    for i in 0..48 {
        let mut mean = [0; 3].map(|_| rng.random_range(-1.2f32..1.2));
        let mut rotation = [0; 4].map(|_| rng.random_range(-1.0f32..1.0));
        match i {
            // Behind the camera (and one just at it).
            0 => mean = (eye * 1.5).to_array(),
            1 => mean = (eye * 0.999).to_array(),
            2 => rotation = [0.0; 4],
            _ => {}
        }
        g.means.push(mean);
        g.log_scales
            .push([0; 3].map(|_| rng.random_range(-3.5f32..-1.2)));
        g.rotations.push(rotation);
        g.opacity_logits.push(rng.random_range(-3.0f32..4.0));
        for k in 0..stride {
            let spread = if k < 3 { 1.0 } else { 0.4 };
            g.sh.push(rng.random_range(-spread..spread));
        }
    }
    // Non-finite values in a mean and in an SH coefficient.
    g.means[3][1] = f32::NAN;
    g.sh[4 * stride + stride - 1] = f32::INFINITY;
    // A very flat Gaussian and a huge one.
    g.log_scales[5] = [-9.0, -1.0, -1.5];
    g.log_scales[6] = [0.5, 0.4, 0.3];
    g
}

fn render_via_cli(
    dir: &Path,
    g: &Gaussians,
    info: &CameraInfo,
    background: V3,
) -> (Camera, Vec<[u8; 3]>) {
    let ply = dir.join("scene.ply");
    let cam_path = dir.join("camera.json");
    let out = dir.join("render.png");
    write_ply(&ply, g.view()).unwrap();
    write_nerfies_camera(&cam_path, info).unwrap();
    let bg = format!("{},{},{}", background[0], background[1], background[2]);
    let stdout = support::evogs_ok(&[
        "render",
        "--ply",
        s(&ply),
        "--camera",
        s(&cam_path),
        "--out",
        s(&out),
        "--background",
        &bg,
    ]);
    assert!(
        stdout.contains("2 non-finite") && stdout.contains("zero quaternion"),
        "{stdout}"
    );
    assert!(stdout.contains("behind near plane"), "{stdout}");
    // The camera the CLI used is the one read back from the file.
    let camera = read_nerfies_camera(&cam_path).unwrap().camera;
    let img = image::open(&out).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (camera.width, camera.height));
    (camera, img.pixels().map(|p| p.0).collect())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 8, ..ProptestConfig::default() })]

    #[test]
    fn cli_render_matches_f64_reference(
        seed in any::<u64>(),
        degree in 0u32..=3,
        azimuth in 0.0f32..6.2,
        background in prop::sample::select(vec![[0.0, 0.0, 0.0], [0.25, 0.5, 1.0], [1.0, 1.0, 1.0]]),
    ) {
        let eye = Vec3::new(3.5 * azimuth.cos(), 3.5 * azimuth.sin(), 1.2);
        let base = Camera::look_at(56, 40, 1.1, eye, Vec3::ZERO, Vec3::Z);
        // Off-centre principal point and non-square pixels.
        let camera = Camera { cx: 56.0 * 0.37, cy: 40.0 * 0.62, fy: base.fx * 1.1, ..base };
        let g = random_scene(seed, degree, eye);
        let dir = tempfile::tempdir().unwrap();
        let (camera, pixels) = render_via_cli(dir.path(), &g, &CameraInfo::pinhole(camera), background);
        let want = splat_reference::render(
            &Params::from(&g), &RefCam::from(&camera), background, g.sh_degree,
        ).color;
        let mut worst = 0i32;
        for (got, want) in pixels.iter().zip(&want) {
            for ch in 0..3 {
                let expected = (want[ch].clamp(0.0, 1.0) * 255.0).round() as i32;
                worst = worst.max((got[ch] as i32 - expected).abs());
            }
        }
        prop_assert!(worst <= 1, "largest difference {worst} levels");
        // The scene is not trivially empty: many pixels differ from the background.
        let bg = background.map(|v| (v * 255.0).round() as u8);
        let covered = pixels.iter().filter(|p| **p != bg).count();
        prop_assert!(covered > pixels.len() / 10, "only {covered} pixels drawn");
    }
}
