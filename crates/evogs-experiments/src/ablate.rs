//! The paper's ablation ladder at equal iterations on one dataset: the rows ([`ladder`], each a
//! [`LadderRow`]), the runner ([`run_ablation`]: train, then evaluate on test and val, a row's
//! result an [`AblationResult`]), and its outputs ([`write_outputs`]: `ablation.md`,
//! `ablation.json`, `ablation.png`, each written atomically).
//!
//! [`train_and_evaluate`] is the one-method piece `evogs demo` shares. The row and result types
//! are defined in the module below this one and the plot (`ablate_data`) and re-exported here.

use std::path::{Path, PathBuf};

use evogs_io::Split;

pub use crate::ablate_data::{AblationResult, LadderRow, Scores, SeedRun, Spread};
use crate::ablate_plot;
use crate::error::ExperimentError;
use crate::write::{write_bytes, write_json, write_png};
use evogs_backbones::{
    DensifyPolicy, EvoConfig, EvoSettings, Gain, HistoryMode, Precision, Storage,
};
use evogs_eval::LoadedRun;
use evogs_eval::eval::{EvalLpips, evaluate};
use evogs_train::config::{Method, TrainConfig};
use evogs_train::run::{TrainRequest, train};
use evogs_train::trainer::StepReport;

/// The ladder, in the paper's order: baseline; Φ alone; evolution with re-queried history; with
/// the buffer; + uncertainty trigger; + deformation-aware clone/split (the full method, learned
/// K, f32); K fixed at 0 (prior only, with standard densification), 0.5, 1 (both on the full
/// method); f16 network; f16 buffer.
pub fn ladder() -> Vec<LadderRow> {
    let full = EvoSettings::default();
    let standard = EvoSettings {
        densify: DensifyPolicy::Standard,
        ..full.clone()
    };
    let evo = |name, description, evo| LadderRow {
        name,
        description,
        method: Method::Evogs,
        evo,
    };
    vec![
        LadderRow {
            name: "baseline",
            description: "D-3DGS",
            method: Method::Baseline,
            evo: full.clone(),
        },
        evo(
            "phi",
            "Φ without evolution",
            EvoSettings {
                evo: EvoConfig {
                    evolution: false,
                    ..standard.evo
                },
                ..standard.clone()
            },
        ),
        evo(
            "evo-requery",
            "evolution, history re-queried from Φ",
            EvoSettings {
                evo: EvoConfig {
                    history: HistoryMode::Requery,
                    ..standard.evo
                },
                ..standard.clone()
            },
        ),
        evo("evo-buffer", "evolution with the buffer", standard.clone()),
        evo(
            "trigger",
            "+ uncertainty trigger",
            EvoSettings {
                densify: DensifyPolicy::Trigger,
                ..full.clone()
            },
        ),
        evo(
            "full",
            "+ deformation-aware clone/split (EvoGS, learned K)",
            full.clone(),
        ),
        // Prior only, with standard densification: under the trigger a K = 0 run keeps about
        // 200 Gaussians (the buffer extrapolates a straight line, the residual and angle gates
        // then refuse every densification; results/evolution-ablation), which measures the
        // trigger, not the prior.
        evo(
            "k0",
            "K fixed at 0 (prior only; standard densification, not the trigger)",
            EvoSettings {
                evo: EvoConfig {
                    gain: Gain::Fixed(0.0),
                    ..standard.evo
                },
                ..standard.clone()
            },
        ),
        evo(
            "k0.5",
            "K fixed at 0.5",
            EvoSettings {
                evo: EvoConfig {
                    gain: Gain::Fixed(0.5),
                    ..full.evo
                },
                ..full.clone()
            },
        ),
        evo(
            "k1",
            "K fixed at 1 (observation only)",
            EvoSettings {
                evo: EvoConfig {
                    gain: Gain::Fixed(1.0),
                    ..full.evo
                },
                ..full.clone()
            },
        ),
        evo(
            "net-f16",
            "Φ in f16",
            EvoSettings {
                net_precision: Precision::F16,
                ..full.clone()
            },
        ),
        evo(
            "buffer-f16",
            "buffer in f16",
            EvoSettings {
                evo: EvoConfig {
                    storage: Storage::F16,
                    ..full.evo
                },
                ..full
            },
        ),
    ]
}

