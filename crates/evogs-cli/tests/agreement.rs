//! `evogs render` agrees with an exact per-pixel f64 evaluation of SPEC §3, written here
//! independently of the rasterizer, to within 8-bit rounding (±1 level), on random small scenes
//! with SH degrees 0–3, an off-centre principal point and hard cases (behind the camera, zero
//! quaternion, NaN).

use std::path::Path;
use std::process::Command;

use evogs_io::{CameraInfo, read_nerfies_camera, write_nerfies_camera, write_ply};
use glam::Vec3;
use proptest::prelude::*;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use splat_raster::{Camera, Gaussians};

type V3 = [f64; 3];
type M3 = [[f64; 3]; 3];

fn mat_mul(a: &M3, b: &M3) -> M3 {
    let mut out = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            out[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    out
}

fn transpose(a: &M3) -> M3 {
    let mut out = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            out[i][j] = a[j][i];
        }
    }
    out
}

/// Real SH basis (Sloan order) up to degree 3 for a unit direction, constants from their
/// closed forms.
fn sh_basis(d: V3, degree: u32) -> Vec<f64> {
    let pi = std::f64::consts::PI;
    let [x, y, z] = d;
    let c0 = 0.5 / pi.sqrt();
    let c1 = (3.0 / (4.0 * pi)).sqrt();
    let mut b = vec![c0];
    if degree >= 1 {
        b.extend([-c1 * y, c1 * z, -c1 * x]);
    }
    if degree >= 2 {
        let a = 0.5 * (15.0 / pi).sqrt();
        let c = 0.25 * (5.0 / pi).sqrt();
        let e = 0.25 * (15.0 / pi).sqrt();
        b.extend([
            a * x * y,
            -a * y * z,
            c * (2.0 * z * z - x * x - y * y),
            -a * x * z,
            e * (x * x - y * y),
        ]);
    }
    if degree >= 3 {
        let k0 = 0.25 * (35.0 / (2.0 * pi)).sqrt();
        let k1 = 0.5 * (105.0 / pi).sqrt();
        let k2 = 0.25 * (21.0 / (2.0 * pi)).sqrt();
        let k3 = 0.25 * (7.0 / pi).sqrt();
        let k5 = 0.25 * (105.0 / pi).sqrt();
        let (xx, yy, zz) = (x * x, y * y, z * z);
        b.extend([
            -k0 * y * (3.0 * xx - yy),
            k1 * x * y * z,
            -k2 * y * (4.0 * zz - xx - yy),
            k3 * z * (2.0 * zz - 3.0 * xx - 3.0 * yy),
            -k2 * x * (4.0 * zz - xx - yy),
            k5 * z * (xx - yy),
            -k0 * x * (xx - 3.0 * yy),
        ]);
    }
    b
}

/// One Gaussian after projection.
struct Splat {
    depth: f64,
    uv: [f64; 2],
    conic: [f64; 3],
    opacity: f64,
    rgb: V3,
}

