//! EvoGS's settings in a run's config (DESIGN §4–6): the ablation switches and the shape of the
//! observation network Φ. Every switch has a command-line spelling (its `FromStr`/`Display`):
//!
//! | setting | spellings | meaning |
//! |---|---|---|
//! | [`Gain`] | `learned`, or a number in \[0, 1\] (`0`, `0.5`, `1`) | K = Ψ(·), or fixed |
//! | [`HistoryMode`] | `buffer`, `requery` | history from the buffer, or re-queried from Φ |
//! | [`DensifyPolicy`] | `standard`, `trigger`, `trigger+deform` | 3DGS ADC, + EvoGS trigger, + deformation-aware clone/split |
//! | [`Storage`] | `f32`, `f16` | buffer storage (`--buffer`) |
//! | [`Precision`] | `f32`, `f16` | Φ's storage (`--net-precision`) |
//! | [`PlaneCombine`] | `concat`, `product` | Φ's planes concatenated or multiplied (`--triplane-combine`) |
//! | [`Layout`] | `pos,rot,scale[,opacity,colour]` | the deformation components |
//!
//! The motion floor (`motion_floor` of [`EvoSettings::evo`], `--motion-floor`) is the trainer's own,
//! 1e-3 of the scene extent per frame spacing instead of evo-state's default 1e-6 (DESIGN §4.7): see
//! [`TRAINER_MOTION_FLOOR`] for the measurement and the reasoning. Φ's tri-plane and B-spline
//! train at 10× the network lr ([`EvoSettings::grid_lr_scale`], `--grid-lr-scale`; see
//! [`TRAINER_GRID_LR_SCALE`]). Ψ trains at its own constant lr ([`EvoSettings::psi_lr`],
//! `--psi-lr`; see [`TRAINER_PSI_LR`]).
//!
//! The settings are recorded in `config.json` for every method; only `--method evogs` uses them
//! (the baseline ignores them, except that it refuses opacity and colour components: D-3DGS's
//! network has heads for position, rotation and scale only). EvoGS trains every component:
//! opacity adds to the opacity logit, colour to the SH DC coefficients (DESIGN §4.1).

use serde::{Deserialize, Serialize};
use strum::{Display, EnumString, IntoStaticStr, VariantNames};

/// The settings' types are the libraries' own, recorded in `config.json` through their `serde`
/// features: evo-state's configuration with its gain, history mode and buffer storage, tiny-nn's
/// precision and plane combination, and splat-core's deformation layout.
pub use evo_state::{EvoConfig, Gain, HistoryMode, Layout, Storage};
pub use tiny_nn::{PlaneCombine, Precision};

use crate::error::BackboneError;
use crate::one_word::{OneWord, unknown};

/// Densification policy (DESIGN §6).
#[derive(EnumString, Display, IntoStaticStr, VariantNames)]
#[strum(parse_err_ty = BackboneError, parse_err_fn = unknown::<Self>)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum DensifyPolicy {
    /// 3DGS adaptive density control.
    #[serde(rename = "standard")]
    #[strum(serialize = "standard")]
    Standard,
    /// ADC gated by EvoGS's uncertainty-aware trigger.
    #[serde(rename = "trigger")]
    #[strum(serialize = "trigger")]
    Trigger,
    /// The trigger plus deformation-aware clone/split (α = 0.5), EvoGS's full policy.
    #[serde(rename = "trigger+deform")]
    #[strum(serialize = "trigger+deform")]
    TriggerDeform,
}

impl OneWord for DensifyPolicy {
    const FIELD: &'static str = "densify";
    const NOUN: &'static str = "value";
    const ONE_OF: bool = true;
}

