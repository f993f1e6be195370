//! Configuration: which deformation components exist, how the buffer is stored, and the
//! ablation switches of DESIGN §4.12.
//!
//! The switches a user picks ([`Gain`], [`HistoryMode`], [`Storage`] (tiny-nn's `Precision`),
//! and splat-core's [`Layout`]) have one command-line spelling each ([`FromStr`] / [`fmt::Display`]) and, with the
//! `serde` feature, one file spelling (lowercase names; a fixed gain is `{"fixed": k}`), as does
//! the whole [`EvoConfig`]. The one-word enums derive theirs with `strum` (`EnumString`,
//! `Display`, `IntoStaticStr`, `VariantNames`); [`Gain`], which carries a number, and [`Layout`],
//! a set, spell themselves.

use std::fmt;
use std::str::FromStr;

use strum::{Display, EnumString, IntoStaticStr, VariantNames};
use thiserror::Error;

pub use splat_core::{Component, Layout};

/// Element type of the buffer of corrected states and of the residual memory: tiny-nn's
/// [`tiny_nn::Precision`], the one f32/f16 storage type of the workspace (spelled `f32` / `f16`),
/// named for its use here. `F32` takes 4·D bytes per Gaussian per frame, `F16` 2·D; in f16,
/// values beyond ±65504 saturate and are counted.
pub use tiny_nn::Precision as Storage;

/// How the gain K is chosen once three history frames exist (h = 3); spelled `learned` or the
/// fixed value (`0`, `0.5`, `1`).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(rename_all = "lowercase")
)]
pub enum Gain {
    /// K = Ψ(inputs), the EvoGS method.
    Learned,
    /// K fixed at a constant in [0, 1] (0 = prior only, 0.5, 1 = observation only). The warm-up
    /// (h <= 1: d̃ = z; h = 2: K = 0.5) is kept, "all other settings unchanged" as in the paper's
    /// ablation.
    Fixed(f32),
}

/// Where the history states come from (spelled `buffer` / `requery`).
#[derive(EnumString, Display, IntoStaticStr, VariantNames)]
#[strum(serialize_all = "lowercase", parse_err_ty = ParseError, parse_err_fn = ParseError::one_of::<Self>)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(rename_all = "lowercase")
)]
pub enum HistoryMode {
    /// The persistent buffer of corrected states (EvoGS).
    Buffer,
    /// Re-queried from the observation network at the history times ("without buffer"). No
    /// buffer is kept; every frame before the query counts as available.
    Requery,
}

/// A spelling of a [`Gain`] or [`HistoryMode`] that names none.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
#[error("`{value}`: expected {expected}")]
pub struct ParseError {
    /// The spelling given.
    pub value: String,
    /// What is accepted.
    pub expected: String,
}

impl ParseError {
    /// `value` names no variant of `T`: expected "one of" `T`'s spellings.
    fn one_of<T: VariantNames>(value: &str) -> Self {
        Self {
            value: value.to_string(),
            expected: format!("one of {}", T::VARIANTS.join(", ")),
        }
    }
}

impl FromStr for Gain {
    type Err = ParseError;

    /// `learned`, or a number in [0, 1].
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if s == "learned" {
            return Ok(Self::Learned);
        }
        match s.parse::<f32>() {
            Ok(k) if (0.0..=1.0).contains(&k) => Ok(Self::Fixed(k)),
            _ => Err(ParseError {
                value: s.to_string(),
                expected: "`learned` or a number in [0, 1] such as 0, 0.5 or 1".to_string(),
            }),
        }
    }
}

impl fmt::Display for Gain {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Learned => f.write_str("learned"),
            Self::Fixed(k) => write!(f, "{k}"),
        }
    }
}

