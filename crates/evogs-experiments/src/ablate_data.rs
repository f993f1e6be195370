//! The ablation ladder's data: a row ([`LadderRow`]: a name and the switches it sets), one
//! trained and evaluated run's [`Scores`], and a row's result over its seeds ([`AblationResult`]:
//! the mean scores, their sample standard deviations ([`Spread`]) and each [`SeedRun`]).
//!
//! What it is not: the ladder or its runner ([`ablate`](crate::ablate), which re-exports these
//! types) or the plot ([`ablate_plot`](crate::ablate_plot)). Both import this module, which
//! imports neither.

use std::path::PathBuf;

use evogs_backbones::EvoSettings;
use evogs_train::config::Method;
use serde::Serialize;

/// One row of the ladder: a name and the switches it sets.
#[derive(Clone, Debug, PartialEq)]
pub struct LadderRow {
    /// Short name (`--rows` spelling, run directory name).
    pub name: &'static str,
    /// What the row isolates.
    pub description: &'static str,
    /// Baseline or EvoGS.
    pub method: Method,
    /// EvoGS's switches (recorded, ignored by the baseline).
    pub evo: EvoSettings,
}

impl LadderRow {
    /// The switches as one line, e.g. `evogs evolution=on history=buffer densify=standard
    /// gain=learned net=f32 buffer=f32`; `baseline` for the baseline.
    pub fn switches(&self) -> String {
        match self.method {
            Method::Baseline => "baseline".to_string(),
            Method::Evogs => {
                let e = &self.evo;
                format!(
                    "evogs evolution={} history={} densify={} gain={} net={} buffer={}",
                    if e.evo.evolution { "on" } else { "off" },
                    e.evo.history,
                    e.densify,
                    e.evo.gain,
                    e.net_precision,
                    e.evo.storage
                )
            }
        }
    }
}

/// One trained and evaluated run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Scores {
    /// Mean test PSNR (dB).
    pub psnr: f64,
    /// Mean test SSIM.
    pub ssim: f64,
    /// Mean val PSNR (dB), when the dataset has a val split.
    pub val_psnr: Option<f64>,
    /// Mean val SSIM, when the dataset has a val split.
    pub val_ssim: Option<f64>,
    /// Mean test LPIPS (AlexNet), when its weights are installed.
    pub lpips_alex: Option<f64>,
    /// Mean val LPIPS (AlexNet), with a val split and the weights.
    pub val_lpips_alex: Option<f64>,
    /// Fixed-camera flicker (rendered) on the test split; NaN when not measurable.
    pub flicker: f64,
    /// Trajectory jitter on the test split; NaN when not measurable.
    pub jitter: f64,
    /// Training time (s).
    pub seconds: f64,
    /// Final Gaussian count.
    pub gaussians: usize,
    /// Bytes of the evolution state: buffer and per-frame residual memory (0 for the baseline
    /// and with evolution off; the memory alone with history re-queried).
    pub state_bytes: usize,
    /// Mean of the gain K over the last quarter's training steps (`train_metrics.json`'s
    /// `gain.all`); `None` without evolution.
    pub k_mean: Option<f64>,
    /// Standard deviation of K over those samples (Gaussians × steps): how much "learned K"
    /// varies inside one run.
    pub k_std: Option<f64>,
    /// Mean K of the moving Gaussians (both speeds at or above the motion floor).
    pub k_moving: Option<f64>,
    /// Mean K of the still Gaussians.
    pub k_still: Option<f64>,
}

/// One trained and evaluated run of a row.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SeedRun {
    /// The training seed.
    pub seed: u64,
    /// Its run directory.
    pub run: PathBuf,
    /// Its scores.
    #[serde(flatten)]
    pub scores: Scores,
}

/// Sample standard deviations over seeds of the [`Scores`] (n − 1 in the denominator).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Spread {
    /// Of the test PSNR (dB).
    pub psnr: f64,
    /// Of the test SSIM.
    pub ssim: f64,
    /// Of the val PSNR.
    pub val_psnr: Option<f64>,
    /// Of the val SSIM.
    pub val_ssim: Option<f64>,
    /// Of the test LPIPS (AlexNet).
    pub lpips_alex: Option<f64>,
    /// Of the val LPIPS (AlexNet).
    pub val_lpips_alex: Option<f64>,
    /// Of the flicker.
    pub flicker: f64,
    /// Of the jitter.
    pub jitter: f64,
    /// Of the training time (s).
    pub seconds: f64,
    /// Of the final Gaussian count.
    pub gaussians: f64,
    /// Of the run's mean K.
    pub k_mean: Option<f64>,
}

