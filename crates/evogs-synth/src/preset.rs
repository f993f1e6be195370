//! Named presets and the scene specification they produce.

use serde::Serialize;

use super::SynthError;
use super::effects::{AppearanceChange, Jump, LargeMotion, Occlusion, RigidMotion, Wave};
use super::protocol::{CaptureNoise, Protocol};

/// A named scene recipe.
#[derive(strum::IntoStaticStr, strum::EnumString)]
#[strum(serialize_all = "lowercase")]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// Rigid motion only: the object rotates and translates.
    Rigid,
    /// Non-rigid wave only: the body bends under a travelling wave.
    Wave,
    /// Abrupt jump only: the satellite teleports between two training frames, then moves.
    Jump,
    /// Every effect at once: rigid motion, wave, large motion, jump, appearance change, occlusion.
    Mixed,
}

impl Preset {
    /// All presets.
    pub const ALL: [Preset; 4] = [Preset::Rigid, Preset::Wave, Preset::Jump, Preset::Mixed];

    /// The preset's name (`rigid`, `wave`, `jump`, `mixed`).
    pub fn name(self) -> &'static str {
        self.into()
    }

    /// One line saying which effects the preset enables.
    pub fn help(self) -> &'static str {
        match self {
            Self::Rigid => "effects: rigid translation and rotation",
            Self::Wave => "effects: non-rigid wave (the body bends)",
            Self::Jump => {
                "effects: abrupt jump (the satellite teleports between two training frames, then moves)"
            }
            Self::Mixed => {
                "effects: rigid motion, non-rigid wave, large motion, abrupt jump, appearance change, occlusion"
            }
        }
    }

    /// The preset with this name.
    pub fn from_name(name: &str) -> Option<Self> {
        name.parse().ok()
    }
}

/// Everything that determines a scene besides the seed.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SceneSpec {
    /// The preset this spec came from, if any.
    pub preset: Option<Preset>,
    /// Image width and height in pixels.
    pub image_size: u32,
    /// Horizontal field of view, radians (`camera_angle_x`).
    pub camera_angle_x: f32,
    /// Training frames (times `k / (F − 1)`).
    pub train_frames: usize,
    /// Test frames (held-out times and cameras).
    pub test_frames: usize,
    /// Validation frames (held-out times and cameras).
    pub val_frames: usize,
    /// Gaussians of the body sphere.
    pub body_gaussians: usize,
    /// Gaussians of the satellite cube (rounded to 6 square faces).
    pub satellite_gaussians: usize,
    /// Gaussians of the occluder panel (only with [`Occlusion`]).
    pub occluder_gaussians: usize,
    /// Rigid motion, if enabled.
    pub rigid: Option<RigidMotion>,
    /// Non-rigid wave, if enabled.
    pub wave: Option<Wave>,
    /// Large motion, if enabled.
    pub large_motion: Option<LargeMotion>,
    /// Abrupt jump, if enabled.
    pub jump: Option<Jump>,
    /// Appearance change, if enabled.
    pub appearance: Option<AppearanceChange>,
    /// Occlusion, if enabled.
    pub occlusion: Option<Occlusion>,
    /// How the scene is captured (DESIGN §10.2); left out of `scene.json` when `dnerf`.
    #[serde(skip_serializing_if = "Protocol::is_dnerf")]
    pub protocol: Protocol,
    /// Capture noise of the training frames; left out of `scene.json` when off.
    #[serde(skip_serializing_if = "CaptureNoise::is_off")]
    pub noise: CaptureNoise,
}

/// Default image side.
pub const DEFAULT_SIZE: u32 = 128;
/// Default number of training frames.
pub const DEFAULT_FRAMES: usize = 40;

impl SceneSpec {
    /// A spec with no effects at the default sizes.
    pub fn still() -> Self {
        Self {
            preset: None,
            image_size: DEFAULT_SIZE,
            camera_angle_x: 0.69,
            train_frames: DEFAULT_FRAMES,
            test_frames: 10,
            val_frames: 10,
            body_gaussians: 2400,
            satellite_gaussians: 600,
            occluder_gaussians: 400,
            rigid: None,
            wave: None,
            large_motion: None,
            jump: None,
            appearance: None,
            occlusion: None,
            protocol: Protocol::Dnerf,
            noise: CaptureNoise::default(),
        }
    }