/// Configuration of an [`crate::EvoState`].
///
/// With the `serde` feature it is written as one object in evogs's `config.json` (embedded in the
/// trainer's EvoGS settings): `layout` is spelled `components` and `storage` `buffer` there (the
/// trainer's `--components` and `--buffer`); `beta` and `max_gap` are written only where they
/// differ from their defaults; `extent` is not written (it is the scene's, set when the state is
/// built). A file that predates `evolution` or `motion_floor` reads them as their defaults here
/// (on, and 1e-6).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct EvoConfig {
    /// `false`: the baseline, d̃ = z, nothing stored, EvoGS losses zero.
    #[cfg_attr(feature = "serde", serde(default = "serde_defaults::evolution"))]
    pub evolution: bool,
    /// How K is chosen once three history frames exist (default: learned by Ψ).
    pub gain: Gain,
    /// Where the history states come from (default: the buffer).
    pub history: HistoryMode,
    /// Element type of the buffer of corrected states and of the residual memory.
    #[cfg_attr(feature = "serde", serde(rename = "buffer"))]
    pub storage: Storage,
    /// The deformation components a row of z, d̂ and d̃ holds; D = `layout.dim()`.
    #[cfg_attr(feature = "serde", serde(rename = "components"))]
    pub layout: Layout,
    /// Motion floor, relative to the scene extent (DESIGN §4.7: 1e-6 here, the trainer uses 1e-3): below it θ = 0.
    #[cfg_attr(feature = "serde", serde(default = "serde_defaults::motion_floor"))]
    pub motion_floor: f32,
    /// λ1, weight of L_sup (DESIGN §4.11: 0.5).
    pub lambda_sup: f32,
    /// λ2, weight of L_prior (DESIGN §4.11: 0.5).
    pub lambda_prior: f32,
    /// Residual memory momentum β (DESIGN §4.8: 0.9).
    #[cfg_attr(
        feature = "serde",
        serde(
            default = "serde_defaults::beta",
            skip_serializing_if = "serde_defaults::is_beta"
        )
    )]
    pub beta: f32,
    /// History frames must lie within this many frames of the one after them (DESIGN §4.3: 3).
    #[cfg_attr(
        feature = "serde",
        serde(
            default = "serde_defaults::max_gap",
            skip_serializing_if = "serde_defaults::is_max_gap"
        )
    )]
    pub max_gap: usize,
    /// Scene extent (scene units); Ψ's inputs in scene units are divided by it. Not recorded by
    /// `serde` (read back as the default, 1).
    #[cfg_attr(feature = "serde", serde(skip, default = "serde_defaults::extent"))]
    pub extent: f32,
}

impl Default for EvoConfig {
    fn default() -> Self {
        Self {
            evolution: true,
            gain: Gain::Learned,
            history: HistoryMode::Buffer,
            storage: Storage::F32,
            layout: Layout::default(),
            motion_floor: 1e-6,
            lambda_sup: 0.5,
            lambda_prior: 0.5,
            beta: 0.9,
            max_gap: 3,
            extent: 1.0,
        }
    }
}

/// serde's defaults and omissions: [`EvoConfig::default`]'s values.
#[cfg(feature = "serde")]
mod serde_defaults {
    use super::EvoConfig;

    pub(super) fn evolution() -> bool {
        EvoConfig::default().evolution
    }
    pub(super) fn motion_floor() -> f32 {
        EvoConfig::default().motion_floor
    }
    pub(super) fn beta() -> f32 {
        EvoConfig::default().beta
    }
    pub(super) fn is_beta(v: &f32) -> bool {
        v.to_bits() == beta().to_bits()
    }
    pub(super) fn max_gap() -> usize {
        EvoConfig::default().max_gap
    }
    pub(super) fn is_max_gap(v: &usize) -> bool {
        *v == max_gap()
    }
    pub(super) fn extent() -> f32 {
        EvoConfig::default().extent
    }
}

/// A configuration value out of its range.
#[derive(Debug, Error, Clone, PartialEq)]
#[error("evo-state config: field `{field}` = {value} {problem}")]
pub struct ConfigError {
    /// The field of [`EvoConfig`].
    pub field: &'static str,
    /// Its value, as written.
    pub value: String,
    /// What is wrong with it (e.g. `must be in [0, 1)`).
    pub problem: &'static str,
}

impl EvoConfig {
    /// Deformation dimension D.
    pub fn dim(&self) -> usize {
        self.layout.dim()
    }

    /// Bytes the buffer of corrected states takes for `rows` Gaussians over `frames` frames:
    /// exactly `rows · frames · D · (4 or 2)`, 0 when no buffer is kept (evolution off or
    /// history re-queried).
    pub fn buffer_bytes(&self, rows: usize, frames: usize) -> usize {
        if self.evolution && self.history == HistoryMode::Buffer {
            rows * frames * self.dim() * self.storage.bytes()
        } else {
            0
        }
    }

    /// Bytes the per-frame residual memory takes: `rows · frames · D · (4 or 2)` with evolution
    /// on (with either history mode), 0 with evolution off.
    pub fn memory_bytes(&self, rows: usize, frames: usize) -> usize {
        if self.evolution {
            rows * frames * self.dim() * self.storage.bytes()
        } else {
            0
        }
    }

