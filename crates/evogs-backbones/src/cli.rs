//! EvoGS's and SC-GS's settings on the command line (cargo feature `clap`): one flag per switch
//! of [`EvoSettings`] ([`EvoArgs`]) and of [`ScgsSettings`] ([`ScgsArgs`]), flattened into
//! `evogs train`, each default read from the type's `Default`, so a default is written once and
//! the help shows it from there; and
//! the value parser of a setting spelled by one word ([`words`]), whose help lists the spellings
//! the type declares.
//!
//! What it is not: the trainer's flags (preset, iterations, …: the binary's), nor a second
//! parser: every value is read by its type's `FromStr`, with its own one-line message.

use std::ffi::OsStr;
use std::marker::PhantomData;
use std::str::FromStr;

use clap::builder::{PossibleValue, TypedValueParser};
use clap::{Arg, Args, Command};
use strum::VariantNames;

use crate::evo_settings::{
    DensifyPolicy, EvoSettings, Gain, HistoryMode, Layout, PlaneCombine, Precision, Storage,
};
use crate::scgs::{EvolutionOn, Placement, ScgsSettings};

/// The value parser of a setting spelled by one word: the type's `FromStr` (its message for an
/// unknown word, as clap reports any parse error), with the type's spellings
/// ([`VariantNames::VARIANTS`]) as the possible values the help lists.
pub struct Words<T>(PhantomData<fn() -> T>);

impl<T> Clone for Words<T> {
    fn clone(&self) -> Self {
        Self(PhantomData)
    }
}

/// [`Words`] of `T`.
pub fn words<T>() -> Words<T> {
    Words(PhantomData)
}

impl<T> TypedValueParser for Words<T>
where
    T: VariantNames + FromStr + Clone + Send + Sync + 'static,
    T::Err: Into<Box<dyn std::error::Error + Send + Sync>>,
{
    type Value = T;

    fn parse_ref(&self, cmd: &Command, arg: Option<&Arg>, value: &OsStr) -> Result<T, clap::Error> {
        let parse: fn(&str) -> Result<T, T::Err> = T::from_str;
        parse.parse_ref(cmd, arg, value)
    }

    fn possible_values(&self) -> Option<Box<dyn Iterator<Item = PossibleValue> + '_>> {
        Some(Box::new(
            T::VARIANTS.iter().copied().map(PossibleValue::new),
        ))
    }
}

/// The defaults every flag of [`EvoArgs`] shows and starts from.
fn defaults() -> EvoSettings {
    EvoSettings::default()
}

/// EvoGS's switches (`--method evogs`), each defaulting to [`EvoSettings::default`]'s value.
/// The presets share these defaults (`evogs-cli`'s test `presets_share_the_evogs_defaults`);
/// [`EvoArgs::apply`] writes every one into a run's settings.
#[derive(Clone, Debug, PartialEq, Args)]
pub struct EvoArgs {
    /// EvoGS gain K: learned (Ψ), or fixed at a number in [0, 1] (0 = prior only, 1 =
    /// observation only).
    #[arg(long, value_name = "learned|0|0.5|1", default_value_t = defaults().evo.gain)]
    pub gain: Gain,

    /// EvoGS history: from the buffer of corrected states, or re-queried from Φ ("without
    /// buffer").
    #[arg(long, value_parser = words::<HistoryMode>(), default_value_t = defaults().evo.history)]
    pub history: HistoryMode,

    /// EvoGS densification: standard 3DGS, + uncertainty trigger, + deformation-aware
    /// clone/split.
    #[arg(long, value_parser = words::<DensifyPolicy>(), default_value_t = defaults().densify)]
    pub densify: DensifyPolicy,

    /// EvoGS buffer storage.
    #[arg(long, value_parser = words::<Storage>(), default_value_t = defaults().evo.storage)]
    pub buffer: Storage,

    /// EvoGS Φ storage precision.
    #[arg(long, value_parser = words::<Precision>(), default_value_t = defaults().net_precision)]
    pub net_precision: Precision,