/// One row's result over its seeds.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AblationResult {
    /// The row's name.
    pub name: String,
    /// What it isolates.
    pub description: String,
    /// Its switches ([`LadderRow::switches`]).
    pub switches: String,
    /// Its run directory (of the first seed).
    pub run: PathBuf,
    /// Mean scores over the seeds (Gaussian count and state bytes rounded; an optional score
    /// only where every seed has it).
    #[serde(flatten)]
    pub scores: Scores,
    /// Sample standard deviation over the seeds; `None` with one seed.
    pub std: Option<Spread>,
    /// Each seed's run.
    pub seeds: Vec<SeedRun>,
}

fn mean(values: &[f64]) -> f64 {
    values.iter().sum::<f64>() / values.len() as f64
}

/// Sample standard deviation (n − 1); 0 for one value.
fn sample_std(values: &[f64]) -> f64 {
    if values.len() < 2 {
        return 0.0;
    }
    let m = mean(values);
    (values.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (values.len() - 1) as f64).sqrt()
}

/// The values of `field` over `runs`, when every run has one.
fn all_some(runs: &[SeedRun], field: impl Fn(&Scores) -> Option<f64>) -> Option<Vec<f64>> {
    runs.iter().map(|r| field(&r.scores)).collect()
}

/// The scores of [`Spread`] over `runs`, each folded by `fold` (the mean, or the sample standard
/// deviation); an optional score only where every run has it.
fn fold_scores(runs: &[SeedRun], fold: fn(&[f64]) -> f64) -> Spread {
    let all = |f: fn(&Scores) -> f64| fold(&runs.iter().map(|r| f(&r.scores)).collect::<Vec<_>>());
    let some = |f: fn(&Scores) -> Option<f64>| all_some(runs, f).map(|v| fold(&v));
    Spread {
        psnr: all(|s| s.psnr),
        ssim: all(|s| s.ssim),
        val_psnr: some(|s| s.val_psnr),
        val_ssim: some(|s| s.val_ssim),
        lpips_alex: some(|s| s.lpips_alex),
        val_lpips_alex: some(|s| s.val_lpips_alex),
        flicker: all(|s| s.flicker),
        jitter: all(|s| s.jitter),
        seconds: all(|s| s.seconds),
        gaussians: all(|s| s.gaussians as f64),
        k_mean: some(|s| s.k_mean),
    }
}

impl AblationResult {
    /// The result of `row` over `runs` (at least one): means and, with two or more, sample
    /// standard deviations.
    pub fn of(row: &LadderRow, runs: Vec<SeedRun>) -> Self {
        assert!(!runs.is_empty(), "a row's result needs a run");
        let values = |f: fn(&Scores) -> f64| runs.iter().map(|r| f(&r.scores)).collect::<Vec<_>>();
        let opt_mean = |f: fn(&Scores) -> Option<f64>| all_some(&runs, f).map(|v| mean(&v));
        let m = fold_scores(&runs, mean);
        let scores = Scores {
            psnr: m.psnr,
            ssim: m.ssim,
            val_psnr: m.val_psnr,
            val_ssim: m.val_ssim,
            lpips_alex: m.lpips_alex,
            val_lpips_alex: m.val_lpips_alex,
            flicker: m.flicker,
            jitter: m.jitter,
            seconds: m.seconds,
            gaussians: m.gaussians.round() as usize,
            state_bytes: mean(&values(|s| s.state_bytes as f64)).round() as usize,
            k_mean: m.k_mean,
            k_std: opt_mean(|s| s.k_std),
            k_moving: opt_mean(|s| s.k_moving),
            k_still: opt_mean(|s| s.k_still),
        };
        let std = (runs.len() > 1).then(|| fold_scores(&runs, sample_std));
        Self {
            name: row.name.to_string(),
            description: row.description.to_string(),
            switches: row.switches(),
            run: runs[0].run.clone(),
            scores,
            std,
            seeds: runs,
        }
    }
}