    /// The spec of a preset at the default sizes.
    pub fn preset(preset: Preset) -> Self {
        let rigid = RigidMotion {
            axis: [0.2, 0.3, 1.0],
            angle: 0.8 * std::f32::consts::PI,
            velocity: [0.3, -0.2, 0.1],
        };
        let wave = Wave {
            amplitude: 0.09,
            wavelength: 0.7,
            cycles: 1.5,
        };
        let jump = Jump {
            time: 0.5,
            offset: [-0.5, 0.9, 0.35],
            velocity: [0.0, 0.0, -0.6],
        };
        let mut spec = Self {
            preset: Some(preset),
            ..Self::still()
        };
        match preset {
            Preset::Rigid => spec.rigid = Some(rigid),
            Preset::Wave => spec.wave = Some(wave),
            Preset::Jump => spec.jump = Some(jump),
            Preset::Mixed => {
                spec.rigid = Some(RigidMotion {
                    angle: 0.5 * std::f32::consts::PI,
                    velocity: [0.0; 3],
                    ..rigid
                });
                spec.wave = Some(wave);
                spec.large_motion = Some(LargeMotion {
                    length: 1.6,
                    lift: 0.4,
                });
                spec.jump = Some(jump);
                spec.appearance = Some(AppearanceChange {
                    tint: [0.95, 0.25, 0.6],
                    strength: 0.7,
                });
                spec.occlusion = Some(Occlusion {
                    radius: 1.5,
                    size: [0.5, 0.8],
                    turns: 1.0,
                });
            }
        }
        spec.with_frames(DEFAULT_FRAMES)
    }

    /// Sets the image side.
    #[must_use]
    pub fn with_size(mut self, size: u32) -> Self {
        self.image_size = size;
        self
    }

    /// Sets the number of training frames; test and val get a fifth of it (at least 2 each), and
    /// a jump is moved to a quarter of the way between the two middle training times.
    #[must_use]
    pub fn with_frames(mut self, frames: usize) -> Self {
        self.train_frames = frames;
        self.test_frames = (frames / 5).max(2);
        self.val_frames = (frames / 5).max(2);
        if let Some(jump) = &mut self.jump {
            let intervals = frames.saturating_sub(1).max(1);
            jump.time = ((intervals / 2) as f32 + 0.25) / intervals as f32;
        }
        self
    }

    /// Sets the capture protocol.
    #[must_use]
    pub fn with_protocol(mut self, protocol: Protocol) -> Self {
        self.protocol = protocol;
        self
    }

    /// Sets the capture noise of the training frames.
    #[must_use]
    pub fn with_noise(mut self, noise: CaptureNoise) -> Self {
        self.noise = noise;
        self
    }

    /// Scales every Gaussian count by `factor` (at least 6 each).
    #[must_use]
    pub fn with_gaussian_scale(mut self, factor: f32) -> Self {
        let scale = |n: usize| ((n as f32 * factor).round() as usize).max(6);
        self.body_gaussians = scale(self.body_gaussians);
        self.satellite_gaussians = scale(self.satellite_gaussians);
        self.occluder_gaussians = scale(self.occluder_gaussians);
        self
    }

