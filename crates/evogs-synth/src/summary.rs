//! A short human-readable summary of a scene (counts, times, image statistics), as JSON.

use std::collections::BTreeMap;
use std::fmt;

use evogs_io::Split;
use serde::Serialize;

use super::{CaptureNoise, Part, Protocol, SyntheticScene};

/// Statistics of one split.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SplitSummary {
    /// `train`, `test` or `val`.
    pub name: &'static str,
    /// Number of frames.
    pub frames: usize,
    /// Earliest time.
    pub time_min: f32,
    /// Latest time.
    pub time_max: f32,
    /// Mean colour over black (premultiplied), rounded to 1e-4.
    pub mean_rgb: [f64; 3],
    /// Mean alpha, rounded to 1e-4.
    pub mean_alpha: f64,
}

/// What a scene holds, in a stable, readable form.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SceneSummary {
    /// Preset name, if the spec came from one.
    pub preset: Option<&'static str>,
    /// The seed.
    pub seed: u64,
    /// Enabled effects.
    pub effects: Vec<&'static str>,
    /// Number of Gaussians.
    pub gaussians: usize,
    /// Gaussians per part.
    pub parts: BTreeMap<&'static str, usize>,
    /// Image side in pixels.
    pub image_size: u32,
    /// Distinct frame times with stored ground truth.
    pub trajectory_frames: usize,
    /// Which per-frame quantities are stored.
    pub stored: Vec<&'static str>,
    /// Time of the jump, if any.
    pub jump_time: Option<f32>,
    /// Per split.
    pub splits: Vec<SplitSummary>,
    /// Capture protocol; left out when `dnerf`.
    #[serde(skip_serializing_if = "Protocol::is_dnerf")]
    pub protocol: Protocol,
    /// Capture noise of the training frames; left out when off.
    #[serde(skip_serializing_if = "CaptureNoise::is_off")]
    pub noise: CaptureNoise,
    /// Frames of the fixed-camera sequence; left out when there is none.
    #[serde(skip_serializing_if = "is_zero")]
    pub fixed_camera_frames: usize,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

fn round4(v: f64) -> f64 {
    (v * 1e4).round() / 1e4
}

impl SceneSummary {
    /// Summarises a scene.
    pub fn of(scene: &SyntheticScene) -> Self {
        let mut parts = BTreeMap::new();
        for p in &scene.parts {
            let name = match p {
                Part::Body => "body",
                Part::Satellite => "satellite",
                Part::Occluder => "occluder",
            };
            *parts.entry(name).or_insert(0) += 1;
        }
        let traj = &scene.trajectories;
        let mut stored = vec!["means"];
        if traj.rotations.is_some() {
            stored.push("rotations");
        }
        if traj.sh_dc.is_some() {
            stored.push("sh_dc");
        }
        let splits = Split::ALL
            .into_iter()
            .map(|split| {
                let frames = scene.split(split);
                let pixels: usize = frames.iter().map(|f| f.alpha.len()).sum();
                let mut rgb = [0.0f64; 3];
                let mut alpha = 0.0f64;
                for f in frames {
                    for (c, &a) in f.color.iter().zip(&f.alpha) {
                        for k in 0..3 {
                            rgb[k] += f64::from(c[k]);
                        }
                        alpha += f64::from(a);
                    }
                }
                let n = pixels.max(1) as f64;
                SplitSummary {
                    name: split.name(),
                    frames: frames.len(),
                    time_min: frames.iter().map(|f| f.time).fold(f32::INFINITY, f32::min),
                    time_max: frames
                        .iter()
                        .map(|f| f.time)
                        .fold(f32::NEG_INFINITY, f32::max),
                    mean_rgb: rgb.map(|v| round4(v / n)),
                    mean_alpha: round4(alpha / n),
                }
            })
            .collect();
        Self {
            preset: scene.spec.preset.map(|p| p.name()),
            seed: scene.seed,
            effects: scene.spec.effect_names(),
            gaussians: scene.canonical.len(),
            parts,
            image_size: scene.spec.image_size,
            trajectory_frames: traj.times.len(),
            stored,
            jump_time: scene.spec.jump.map(|j| j.time),
            splits,
            protocol: scene.spec.protocol,
            noise: scene.spec.noise,
            fixed_camera_frames: scene.fixed.len(),
        }
    }
}

impl fmt::Display for SceneSummary {
    /// Pretty-printed JSON.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let text = serde_json::to_string_pretty(self).map_err(|_| fmt::Error)?;
        f.write_str(&text)
    }
}