/// EvoGS's settings: evo-state's configuration, the densification policy and Φ's shape.
///
/// Recorded in `config.json` as one flat object: evo-state's [`EvoConfig`] (its own `serde`
/// spelling: `evolution`, `gain`, `history`, `buffer`, `components`, `motion_floor`, `lambda_sup`,
/// `lambda_prior`), then the fields below. Fields a file predates read as what its run trained
/// with: `evolution` on and `motion_floor` 1e-6 (evo-state's defaults), `grid_lr_scale` 1 and
/// `psi_lr` none (see those fields).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EvoSettings {
    /// evo-state's configuration, the one source of the evolution's settings: `evolution`
    /// (`false` runs Φ alone, the ablation "Φ without evolution": d̃ = z, no buffer, no Ψ, EvoGS
    /// losses zero), `gain` (`--gain`), `history` (`--history`), `storage` (`--buffer`), `layout`
    /// (`--components`), `motion_floor` (`--motion-floor`: below this speed per frame spacing,
    /// relative to the scene extent, a Gaussian counts as still and its θ is 0; see
    /// [`TRAINER_MOTION_FLOOR`]), λ1 `lambda_sup` and λ2 `lambda_prior` (0.5 each). Its `extent`
    /// is the scene's: the backbone sets it when it sizes the state
    /// ([`crate::PerGaussianState::prepare`]); it is not recorded.
    #[serde(flatten)]
    pub evo: EvoConfig,
    /// `--densify`.
    pub densify: DensifyPolicy,
    /// `--net-precision`: storage of Φ's parameters and activations.
    pub net_precision: Precision,
    /// Φ's tri-plane channels per plane.
    pub triplane_channels: usize,
    /// Φ's tri-plane resolutions.
    pub triplane_resolutions: Vec<usize>,
    /// `--triplane-combine`: how Φ's three planes of a resolution are combined: `concat`
    /// (3C features) or `product` (their element-wise product, C features: K-Planes' and
    /// 4DGaussians' HexPlane combination, which localises a feature in all three axes).
    /// Absent in older `config.json` files: `concat`, which those runs were trained with.
    #[serde(default = "concat")]
    pub triplane_combine: PlaneCombine,
    /// Φ's B-spline control vectors (M >= 4).
    pub bspline_controls: usize,
    /// Width of each B-spline control vector.
    pub bspline_width: usize,
    /// Hidden layers of Φ's decoder (its width is half the baseline network's width).
    pub hidden_layers: usize,
    /// `--grid-lr-scale`: factor on the network lr for Φ's tri-plane features and B-spline
    /// controls (the decoder MLP and Ψ keep the network lr); default [`TRAINER_GRID_LR_SCALE`].
    /// Absent in older `config.json` files: 1, which those runs were trained with.
    #[serde(default = "unit_scale")]
    pub grid_lr_scale: f32,
    /// `--psi-lr`: Ψ's own constant learning rate (DESIGN §4.9), default [`TRAINER_PSI_LR`].
    /// Absent (`null`) in older `config.json` files: Ψ then trained at the deformation network's
    /// decaying schedule, which those runs keep.
    #[serde(default)]
    pub psi_lr: Option<f32>,
}

/// Φ's grid and spline train at 10× the deformation-network lr (D-3DGS's 8e-4 → 1.6e-6): the
/// convention of grid-based deformation fields (4DGaussians' HexPlane: grid lr 1.6e-3 against
/// 1.6e-4 for its MLP; Grid4D likewise 5 against 0.5). At 1× Φ barely moves: its output layer
/// starts at zero and its features at ±0.1, so over a 3 000-iteration run each parameter can move
/// by about 0.4 in total and the deformation stays near 0.01 scene units (measured with
/// `evogs export` on `evogs synth --preset wave`: median displacement between t = 0.25 and 0.75
/// of 0.0007, against the wave's 0.09 amplitude). At 10× the same training run moves 0.063 and
/// its training-view PSNR goes from 25.3 to 30.4 dB (training views only; see
/// `results/evogs-vs-baseline/README.md`).
pub const TRAINER_GRID_LR_SCALE: f32 = 10.0;

/// Ψ's learning rate (constant, Adam; DESIGN §4.9). Provisional: 1e-3 is Adam's usual rate for a
/// small MLP, not yet chosen by a sweep on training views.
pub const TRAINER_PSI_LR: f32 = 1e-3;

/// The most channels per plane of Φ's tri-plane (8 by default; 16 the most any result used).
/// With [`MAX_TRIPLANE_LEVELS`] levels of [`MAX_TRIPLANE_RESOLUTION`]² this bounds the planes
/// at 8 × 3 × 1024² × 128 f32 = 12.9 GB: the bounds stop absurd values (2^31 overflowed an
/// allocation size), the memory estimate (`--memory-limit`) the merely large ones.
pub const MAX_TRIPLANE_CHANNELS: usize = 128;
/// The most tri-plane resolutions (2 by default).
pub const MAX_TRIPLANE_LEVELS: usize = 8;
/// The largest tri-plane resolution (64 by default; 128 the largest any result used).
pub const MAX_TRIPLANE_RESOLUTION: usize = 1024;
/// The most B-spline control vectors (16 by default; 48 the most any result used).
pub const MAX_BSPLINE_CONTROLS: usize = 1024;
/// The longest B-spline control vector (8 by default; 32 the longest any result used).
pub const MAX_BSPLINE_WIDTH: usize = 256;
/// The most hidden layers of Φ's decoder (2 by default).
pub const MAX_HIDDEN_LAYERS: usize = 16;