    /// EvoGS deformation components, comma-separated; opacity adds to the opacity logit, colour
    /// to the SH DC (EvoGS only; the baseline refuses them).
    #[arg(
        long,
        value_name = "pos,rot,scale[,opacity,colour]",
        default_value_t = defaults().evo.layout
    )]
    pub components: Layout,

    /// EvoGS motion floor: below this speed per frame spacing, as a fraction of the scene
    /// extent, a Gaussian counts as still and its angular deviation θ is 0 (the default is the trainer's; the
    /// paper's 1e-6 is far below the noise, see docs/DESIGN.md §4.7).
    #[arg(
        long,
        value_name = "F",
        allow_negative_numbers = true,
        default_value_t = defaults().evo.motion_floor
    )]
    pub motion_floor: f32,

    /// EvoGS: factor on the network learning rate for Φ's tri-plane features and B-spline
    /// controls (as grid-based deformation fields, 4DGaussians, train their grids).
    #[arg(long, value_name = "S", default_value_t = defaults().grid_lr_scale)]
    pub grid_lr_scale: f32,

    /// EvoGS: Ψ's own learning rate (constant, Adam; provisional; recorded in config.json).
    #[arg(
        long,
        value_name = "LR",
        default_value_t = defaults().psi_lr.expect("EvoGS's defaults set Ψ's rate")
    )]
    pub psi_lr: f32,

    /// EvoGS: Φ's B-spline control vectors over the frames' time span (at least 4; more let the
    /// deformation change faster in time).
    #[arg(long, value_name = "M", default_value_t = defaults().bspline_controls)]
    pub bspline_controls: usize,

    /// EvoGS: Φ's time features, the length of each B-spline control vector (at least 1; more
    /// give the decoder more independent curves over time).
    #[arg(long, value_name = "W", default_value_t = defaults().bspline_width)]
    pub bspline_width: usize,

    /// EvoGS: Φ's tri-plane resolutions, comma-separated (their features are concatenated).
    #[arg(
        long,
        value_name = "R,R",
        value_delimiter = ',',
        default_values_t = defaults().triplane_resolutions
    )]
    pub triplane_resolutions: Vec<usize>,

    /// EvoGS: how Φ's three planes of a resolution are combined: concat (3C features) or product
    /// (C features, each localised in all three axes: K-Planes, 4DGaussians).
    #[arg(
        long,
        value_parser = words::<PlaneCombine>(),
        default_value_t = defaults().triplane_combine
    )]
    pub triplane_combine: PlaneCombine,

    /// EvoGS: Φ's tri-plane channels per plane.
    #[arg(long, value_name = "C", default_value_t = defaults().triplane_channels)]
    pub triplane_channels: usize,
}

impl EvoArgs {
    /// Writes every switch into `settings` (the others, `evolution`, λ1, λ2, Φ's hidden layers,
    /// are left as they are).
    pub fn apply(&self, settings: &mut EvoSettings) {
        let e = settings;
        e.evo.gain = self.gain;
        e.evo.history = self.history;
        e.densify = self.densify;
        e.evo.storage = self.buffer;
        e.net_precision = self.net_precision;
        e.evo.layout = self.components;
        e.evo.motion_floor = self.motion_floor;
        e.grid_lr_scale = self.grid_lr_scale;
        e.psi_lr = Some(self.psi_lr);
        e.bspline_controls = self.bspline_controls;
        e.bspline_width = self.bspline_width;
        e.triplane_resolutions
            .clone_from(&self.triplane_resolutions);
        e.triplane_combine = self.triplane_combine;
        e.triplane_channels = self.triplane_channels;
    }
}

/// The defaults every flag of [`ScgsArgs`] shows and starts from.
fn scgs_defaults() -> ScgsSettings {
    ScgsSettings::default()
}

/// SC-GS's settings (`--backbone scgs`), each defaulting to [`ScgsSettings::default`]'s value
/// (SC-GS's D-NeRF recipe); [`ScgsArgs::apply`] writes every one into a run's settings. The
/// network's width is not here: its default depends on the trainer's preset (`--control-width`
/// is the binary's flag).
#[derive(Clone, Debug, PartialEq, Args)]
pub struct ScgsArgs {
    /// SC-GS: control points that carry the motion.
    #[arg(long, value_name = "M", default_value_t = scgs_defaults().control_points)]
    pub control_points: usize,

    /// SC-GS: nearest control points that move each Gaussian (K).
    #[arg(long, value_name = "K", default_value_t = scgs_defaults().neighbours)]
    pub control_neighbours: usize,

    /// SC-GS: hidden layers of the control points' network.
    #[arg(long, value_name = "D", default_value_t = scgs_defaults().depth)]
    pub control_depth: usize,

    /// SC-GS: weight of the as-rigid-as-possible loss on the control points' trajectories
    /// (0 turns it off).
    #[arg(long, value_name = "W", default_value_t = scgs_defaults().arap_weight)]
    pub arap_weight: f32,

    /// SC-GS: factor on the network learning rate for the control points' positions (0 keeps
    /// them where they started, as SC-GS's code does).
    #[arg(long, value_name = "S", default_value_t = scgs_defaults().position_lr_scale)]
    pub control_position_lr_scale: f32,

    /// SC-GS: place the control points again on the Gaussians after every densification that
    /// changed them (each keeping the radius and weight of the old point nearest to it), instead
    /// of once when the deformation starts.
    #[arg(long, default_value_t = scgs_defaults().follow_densify)]
    pub control_follow_densify: bool,

