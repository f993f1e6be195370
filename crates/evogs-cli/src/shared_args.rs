//! Flags several subcommands share, each declared once and flattened where it is used: the
//! rasterizer backend ([`RasterArgs`]), a time budget ([`BudgetArgs`]), the deformation backbone
//! with SC-GS's settings ([`BackboneArgs`]), the rule for frame times ([`TimeFromArg`]), the help
//! of a flag whose default is the preset's ([`by_preset`]), and the parsers of values the
//! libraries do not parse themselves. The
//! subcommands' own flags are in their modules (`train_cmd`, `eval_cmd`, …); this module imports
//! none of them.

use clap::Args;
use clap::ValueEnum;
use clap::builder::PossibleValue;
use evogs_io::TimeFrom;
use splat_raster::BackendChoice;

/// A time rule as a command-line value; names and help come from the library.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TimeFromArg(pub TimeFrom);

/// Every rule, as [`TimeFrom::ALL`] lists them.
const TIME_FROM_ARGS: [TimeFromArg; TimeFrom::ALL.len()] = {
    let mut args = [TimeFromArg(TimeFrom::ALL[0]); TimeFrom::ALL.len()];
    let mut i = 1;
    while i < args.len() {
        args[i] = TimeFromArg(TimeFrom::ALL[i]);
        i += 1;
    }
    args
};

impl ValueEnum for TimeFromArg {
    fn value_variants<'a>() -> &'a [Self] {
        &TIME_FROM_ARGS
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        Some(PossibleValue::new(self.0.name()).help(self.0.help()))
    }
}

/// `--backend` of the commands that render a trained run or a scene (`evogs train` has its own:
/// there it is optional, since `--resume` keeps the run's).
#[derive(Clone, Copy, Debug, Args)]
pub struct RasterArgs {
    /// Rasterizer backend: cpu, wgpu (any adapter; an error without one) or auto (wgpu on a
    /// hardware GPU, cpu otherwise).
    #[arg(
        long,
        value_name = "cpu|wgpu|auto",
        default_value_t = BackendChoice::default(),
        value_parser = parse_backend
    )]
    pub backend: BackendChoice,
}

/// A time budget on the command line (`evogs train`, `bench`, `ablate`).
#[derive(Debug, Args)]
pub struct BudgetArgs {
    /// Train for this much time instead of a number of iterations (180s, 3m, 2m30s, 1h): the
    /// schedule (warm-up, SH steps, lr decays, densification, opacity resets) is the preset's,
    /// or --iterations', mapped onto the share of the budget spent, so it ends when the budget
    /// is spent. Counts the training loop, not the loading or evaluations; recorded in
    /// config.json and train_metrics.json with the iterations reached [default: no budget].
    #[arg(long, value_name = "DURATION", value_parser = parse_time_budget, allow_hyphen_values = true)]
    pub time_budget: Option<f64>,

    /// The clock --time-budget is measured on: cpu (the process's CPU time, all threads summed:
    /// fair on a machine shared with other jobs; with T threads a budget lasts about 1/T of it
    /// in wall time) or wall (wall-clock time) [default: `BudgetClock::default()`].
    #[arg(
        long,
        value_parser = evogs_backbones::cli::words::<evogs_train::budget::BudgetClock>(),
        requires = "time_budget",
        help = format!(
            "The clock --time-budget is measured on: cpu (the process's CPU time, all threads \
             summed: fair on a machine shared with other jobs; with T threads a budget lasts \
             about 1/T of it in wall time) or wall (wall-clock time) [default: {}]",
            evogs_train::budget::BudgetClock::default()
        )
    )]
    pub budget_clock: Option<evogs_train::budget::BudgetClock>,
}

impl BudgetArgs {
    /// The budget the flags ask for.
    pub fn budget(&self) -> Option<evogs_train::budget::TimeBudget> {
        self.time_budget
            .map(|seconds| evogs_train::budget::TimeBudget {
                seconds,
                clock: self.budget_clock.unwrap_or_default(),
            })
    }
}

/// `--time-budget`: a duration ([`evogs_train::budget::parse_duration`]).
fn parse_time_budget(text: &str) -> Result<f64, String> {
    evogs_train::budget::parse_duration(text)
}

/// The value parser of a whole-number flag in `min..=max`: any other text (a negative number,
/// a fraction, a word) is refused naming the flag and the range ("invalid value '-5' for
/// '--iterations <N>': expected a whole number >= 1"), where clap's own unsigned parsers said
/// "invalid digit found in string" or "not in 1..18446744073709551615".
#[derive(Clone, Copy, Debug)]
pub struct Whole<T> {
    min: u64,
    max: u64,
    _as: std::marker::PhantomData<fn() -> T>,
}

/// [`Whole`] from `min`, unbounded above (`u64::MAX`, or the type's own bound).
pub fn whole<T>(min: u64) -> Whole<T> {
    Whole {
        min,
        max: u64::MAX,
        _as: std::marker::PhantomData,
    }
}

impl<T> Whole<T> {
    /// The same with `max` as the largest value.
    #[must_use]
    pub fn to(self, max: u64) -> Self {
        Self { max, ..self }
    }
}