/// serde's default of [`EvoSettings::triplane_combine`].
fn concat() -> PlaneCombine {
    PlaneCombine::Concat
}

/// serde's default of [`EvoSettings::grid_lr_scale`].
fn unit_scale() -> f32 {
    1.0
}

/// The trainer's motion floor: 1e-3 of the scene extent per frame spacing, a deliberate
/// deviation from the paper's 1e-6 (DESIGN §4.7; evo-state keeps 1e-6, the trainer sets its own).
///
/// Why: θ is the angle between two consecutive velocities of a Gaussian's evolved position. For
/// a Gaussian that does not move, those velocities are optimisation noise (Φ's output changing
/// between the iterations that wrote the buffer's frames), and the angle between two noise
/// vectors averages π/2 or more, so with a floor of 1e-6 the trigger (τ_θ = π/3) blocked almost
/// every densification. Measured with `evogs train --motion-report` on the training views of
/// `evogs synth --preset jump --size 64 --frames 24` (preset tiny): during the densification
/// window every decade of speed below 1e-3·extent per frame spacing had a mean θ of 1.5–1.9 rad
/// (noise), while the scenes' genuine motions are faster: the jump's satellite moves 3.6e-3 and
/// the wave's body up to 5e-3 of the extent per frame spacing at 24 frames. In pixels (fx /
/// distance of the training cameras), 1e-3·extent per frame spacing is 0.14 px on the synthetic
/// scenes at 64×64, 0.28 px at 128×128, and 0.67 px on D-NeRF lego at 400×400: below the floor a
/// Gaussian moves less than a pixel between consecutive frames, i.e. it is visibly still, and
/// the direction of its motion is not observable from the images. Selectable with
/// `--motion-floor`, recorded in `config.json`.
pub const TRAINER_MOTION_FLOOR: f32 = 1e-3;

impl Default for EvoSettings {
    /// The method: evo-state's defaults (learned gain, buffer history, f32 storage, position +
    /// rotation + scale, λ1 = λ2 = 0.5) with the trainer's motion floor; trigger +
    /// deformation-aware densification; Φ with 8 channels at resolutions 32 and 64 (concatenated),
    /// 16 control vectors of width 8 and 2 hidden layers; the trainer's motion floor and grid lr
    /// scale.
    fn default() -> Self {
        Self {
            evo: EvoConfig {
                motion_floor: TRAINER_MOTION_FLOOR,
                ..EvoConfig::default()
            },
            densify: DensifyPolicy::TriggerDeform,
            net_precision: Precision::F32,
            triplane_channels: 8,
            triplane_resolutions: vec![32, 64],
            triplane_combine: PlaneCombine::Concat,
            bspline_controls: 16,
            bspline_width: 8,
            hidden_layers: 2,
            grid_lr_scale: TRAINER_GRID_LR_SCALE,
            psi_lr: Some(TRAINER_PSI_LR),
        }
    }
}

