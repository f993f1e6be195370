//! The paper's ablation ladder at equal iterations on one dataset: the rows ([`ladder`]), the
//! runner ([`run_ablation`]: train, then evaluate on test and val), and its outputs
//! ([`write_outputs`]: `ablation.md`, `ablation.json`, `ablation.png`, each written atomically).
//!
//! [`train_and_evaluate`] is the one-method piece `evogs demo` shares.

use std::path::{Path, PathBuf};

use evogs_io::Split;
use serde::Serialize;

use crate::error::ExperimentError;
use crate::write::{write_bytes, write_json, write_png};
use evogs_train::config::{Method, TrainConfig};
use evogs_train::eval::{EvalLpips, evaluate};
use evogs_train::evo_settings::{
    DensifyPolicy, EvoSettings, Gain, HistoryMode, Precision, Storage,
};
use evogs_train::run::{LoadedRun, TrainRequest, train};

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
                    if e.evolution { "on" } else { "off" },
                    e.history,
                    e.densify,
                    e.gain,
                    e.net_precision,
                    e.buffer
                )
            }
        }
    }
}

/// The ladder, in the paper's order: baseline; Φ alone; evolution with re-queried history; with
/// the buffer; + uncertainty trigger; + deformation-aware clone/split (the full method, learned
/// K, f32); K fixed at 0, 0.5, 1; f16 network; f16 buffer.
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
                evolution: false,
                ..standard.clone()
            },
        ),
        evo(
            "evo-requery",
            "evolution, history re-queried from Φ",
            EvoSettings {
                history: HistoryMode::Requery,
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
        evo(
            "k0",
            "K fixed at 0 (prior only)",
            EvoSettings {
                gain: Gain::Fixed(0.0),
                ..full.clone()
            },
        ),
        evo(
            "k0.5",
            "K fixed at 0.5",
            EvoSettings {
                gain: Gain::Fixed(0.5),
                ..full.clone()
            },
        ),
        evo(
            "k1",
            "K fixed at 1 (observation only)",
            EvoSettings {
                gain: Gain::Fixed(1.0),
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
                buffer: Storage::F16,
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
    let backend = config.backend;
    let summary = train(
        &TrainRequest {
            data: data.to_path_buf(),
            out: out.to_path_buf(),
            config,
            resume: false,
            stop_after: None,
            resume_backend: None,
        },
        &mut |_, _| {},
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
    })
}

/// What to run.
#[derive(Clone, Debug)]
pub struct AblationRequest {
    /// Dataset directory.
    pub data: PathBuf,
    /// Output directory: one run directory per row, and the tables and plot.
    pub out: PathBuf,
    /// Preset, iterations, seed and the rest; each row sets `method` and `evogs`.
    pub config: TrainConfig,
    /// The rows, in order.
    pub rows: Vec<LadderRow>,
}

/// One row's result.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AblationResult {
    /// The row's name.
    pub name: String,
    /// What it isolates.
    pub description: String,
    /// Its switches ([`LadderRow::switches`]).
    pub switches: String,
    /// Its run directory.
    pub run: PathBuf,
    /// Its scores.
    #[serde(flatten)]
    pub scores: Scores,
}

/// Progress of [`run_ablation`].
#[derive(Debug)]
pub enum Progress<'a> {
    /// Row `index` (0-based) of `total` is starting.
    Started {
        /// 0-based.
        index: usize,
        /// Rows in all.
        total: usize,
        /// The row.
        row: &'a LadderRow,
    },
    /// Row `index` of `total` is done.
    Finished {
        /// 0-based.
        index: usize,
        /// Rows in all.
        total: usize,
        /// Its result.
        result: &'a AblationResult,
    },
}