/// The ladder's rows named in `names` (in the ladder's order; each name once); all rows when
/// `names` is empty.
pub fn select(names: &[String]) -> Result<Vec<LadderRow>, ExperimentError> {
    let all = ladder();
    for (i, name) in names.iter().enumerate() {
        if !all.iter().any(|r| r.name == name) {
            let known: Vec<&str> = all.iter().map(|r| r.name).collect();
            return Err(ExperimentError::config(
                "rows",
                format!(
                    "unknown row `{name}`; expected some of {}",
                    known.join(", ")
                ),
            ));
        }
        if names[..i].contains(name) {
            return Err(ExperimentError::config(
                "rows",
                format!("`{name}` is listed twice"),
            ));
        }
    }
    if names.is_empty() {
        return Ok(all);
    }
    Ok(all
        .into_iter()
        .filter(|r| names.iter().any(|n| n == r.name))
        .collect())
}

/// Trains `config` on `data` into the run directory `out`, then evaluates it on the test split
/// (and on val when `with_val`), LPIPS with the networks of `lpips`.
pub fn train_and_evaluate(
    data: &Path,
    out: &Path,
    config: TrainConfig,
    with_val: bool,
    lpips: &EvalLpips,
) -> Result<Scores, ExperimentError> {
    train_and_evaluate_with_progress(data, out, config, with_val, lpips, &mut |_| {})
}

/// [`train_and_evaluate`], calling `progress` after every training iteration.
pub fn train_and_evaluate_with_progress(
    data: &Path,
    out: &Path,
    config: TrainConfig,
    with_val: bool,
    lpips: &EvalLpips,
    progress: &mut dyn FnMut(&StepReport),
) -> Result<Scores, ExperimentError> {
    let backend = config.backend;
    let summary = train(
        &TrainRequest {
            data: data.to_path_buf(),
            out: out.to_path_buf(),
            config,
            resume: false,
            stop_after: None,
            resume_backend: None,
            resume_net_backend: None,
        },
        &mut |report, _| progress(report),
    )?;
    let mut run = LoadedRun::open(out)?;
    // Evaluated on the backend it trained on.
    run.use_backend(backend)?;
    let report = evaluate(&mut run, Split::Test, lpips)?;
    let (val_psnr, val_ssim, val_lpips_alex) = if with_val {
        let val = evaluate(&mut run, Split::Val, lpips)?;
        (
            Some(val.mean_psnr),
            Some(val.mean_ssim),
            val.mean_lpips_alex,
        )
    } else {
        (None, None, None)
    };
    let temporal = report.temporal.as_ref();
    let gain = summary.gain.as_ref();
    Ok(Scores {
        psnr: report.mean_psnr,
        ssim: report.mean_ssim,
        val_psnr,
        val_ssim,
        lpips_alex: report.mean_lpips_alex,
        val_lpips_alex,
        flicker: temporal.map_or(f64::NAN, |t| t.flicker_rendered),
        jitter: temporal.map_or(f64::NAN, |t| t.jitter),
        seconds: summary.seconds,
        gaussians: summary.gaussians,
        state_bytes: run.backbone.state_bytes(),
        k_mean: gain.and_then(|g| g.all.as_ref()).map(|s| s.mean),
        k_std: gain.and_then(|g| g.all.as_ref()).map(|s| s.std),
        k_moving: gain.and_then(|g| g.moving.as_ref()).map(|s| s.mean),
        k_still: gain.and_then(|g| g.still.as_ref()).map(|s| s.mean),
    })
}

/// What to run.
#[derive(Clone, Debug)]
pub struct AblationRequest {
    /// Dataset directory.
    pub data: PathBuf,
    /// Output directory: one run directory per row (per row and seed with several seeds), and
    /// the tables and plot.
    pub out: PathBuf,
    /// Preset, iterations and the rest; each row sets `method` and `evogs`, each seed `seed`.
    pub config: TrainConfig,
    /// The rows, in order.
    pub rows: Vec<LadderRow>,
    /// The training seeds: every row runs once per seed (the scene stays the same).
    pub seeds: Vec<u64>,
}

