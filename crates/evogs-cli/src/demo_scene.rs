//! The built-in procedural scene: a rainbow torus standing over a checkered ground disc, with
//! four glossy spheres around it. About 8,000 Gaussians at SH degree 1, built deterministically
//! (no random numbers: Fibonacci and grid samplings).
//!
//! Shading is baked: a Lambert term from one light in the DC colour, and a specular term in the
//! degree-1 band. A mirror-reflection highlight `k · (r · L)` with `r = d − 2 (d·n) n` is linear in
//! the view direction `d`, so it is exactly a degree-1 SH function, and the highlights move as
//! the camera moves.

use std::f32::consts::{PI, TAU};

use glam::{Quat, Vec3};
use splat_core::sh::{SH_C1, dc_from_rgb};
use splat_raster::{Camera, Gaussians};

/// Default image width of the demo render.
pub const DEFAULT_WIDTH: u32 = 800;
/// Default image height of the demo render.
pub const DEFAULT_HEIGHT: u32 = 600;

/// Direction towards the light (normalised when used).
const LIGHT: Vec3 = Vec3::new(0.45, -0.55, 0.8);

/// A surface sample: position, outward normal, albedo, splat radius, gloss.
struct Surfel {
    position: Vec3,
    normal: Vec3,
    albedo: Vec3,
    radius: f32,
    gloss: f32,
}

/// The camera the demo is rendered from: above and in front, looking at the torus.
pub fn default_camera(width: u32, height: u32) -> Camera {
    Camera::look_at(
        width,
        height,
        50f32.to_radians(),
        Vec3::new(3.7, -4.8, 2.7),
        Vec3::new(0.0, 0.0, 0.65),
        Vec3::Z,
    )
}

/// HSV (h in turns) to RGB.
fn hsv(h: f32, s: f32, v: f32) -> Vec3 {
    let h6 = (h.rem_euclid(1.0)) * 6.0;
    let c = v * s;
    let x = c * (1.0 - ((h6 % 2.0) - 1.0).abs());
    let (r, g, b) = match h6 as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    Vec3::new(r, g, b) + Vec3::splat(v - c)
}

fn ground(out: &mut Vec<Surfel>) {
    const COUNT: usize = 4000;
    const RADIUS: f32 = 3.0;
    let golden = PI * (3.0 - 5f32.sqrt());
    for i in 0..COUNT {
        let r = RADIUS * ((i as f32 + 0.5) / COUNT as f32).sqrt();
        let a = i as f32 * golden;
        let p = Vec3::new(r * a.cos(), r * a.sin(), 0.0);
        let checker = ((p.x / 0.5).floor() + (p.y / 0.5).floor()) as i32 & 1 == 0;
        let albedo = if checker {
            Vec3::new(0.86, 0.83, 0.76)
        } else {
            Vec3::new(0.34, 0.36, 0.42)
        };
        out.push(Surfel {
            position: p,
            normal: Vec3::Z,
            albedo,
            radius: 0.052,
            gloss: 0.1,
        });
    }
}

fn torus(out: &mut Vec<Surfel>) {
    const MAJOR: usize = 72;
    const MINOR: usize = 26;
    let (big, small) = (0.8f32, 0.27f32);
    let centre = Vec3::new(0.0, 0.0, 1.12);
    // Stand the ring up, turned towards the default camera.
    let tilt = Quat::from_rotation_z(0.1) * Quat::from_rotation_x(1.2);
    for i in 0..MAJOR {
        let u = TAU * i as f32 / MAJOR as f32;
        for j in 0..MINOR {
            let v = TAU * (j as f32 + 0.5 * (i % 2) as f32) / MINOR as f32;
            let ring = Vec3::new(u.cos(), u.sin(), 0.0);
            let normal = ring * v.cos() + Vec3::Z * v.sin();
            let local = ring * big + normal * small;
            out.push(Surfel {
                position: centre + tilt * local,
                normal: tilt * normal,
                albedo: hsv(i as f32 / MAJOR as f32, 0.75, 0.95),
                radius: 0.05,
                gloss: 0.18,
            });
        }
    }
}

