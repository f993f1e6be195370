//! Capture protocols (DESIGN §10.2): where the cameras of each split are, and the optional
//! per-frame capture noise of the training frames.
//!
//! What it is not: the renderer or the writer (`scene` and `write`); this module only places
//! cameras and perturbs what a capture records.

use std::f32::consts::TAU;

use glam::Vec3;
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::Serialize;
use splat_raster::Camera;

use super::SynthFrame;

/// How a scene is captured (recorded in `scene.json` when it is not the default `dnerf`).
#[derive(strum::IntoStaticStr, strum::EnumString)]
#[strum(serialize_all = "lowercase")]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Protocol {
    /// D-NeRF style: a new random camera on the sphere at every time step; test and val at
    /// held-out times with new random cameras.
    #[default]
    Dnerf,
    /// One camera moving smoothly along a short arc (a hand-held phone); test and val at the
    /// training timestamps, seen by rig cameras at a fixed azimuth offset (NeRF-DS, HyperNeRF
    /// vrig). A fixed camera also records every training time (the flicker ground truth).
    Monocular,
}

impl Protocol {
    /// Both protocols.
    pub const ALL: [Protocol; 2] = [Protocol::Dnerf, Protocol::Monocular];

    /// The protocol's name (`dnerf`, `monocular`).
    pub fn name(self) -> &'static str {
        self.into()
    }

    /// One line saying where the cameras are.
    pub fn help(self) -> &'static str {
        match self {
            Self::Dnerf => {
                "a new random camera per time step; test and val at held-out times (D-NeRF)"
            }
            Self::Monocular => {
                "one camera moving along a short arc; test and val at training times from rig \
                 cameras at a fixed offset (NeRF-DS, HyperNeRF); plus a fixed-camera sequence"
            }
        }
    }

    /// The protocol with this name.
    pub fn from_name(name: &str) -> Option<Self> {
        name.parse().ok()
    }

    /// Whether this is the default (`dnerf`), which `scene.json` leaves unrecorded so that its
    /// files stay what they were before protocols existed.
    pub fn is_dnerf(&self) -> bool {
        *self == Self::Dnerf
    }
}

/// Azimuth swept by the monocular camera over t ∈ [0, 1], radians (about 34°).
pub const MONOCULAR_ARC: f32 = 0.6;
/// Amplitude of the monocular camera's vertical bob (`z` on the unit sphere, one period over
/// the sequence): a hand-held path is not a perfect circle.
pub const MONOCULAR_BOB: f32 = 0.05;
/// Azimuth offset of the monocular rig cameras, radians: test at `+`, val at `−`.
pub const RIG_OFFSET: f32 = 0.2;

/// Per-frame capture noise of the training frames (test, val and the fixed-camera sequence stay
/// exact ground truth). Both off (0) by default.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct CaptureNoise {
    /// Pose jitter σ: every coordinate of the recorded camera centre and of its look-at target
    /// gets an independent N(0, (σ·distance)²) offset; the image is rendered from the true
    /// camera. In units of the camera distance (so 0.01 tilts the view by about 0.6°).
    pub pose: f32,
    /// Image noise σ: N(0, σ²) added to each channel of the object's straight (un-premultiplied)
    /// colour, clamped to [0, 1]; transparent pixels stay transparent.
    pub image: f32,
}

impl CaptureNoise {
    /// Whether both levels are zero (`scene.json` then leaves the noise unrecorded).
    pub fn is_off(&self) -> bool {
        self.pose == 0.0 && self.image == 0.0
    }

    /// The largest accepted pose σ (half the camera distance).
    pub const MAX_POSE: f32 = 0.5;
    /// The largest accepted image σ.
    pub const MAX_IMAGE: f32 = 1.0;
}

/// The monocular camera at time `t` with an extra azimuth `offset`: azimuth
/// `a0 + MONOCULAR_ARC·(t − 0.5) + offset`, height `z0 + MONOCULAR_BOB·sin(2π t)` on the unit
/// sphere, at `distance`, looking at the origin, world up +z.
pub(crate) fn monocular_camera(
    start: (f32, f32),
    t: f32,
    offset: f32,
    size: u32,
    fov_x: f32,
    distance: f32,
) -> Camera {
    let (a0, z0) = start;
    let azimuth = a0 + MONOCULAR_ARC * (t - 0.5) + offset;
    let z = z0 + MONOCULAR_BOB * (TAU * t).sin();
    let r = (1.0 - z * z).sqrt();
    let eye = Vec3::new(r * azimuth.cos(), r * azimuth.sin(), z) * distance;
    Camera::look_at(size, size, fov_x, eye, Vec3::ZERO, Vec3::Z)
}

