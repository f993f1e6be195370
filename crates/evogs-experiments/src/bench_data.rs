//! The D-NeRF benchmark's data: one trained and evaluated run ([`BenchRun`]: its [`SplitScore`]s
//! and its PSNR-against-time curve of [`CurvePoint`]s), Deformable-3D-Gaussians' published
//! figures ([`PUBLISHED`], [`published_for`]) and SC-GS's ([`PUBLISHED_SCGS`],
//! [`published_scgs_for`]).
//!
//! What it is not: the benchmark's runner or its table ([`bench`](mod@crate::bench), which
//! re-exports these items) or its plot ([`bench_plot`](crate::bench_plot)). Both import this
//! module, which imports neither.

use std::path::PathBuf;

use evogs_train::config::Method;
use serde::{Deserialize, Serialize};

/// A published figure.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Published {
    /// The method.
    pub method: &'static str,
    /// The scene (our short name).
    pub scene: &'static str,
    /// Image side in pixels (D-NeRF images are square).
    pub resolution: u32,
    /// The split the figure is on.
    pub split: &'static str,
    /// PSNR (dB).
    pub psnr: f64,
    /// SSIM.
    pub ssim: f64,
    /// LPIPS (VGG).
    pub lpips: f64,
    /// Where it is published.
    pub source: &'static str,
}

const D3DGS_README: &str = "ingra14m/Deformable-3D-Gaussians README, 400x400 table";
const D3DGS_PAPER: &str = "Deformable 3D Gaussians (CVPR 2024), Table 1, 800x800";

/// Deformable-3D-Gaussians' published figures for the D-NeRF scenes: its repository's 400×400
/// table (every scene but lego) and its paper's 800×800 table (lego on val, as it recommends).
pub const PUBLISHED: [Published; 11] = [
    Published {
        method: "D-3DGS",
        scene: "lego",
        resolution: 800,
        split: "val",
        psnr: 33.07,
        ssim: 0.9794,
        lpips: 0.0183,
        source: D3DGS_PAPER,
    },
    Published {
        method: "D-3DGS",
        scene: "jumpingjacks",
        resolution: 800,
        split: "test",
        psnr: 37.72,
        ssim: 0.9897,
        lpips: 0.0126,
        source: D3DGS_PAPER,
    },
    Published {
        method: "D-3DGS",
        scene: "hook",
        resolution: 800,
        split: "test",
        psnr: 37.42,
        ssim: 0.9867,
        lpips: 0.0144,
        source: D3DGS_PAPER,
    },
    Published {
        method: "D-3DGS",
        scene: "mutant",
        resolution: 800,
        split: "test",
        psnr: 42.63,
        ssim: 0.9951,
        lpips: 0.0052,
        source: D3DGS_PAPER,
    },
    Published {
        method: "D-3DGS",
        scene: "jumpingjacks",
        resolution: 400,
        split: "test",
        psnr: 39.10,
        ssim: 0.9930,
        lpips: 0.0090,
        source: D3DGS_README,
    },
    Published {
        method: "D-3DGS",
        scene: "hook",
        resolution: 400,
        split: "test",
        psnr: 37.77,
        ssim: 0.9897,
        lpips: 0.0103,
        source: D3DGS_README,
    },
    Published {
        method: "D-3DGS",
        scene: "mutant",
        resolution: 400,
        split: "test",
        psnr: 43.73,
        ssim: 0.9969,
        lpips: 0.0029,
        source: D3DGS_README,
    },
    Published {
        method: "D-3DGS",
        scene: "standup",
        resolution: 400,
        split: "test",
        psnr: 45.38,
        ssim: 0.9967,
        lpips: 0.0032,
        source: D3DGS_README,
    },
    Published {
        method: "D-3DGS",
        scene: "hellwarrior",
        resolution: 400,
        split: "test",
        psnr: 42.11,
        ssim: 0.9885,
        lpips: 0.0153,
        source: D3DGS_README,
    },
    Published {
        method: "D-3DGS",
        scene: "trex",
        resolution: 400,
        split: "test",
        psnr: 38.40,
        ssim: 0.9959,
        lpips: 0.0041,
        source: D3DGS_README,
    },
    Published {
        method: "D-3DGS",
        scene: "bouncingballs",
        resolution: 400,
        split: "test",
        psnr: 41.46,
        ssim: 0.9958,
        lpips: 0.0046,
        source: D3DGS_README,
    },
];