    /// SC-GS: what `--control-follow-densify` spreads the control points over: the Gaussians'
    /// canonical positions, or their trajectories (positions at 16 times, SC-GS's way), which
    /// puts more control points where the motion differs.
    #[arg(long, value_parser = words::<Placement>(), default_value_t = scgs_defaults().placement)]
    pub control_placement: Placement,

    /// EvoGS(SC-GS): keep the evolution state on the control points (their translation,
    /// rotation and scale before the skinning) or on every Gaussian (the paper's wording).
    #[arg(long, value_parser = words::<EvolutionOn>(), default_value_t = scgs_defaults().evolution_on)]
    pub evolution_on: EvolutionOn,
}

impl ScgsArgs {
    /// Writes every flag into `settings` (the encodings' frequencies are left as they are).
    pub fn apply(&self, settings: &mut ScgsSettings) {
        settings.control_points = self.control_points;
        settings.neighbours = self.control_neighbours;
        settings.depth = self.control_depth;
        settings.arap_weight = self.arap_weight;
        settings.position_lr_scale = self.control_position_lr_scale;
        settings.follow_densify = self.control_follow_densify;
        settings.placement = self.control_placement;
        settings.evolution_on = self.evolution_on;
    }

    /// The flags that give these values back (`evogs bench --jobs` hands them to its parts).
    pub fn flags(&self) -> Vec<String> {
        [
            ("--control-points", self.control_points.to_string()),
            ("--control-neighbours", self.control_neighbours.to_string()),
            ("--control-depth", self.control_depth.to_string()),
            ("--arap-weight", self.arap_weight.to_string()),
            (
                "--control-position-lr-scale",
                self.control_position_lr_scale.to_string(),
            ),
            ("--evolution-on", self.evolution_on.to_string()),
            ("--control-placement", self.control_placement.to_string()),
        ]
        .into_iter()
        .flat_map(|(flag, value)| [flag.to_string(), value])
        .chain(
            self.control_follow_densify
                .then(|| "--control-follow-densify".to_string()),
        )
        .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        evo: EvoArgs,
        #[command(flatten)]
        scgs: ScgsArgs,
    }

    /// SC-GS's flags: none gives the defaults; each changes its field.
    #[test]
    fn scgs_flags_default_to_the_settings_and_change_their_field() {
        let mut settings = ScgsSettings {
            control_points: 3,
            ..ScgsSettings::default()
        };
        Cli::parse_from(["evogs"]).scgs.apply(&mut settings);
        assert_eq!(settings, ScgsSettings::default());
        Cli::parse_from(["evogs", "--control-points", "64", "--arap-weight", "0"])
            .scgs
            .apply(&mut settings);
        assert_eq!((settings.control_points, settings.arap_weight), (64, 0.0));
        // The flags written back parse to the same values.
        let cli = Cli::parse_from([
            "evogs",
            "--control-depth",
            "6",
            "--arap-weight",
            "2.5e-5",
            "--control-follow-densify",
            "--control-placement",
            "trajectories",
        ]);
        let mut again = vec!["evogs".to_string()];
        again.extend(cli.scgs.flags());
        assert_eq!(Cli::parse_from(again).scgs, cli.scgs);
    }

    /// No flag gives the defaults exactly (every default survives its trip through clap's
    /// text); flags change what they name.
    #[test]
    fn no_flag_applies_the_defaults_and_flags_change_their_field() {
        let mut settings = EvoSettings {
            psi_lr: None,
            bspline_controls: 99,
            ..EvoSettings::default()
        };
        Cli::parse_from(["evogs"]).evo.apply(&mut settings);
        assert_eq!(settings, EvoSettings::default());
        let cli = Cli::parse_from([
            "evogs",
            "--gain",
            "0.5",
            "--history",
            "requery",
            "--components",
            "pos,opacity",
            "--triplane-resolutions",
            "8,16,32",
            "--psi-lr",
            "2e-3",
        ]);
        cli.evo.apply(&mut settings);
        assert_eq!(settings.evo.gain, Gain::Fixed(0.5));
        assert_eq!(settings.evo.history, HistoryMode::Requery);
        assert_eq!(settings.evo.layout.to_string(), "pos,opacity");
        assert_eq!(settings.triplane_resolutions, [8, 16, 32]);
        assert_eq!(settings.psi_lr, Some(2e-3));
    }

    /// A word that spells no value is refused with the type's own message; the spellings are
    /// the type's.
    #[test]
    fn one_word_values_keep_their_message_and_list_their_spellings() {
        let e = Cli::try_parse_from(["evogs", "--densify", "sometimes"])
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("unknown"), "{e}");
        let names: Vec<String> = words::<DensifyPolicy>()
            .possible_values()
            .unwrap()
            .map(|p| p.get_name().to_string())
            .collect();
        assert_eq!(names, DensifyPolicy::VARIANTS);
    }
}