impl<T> clap::builder::TypedValueParser for Whole<T>
where
    T: TryFrom<u64> + Clone + Send + Sync + 'static,
{
    type Value = T;

    fn parse_ref(
        &self,
        cmd: &clap::Command,
        arg: Option<&clap::Arg>,
        value: &std::ffi::OsStr,
    ) -> Result<T, clap::Error> {
        let text = value.to_string_lossy();
        let range = if self.max == u64::MAX {
            format!(">= {}", self.min)
        } else {
            format!("in {}..={}", self.min, self.max)
        };
        text.trim()
            .parse::<u64>()
            .ok()
            .filter(|v| (self.min..=self.max).contains(v))
            .and_then(|v| T::try_from(v).ok())
            .ok_or_else(|| {
                let flag = arg.map_or_else(|| "the value".to_string(), ToString::to_string);
                clap::Error::raw(
                    clap::error::ErrorKind::ValueValidation,
                    format!(
                        "invalid value '{text}' for '{flag}': expected a whole number {range}\n"
                    ),
                )
                .with_cmd(cmd)
            })
    }
}

/// Parses `cpu`, `wgpu` or `auto`.
pub fn parse_backend(text: &str) -> Result<BackendChoice, String> {
    text.parse()
        .map_err(|e: splat_raster::RasterError| e.to_string())
}

/// Parses `R,G,B` with each channel a number in [0, 1].
pub fn parse_background(text: &str) -> Result<[f32; 3], String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!(
            "expected three comma-separated numbers R,G,B, found {} part(s)",
            parts.len()
        ));
    }
    let mut colour = [0f32; 3];
    for (channel, (slot, part)) in colour.iter_mut().zip(&parts).enumerate() {
        let value: f32 = part
            .parse()
            .map_err(|_| format!("channel {channel} `{part}` is not a number"))?;
        if !(0.0..=1.0).contains(&value) {
            return Err(format!("channel {channel} is {value}, outside [0, 1]"));
        }
        *slot = value;
    }
    Ok(colour)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn background_parsing() {
        assert_eq!(parse_background("0,0.5, 1").unwrap(), [0.0, 0.5, 1.0]);
        assert!(parse_background("1,1").unwrap_err().contains("three"));
        assert!(parse_background("1,x,1").unwrap_err().contains("channel 1"));
        assert!(parse_background("1,1,1.5").unwrap_err().contains("outside"));
        assert!(parse_background("NaN,0,0").unwrap_err().contains("outside"));
    }
}

/// `text` and the value `value` reads from each preset's settings, in `Preset::ALL`'s order
/// ("[preset: paper 256; cpu 64; tiny 32; dnerf 64; scgs 64]"): the help of a flag whose default
/// is the preset's comes from the presets.
pub fn by_preset<T: std::fmt::Display>(
    text: &str,
    value: impl Fn(&evogs_train::TrainConfig) -> T,
) -> String {
    let values: Vec<String> = evogs_train::Preset::ALL
        .iter()
        .map(|&p| format!("{p} {}", value(&evogs_train::TrainConfig::preset(p))))
        .collect();
    format!("{text} [preset: {}]", values.join("; "))
}

/// The deformation backbone and SC-GS's settings, flattened into `evogs train`, `ablate` and
/// `bench`: the backbone and the control points' network width default to the preset's (the
/// `scgs` preset's are `scgs` and 64), SC-GS's other settings to
/// [`evogs_backbones::ScgsSettings::default`]'s.
#[derive(Clone, Debug, Args)]
pub struct BackboneArgs {
    /// Deformation backbone.
    #[arg(
        long,
        value_parser = evogs_backbones::cli::words::<evogs_train::BackboneKind>(),
        help = by_preset(
            "Deformation backbone: d3dgs (Deformable-3D-Gaussians' MLP), 4dgs (4DGaussians' \
             HexPlane field with its regularisers), grid4d (Grid4D's 4D decomposed hash grids \
             with directional attention) or scgs (SC-GS's sparse control points: a network on a \
             few hundred points, each Gaussian skinned by its nearest ones). With --method evogs, \
             d3dgs's Φ is the tri-plane network, 4dgs's and grid4d's fields become Φ at half \
             their width, scgs's skinning becomes Φ as it is",
            |c| c.backbone,
        )
    )]
    pub backbone: Option<evogs_train::BackboneKind>,

    /// SC-GS: hidden width of the control points' network.
    #[arg(
        long,
        value_name = "W",
        allow_negative_numbers = true,
        value_parser = whole::<usize>(1),
        help = by_preset("SC-GS: hidden width of the control points' network", |c| c.backbones.scgs.width)
    )]
    pub control_width: Option<usize>,

    /// SC-GS's other settings.
    #[command(flatten)]
    pub scgs: evogs_backbones::cli::ScgsArgs,
}

impl BackboneArgs {
    /// Writes the flags given into `config` (made from its preset).
    pub fn apply(&self, config: &mut evogs_train::TrainConfig) {
        if let Some(b) = self.backbone {
            config.backbone = b;
        }
        if let Some(w) = self.control_width {
            config.backbones.scgs.width = w;
        }
        self.scgs.apply(&mut config.backbones.scgs);
    }

    /// The flags that give these values back under `preset` (`evogs bench --jobs` hands them to
    /// its parts): SC-GS's only when the backbone is SC-GS.
    pub fn flags(&self, preset: evogs_train::Preset) -> Vec<String> {
        let mut config = evogs_train::TrainConfig::preset(preset);
        self.apply(&mut config);
        let mut f = Vec::new();
        if let Some(b) = self.backbone {
            f.extend(["--backbone".to_string(), b.to_string()]);
        }
        if config.backbone == evogs_train::BackboneKind::Scgs {
            if let Some(w) = self.control_width {
                f.extend(["--control-width".to_string(), w.to_string()]);
            }
            f.extend(self.scgs.flags());
        }
        f
    }
}
