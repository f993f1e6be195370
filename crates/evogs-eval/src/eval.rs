//! Evaluation of a run on a split: per-image PSNR, SSIM and LPIPS (`lpips_alex`, and
//! `lpips_vgg` when asked for; see [`EvalLpips`]) and their means, fixed-camera flicker and
//! trajectory jitter (DESIGN §8), written as JSON and as a markdown table.
//!
//! Temporal metrics: the split's distinct times, sorted, are rendered from one fixed camera (the
//! split's first). Flicker compares consecutive renders; its ground-truth part exists only when
//! every view of the split shares that camera (then the images are a fixed-camera sequence).
//! Jitter is the mean norm of the second time difference of the deformed means over the same
//! times, counted where a Gaussian is drawn in the fixed camera at all three times.

use std::fmt::Write as _;
use std::path::Path;

use evogs_io::{ImageRgb, Split, save_png};
use serde::{Deserialize, Serialize};
use splat_raster::RenderOptions;

use evogs_metrics::lpips::{Backbone, Lpips, LpipsError};
use evogs_metrics::{ImageSize, flicker, psnr, ssim, trajectory_jitter};
use evogs_train::TrainError;
use evogs_train::data::{SplitViews, load_split};
use evogs_train::run::{write_json, write_text};

use crate::loaded::LoadedRun;

/// One evaluated image.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImageScore {
    /// Image file name.
    pub name: String,
    /// Its time.
    pub time: f32,
    /// PSNR in dB.
    pub psnr: f64,
    /// SSIM.
    pub ssim: f64,
    /// LPIPS with the AlexNet backbone, when its weights were loaded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lpips_alex: Option<f64>,
    /// LPIPS with the VGG16 backbone, when asked for and its weights were loaded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lpips_vgg: Option<f64>,
}

impl ImageScore {
    /// The image's LPIPS with `backbone`, if computed.
    pub fn lpips(&self, backbone: Backbone) -> Option<f64> {
        match backbone {
            Backbone::Alex => self.lpips_alex,
            Backbone::Vgg => self.lpips_vgg,
        }
    }
}

/// The LPIPS networks an evaluation runs, loaded once and shared by every image.
#[derive(Debug, Default)]
pub struct EvalLpips {
    /// The loaded networks, AlexNet first.
    pub nets: Vec<Lpips>,
    /// One line for each requested backbone whose weights are not installed: the file looked
    /// for and the command that installs it.
    pub missing: Vec<String>,
}

impl EvalLpips {
    /// Loads `backbones` from the weights directory found for `dir` (the search order of
    /// [`evogs_metrics::lpips::weights`]). A backbone without a weights file is noted in
    /// [`EvalLpips::missing`] and skipped; a malformed file is an error.
    pub fn find(backbones: &[Backbone], dir: Option<&Path>) -> Result<Self, TrainError> {
        let mut out = Self::default();
        for &backbone in backbones {
            match Lpips::find(backbone, dir) {
                Ok(net) => out.nets.push(net),
                Err(e @ LpipsError::Missing { .. }) => out.missing.push(e.to_string()),
                Err(e) => return Err(e.into()),
            }
        }
        Ok(out)
    }
}

/// Temporal consistency over the split's times from a fixed camera.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Temporal {
    /// Distinct times rendered.
    pub frames: usize,
    /// Mean absolute difference of consecutive renders.
    pub flicker_rendered: f64,
    /// The same for the ground truth, when the split is a fixed-camera sequence.
    pub flicker_ground_truth: Option<f64>,
    /// Rendered minus ground truth (or rendered alone without ground truth).
    pub flicker_excess: f64,
    /// Mean norm of the second time difference of visible Gaussians' positions (world units).
    pub jitter: f64,
    /// Number of (Gaussian, frame) terms in the jitter mean.
    pub jitter_terms: usize,
}

