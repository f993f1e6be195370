//! The motion model: where every Gaussian is, how it is turned and what colour it has at time t.

use std::f32::consts::{PI, TAU};

use glam::{Quat, Vec3};
use serde::Serialize;
use splat_core::sh::{dc_from_rgb, rgb_from_dc};
use splat_raster::Gaussians;

use super::SceneSpec;
use super::effects::{AppearanceChange, Jump, LargeMotion, Occlusion, RigidMotion, Wave};

/// Which part of the object a Gaussian belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Part {
    /// The checkered sphere (waves and appearance change act on it).
    Body,
    /// The small cube (the jump acts on it).
    Satellite,
    /// The orbiting panel of the occlusion effect.
    Occluder,
}

/// The enabled effects of a spec, evaluated at any time. Disabled effects are skipped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionModel {
    /// Rigid motion of body and satellite.
    pub rigid: Option<RigidMotion>,
    /// Wave on the body.
    pub wave: Option<Wave>,
    /// Large motion of body and satellite.
    pub large_motion: Option<LargeMotion>,
    /// Jump of the satellite.
    pub jump: Option<Jump>,
    /// Colour change of the body.
    pub appearance: Option<AppearanceChange>,
    /// Orbit of the occluder.
    pub occlusion: Option<Occlusion>,
}

impl MotionModel {
    /// The effects of a spec.
    pub fn of(spec: &SceneSpec) -> Self {
        Self {
            rigid: spec.rigid,
            wave: spec.wave,
            large_motion: spec.large_motion,
            jump: spec.jump,
            appearance: spec.appearance,
            occlusion: spec.occlusion,
        }
    }

    /// True when Gaussians turn over time (rigid rotation or the occluder's orbit): only then are
    /// per-frame rotations stored.
    pub fn rotates(&self) -> bool {
        self.rigid.is_some() || self.occlusion.is_some()
    }

    /// True when colours change over time: only then are per-frame SH DC values stored.
    pub fn recolours(&self) -> bool {
        self.appearance.is_some()
    }

    /// Rotation and translation of the rigid motion at `t` (identity when disabled).
    pub fn rigid_at(&self, t: f32) -> (Quat, Vec3) {
        match &self.rigid {
            Some(r) => (
                Quat::from_axis_angle(Vec3::from_array(r.axis).normalize(), r.angle * t),
                Vec3::from_array(r.velocity) * (t - 0.5),
            ),
            None => (Quat::IDENTITY, Vec3::ZERO),
        }
    }

    /// Translation of the large motion at `t` (zero when disabled).
    pub fn large_at(&self, t: f32) -> Vec3 {
        self.large_motion.map_or(Vec3::ZERO, |l| {
            Vec3::new(l.length * (t - 0.5), 0.0, l.lift * (PI * t).sin())
        })
    }

    /// Displacement of the satellite by the jump at `t` (zero before the jump or when disabled).
    pub fn jump_at(&self, t: f32) -> Vec3 {
        match &self.jump {
            Some(j) if t >= j.time => {
                Vec3::from_array(j.offset) + Vec3::from_array(j.velocity) * (t - j.time)
            }
            _ => Vec3::ZERO,
        }
    }

    /// Non-rigid displacement of a body point at `t` (zero when disabled).
    pub fn wave_at(&self, p: Vec3, t: f32) -> Vec3 {
        self.wave.map_or(Vec3::ZERO, |w| {
            Vec3::Z * w.amplitude * (TAU * (p.x / w.wavelength - t * w.cycles)).sin()
        })
    }

    /// Rotation of the occluder's orbit at `t`.
    pub fn orbit_at(&self, t: f32) -> Quat {
        self.occlusion
            .map_or(Quat::IDENTITY, |o| Quat::from_rotation_z(TAU * o.turns * t))
    }

    /// The deformed Gaussians at time `t` (means, rotations and colours; scales and opacities do
    /// not change).
    pub fn deform(&self, canonical: &Gaussians, parts: &[Part], t: f32) -> Gaussians {
        let mut out = canonical.clone();
        let (rigid_q, rigid_t) = self.rigid_at(t);
        let large = self.large_at(t);
        let jump = self.jump_at(t);
        let orbit = self.orbit_at(t);
        let stride = canonical.sh_stride();
        let blend = self.appearance.map(|a| (a, a.strength * (PI * t).sin()));
        for (i, &part) in parts.iter().enumerate() {
            let p = Vec3::from_array(canonical.means[i]);
            let r = canonical.rotations[i];
            let q = Quat::from_xyzw(r[1], r[2], r[3], r[0]);
            let (mean, turn) = match part {
                Part::Occluder => (orbit * p, orbit),
                Part::Body | Part::Satellite => {
                    let local = match part {
                        Part::Body => p + self.wave_at(p, t),
                        _ => p + jump,
                    };
                    (rigid_q * local + rigid_t + large, rigid_q)
                }
            };
            out.means[i] = mean.to_array();
            if self.rotates() {
                let q2 = turn * q;
                // Keep the stored norm: turning a unit rotation does not change |q|.
                out.rotations[i] = [q2.w, q2.x, q2.y, q2.z];
            }
            if let (Some((a, s)), Part::Body) = (blend, part) {
                let dc = &mut out.sh[i * stride..i * stride + 3];
                for (v, tint) in dc.iter_mut().zip(a.tint) {
                    let rgb = rgb_from_dc(*v);
                    *v = dc_from_rgb(rgb + s * (tint - rgb));
                }
            }
        }
        out
    }
}