impl AblationRequest {
    /// The run directory of `row` for `seed`: `OUT/<row>` with one seed, `OUT/<row>/seed<S>`
    /// with several.
    pub fn run_dir(&self, row: &LadderRow, seed: u64) -> PathBuf {
        let dir = self.out.join(row.name);
        if self.seeds.len() > 1 {
            dir.join(format!("seed{seed}"))
        } else {
            dir
        }
    }
}

/// `count` consecutive seeds from `first`: `first, first + 1, …` (wrapping).
pub fn seeds_from(first: u64, count: usize) -> Vec<u64> {
    (0..count as u64).map(|i| first.wrapping_add(i)).collect()
}

/// Progress of [`run_ablation`]: one run is a row for one seed.
#[derive(Debug)]
pub enum Progress<'a> {
    /// Run `index` (0-based) of `total` is starting.
    Started {
        /// 0-based, over rows × seeds.
        index: usize,
        /// Runs in all.
        total: usize,
        /// The row.
        row: &'a LadderRow,
        /// The seed.
        seed: u64,
    },
    /// Run `index` of `total` is done.
    Finished {
        /// 0-based.
        index: usize,
        /// Runs in all.
        total: usize,
        /// The row.
        row: &'a LadderRow,
        /// Its run.
        run: &'a SeedRun,
    },
}