/// The monocular camera's start: azimuth uniform in [0, 2π), height `z0` uniform in
/// [0.1, 0.5] (elevation about 6° to 30°).
pub(crate) fn monocular_start(rng: &mut ChaCha8Rng) -> (f32, f32) {
    let a0: f32 = rng.random_range(0.0..TAU);
    let z0: f32 = rng.random_range(0.1..0.5);
    (a0, z0)
}

fn normal3(rng: &mut ChaCha8Rng) -> Vec3 {
    Vec3::new(
        rng.sample(StandardNormal),
        rng.sample(StandardNormal),
        rng.sample(StandardNormal),
    )
}

/// The camera a capture with pose jitter `sigma` records for `camera` (which looks at the
/// origin from `distance`): centre and target each moved by N(0, (σ·distance)²) per coordinate.
pub(crate) fn jitter_pose(
    rng: &mut ChaCha8Rng,
    camera: &Camera,
    sigma: f32,
    distance: f32,
) -> Camera {
    let eye = camera.center() + normal3(rng) * (sigma * distance);
    let target = normal3(rng) * (sigma * distance);
    let fov_x = 2.0 * (0.5 * camera.width as f32 / camera.fx).atan();
    Camera::look_at(camera.width, camera.height, fov_x, eye, target, Vec3::Z)
}

/// Adds image noise `sigma` to `frame` in place (see [`CaptureNoise::image`]).
pub(crate) fn add_image_noise(rng: &mut ChaCha8Rng, frame: &mut SynthFrame, sigma: f32) {
    for (c, &a) in frame.color.iter_mut().zip(&frame.alpha) {
        if a <= 0.0 {
            continue;
        }
        for v in c.iter_mut() {
            let n: f32 = rng.sample(StandardNormal);
            *v = (*v + a * sigma * n).clamp(0.0, a);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn names_round_trip() {
        for p in Protocol::ALL {
            assert_eq!(Protocol::from_name(p.name()), Some(p));
        }
        assert_eq!(Protocol::from_name("nerfds"), None);
        assert!(Protocol::default().is_dnerf());
    }

    #[test]
    fn monocular_camera_sweeps_the_arc_and_looks_at_the_origin() {
        let start = (1.0, 0.3);
        let a = monocular_camera(start, 0.0, 0.0, 32, 0.7, 4.0);
        let b = monocular_camera(start, 1.0, 0.0, 32, 0.7, 4.0);
        let (ca, cb) = (a.center(), b.center());
        assert!((ca.length() - 4.0).abs() < 1e-4 && (cb.length() - 4.0).abs() < 1e-4);
        // The azimuth sweeps MONOCULAR_ARC; the bob is back to z0 at t = 1.
        let az = |c: Vec3| c.y.atan2(c.x);
        assert!((az(cb) - az(ca) - MONOCULAR_ARC).abs() < 1e-4);
        assert!((ca.z - cb.z).abs() < 1e-4);
        // The rig offset turns the camera about +z only.
        let rig = monocular_camera(start, 0.0, RIG_OFFSET, 32, 0.7, 4.0);
        assert!((az(rig.center()) - az(ca) - RIG_OFFSET).abs() < 1e-4);
        assert!((rig.center().z - ca.z).abs() < 1e-5);
        let p = a.world_to_camera(Vec3::ZERO);
        assert!(p.x.abs() < 1e-4 && p.y.abs() < 1e-4 && p.z > 0.0);
    }

    #[test]
    fn pose_jitter_has_the_asked_scale() {
        let camera = monocular_camera((0.0, 0.2), 0.5, 0.0, 32, 0.7, 4.0);
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let n = 400;
        let mut sq = 0.0f64;
        for _ in 0..n {
            let j = jitter_pose(&mut rng, &camera, 0.01, 4.0);
            sq += f64::from((j.center() - camera.center()).length_squared());
            assert!((j.fx - camera.fx).abs() < 1e-3, "intrinsics are kept");
        }
        // E|offset|² = 3 (σ·d)² = 3 · 0.04² = 0.0048.
        let rms = (sq / f64::from(n)).sqrt();
        assert!((rms - 0.0048f64.sqrt()).abs() < 0.01, "{rms}");
    }
}