/// Runs every row of `request` (train, evaluate on test, and on val when the dataset has one;
/// LPIPS with the networks of `lpips`), writes the outputs ([`write_outputs`]) and returns the
/// results.
pub fn run_ablation(
    request: &AblationRequest,
    lpips: &EvalLpips,
    progress: &mut dyn FnMut(Progress<'_>),
) -> Result<Vec<AblationResult>, ExperimentError> {
    if request.rows.is_empty() {
        return Err(ExperimentError::config("rows", "no rows to run"));
    }
    let dataset = evogs_train::data::open_dataset(&request.data, request.config.time_from)?;
    let with_val = !dataset.split(Split::Val).is_empty();
    std::fs::create_dir_all(&request.out).map_err(|e| ExperimentError::dir(&request.out, e))?;
    let total = request.rows.len();
    let mut results = Vec::with_capacity(total);
    for (index, row) in request.rows.iter().enumerate() {
        progress(Progress::Started { index, total, row });
        let mut config = request.config.clone();
        config.method = row.method;
        config.evogs = row.evo.clone();
        let run = request.out.join(row.name);
        let scores = train_and_evaluate(&request.data, &run, config, with_val, lpips)?;
        results.push(AblationResult {
            name: row.name.to_string(),
            description: row.description.to_string(),
            switches: row.switches(),
            run,
            scores,
        });
        progress(Progress::Finished {
            index,
            total,
            result: results.last().expect("just pushed"),
        });
    }
    write_outputs(&request.out, &request.config, &results)?;
    Ok(results)
}

/// The markdown table of `results` under a heading naming the preset and budget.
pub fn table(config: &TrainConfig, results: &[AblationResult]) -> String {
    let with_val = results.iter().any(|r| r.scores.val_psnr.is_some());
    let mut s = format!(
        "# evogs ablate: {} iterations per row, seed {}\n\n\
         | row | switches | PSNR (dB) | SSIM | lpips_alex |{} flicker | jitter | training (s) | Gaussians | state (KiB) |\n\
         | --- | --- | ---: | ---: | ---: |{} ---: | ---: | ---: | ---: | ---: |\n",
        config.iterations,
        config.seed,
        if with_val {
            " val PSNR (dB) | val SSIM | val lpips_alex |"
        } else {
            ""
        },
        if with_val {
            " ---: | ---: | ---: |"
        } else {
            ""
        },
    );
    for r in results {
        let c = &r.scores;
        let val = if with_val {
            format!(
                " {} | {} | {} |",
                c.val_psnr.map_or("-".into(), |v| format!("{v:.2}")),
                c.val_ssim.map_or("-".into(), |v| format!("{v:.4}")),
                c.val_lpips_alex.map_or("-".into(), |v| format!("{v:.4}"))
            )
        } else {
            String::new()
        };
        s += &format!(
            "| {} | {} | {:.2} | {:.4} | {} |{val} {:.5} | {:.3e} | {:.1} | {} | {:.1} |\n",
            r.name,
            r.switches,
            c.psnr,
            c.ssim,
            c.lpips_alex.map_or("-".into(), |v| format!("{v:.4}")),
            c.flicker,
            c.jitter,
            c.seconds,
            c.gaussians,
            c.state_bytes as f64 / 1024.0
        );
    }
    s
}

/// Writes `ablation.md`, `ablation.json` and `ablation.png` (PSNR against training time, one
/// labelled point per row) into `out`, each atomically.
pub fn write_outputs(
    out: &Path,
    config: &TrainConfig,
    results: &[AblationResult],
) -> Result<(), ExperimentError> {
    write_bytes(&out.join("ablation.md"), table(config, results).as_bytes())?;
    write_json(
        &out.join("ablation.json"),
        &serde_json::json!({
            "iterations": config.iterations,
            "seed": config.seed,
            "rows": results,
        }),
    )?;
    let png = out.join("ablation.png");
    let image = crate::ablate_plot::plot(results)
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
                TriggerDeform,
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
            assert_eq!(row.evo.evolution, evolution, "{name}");
            assert_eq!(row.evo.history, history, "{name}");
            assert_eq!(row.evo.densify, densify, "{name}");
            assert_eq!(row.evo.gain, gain, "{name}");
            assert_eq!(row.evo.net_precision, net, "{name}");
            assert_eq!(row.evo.buffer, buffer, "{name}");
            // Everything else is the method's default.
            let rest = EvoSettings {
                evolution: true,
                history: Buffer,
                densify: TriggerDeform,
                gain: Learned,
                net_precision: P::F32,
                buffer: S::F32,
                ..row.evo.clone()
            };
            assert_eq!(rest, EvoSettings::default(), "{name}");
            row.evo.validate().unwrap();
        }
    }

    #[test]
    fn evolution_defaults_on_in_older_configs() {
        let mut json = serde_json::to_value(EvoSettings::default()).unwrap();
        json.as_object_mut().unwrap().remove("evolution");
        let back: EvoSettings = serde_json::from_value(json).unwrap();
        assert!(back.evolution);
        let off = EvoSettings {
            evolution: false,
            ..EvoSettings::default()
        };
        let round: EvoSettings =
            serde_json::from_value(serde_json::to_value(&off).unwrap()).unwrap();
        assert!(!round.evolution);
        // The switch reaches evo-state, which then keeps no buffer.
        let config = evogs_train::evo_backbone::evo_config(&off, 1.0);
        assert!(!config.evolution);
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
