//! The canonical object: a checkered body sphere, a satellite cube and (with occlusion) a panel.
//! Flat disc-like Gaussians lie tangent to each surface; colours are SH degree 0.

use std::f32::consts::{PI, TAU};

use glam::{Quat, Vec3};
use splat_core::logit;
use splat_core::sh::dc_from_rgb;
use splat_raster::Gaussians;

use super::effects::Occlusion;
use super::motion::Part;

/// Body sphere radius.
pub(crate) const BODY_RADIUS: f32 = 0.55;
/// Satellite cube centre.
pub(crate) const SATELLITE_CENTRE: Vec3 = Vec3::new(0.9, 0.0, 0.15);
/// Satellite cube half side.
pub(crate) const SATELLITE_HALF: f32 = 0.16;
/// Height of the occluder panel's centre.
const OCCLUDER_Z: f32 = 0.1;
/// Opacity of every Gaussian.
const OPACITY: f32 = 0.92;

/// Colour palettes the seed picks from: (body colour A, body colour B, satellite).
const PALETTES: [[[f32; 3]; 3]; 4] = [
    [[0.90, 0.85, 0.75], [0.15, 0.45, 0.80], [0.95, 0.55, 0.10]],
    [[0.95, 0.90, 0.80], [0.20, 0.60, 0.30], [0.85, 0.20, 0.25]],
    [[0.85, 0.85, 0.90], [0.55, 0.25, 0.70], [0.95, 0.80, 0.15]],
    [[0.92, 0.88, 0.70], [0.80, 0.30, 0.20], [0.20, 0.55, 0.85]],
];

/// Adds one disc-like Gaussian tangent to `normal` with in-plane standard deviation `sigma`.
fn push(
    g: &mut Gaussians,
    parts: &mut Vec<Part>,
    part: Part,
    at: Vec3,
    normal: Vec3,
    sigma: f32,
    rgb: [f32; 3],
) {
    let q = Quat::from_rotation_arc(Vec3::Z, normal.normalize());
    g.means.push(at.to_array());
    g.log_scales
        .push([sigma.ln(), sigma.ln(), (0.2 * sigma).ln()]);
    g.rotations.push([q.w, q.x, q.y, q.z]);
    g.opacity_logits.push(logit(OPACITY));
    g.sh.extend(rgb.map(dc_from_rgb));
    parts.push(part);
}

/// Builds the canonical Gaussians and their parts. `palette` selects the colours.
pub(crate) fn build(
    body: usize,
    satellite: usize,
    occluder: Option<(usize, &Occlusion)>,
    palette: usize,
) -> (Gaussians, Vec<Part>) {
    let [col_a, col_b, col_sat] = PALETTES[palette % PALETTES.len()];
    let mut g = Gaussians::with_degree(0);
    let mut parts = Vec::new();

    // Body: Fibonacci sphere, checkered in 8 longitude sectors × 6 latitude bands.
    let spacing = (4.0 * PI * BODY_RADIUS * BODY_RADIUS / body as f32).sqrt();
    let golden = PI * (3.0 - 5f32.sqrt());
    for i in 0..body {
        let z = 1.0 - 2.0 * (i as f32 + 0.5) / body as f32;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = golden * i as f32;
        let n = Vec3::new(r * phi.cos(), r * phi.sin(), z);
        let sector = ((phi.rem_euclid(TAU) / TAU) * 8.0) as usize;
        let band = (((z + 1.0) / 2.0) * 6.0).min(5.0) as usize;
        let rgb = if (sector + band).is_multiple_of(2) {
            col_a
        } else {
            col_b
        };
        push(
            &mut g,
            &mut parts,
            Part::Body,
            n * BODY_RADIUS,
            n,
            0.6 * spacing,
            rgb,
        );
    }

    // Satellite: a grid on each of the six faces, faces shaded differently.
    let side = ((satellite as f32 / 6.0).sqrt().round() as usize).max(1);
    let step = 2.0 * SATELLITE_HALF / side as f32;
    for (face, axis) in [
        Vec3::X,
        Vec3::NEG_X,
        Vec3::Y,
        Vec3::NEG_Y,
        Vec3::Z,
        Vec3::NEG_Z,
    ]
    .into_iter()
    .enumerate()
    {
        let (u, v) = (axis.any_orthonormal_pair().0, axis.any_orthonormal_pair().1);
        let shade = 0.7 + 0.06 * face as f32;
        let rgb = col_sat.map(|c| (c * shade).min(1.0));
        for a in 0..side {
            for b in 0..side {
                let s = -SATELLITE_HALF + (a as f32 + 0.5) * step;
                let t = -SATELLITE_HALF + (b as f32 + 0.5) * step;
                let at = SATELLITE_CENTRE + axis * SATELLITE_HALF + u * s + v * t;
                push(
                    &mut g,
                    &mut parts,
                    Part::Satellite,
                    at,
                    axis,
                    0.6 * step,
                    rgb,
                );
            }
        }
    }

    // Occluder: a dark panel at angle 0 of its orbit, facing the origin.
    if let Some((count, occ)) = occluder {
        let aspect = occ.size[1] / occ.size[0];
        let cols = ((count as f32 / aspect).sqrt().round() as usize).max(1);
        let rows = (count / cols).max(1);
        let step = occ.size[0] / cols as f32;
        for a in 0..cols {
            for b in 0..rows {
                let y = -0.5 * occ.size[0] + (a as f32 + 0.5) * step;
                let z =
                    OCCLUDER_Z - 0.5 * occ.size[1] + (b as f32 + 0.5) * occ.size[1] / rows as f32;
                let checker = (a / 3 + b / 3).is_multiple_of(2);
                let rgb = if checker {
                    [0.12, 0.14, 0.22]
                } else {
                    [0.3, 0.32, 0.38]
                };
                push(
                    &mut g,
                    &mut parts,
                    Part::Occluder,
                    Vec3::new(occ.radius, y, z),
                    Vec3::NEG_X,
                    0.6 * step,
                    rgb,
                );
            }
        }
    }
    (g, parts)
}