/// Where SC-GS's figures are published.
const SCGS_README: &str = "yihua7/SC-GS README, D-NeRF table (assets/D-NeRF-Results.png; 400x400 by the readme's best-PSNR command)";

/// SC-GS's published figure for one scene (its readme's D-NeRF table, test split, LPIPS VGG).
const fn scgs(scene: &'static str, psnr: f64, ssim: f64, lpips: f64) -> Published {
    Published {
        method: "SC-GS",
        scene,
        resolution: 400,
        split: "test",
        psnr,
        ssim,
        lpips,
        source: SCGS_README,
    }
}

/// SC-GS's published figures for the D-NeRF scenes (no lego in its table).
pub const PUBLISHED_SCGS: [Published; 7] = [
    scgs("hook", 39.87, 0.997, 0.0076),
    scgs("jumpingjacks", 41.13, 0.998, 0.0067),
    scgs("trex", 41.24, 0.998, 0.0046),
    scgs("bouncingballs", 44.91, 0.998, 0.0166),
    scgs("hellwarrior", 42.93, 0.994, 0.0155),
    scgs("mutant", 45.19, 0.999, 0.0028),
    scgs("standup", 47.89, 0.999, 0.0023),
];

/// SC-GS's published figure for `scene`, when its table has one.
pub fn published_scgs_for(scene: &str) -> Option<&'static Published> {
    PUBLISHED_SCGS.iter().find(|p| p.scene == scene)
}

/// The published figure for `scene` closest to `resolution` (the same resolution when there is
/// one, else the nearest).
pub fn published_for(scene: &str, resolution: u32) -> Option<&'static Published> {
    PUBLISHED
        .iter()
        .filter(|p| p.scene == scene)
        .min_by_key(|p| p.resolution.abs_diff(resolution))
}

/// A split's mean scores.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SplitScore {
    /// `test` or `val`.
    pub split: String,
    /// Images.
    pub images: usize,
    /// Mean PSNR (dB).
    pub psnr: f64,
    /// Mean SSIM.
    pub ssim: f64,
    /// Mean LPIPS with the AlexNet backbone, when its weights were loaded.
    pub lpips_alex: Option<f64>,
    /// Mean LPIPS with the VGG16 backbone (the one D-3DGS reports), when asked for and loaded.
    pub lpips_vgg: Option<f64>,
}

/// One point of a run's curve.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CurvePoint {
    /// Iterations done.
    pub iteration: u64,
    /// Training time so far (s), evaluations excluded.
    pub seconds: f64,
    /// Mean PSNR on the headline split (dB).
    pub psnr: f64,
}

/// One trained and evaluated run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BenchRun {
    /// Scene name.
    pub scene: String,
    /// Method.
    pub method: Method,
    /// Run directory.
    pub run: PathBuf,
    /// Image side in pixels.
    pub resolution: u32,
    /// Iterations trained.
    pub iterations: u64,
    /// Under a time budget, the schedule iterations its last step took beyond the pace a step
    /// may take (`train_metrics.json`'s `budget.lagged`): the schedule fell behind the budget
    /// and ended compressed into that step. 0 when it kept pace or without a budget (and in
    /// records written before it was kept).
    #[serde(default)]
    pub schedule_lagged: u64,
    /// Training time (s, wall clock, curve evaluations excluded).
    pub seconds: f64,
    /// Peak resident memory of the process during the run (bytes), where measurable.
    pub peak_rss_bytes: Option<u64>,
    /// Gaussians at the end.
    pub gaussians: usize,
    /// Gaussians with a non-finite value (0 for a healthy run): the larger of the count in the
    /// trained canonical Gaussians and the most deformed ones at one evaluated time (both
    /// splits' views and temporal-metric times;
    /// [`evogs_eval::eval::EvalReport::non_finite_gaussians`]).
    pub non_finite: usize,
    /// The headline split ([`headline_split`](crate::bench::headline_split)).
    pub headline: String,
    /// Test and val scores (headline first).
    pub scores: Vec<SplitScore>,
    /// PSNR on the headline split against training time.
    pub curve: Vec<CurvePoint>,
}

impl BenchRun {
    /// The score on `split`, when evaluated.
    pub fn score(&self, split: &str) -> Option<&SplitScore> {
        self.scores.iter().find(|s| s.split == split)
    }
}