/// Runs every row of `request` for every seed (seed by seed, so that a stopped sweep has whole
/// ladders; train, evaluate on test, and on val when the dataset has one; LPIPS with the networks
/// of `lpips`), writes the outputs ([`write_outputs`]) after every run, and returns the results.
pub fn run_ablation(
    request: &AblationRequest,
    lpips: &EvalLpips,
    progress: &mut dyn FnMut(Progress<'_>),
) -> Result<Vec<AblationResult>, ExperimentError> {
    if request.rows.is_empty() {
        return Err(ExperimentError::config("rows", "no rows to run"));
    }
    if request.seeds.is_empty() {
        return Err(ExperimentError::config("seeds", "no seeds to run"));
    }
    let dataset = evogs_train::data::open_dataset(&request.data, request.config.time_from)?;
    let with_val = !dataset.split(Split::Val).is_empty();
    std::fs::create_dir_all(&request.out).map_err(|e| ExperimentError::dir(&request.out, e))?;
    let total = request.rows.len() * request.seeds.len();
    let mut runs: Vec<Vec<SeedRun>> = vec![Vec::new(); request.rows.len()];
    let mut index = 0;
    let mut results = Vec::new();
    for &seed in &request.seeds {
        for (r, row) in request.rows.iter().enumerate() {
            progress(Progress::Started {
                index,
                total,
                row,
                seed,
            });
            let mut config = request.config.clone();
            config = config.with_method(row.method);
            config.backbones.evogs = row.evo.clone();
            config.seed = seed;
            let run = request.run_dir(row, seed);
            let scores = train_and_evaluate(&request.data, &run, config, with_val, lpips)?;
            runs[r].push(SeedRun { seed, run, scores });
            progress(Progress::Finished {
                index,
                total,
                row,
                run: runs[r].last().expect("just pushed"),
            });
            index += 1;
            results = request
                .rows
                .iter()
                .zip(&runs)
                .filter(|(_, v)| !v.is_empty())
                .map(|(row, v)| AblationResult::of(row, v.clone()))
                .collect();
            write_outputs(&request.out, &request.config, &results)?;
        }
    }
    Ok(results)
}

/// `mean` with `digits` decimals, followed by ` ± std` where there is a spread.
fn cell(mean: f64, std: Option<f64>, digits: usize) -> String {
    match std {
        Some(s) => format!("{mean:.digits$} ± {s:.digits$}"),
        None => format!("{mean:.digits$}"),
    }
}

fn opt_cell(mean: Option<f64>, std: Option<Option<f64>>, digits: usize) -> String {
    mean.map_or("-".into(), |m| cell(m, std.flatten(), digits))
}

/// The seeds of `results` as the heading says them: `seed 3`, or `seeds 0, 1, 2 (mean ± sample
/// std over seeds)`.
fn seeds_heading(config: &TrainConfig, results: &[AblationResult]) -> String {
    let mut seeds: Vec<u64> = results
        .iter()
        .flat_map(|r| r.seeds.iter().map(|s| s.seed))
        .collect();
    seeds.sort_unstable();
    seeds.dedup();
    match seeds.as_slice() {
        [] => format!("seed {}", config.seed),
        [one] => format!("seed {one}"),
        many => format!(
            "seeds {} (mean ± sample std over seeds)",
            many.iter()
                .map(u64::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// The markdown table of `results` under a heading naming the preset, budget and seeds. With
/// several seeds every score is `mean ± sample std` and a `seeds` column counts the runs. The K
/// columns (mean K, and its standard deviation inside a run) are `-` without evolution.
pub fn table(config: &TrainConfig, results: &[AblationResult]) -> String {
    let with_val = results.iter().any(|r| r.scores.val_psnr.is_some());
    let multi = results.iter().any(|r| r.seeds.len() > 1);
    let mut s = format!(
        "# evogs ablate: backbone `{}`, {} per row, {}\n\n\
         | row | switches |{} PSNR (dB) | SSIM | lpips_alex |{} flicker | jitter | training (s) | Gaussians | state (KiB) | K mean | K std (in run) | K moving / still |\n\
         | --- | --- |{} ---: | ---: | ---: |{} ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n",
        config.backbone,
        config.length(),
        seeds_heading(config, results),
        if multi { " seeds |" } else { "" },
        if with_val {
            " val PSNR (dB) | val SSIM | val lpips_alex |"
        } else {
            ""
        },
        if multi { " ---: |" } else { "" },
        if with_val {
            " ---: | ---: | ---: |"
        } else {
            ""
        },
    );
    for r in results {
        let c = &r.scores;
        let d = r.std.as_ref();
        let val = if with_val {
            format!(
                " {} | {} | {} |",
                opt_cell(c.val_psnr, d.map(|d| d.val_psnr), 2),
                opt_cell(c.val_ssim, d.map(|d| d.val_ssim), 4),
                opt_cell(c.val_lpips_alex, d.map(|d| d.val_lpips_alex), 4),
            )
        } else {
            String::new()
        };
        let seeds = if multi {
            format!(" {} |", r.seeds.len())
        } else {
            String::new()
        };
        let jitter = match d {
            Some(d) => format!("{:.3e} ± {:.1e}", c.jitter, d.jitter),
            None => format!("{:.3e}", c.jitter),
        };
        let moving_still = match (c.k_moving, c.k_still) {
            (None, None) => "-".to_string(),
            (m, s) => format!(
                "{} / {}",
                m.map_or("-".into(), |v| format!("{v:.3}")),
                s.map_or("-".into(), |v| format!("{v:.3}"))
            ),
        };
        s += &format!(
            "| {} | {} |{seeds} {} | {} | {} |{val} {} | {jitter} | {} | {} | {:.1} | {} | {} | {moving_still} |\n",
            r.name,
            r.switches,
            cell(c.psnr, d.map(|d| d.psnr), 2),
            cell(c.ssim, d.map(|d| d.ssim), 4),
            opt_cell(c.lpips_alex, d.map(|d| d.lpips_alex), 4),
            cell(c.flicker, d.map(|d| d.flicker), 5),
            cell(c.seconds, d.map(|d| d.seconds), 1),
            cell(c.gaussians as f64, d.map(|d| d.gaussians), 0),
            c.state_bytes as f64 / 1024.0,
            opt_cell(c.k_mean, d.map(|d| d.k_mean), 3),
            c.k_std.map_or("-".into(), |v| format!("{v:.3}")),
        );
    }
    s
}

/// Writes `ablation.md`, `ablation.json` and `ablation.png` (PSNR against training time, one
/// labelled point per row, with error bars of ± one standard deviation over seeds) into `out`,
/// each atomically.
pub fn write_outputs(
    out: &Path,
    config: &TrainConfig,
    results: &[AblationResult],
) -> Result<(), ExperimentError> {
    write_bytes(&out.join("ablation.md"), table(config, results).as_bytes())?;
    let mut json = serde_json::json!({
        "backbone": config.backbone,
        "iterations": config.iterations,
        "seeds": results.first().map(|r| r.seeds.iter().map(|s| s.seed).collect::<Vec<_>>()),
        "rows": results,
    });
    if let Some(budget) = &config.budget {
        json["budget"] = serde_json::json!(budget);
    }
    write_json(&out.join("ablation.json"), &json)?;
    let png = out.join("ablation.png");
    let image = ablate_plot::plot(results)
        .map_err(|problem| ExperimentError::output(&png, format!("plotting: {problem}")))?;
    write_png(&png, &image)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every row's switches, written out: (name, method, evolution, history, densify, gain, net,
    /// buffer).
    #[test]
    fn rows_map_to_their_switches() {
        use DensifyPolicy::*;
        use Gain::*;
        use HistoryMode::*;
        use Precision as P;
        use Storage as S;
        let expected = [
            (
                "baseline",
                Method::Baseline,
                true,
                Buffer,
                TriggerDeform,
                Learned,
                P::F32,
                S::F32,
            ),
            (
                "phi",
                Method::Evogs,
                false,
                Buffer,
                Standard,
                Learned,
                P::F32,
                S::F32,
            ),
            (
                "evo-requery",
                Method::Evogs,
                true,
                Requery,
                Standard,
                Learned,
                P::F32,
                S::F32,
            ),
            (
                "evo-buffer",
                Method::Evogs,
                true,
                Buffer,
                Standard,
                Learned,
                P::F32,
                S::F32,
            ),
            (
                "trigger",
                Method::Evogs,
                true,
                Buffer,
                Trigger,
                Learned,
                P::F32,
                S::F32,
            ),
            (
                "full",
                Method::Evogs,
                true,
                Buffer,
                TriggerDeform,
                Learned,
                P::F32,
                S::F32,
            ),
            (
                "k0",
                Method::Evogs,
                true,
                Buffer,
                Standard,
                Fixed(0.0),
                P::F32,
                S::F32,
            ),
            (
                "k0.5",
                Method::Evogs,
                true,
                Buffer,
                TriggerDeform,
                Fixed(0.5),
                P::F32,
                S::F32,
            ),
            (
                "k1",
                Method::Evogs,
                true,
                Buffer,
                TriggerDeform,
                Fixed(1.0),
                P::F32,
                S::F32,
            ),
            (
                "net-f16",
                Method::Evogs,
                true,
                Buffer,
                TriggerDeform,
                Learned,
                P::F16,
                S::F32,
            ),
            (
                "buffer-f16",
                Method::Evogs,
                true,
                Buffer,
                TriggerDeform,
                Learned,
                P::F32,
                S::F16,
            ),
        ];
        let rows = ladder();
        assert_eq!(rows.len(), expected.len());
        for (row, (name, method, evolution, history, densify, gain, net, buffer)) in
            rows.iter().zip(expected)
        {
            assert_eq!(row.name, name);
            assert_eq!(row.method, method, "{name}");
            assert_eq!(row.evo.evo.evolution, evolution, "{name}");
            assert_eq!(row.evo.evo.history, history, "{name}");
            assert_eq!(row.evo.densify, densify, "{name}");
            assert_eq!(row.evo.evo.gain, gain, "{name}");
            assert_eq!(row.evo.net_precision, net, "{name}");
            assert_eq!(row.evo.evo.storage, buffer, "{name}");
            // Everything else is the method's default.
            let rest = EvoSettings {
                evo: EvoConfig {
                    evolution: true,
                    history: Buffer,
                    gain: Learned,
                    storage: S::F32,
                    ..row.evo.evo
                },
                densify: TriggerDeform,
                net_precision: P::F32,
                ..row.evo.clone()
            };
            assert_eq!(rest, EvoSettings::default(), "{name}");
            row.evo.validate().unwrap();
        }
    }

    #[test]
    fn switches_line() {
        let rows = ladder();
        assert_eq!(rows[0].switches(), "baseline");
        assert_eq!(
            rows[1].switches(),
            "evogs evolution=off history=buffer densify=standard gain=learned net=f32 buffer=f32"
        );
        assert_eq!(
            rows[7].switches(),
            "evogs evolution=on history=buffer densify=trigger+deform gain=0.5 net=f32 buffer=f32"
        );
    }

    fn scores(psnr: f64, gaussians: usize, k: Option<f64>) -> Scores {
        Scores {
            psnr,
            ssim: 0.9,
            val_psnr: Some(psnr - 1.0),
            val_ssim: Some(0.8),
            lpips_alex: None,
            val_lpips_alex: None,
            flicker: 0.001,
            jitter: 1e-4,
            seconds: 10.0,
            gaussians,
            state_bytes: 2048,
            k_mean: k,
            k_std: k.map(|_| 0.1),
            k_moving: k,
            k_still: None,
        }
    }

    fn run(seed: u64, s: Scores) -> SeedRun {
        SeedRun {
            seed,
            run: PathBuf::from(format!("out/full/seed{seed}")),
            scores: s,
        }
    }

    #[test]
    fn a_row_over_seeds_reports_the_mean_and_the_sample_std() {
        let row = ladder().into_iter().find(|r| r.name == "full").unwrap();
        let r = AblationResult::of(
            &row,
            vec![
                run(0, scores(20.0, 100, Some(0.4))),
                run(1, scores(21.0, 200, Some(0.5))),
                run(2, scores(22.0, 301, Some(0.6))),
            ],
        );
        assert!((r.scores.psnr - 21.0).abs() < 1e-12);
        assert_eq!(r.scores.val_psnr, Some(20.0));
        assert_eq!(r.scores.gaussians, 200); // 601 / 3 rounded
        assert!((r.scores.k_mean.unwrap() - 0.5).abs() < 1e-12);
        let d = r.std.as_ref().unwrap();
        // Sample std of 20, 21, 22 is 1; of 0.4, 0.5, 0.6 is 0.1.
        assert!((d.psnr - 1.0).abs() < 1e-12);
        assert!((d.val_psnr.unwrap() - 1.0).abs() < 1e-12);
        assert!((d.k_mean.unwrap() - 0.1).abs() < 1e-12);
        assert_eq!(d.lpips_alex, None);
        assert_eq!(d.ssim, 0.0);
        assert_eq!(r.seeds.len(), 3);
        assert_eq!(r.run, PathBuf::from("out/full/seed0"));
        // A score only some seeds have is left out of the mean.
        let mixed = AblationResult::of(
            &row,
            vec![
                run(0, scores(20.0, 1, Some(0.4))),
                run(1, scores(20.0, 1, None)),
            ],
        );
        assert_eq!(mixed.scores.k_mean, None);
        // One seed: no spread.
        let one = AblationResult::of(&row, vec![run(5, scores(20.0, 7, None))]);
        assert!(one.std.is_none());
        assert_eq!(one.scores, scores(20.0, 7, None));
    }

    #[test]
    fn table_with_seeds_shows_mean_plus_minus_std_and_the_k_columns() {
        let rows = ladder();
        let (phi, full) = (&rows[1], &rows[5]);
        let config = TrainConfig::preset(evogs_train::Preset::Tiny);
        let results = vec![
            AblationResult::of(
                phi,
                vec![
                    run(0, scores(20.0, 100, None)),
                    run(1, scores(22.0, 300, None)),
                ],
            ),
            AblationResult::of(
                full,
                vec![
                    run(0, scores(21.0, 100, Some(0.25))),
                    run(1, scores(21.5, 100, Some(0.75))),
                ],
            ),
        ];
        let t = table(&config, &results);
        assert!(
            t.contains("seeds 0, 1 (mean ± sample std over seeds)"),
            "{t}"
        );
        assert!(t.contains("| row | switches | seeds | PSNR (dB) |"), "{t}");
        let phi_line = t.lines().find(|l| l.starts_with("| phi ")).unwrap();
        assert!(phi_line.contains("| 2 | 21.00 ± 1.41 |"), "{phi_line}");
        assert!(phi_line.contains("| 200 ± 141 |"), "{phi_line}");
        assert!(phi_line.ends_with("| - | - | - |"), "{phi_line}");
        let full_line = t.lines().find(|l| l.starts_with("| full ")).unwrap();
        assert!(full_line.contains("| 21.25 ± 0.35 |"), "{full_line}");
        assert!(
            full_line.ends_with("| 0.500 ± 0.354 | 0.100 | 0.500 / - |"),
            "{full_line}"
        );
        // One seed: the heading names it and the cells carry no spread.
        let single = vec![AblationResult::of(phi, vec![run(4, scores(20.0, 1, None))])];
        let t = table(&config, &single);
        assert!(t.contains("per row, seed 4\n"), "{t}");
        assert!(!t.contains('±'), "{t}");
    }

    /// The table's format over three seeds (with val, LPIPS on some rows only, and rows with and
    /// without evolution), and with one seed.
    #[test]
    fn table_format_snapshot() {
        let rows = ladder();
        let config = TrainConfig::preset(evogs_train::Preset::Tiny);
        let with_lpips = |mut s: Scores, v: f64| {
            s.lpips_alex = Some(v);
            s.val_lpips_alex = Some(v + 0.01);
            s
        };
        let results = vec![
            AblationResult::of(
                &rows[1],
                vec![
                    run(0, with_lpips(scores(22.0, 3000, None), 0.06)),
                    run(1, with_lpips(scores(22.5, 3100, None), 0.07)),
                    run(2, with_lpips(scores(21.5, 2900, None), 0.05)),
                ],
            ),
            AblationResult::of(
                &rows[5],
                vec![
                    run(0, scores(22.25, 3050, Some(0.5))),
                    run(1, scores(22.5, 3150, Some(0.6))),
                    run(2, scores(22.0, 2950, Some(0.7))),
                ],
            ),
            AblationResult::of(
                &rows[6],
                vec![
                    run(0, scores(20.0, 3400, Some(0.0))),
                    run(1, scores(20.5, 3300, Some(0.0))),
                    run(2, scores(19.5, 3500, Some(0.0))),
                ],
            ),
        ];
        insta::assert_snapshot!("table_three_seeds", table(&config, &results));
        let single = vec![AblationResult::of(
            &rows[5],
            vec![run(3, scores(22.25, 3050, Some(0.5)))],
        )];
        insta::assert_snapshot!("table_one_seed", table(&config, &single));
    }

    #[test]
    fn run_directories_gain_a_seed_level_only_with_several_seeds() {
        let row = &ladder()[0];
        let mut request = AblationRequest {
            data: PathBuf::from("d"),
            out: PathBuf::from("o"),
            config: TrainConfig::preset(evogs_train::Preset::Tiny),
            rows: vec![row.clone()],
            seeds: seeds_from(7, 1),
        };
        assert_eq!(request.run_dir(row, 7), PathBuf::from("o/baseline"));
        request.seeds = seeds_from(7, 3);
        assert_eq!(request.seeds, [7, 8, 9]);
        assert_eq!(request.run_dir(row, 8), PathBuf::from("o/baseline/seed8"));
        assert_eq!(seeds_from(u64::MAX, 2), [u64::MAX, 0]);
    }

    #[test]
    fn select_keeps_ladder_order_and_refuses_bad_names() {
        let names = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        let rows = select(&names(&["k1", "baseline"])).unwrap();
        let got: Vec<&str> = rows.iter().map(|r| r.name).collect();
        assert_eq!(got, ["baseline", "k1"]);
        assert_eq!(select(&[]).unwrap().len(), ladder().len());
        let e = select(&names(&["nope"])).unwrap_err().to_string();
        assert!(
            e.contains("rows") && e.contains("nope") && e.contains("k0.5"),
            "{e}"
        );
        let e = select(&names(&["phi", "phi"])).unwrap_err().to_string();
        assert!(e.contains("twice"), "{e}");
    }
}