    /// Names of the enabled effects, in a fixed order.
    pub fn effect_names(&self) -> Vec<&'static str> {
        let flags = [
            (self.rigid.is_some(), "rigid"),
            (self.wave.is_some(), "wave"),
            (self.large_motion.is_some(), "large_motion"),
            (self.jump.is_some(), "jump"),
            (self.appearance.is_some(), "appearance"),
            (self.occlusion.is_some(), "occlusion"),
        ];
        flags.into_iter().filter(|f| f.0).map(|f| f.1).collect()
    }

    /// Training times `k / (F − 1)`.
    pub fn train_times(&self) -> Vec<f32> {
        let intervals = (self.train_frames - 1) as f32;
        (0..self.train_frames)
            .map(|k| k as f32 / intervals)
            .collect()
    }

    /// Held-out times: midpoints of `count` training intervals spread over [0, 1], the spread
    /// shifted by `shift` (in units of a held-out step) so test and val use different intervals
    /// where they can.
    pub(crate) fn held_out_times(&self, count: usize, shift: f32) -> Vec<f32> {
        let intervals = self.train_frames - 1;
        (0..count)
            .map(|j| {
                let k = (((j as f32 + shift) * intervals as f32 / count as f32) as usize)
                    .min(intervals - 1);
                (k as f32 + 0.5) / intervals as f32
            })
            .collect()
    }

    /// Rig times (monocular protocol): `count` training times at indices `⌊(j + shift)·F/count⌋`,
    /// so test (`shift` 0.5) and val (`shift` 0) use different training times where they can.
    pub(crate) fn rig_times(&self, count: usize, shift: f32) -> Vec<f32> {
        let train = self.train_times();
        let frames = train.len();
        (0..count)
            .map(|j| {
                let k =
                    (((j as f32 + shift) * frames as f32 / count as f32) as usize).min(frames - 1);
                train[k]
            })
            .collect()
    }

    /// Checks ranges; errors name the field.
    pub fn validate(&self) -> Result<(), SynthError> {
        let bad = |field, problem: String| Err(SynthError::Spec { field, problem });
        if !(8..=4096).contains(&self.image_size) {
            return bad(
                "image_size",
                format!("{} is outside 8..=4096", self.image_size),
            );
        }
        if !(self.camera_angle_x > 0.05 && self.camera_angle_x < 3.0) {
            return bad(
                "camera_angle_x",
                format!("{} is outside (0.05, 3) radians", self.camera_angle_x),
            );
        }
        if !(3..=10_000).contains(&self.train_frames) {
            return bad(
                "train_frames",
                format!("{} is outside 3..=10000", self.train_frames),
            );
        }
        for (field, n) in [
            ("test_frames", self.test_frames),
            ("val_frames", self.val_frames),
        ] {
            if !(1..=10_000).contains(&n) {
                return bad(field, format!("{n} is outside 1..=10000"));
            }
        }
        for (field, n) in [
            ("body_gaussians", self.body_gaussians),
            ("satellite_gaussians", self.satellite_gaussians),
            ("occluder_gaussians", self.occluder_gaussians),
        ] {
            if !(6..=2_000_000).contains(&n) {
                return bad(field, format!("{n} is outside 6..=2000000"));
            }
        }
        for (field, sigma, max) in [
            ("noise.pose", self.noise.pose, CaptureNoise::MAX_POSE),
            ("noise.image", self.noise.image, CaptureNoise::MAX_IMAGE),
        ] {
            if !(0.0..=max).contains(&sigma) {
                return bad(field, format!("{sigma} is outside 0..={max}"));
            }
        }
        if let Some(jump) = &self.jump {
            let times = self.train_times();
            let between = times
                .windows(2)
                .any(|w| jump.time > w[0] + 1e-4 && jump.time < w[1] - 1e-4);
            if !between {
                return bad(
                    "jump.time",
                    format!(
                        "{} is not strictly between two consecutive training times",
                        jump.time
                    ),
                );
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_help_names_the_effects() {
        for p in Preset::ALL {
            assert_eq!(Preset::from_name(p.name()), Some(p));
            assert!(p.help().starts_with("effects: "));
        }
        assert_eq!(Preset::from_name("nope"), None);
    }

    #[test]
    fn names_are_the_lowercase_spellings_and_only_exact_names_are_found() {
        let names: Vec<&str> = Preset::ALL.iter().map(|p| p.name()).collect();
        assert_eq!(names, ["rigid", "wave", "jump", "mixed"]);
        let names: Vec<&str> = Protocol::ALL.iter().map(|p| p.name()).collect();
        assert_eq!(names, ["dnerf", "monocular"]);
        assert_eq!(Preset::from_name("Rigid"), None);
        assert_eq!(Preset::from_name("dnerf"), None);
        assert_eq!(Protocol::from_name(""), None);
    }

    #[test]
    fn each_preset_enables_exactly_its_effects() {
        assert_eq!(SceneSpec::preset(Preset::Rigid).effect_names(), ["rigid"]);
        assert_eq!(SceneSpec::preset(Preset::Wave).effect_names(), ["wave"]);
        assert_eq!(SceneSpec::preset(Preset::Jump).effect_names(), ["jump"]);
        assert_eq!(
            SceneSpec::preset(Preset::Mixed).effect_names(),
            [
                "rigid",
                "wave",
                "large_motion",
                "jump",
                "appearance",
                "occlusion"
            ]
        );
    }

    #[test]
    fn jump_time_stays_between_training_frames_for_any_count() {
        for frames in 3..60 {
            let spec = SceneSpec::preset(Preset::Jump).with_frames(frames);
            spec.validate().unwrap();
        }
        let mut spec = SceneSpec::preset(Preset::Jump);
        spec.jump.as_mut().unwrap().time = 0.0;
        let err = spec.validate().unwrap_err().to_string();
        assert!(err.starts_with("scene spec field `jump.time`"), "{err}");
    }

    #[test]
    fn out_of_range_fields_are_named() {
        let err = SceneSpec::preset(Preset::Rigid)
            .with_size(2)
            .validate()
            .unwrap_err();
        assert_eq!(
            err.to_string(),
            "scene spec field `image_size`: 2 is outside 8..=4096"
        );
        let err = SceneSpec::preset(Preset::Wave)
            .with_frames(2)
            .validate()
            .unwrap_err();
        assert!(err.to_string().contains("`train_frames`"));
    }
}