    /// Checks every field.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let err = |field, value: String, problem| {
            Err(ConfigError {
                field,
                value,
                problem,
            })
        };
        if self.layout.dim() == 0 {
            return err(
                "layout",
                format!("{:?}", self.layout),
                "enables no component",
            );
        }
        if !(0.0..1.0).contains(&self.beta) {
            return err("beta", self.beta.to_string(), "must be in [0, 1)");
        }
        if self.max_gap == 0 {
            return err("max_gap", "0".into(), "must be at least 1");
        }
        if !(self.motion_floor.is_finite() && self.motion_floor >= 0.0) {
            return err(
                "motion_floor",
                self.motion_floor.to_string(),
                "must be finite and >= 0",
            );
        }
        if !(self.extent.is_finite() && self.extent > 0.0) {
            return err("extent", self.extent.to_string(), "must be finite and > 0");
        }
        if let Gain::Fixed(k) = self.gain
            && !(0.0..=1.0).contains(&k)
        {
            return err("gain", k.to_string(), "fixed gain must be in [0, 1]");
        }
        for (field, v) in [
            ("lambda_sup", self.lambda_sup),
            ("lambda_prior", self.lambda_prior),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return err(field, v.to_string(), "must be finite and >= 0");
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dim_is_the_sum_of_enabled_components() {
        assert_eq!(Layout::default().dim(), 10);
        let all = Layout {
            position: true,
            rotation: true,
            scale: true,
            opacity: true,
            colour: true,
        };
        assert_eq!(all.dim(), 14);
        assert_eq!(all.range(Component::Colour), Some(11..14));
        let only_opacity = Layout {
            opacity: true,
            ..Layout::from_bits(0).unwrap()
        };
        assert_eq!(only_opacity.dim(), 1);
        assert_eq!(only_opacity.range(Component::Position), None);
        for bits in 0..32u8 {
            assert_eq!(Layout::from_bits(bits).unwrap().bits(), bits);
        }
        assert_eq!(Layout::from_bits(32), None);
    }

    #[test]
    fn buffer_bytes_for_the_paper_setting() {
        // Neu3D: 150K Gaussians, 300 frames, D = 10.
        let f32_config = EvoConfig::default();
        assert_eq!(f32_config.buffer_bytes(150_000, 300), 1_800_000_000);
        let f16_config = EvoConfig {
            storage: Storage::F16,
            ..EvoConfig::default()
        };
        assert_eq!(f16_config.buffer_bytes(150_000, 300), 900_000_000);
        let requery = EvoConfig {
            history: HistoryMode::Requery,
            ..EvoConfig::default()
        };
        assert_eq!(requery.buffer_bytes(150_000, 300), 0);
        // The memory is kept per frame beside the buffer, in its storage, in both history modes.
        assert_eq!(f32_config.memory_bytes(150_000, 300), 1_800_000_000);
        assert_eq!(f16_config.memory_bytes(150_000, 300), 900_000_000);
        assert_eq!(requery.memory_bytes(150_000, 300), 1_800_000_000);
        let off = EvoConfig {
            evolution: false,
            ..EvoConfig::default()
        };
        assert_eq!(off.memory_bytes(150_000, 300), 0);
    }

    #[test]
    fn switches_parse_and_print() {
        assert_eq!("learned".parse::<Gain>().unwrap(), Gain::Learned);
        assert_eq!("0.5".parse::<Gain>().unwrap(), Gain::Fixed(0.5));
        assert_eq!(Gain::Fixed(0.0).to_string(), "0");
        assert_eq!(Gain::Fixed(1.0).to_string(), "1");
        for bad in ["1.5", "-0.1", "NaN", "psi"] {
            let e = bad.parse::<Gain>().unwrap_err().to_string();
            assert!(e.contains("`learned` or a number in [0, 1]"), "{e}");
        }
        for h in [HistoryMode::Buffer, HistoryMode::Requery] {
            assert_eq!(h.to_string().parse::<HistoryMode>().unwrap(), h);
        }
        for s in [Storage::F32, Storage::F16] {
            assert_eq!(s.to_string().parse::<Storage>().unwrap(), s);
        }
        assert_eq!(
            "bf16".parse::<Storage>().unwrap_err().to_string(),
            "unknown value `bf16`; expected one of f32, f16"
        );
        assert!("memory".parse::<HistoryMode>().is_err());
    }

    #[test]
    fn bad_fields_are_named() {
        let bad = EvoConfig {
            beta: 1.0,
            ..EvoConfig::default()
        };
        assert_eq!(bad.validate().unwrap_err().field, "beta");
        let bad = EvoConfig {
            gain: Gain::Fixed(1.5),
            ..EvoConfig::default()
        };
        assert_eq!(bad.validate().unwrap_err().field, "gain");
        let bad = EvoConfig {
            extent: 0.0,
            ..EvoConfig::default()
        };
        assert!(bad.validate().unwrap_err().to_string().contains("extent"));
        assert!(EvoConfig::default().validate().is_ok());
    }
}