/// `eval_<split>.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EvalReport {
    /// The split.
    pub split: String,
    /// Iterations the run was trained for.
    pub iteration: u64,
    /// Network width of the run.
    pub net_width: usize,
    /// Every image.
    pub images: Vec<ImageScore>,
    /// Mean PSNR.
    pub mean_psnr: f64,
    /// Mean SSIM.
    pub mean_ssim: f64,
    /// Mean LPIPS (AlexNet), when computed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mean_lpips_alex: Option<f64>,
    /// Mean LPIPS (VGG16), when computed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mean_lpips_vgg: Option<f64>,
    /// Requested LPIPS backbones that were not computed (weights missing, images below the
    /// network's minimum size), and why (one line each).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub lpips_missing: Vec<String>,
    /// Temporal metrics (absent with fewer than two distinct times).
    pub temporal: Option<Temporal>,
    /// Views (and times of the temporal metrics) at which a deformed Gaussian held a non-finite
    /// value (the rendered image is then not trustworthy). Reports written before it existed
    /// read as 0.
    #[serde(default)]
    pub non_finite_views: usize,
    /// The most Gaussians with a non-finite deformed value at one of those views
    /// ([`non_finite_gaussians`]).
    #[serde(default)]
    pub non_finite_gaussians: usize,
}

/// How many of `g`'s Gaussians hold a non-finite value (mean, scale, rotation, opacity or SH).
pub fn non_finite_gaussians(g: &splat_raster::Gaussians) -> usize {
    let stride = if g.is_empty() {
        0
    } else {
        g.sh.len() / g.len()
    };
    (0..g.len())
        .filter(|&i| {
            let finite = |v: &[f32]| v.iter().all(|x| x.is_finite());
            !(finite(&g.means[i])
                && finite(&g.log_scales[i])
                && finite(&g.rotations[i])
                && g.opacity_logits[i].is_finite()
                && finite(&g.sh[i * stride..(i + 1) * stride]))
        })
        .count()
}

/// Non-finite deformed Gaussians over the views of an evaluation: views affected and the most
/// Gaussians at one.
#[derive(Clone, Copy, Debug, Default)]
struct NonFiniteTally {
    views: usize,
    most: usize,
}

impl NonFiniteTally {
    fn add(&mut self, g: &splat_raster::Gaussians) {
        let n = non_finite_gaussians(g);
        if n > 0 {
            self.views += 1;
            self.most = self.most.max(n);
        }
    }
}

impl EvalReport {
    /// The mean LPIPS with `backbone`, if computed.
    pub fn mean_lpips(&self, backbone: Backbone) -> Option<f64> {
        match backbone {
            Backbone::Alex => self.mean_lpips_alex,
            Backbone::Vgg => self.mean_lpips_vgg,
        }
    }

    /// The backbones whose LPIPS the report holds, AlexNet first.
    pub fn lpips_backbones(&self) -> Vec<Backbone> {
        Backbone::ALL
            .into_iter()
            .filter(|&b| self.mean_lpips(b).is_some())
            .collect()
    }
}

/// Evaluates `run` on `split`: renders every view (saved under `renders/<split>/`), scores it
/// (LPIPS with each network of `lpips`), computes the temporal metrics, and writes
/// `eval_<split>.json` and `eval_<split>.md`.
pub fn evaluate(
    run: &mut LoadedRun,
    split: Split,
    lpips: &EvalLpips,
) -> Result<EvalReport, TrainError> {
    evaluate_with_progress(run, split, lpips, &mut |_, _| {})
}