fn sphere(out: &mut Vec<Surfel>, centre: Vec3, radius: f32, albedo: Vec3, gloss: f32) {
    let count = (4.0 * PI * radius * radius / 0.0028).round() as usize;
    let golden = PI * (3.0 - 5f32.sqrt());
    for i in 0..count {
        let z = 1.0 - 2.0 * (i as f32 + 0.5) / count as f32;
        let r = (1.0 - z * z).sqrt();
        let a = i as f32 * golden;
        let normal = Vec3::new(r * a.cos(), r * a.sin(), z);
        out.push(Surfel {
            position: centre + normal * radius,
            normal,
            albedo,
            radius: 0.036,
            gloss,
        });
    }
}

/// Builds the demo scene's Gaussians (SH degree 1).
pub fn build() -> Gaussians {
    let mut surfels = Vec::new();
    ground(&mut surfels);
    torus(&mut surfels);
    sphere(
        &mut surfels,
        Vec3::new(1.75, 0.55, 0.36),
        0.36,
        Vec3::new(0.85, 0.16, 0.12),
        0.3,
    );
    sphere(
        &mut surfels,
        Vec3::new(-2.2, 0.3, 0.36),
        0.36,
        Vec3::new(0.15, 0.3, 0.85),
        0.3,
    );
    sphere(
        &mut surfels,
        Vec3::new(0.55, -1.75, 0.36),
        0.36,
        Vec3::new(0.9, 0.68, 0.2),
        0.45,
    );
    sphere(
        &mut surfels,
        Vec3::new(-1.0, -1.35, 0.26),
        0.26,
        Vec3::new(0.2, 0.7, 0.3),
        0.3,
    );
    let light = LIGHT.normalize();
    let mut g = Gaussians::with_degree(1);
    for s in &surfels {
        let n_dot_l = s.normal.dot(light);
        let colour = s.albedo * (0.3 + 0.7 * n_dot_l.max(0.0));
        // Specular k·(d·v) with v = L − 2 (n·L) n, only where the surface faces the light.
        let v = (light - 2.0 * n_dot_l * s.normal) * s.gloss * (n_dot_l > 0.0) as u8 as f32;
        g.means.push(s.position.to_array());
        let flat = (s.radius * 0.15).ln();
        let wide = s.radius.ln();
        g.log_scales.push([wide, wide, flat]);
        let q = Quat::from_rotation_arc(Vec3::Z, s.normal.normalize());
        g.rotations.push([q.w, q.x, q.y, q.z]);
        g.opacity_logits.push((0.97f32 / 0.03).ln());
        g.sh.extend(colour.to_array().map(dc_from_rgb));
        // Degree-1 basis: −C1·y, C1·z, −C1·x (Sloan order).
        for coeff in [-v.y / SH_C1, v.z / SH_C1, -v.x / SH_C1] {
            g.sh.extend([coeff; 3]);
        }
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scene_is_consistent_deterministic_and_view_dependent() {
        let g = build();
        assert!(g.view().check_lengths().is_ok());
        assert!((6000..10000).contains(&g.len()), "{}", g.len());
        assert_eq!(g.sh_degree, 1);
        assert_eq!(g, build());
        assert!(g.sh.iter().all(|v| v.is_finite()));
        // Some Gaussians carry a non-zero degree-1 band.
        let stride = g.sh_stride();
        let glossy = (0..g.len())
            .filter(|&i| {
                g.sh[i * stride + 3..(i + 1) * stride]
                    .iter()
                    .any(|&c| c != 0.0)
            })
            .count();
        assert!(glossy > g.len() / 4, "{glossy}");
    }

    #[test]
    fn hsv_primaries() {
        assert!((hsv(0.0, 1.0, 1.0) - Vec3::X).length() < 1e-6);
        assert!((hsv(1.0 / 3.0, 1.0, 1.0) - Vec3::Y).length() < 1e-5);
        assert!((hsv(2.0 / 3.0, 1.0, 1.0) - Vec3::Z).length() < 1e-5);
    }
}