impl EvoSettings {
    /// Checks the settings a training run with `--method evogs` needs.
    pub fn validate(&self) -> Result<(), BackboneError> {
        let e = &self.evo;
        let c = e.layout;
        if !(c.position || c.rotation || c.scale || c.opacity || c.colour) {
            return Err(BackboneError::config(
                "evogs.components",
                "at least one component is needed",
            ));
        }
        if let Gain::Fixed(k) = e.gain
            && !(0.0..=1.0).contains(&k)
        {
            return Err(BackboneError::config(
                "evogs.gain",
                format!("{k}: must lie in [0, 1]"),
            ));
        }
        // Upper bounds: a size read from a file must not reach an allocator unchecked (a
        // `config.json` with `triplane_channels = 65536` allocated 1.1 GB before dying).
        for (field, value, max) in [
            (
                "evogs.triplane_channels",
                self.triplane_channels,
                MAX_TRIPLANE_CHANNELS,
            ),
            (
                "evogs.triplane_resolutions",
                self.triplane_resolutions.len(),
                MAX_TRIPLANE_LEVELS,
            ),
            (
                "evogs.triplane_resolutions",
                self.triplane_resolutions.iter().copied().max().unwrap_or(0),
                MAX_TRIPLANE_RESOLUTION,
            ),
            (
                "evogs.bspline_controls",
                self.bspline_controls,
                MAX_BSPLINE_CONTROLS,
            ),
            ("evogs.bspline_width", self.bspline_width, MAX_BSPLINE_WIDTH),
            ("evogs.hidden_layers", self.hidden_layers, MAX_HIDDEN_LAYERS),
        ] {
            if value > max {
                return Err(BackboneError::config(
                    field,
                    format!("{value}: must be at most {max}"),
                ));
            }
        }
        if self.triplane_channels == 0 || self.triplane_resolutions.is_empty() {
            return Err(BackboneError::config(
                "evogs.triplane",
                "needs at least one channel and one resolution",
            ));
        }
        if self.triplane_resolutions.iter().any(|&r| r < 2) {
            return Err(BackboneError::config(
                "evogs.triplane_resolutions",
                "every resolution must be at least 2",
            ));
        }
        if self.bspline_controls < 4 || self.bspline_width == 0 {
            return Err(BackboneError::config(
                "evogs.bspline",
                "needs at least 4 control vectors of width at least 1",
            ));
        }
        if !(e.motion_floor.is_finite() && e.motion_floor >= 0.0) {
            return Err(BackboneError::config(
                "evogs.motion_floor",
                format!("{}: must be finite and non-negative", e.motion_floor),
            ));
        }
        if !(self.grid_lr_scale.is_finite() && self.grid_lr_scale > 0.0) {
            return Err(BackboneError::config(
                "evogs.grid_lr_scale",
                format!("{}: must be finite and positive", self.grid_lr_scale),
            ));
        }
        if let Some(lr) = self.psi_lr
            && !(lr.is_finite() && lr >= 0.0)
        {
            return Err(BackboneError::config(
                "evogs.psi_lr",
                format!("{lr}: must be finite and non-negative"),
            ));
        }
        for (field, v) in [
            ("evogs.lambda_sup", e.lambda_sup),
            ("evogs.lambda_prior", e.lambda_prior),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(BackboneError::config(
                    field,
                    "must be finite and non-negative",
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The settings as `config.json` holds them.
    fn json(s: &EvoSettings) -> serde_json::Map<String, serde_json::Value> {
        match serde_json::to_value(s).unwrap() {
            serde_json::Value::Object(m) => m,
            other => panic!("not an object: {other}"),
        }
    }

    #[test]
    fn evo_states_config_is_written_flat_with_the_files_names() {
        let s = EvoSettings::default();
        // Today's format: evo-state's recorded fields, then the trainer's, in this order. The
        // scene extent and evo-state's constants at their defaults are not written.
        let text = serde_json::to_string(&s).unwrap();
        let at = |key: &str| text.find(&format!("\"{key}\":"));
        let keys = [
            "evolution",
            "gain",
            "history",
            "buffer",
            "components",
            "motion_floor",
            "lambda_sup",
            "lambda_prior",
            "densify",
            "net_precision",
            "triplane_channels",
            "triplane_resolutions",
            "triplane_combine",
            "bspline_controls",
            "bspline_width",
            "hidden_layers",
            "grid_lr_scale",
            "psi_lr",
        ];
        let places: Vec<usize> = keys
            .iter()
            .map(|k| at(k).unwrap_or_else(|| panic!("{k} missing in {text}")))
            .collect();
        assert!(places.is_sorted(), "{text}");
        assert_eq!(json(&s).len(), keys.len(), "{text}");
        for k in ["extent", "beta", "max_gap"] {
            assert_eq!(at(k), None, "{text}");
        }
        let back: EvoSettings = serde_json::from_value(serde_json::to_value(&s).unwrap()).unwrap();
        assert_eq!(back, s);
        // A changed constant is written and read back.
        let mut other = EvoSettings::default();
        other.evo.beta = 0.5;
        other.evo.max_gap = 4;
        let m = json(&other);
        assert_eq!(m["beta"], serde_json::json!(0.5));
        assert_eq!(m["max_gap"], serde_json::json!(4));
        let back: EvoSettings = serde_json::from_value(serde_json::Value::Object(m)).unwrap();
        assert_eq!(back, other);
    }

    #[test]
    fn the_extent_is_the_scenes_not_the_files() {
        let mut s = EvoSettings::default();
        s.evo.extent = 7.0;
        let mut m = json(&s);
        assert!(!m.contains_key("extent"));
        m.insert("extent".into(), serde_json::json!(7.0));
        let back: EvoSettings = serde_json::from_value(serde_json::Value::Object(m)).unwrap();
        assert_eq!(back.evo.extent, EvoConfig::default().extent);
    }

    #[test]
    fn fields_older_files_lack_read_as_those_runs_trained_with() {
        let mut m = json(&EvoSettings::default());
        for key in ["evolution", "motion_floor", "grid_lr_scale", "psi_lr"] {
            m.remove(key).unwrap();
        }
        let old: EvoSettings = serde_json::from_value(serde_json::Value::Object(m)).unwrap();
        assert!(old.evo.evolution);
        assert_eq!(
            old.evo.motion_floor, 1e-6,
            "evo-state's (the paper's) floor"
        );
        assert_eq!(old.grid_lr_scale, 1.0);
        assert_eq!(old.psi_lr, None);
        let paper = EvoConfig::default();
        assert_eq!((old.evo.beta, old.evo.max_gap), (paper.beta, paper.max_gap));
        // Evolution off survives the round trip.
        let mut off = EvoSettings::default();
        off.evo.evolution = false;
        let back: EvoSettings =
            serde_json::from_value(serde_json::to_value(&off).unwrap()).unwrap();
        assert!(!back.evo.evolution);
    }

    #[test]
    fn a_fixed_gain_and_every_switch_round_trip() {
        let mut s = EvoSettings::default();
        s.evo.gain = Gain::Fixed(0.5);
        s.evo.history = HistoryMode::Requery;
        s.evo.storage = Storage::F16;
        s.evo.layout = "pos,rot,scale,opacity,colour".parse().unwrap();
        s.densify = DensifyPolicy::Trigger;
        s.net_precision = Precision::F16;
        let m = json(&s);
        assert_eq!(m["gain"], serde_json::json!({"fixed": 0.5}));
        assert_eq!(m["buffer"], serde_json::json!("f16"));
        let back: EvoSettings = serde_json::from_value(serde_json::Value::Object(m)).unwrap();
        assert_eq!(back, s);
    }
}

#[cfg(test)]
mod bounds {
    use super::*;

    /// Every size has an upper bound, named with the value and the bound; the bound itself is
    /// accepted.
    #[test]
    fn sizes_above_their_bound_are_refused_naming_the_field() {
        type Set = fn(&mut EvoSettings, usize);
        let cases: [(&str, usize, Set); 6] = [
            ("evogs.triplane_channels", MAX_TRIPLANE_CHANNELS, |s, v| {
                s.triplane_channels = v;
            }),
            (
                "evogs.triplane_resolutions",
                MAX_TRIPLANE_RESOLUTION,
                |s, v| {
                    s.triplane_resolutions = vec![32, v];
                },
            ),
            ("evogs.triplane_resolutions", MAX_TRIPLANE_LEVELS, |s, v| {
                s.triplane_resolutions = vec![16; v];
            }),
            ("evogs.bspline_controls", MAX_BSPLINE_CONTROLS, |s, v| {
                s.bspline_controls = v;
            }),
            ("evogs.bspline_width", MAX_BSPLINE_WIDTH, |s, v| {
                s.bspline_width = v;
            }),
            ("evogs.hidden_layers", MAX_HIDDEN_LAYERS, |s, v| {
                s.hidden_layers = v;
            }),
        ];
        for (field, max, set) in cases {
            let mut s = EvoSettings::default();
            set(&mut s, max);
            assert!(s.validate().is_ok(), "{field} = {max}");
            // 2^31 overflowed allocation sizes; the level count is a vector's length, so it is
            // checked just above its bound only (a vector of 2^31 levels is 16 GB itself).
            let huge = if max == MAX_TRIPLANE_LEVELS {
                max + 2
            } else {
                1 << 31
            };
            for value in [max + 1, huge] {
                let mut s = EvoSettings::default();
                set(&mut s, value);
                let e = s.validate().unwrap_err().to_string();
                assert!(
                    e.contains(field) && e.contains(&format!("{value}: must be at most {max}")),
                    "{e}"
                );
            }
        }
    }
}