/// [`evaluate`], calling `progress(done, total)` after each view is scored.
pub fn evaluate_with_progress(
    run: &mut LoadedRun,
    split: Split,
    lpips: &EvalLpips,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<EvalReport, TrainError> {
    let cfg = run.run.train.clone();
    let views = load_split(
        run.data()?,
        split,
        cfg.time_from,
        cfg.background.rgb(),
        cfg.downscale,
    )?;
    let opts = RenderOptions {
        background: cfg.background.rgb(),
        sh_degree: None,
    };
    let dir = run.paths.renders(split);
    std::fs::create_dir_all(&dir).map_err(|e| TrainError::file(&dir, e.to_string()))?;
    let mut images = Vec::with_capacity(views.views.len());
    let mut lpips_missing = lpips.missing.clone();
    let mut non_finite = NonFiniteTally::default();
    for (k, view) in views.views.iter().enumerate() {
        let g = run.deformed(view.time)?;
        non_finite.add(&g);
        let out = run.raster.forward(g.view(), &view.camera, &opts)?;
        let size = ImageSize::new(view.image.width as usize, view.image.height as usize);
        let clamped: Vec<[f32; 3]> = out
            .color
            .iter()
            .map(|c| c.map(|v| v.clamp(0.0, 1.0)))
            .collect();
        let (mut lpips_alex, mut lpips_vgg) = (None, None);
        for net in &lpips.nets {
            let slot = match net.backbone() {
                Backbone::Alex => &mut lpips_alex,
                Backbone::Vgg => &mut lpips_vgg,
            };
            match net.distance(size, &clamped, &view.image.pixels) {
                Ok(d) => *slot = Some(d),
                // Images below the network's minimum: that LPIPS is not reported, and why.
                Err(e @ LpipsError::TooSmall { .. }) => {
                    let line = e.to_string();
                    if !lpips_missing.contains(&line) {
                        lpips_missing.push(line);
                    }
                }
                Err(e) => return Err(e.into()),
            }
        }
        images.push(ImageScore {
            name: view
                .path
                .file_name()
                .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
            time: view.time,
            psnr: psnr(size, &clamped, &view.image.pixels)?,
            ssim: ssim(size, &clamped, &view.image.pixels)?,
            lpips_alex,
            lpips_vgg,
        });
        save_png(
            &dir.join(format!("{k:04}.png")),
            &ImageRgb {
                width: view.image.width,
                height: view.image.height,
                pixels: clamped,
            },
        )?;
        progress(k + 1, views.views.len());
    }
    let count = images.len().max(1) as f64;
    let mean_psnr = images.iter().map(|s| s.psnr).sum::<f64>() / count;
    let mean_ssim = images.iter().map(|s| s.ssim).sum::<f64>() / count;
    let mean_lpips = |backbone| -> Option<f64> {
        let values: Option<Vec<f64>> = images.iter().map(|s| s.lpips(backbone)).collect();
        values
            .filter(|v| !v.is_empty())
            .map(|v| v.iter().sum::<f64>() / count)
    };
    let (mean_lpips_alex, mean_lpips_vgg) = (mean_lpips(Backbone::Alex), mean_lpips(Backbone::Vgg));
    let temporal = temporal_metrics(run, &views, &opts, &mut non_finite)?;
    let report = EvalReport {
        split: split.name().to_string(),
        iteration: run.summary.iteration,
        net_width: cfg.net.width,
        images,
        mean_psnr,
        mean_ssim,
        mean_lpips_alex,
        mean_lpips_vgg,
        lpips_missing,
        temporal,
        non_finite_views: non_finite.views,
        non_finite_gaussians: non_finite.most,
    };
    write_json(&run.paths.eval_json(split), &report)?;
    write_text(&run.paths.eval_markdown(split), &markdown(&report))?;
    Ok(report)
}

fn temporal_metrics(
    run: &mut LoadedRun,
    views: &SplitViews,
    opts: &RenderOptions,
    non_finite: &mut NonFiniteTally,
) -> Result<Option<Temporal>, TrainError> {
    let times = views.times();
    if times.len() < 2 {
        return Ok(None);
    }
    let camera = &views.views[0].camera;
    let fixed_camera = views.views.iter().all(|v| v.camera == *camera);
    let mut renders = Vec::with_capacity(times.len());
    let mut positions = Vec::with_capacity(times.len());
    let mut visible = Vec::with_capacity(times.len());
    for &t in &times {
        let g = run.deformed(t)?;
        non_finite.add(&g);
        let out = run.raster.forward(g.view(), camera, opts)?;
        let mut drawn: Vec<bool> = out.radii().iter().map(|&r| r > 0.0).collect();
        // A non-finite position (counted above) is left out of the jitter, not an error.
        let mut means = g.means;
        for (m, d) in means.iter_mut().zip(&mut drawn) {
            if !m.iter().all(|v| v.is_finite()) {
                *m = [0.0; 3];
                *d = false;
            }
        }
        visible.push(drawn);
        renders.push(out.color);
        positions.push(means);
    }
    let size = ImageSize::new(camera.width as usize, camera.height as usize);
    let rendered: Vec<&[[f32; 3]]> = renders.iter().map(Vec::as_slice).collect();
    let gt_frames: Option<Vec<&[[f32; 3]]>> = fixed_camera.then(|| {
        times
            .iter()
            .map(|&t| {
                let v = views
                    .views
                    .iter()
                    .find(|v| v.time == t)
                    .unwrap_or(&views.views[0]);
                v.image.pixels.as_slice()
            })
            .collect()
    });
    let f = flicker(size, &rendered, gt_frames.as_deref())?;
    let pos: Vec<&[[f32; 3]]> = positions.iter().map(Vec::as_slice).collect();
    let vis: Vec<&[bool]> = visible.iter().map(Vec::as_slice).collect();
    let j = trajectory_jitter(&pos, &vis)?;
    Ok(Some(Temporal {
        frames: times.len(),
        flicker_rendered: f.rendered,
        flicker_ground_truth: f.ground_truth,
        flicker_excess: f.excess,
        jitter: j.mean,
        jitter_terms: j.count,
    }))
}

/// The markdown table of a report: one row per image, the mean, and the temporal metrics.
pub fn markdown(report: &EvalReport) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Evaluation: split `{}`, {} iterations, network width {}\n",
        report.split, report.iteration, report.net_width
    );
    let backbones = report.lpips_backbones();
    let header: String = backbones
        .iter()
        .map(|b| format!(" {} |", b.metric()))
        .collect();
    let _ = writeln!(s, "| image | time | PSNR (dB) | SSIM |{header}");
    let _ = writeln!(
        s,
        "| --- | ---: | ---: | ---: |{}",
        " ---: |".repeat(backbones.len())
    );
    for im in &report.images {
        let lpips: String = backbones
            .iter()
            .map(|&b| {
                im.lpips(b)
                    .map_or(" - |".to_string(), |v| format!(" {v:.4} |"))
            })
            .collect();
        let _ = writeln!(
            s,
            "| {} | {:.3} | {:.2} | {:.4} |{lpips}",
            im.name, im.time, im.psnr, im.ssim
        );
    }
    let mean_lpips: String = backbones
        .iter()
        .map(|&b| {
            report
                .mean_lpips(b)
                .map_or(" - |".to_string(), |v| format!(" **{v:.4}** |"))
        })
        .collect();
    let _ = writeln!(
        s,
        "| **mean** ({} images) | | **{:.2}** | **{:.4}** |{mean_lpips}",
        report.images.len(),
        report.mean_psnr,
        report.mean_ssim
    );
    match &report.temporal {
        Some(t) => {
            let gt = t.flicker_ground_truth.map_or_else(
                || "n/a (no fixed-camera ground truth)".to_string(),
                |g| format!("{g:.5}"),
            );
            let _ = writeln!(
                s,
                "\nTemporal consistency over {} times from a fixed camera:\n",
                t.frames
            );
            let _ = writeln!(s, "| metric | value |");
            let _ = writeln!(s, "| --- | ---: |");
            let _ = writeln!(s, "| flicker (rendered) | {:.5} |", t.flicker_rendered);
            let _ = writeln!(s, "| flicker (ground truth) | {gt} |");
            let _ = writeln!(s, "| flicker (excess) | {:.5} |", t.flicker_excess);
            let _ = writeln!(
                s,
                "| trajectory jitter | {:.3e} ({} terms) |",
                t.jitter, t.jitter_terms
            );
        }
        None => {
            let _ = writeln!(
                s,
                "\nTemporal consistency: n/a (fewer than two distinct times)."
            );
        }
    }
    if !backbones.is_empty() {
        s.push_str(
            "\nLPIPS v0.1 (lower is better) on images clamped to [0, 1]; the column names the backbone.\n",
        );
    }
    for line in &report.lpips_missing {
        let _ = writeln!(s, "\nNot reported: {line}.");
    }
    if report.non_finite_views > 0 {
        let _ = writeln!(
            s,
            "\n**Non-finite deformed Gaussians** at {} of the rendered times (at most {} at one): \
             those renders are not trustworthy.",
            report.non_finite_views, report.non_finite_gaussians
        );
    }
    s
}