/// SPEC §3 forward for one Gaussian in f64, `None` when it is culled.
fn project(g: &Gaussians, i: usize, cam: &Camera) -> Option<Splat> {
    let stride = g.sh_stride();
    let sh = &g.sh[i * stride..(i + 1) * stride];
    let all = g.means[i]
        .iter()
        .chain(&g.log_scales[i])
        .chain(&g.rotations[i])
        .chain(std::iter::once(&g.opacity_logits[i]))
        .chain(sh);
    if all.clone().any(|v| !v.is_finite()) {
        return None;
    }
    let q = g.rotations[i].map(f64::from);
    let n2: f64 = q.iter().map(|v| v * v).sum();
    if n2 < 1e-12 {
        return None;
    }
    let opacity = 1.0 / (1.0 + (-(g.opacity_logits[i] as f64)).exp());
    if opacity < 1.0 / 255.0 {
        return None;
    }
    let w: M3 = [0, 1, 2].map(|r| cam.rotation.row(r).to_array().map(f64::from));
    let t = cam.translation.to_array().map(f64::from);
    let m = g.means[i].map(f64::from);
    let p: V3 = [0, 1, 2].map(|r| (0..3).map(|k| w[r][k] * m[k]).sum::<f64>() + t[r]);
    if p[2] <= 0.01 {
        return None;
    }
    let n = n2.sqrt();
    let [qw, qx, qy, qz] = q.map(|v| v / n);
    let rot: M3 = [
        [
            1.0 - 2.0 * (qy * qy + qz * qz),
            2.0 * (qx * qy - qw * qz),
            2.0 * (qx * qz + qw * qy),
        ],
        [
            2.0 * (qx * qy + qw * qz),
            1.0 - 2.0 * (qx * qx + qz * qz),
            2.0 * (qy * qz - qw * qx),
        ],
        [
            2.0 * (qx * qz - qw * qy),
            2.0 * (qy * qz + qw * qx),
            1.0 - 2.0 * (qx * qx + qy * qy),
        ],
    ];
    let s = g.log_scales[i].map(|v| (v as f64).exp());
    let rs: M3 = [0, 1, 2].map(|r| [0, 1, 2].map(|c| rot[r][c] * s[c]));
    let sigma = mat_mul(&rs, &transpose(&rs));
    let sigma_cam = mat_mul(&mat_mul(&w, &sigma), &transpose(&w));
    let (fx, fy, cx, cy) = (cam.fx as f64, cam.fy as f64, cam.cx as f64, cam.cy as f64);
    let (width, height) = (cam.width as f64, cam.height as f64);
    let (tan_x, tan_y) = (0.5 * width / fx, 0.5 * height / fy);
    let tx = (p[0] / p[2]).clamp(-(cx / fx + 0.3 * tan_x), (width - cx) / fx + 0.3 * tan_x);
    let ty = (p[1] / p[2]).clamp(-(cy / fy + 0.3 * tan_y), (height - cy) / fy + 0.3 * tan_y);
    let j = [
        [fx / p[2], 0.0, -fx * tx / p[2]],
        [0.0, fy / p[2], -fy * ty / p[2]],
    ];
    let mut cov = [[0.0f64; 2]; 2];
    for a in 0..2 {
        for b in 0..2 {
            cov[a][b] = (0..3)
                .flat_map(|k| (0..3).map(move |l| (k, l)))
                .map(|(k, l)| j[a][k] * sigma_cam[k][l] * j[b][l])
                .sum();
        }
    }
    cov[0][0] += 0.3;
    cov[1][1] += 0.3;
    let det = cov[0][0] * cov[1][1] - cov[0][1] * cov[1][0];
    if det <= 0.0 {
        return None;
    }
    let conic = [cov[1][1] / det, -cov[0][1] / det, cov[0][0] / det];
    let centre = cam.center().to_array().map(f64::from);
    let d = [0, 1, 2].map(|k| m[k] - centre[k]);
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let basis = sh_basis(d.map(|v| v / len), g.sh_degree);
    let rgb = [0, 1, 2].map(|c| {
        let v: f64 = basis
            .iter()
            .enumerate()
            .map(|(k, b)| b * sh[k * 3 + c] as f64)
            .sum();
        (v + 0.5).max(0.0)
    });
    Some(Splat {
        depth: p[2],
        uv: [fx * p[0] / p[2] + cx, fy * p[1] / p[2] + cy],
        conic,
        opacity,
        rgb,
    })
}

/// The reference image, row-major.
fn reference(g: &Gaussians, cam: &Camera, background: V3) -> Vec<V3> {
    let mut splats: Vec<Splat> = (0..g.len()).filter_map(|i| project(g, i, cam)).collect();
    splats.sort_by(|a, b| a.depth.total_cmp(&b.depth));
    let mut image = Vec::new();
    for y in 0..cam.height {
        for x in 0..cam.width {
            let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
            let mut colour = [0.0; 3];
            let mut t = 1.0;
            for s in &splats {
                let (dx, dy) = (px - s.uv[0], py - s.uv[1]);
                let [a, b, c] = s.conic;
                let power = 0.5 * (a * dx * dx + c * dy * dy) + b * dx * dy;
                if power < 0.0 {
                    continue;
                }
                let alpha = (s.opacity * (-power).exp()).min(0.99);
                if alpha < 1.0 / 255.0 {
                    continue;
                }
                let next = t * (1.0 - alpha);
                if next < 1e-4 {
                    break;
                }
                for (acc, c) in colour.iter_mut().zip(s.rgb) {
                    *acc += c * alpha * t;
                }
                t = next;
            }
            image.push([0, 1, 2].map(|ch| colour[ch] + t * background[ch]));
        }
    }
    image
}

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
    let result = Command::new(env!("CARGO_BIN_EXE_evogs"))
        .args([
            "render",
            "--ply",
            ply.to_str().unwrap(),
            "--camera",
            cam_path.to_str().unwrap(),
        ])
        .args(["--out", out.to_str().unwrap(), "--background", &bg])
        .output()
        .unwrap();
    assert!(
        result.status.success(),
        "{}",
        String::from_utf8_lossy(&result.stderr)
    );
    let stdout = String::from_utf8_lossy(&result.stdout);
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
        let want = reference(&g, &camera, background);
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
