//! Diagnostic of a training run's deformation (issue Q): trains in segments and, after each,
//! prints the training-view PSNR, the network's gradient norm and update size, the deformation's
//! output scale, how much the Gaussians move over time (all, and those in a canonical box), and
//! the mean PSNR over every training view and, for reporting only, over a second split.
//!
//! ```text
//! cargo run --release -p evogs-train --example probe -- DATA OUT ITERATIONS EVERY \
//!     [--preset cpu] [--method baseline] [--patch JSON] [--region x0,y0,z0,x1,y1,z1] [--report val]
//!     [--stop N] [--continue yes]
//! ```
//! `--patch` is merged into the config (after the preset is scaled to ITERATIONS), e.g.
//! `'{"lr":{"deform_max_steps":40000}}'`. `--stop N` ends the run after iteration N of the
//! ITERATIONS-long schedule (the schedule's first N iterations, not a compressed one).
//! `--continue yes` resumes the run already in OUT with the settings of its `config.json` (e.g. a
//! copy of a warmed-up run whose network settings were edited) instead of starting afresh. Each
//! segment also prints (stderr) the canonical box of the 1% most-moving opaque Gaussians and,
//! with `--region`, the region's mean displacement at t = 0, 0.1, …, 1.

use std::path::PathBuf;

use evogs_eval::LoadedRun;
use evogs_io::Split;
use evogs_metrics::{ImageSize, psnr};
use evogs_train::config::{Method, Preset, TrainConfig};
use evogs_train::data::load_split;
use evogs_train::run::{TrainRequest, train};
use splat_raster::RenderOptions;

fn merge(base: &mut serde_json::Value, patch: &serde_json::Value) {
    match (base, patch) {
        (serde_json::Value::Object(b), serde_json::Value::Object(p)) => {
            for (k, v) in p {
                merge(b.entry(k.clone()).or_insert(serde_json::Value::Null), v);
            }
        }
        (b, p) => *b = p.clone(),
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let data = PathBuf::from(&args[1]);
    let out = PathBuf::from(&args[2]);
    let iterations: u64 = args[3].parse()?;
    let every: u64 = args[4].parse()?;
    let mut preset = Preset::Cpu;
    let mut method = Method::Baseline;
    let mut patch = serde_json::json!({});
    let mut region: Option<[f32; 6]> = None;
    let mut report = Split::Val;
    let mut stop_at = iterations;
    let mut continue_existing = false;
    let mut k = 5;
    while k < args.len() {
        let v = &args[k + 1];
        match args[k].as_str() {
            "--preset" => preset = v.parse()?,
            "--method" => method = v.parse()?,
            "--patch" => patch = serde_json::from_str(v)?,
            "--region" => {
                let p: Vec<f32> = v.split(',').map(|x| x.parse().unwrap()).collect();
                region = Some([p[0], p[1], p[2], p[3], p[4], p[5]]);
            }
            "--stop" => stop_at = v.parse()?,
            "--continue" => continue_existing = v == "yes",
            "--report" => report = if v == "test" { Split::Test } else { Split::Val },
            other => return Err(format!("unknown argument {other}").into()),
        }
        k += 2;
    }
    let mut config = TrainConfig::preset(preset).with_iterations(iterations);
    config.method = method;
    let mut value = serde_json::to_value(&config)?;
    merge(&mut value, &patch);
    let config: TrainConfig = serde_json::from_value(value)?;
    eprintln!("{}", serde_json::to_string(&config)?);
    let bg = config.background.rgb();
    let train_views = load_split(&data, Split::Train, config.time_from, bg, config.downscale)?;
    let report_views = load_split(&data, report, config.time_from, bg, config.downscale)?;
    let opts = RenderOptions {
        background: bg,
        sh_degree: None,
    };
    println!(
        "it\tsecs\ttrain_psnr\tgrad_norm\tupd_rel\tgauss\td_xyz_rms\td_rot_rms\td_scl_rms\tmove50\tmove90\tmove99\tregion_n\tregion_move\ttrain_sub5\t{report}"
    );
    let mut prev_params: Option<Vec<f32>> = None;
    // ITERATIONS = 0: analyse the run in OUT as it is.
    let analyse_only = iterations == 0;
    let mut done = if continue_existing {
        LoadedRun::open(&out)?.summary.iteration
    } else {
        0
    };
    let mut secs = 0.0;
    while done < stop_at || analyse_only {
        let stop = (done + every).min(stop_at);
        let (mut psnr_sum, mut grad_sum, mut n, mut gn) = (0.0, 0.0, 0u64, 0u64);
        let summary = if analyse_only {
            LoadedRun::open(&out)?.summary
        } else {
            train(
                &TrainRequest {
                    data: data.clone(),
                    out: out.clone(),
                    config: config.clone(),
                    resume: done > 0,
                    stop_after: Some(stop),
                    resume_backend: None,
                    resume_net_backend: None,
                },
                &mut |r, _| {
                    psnr_sum += r.psnr;
                    n += 1;
                    if let Some(g) = r.net_grad_norm {
                        grad_sum += g;
                        gn += 1;
                    }
                },
            )?
        };
        secs += summary.seconds;
        done = if analyse_only {
            summary.iteration
        } else {
            stop
        };
        let mut run = LoadedRun::open(&out)?;
        // The run is only marked as deforming once training got past the warm-up.
        let deforms = run.deforms();
        let params: Vec<f32> = run
            .backbone
            .params()
            .iter()
            .flat_map(|(_, p)| {
                let mut v = vec![0.0; p.len()];
                p.read_into(&mut v);
                v
            })
            .collect();
        let upd = prev_params.as_ref().map_or(f64::NAN, |pp| {
            let num: f64 = pp
                .iter()
                .zip(&params)
                .map(|(a, b)| f64::from(a - b).powi(2))
                .sum();
            let den: f64 = pp.iter().map(|a| f64::from(*a).powi(2)).sum();
            (num / den.max(1e-30)).sqrt()
        });
        prev_params = Some(params);
        // Displacements over 11 times.
        let canon = run.canonical.clone();
        let n_g = canon.len();
        let times: Vec<f32> = (0..=10).map(|i| i as f32 / 10.0).collect();
        let mut disp: Vec<Vec<[f32; 3]>> = Vec::new();
        let (mut rx, mut rr, mut rs) = (0.0f64, 0.0f64, 0.0f64);
        for &t in &times {
            let g = run.deformed(t)?;
            let d: Vec<[f32; 3]> = g
                .means
                .iter()
                .zip(&canon.means)
                .map(|(a, b)| [a[0] - b[0], a[1] - b[1], a[2] - b[2]])
                .collect();
            if (t - 0.5).abs() < 1e-6 {
                for (i, di) in d.iter().enumerate() {
                    rx += di.iter().map(|v| f64::from(*v).powi(2)).sum::<f64>();
                    rr += (0..4)
                        .map(|c| f64::from(g.rotations[i][c] - canon.rotations[i][c]).powi(2))
                        .sum::<f64>();
                    rs += (0..3)
                        .map(|c| f64::from(g.log_scales[i][c] - canon.log_scales[i][c]).powi(2))
                        .sum::<f64>();
                }
            }
            disp.push(d);
        }
        let nn = n_g.max(1) as f64;
        // Per Gaussian: largest distance of its position at a time from its mean position.
        let movement = |i: usize| -> f32 {
            let mut mean = [0.0f32; 3];
            for d in &disp {
                for c in 0..3 {
                    mean[c] += d[i][c] / disp.len() as f32;
                }
            }
            disp.iter()
                .map(|d| {
                    ((d[i][0] - mean[0]).powi(2)
                        + (d[i][1] - mean[1]).powi(2)
                        + (d[i][2] - mean[2]).powi(2))
                    .sqrt()
                })
                .fold(0.0, f32::max)
        };
        let opaque: Vec<usize> = (0..n_g)
            .filter(|&i| canon.opacity_logits[i] > (0.1f32 / 0.9).ln())
            .collect();
        let mut moves: Vec<f32> = opaque.iter().map(|&i| movement(i)).collect();
        // Where the most-moving 1% sit in the canonical space (5th..95th percentile per axis).
        let mut by_move: Vec<(f32, usize)> = opaque.iter().map(|&i| (movement(i), i)).collect();
        by_move.sort_by(|a, b| b.0.total_cmp(&a.0));
        let top: Vec<usize> = by_move
            .iter()
            .filter(|m| m.0.is_finite())
            .take(opaque.len().div_ceil(100))
            .map(|m| m.1)
            .collect();
        if !top.is_empty() {
            let pct = |c: usize, p: f64| {
                let mut v: Vec<f32> = top.iter().map(|&i| canon.means[i][c]).collect();
                v.sort_by(f32::total_cmp);
                v[((v.len() - 1) as f64 * p) as usize]
            };
            eprintln!(
                "it {done}: top-1% movers ({}) box {:.2},{:.2},{:.2},{:.2},{:.2},{:.2}",
                top.len(),
                pct(0, 0.05),
                pct(1, 0.05),
                pct(2, 0.05),
                pct(0, 0.95),
                pct(1, 0.95),
                pct(2, 0.95)
            );
        }
        moves.sort_by(f32::total_cmp);
        let q = |p: f64| {
            if moves.is_empty() {
                f32::NAN
            } else {
                moves[((moves.len() - 1) as f64 * p) as usize]
            }
        };
        let (region_n, region_move) = match region {
            Some(b) => {
                let inside: Vec<usize> = opaque
                    .iter()
                    .copied()
                    .filter(|&i| {
                        let m = canon.means[i];
                        (0..3).all(|c| m[c] >= b[c] && m[c] <= b[c + 3])
                    })
                    .collect();
                let mean_move =
                    inside.iter().map(|&i| movement(i)).sum::<f32>() / inside.len().max(1) as f32;
                // Mean displacement of the region per time.
                let traj: Vec<String> = disp
                    .iter()
                    .map(|d| {
                        let mut s = [0.0f32; 3];
                        for &i in &inside {
                            for c in 0..3 {
                                s[c] += d[i][c] / inside.len().max(1) as f32;
                            }
                        }
                        format!("({:.3},{:.3},{:.3})", s[0], s[1], s[2])
                    })
                    .collect();
                eprintln!("it {done}: region trajectory t=0..1: {}", traj.join(" "));
                // Against the ground truth: the share of the region's Gaussians whose centre,
                // deformed to each training view's time (or left canonical), projects onto the
                // object in that view's image (a pixel brighter than the black background).
                let mut off = Vec::new();
                for v in &train_views.views {
                    let g = run.deformed(v.time)?;
                    let on_object = |p: [f32; 3]| {
                        let c = v.camera.world_to_camera(glam::Vec3::from(p));
                        if c.z <= 0.0 {
                            return false;
                        }
                        let u = v.camera.fx * c.x / c.z + v.camera.cx;
                        let w = v.camera.fy * c.y / c.z + v.camera.cy;
                        if u < 0.0 || w < 0.0 {
                            return false;
                        }
                        let (u, w) = (u as u32, w as u32);
                        u < v.image.width
                            && w < v.image.height
                            && v.image.pixels[(w * v.image.width + u) as usize]
                                .iter()
                                .any(|&x| x > 0.05)
                    };
                    let n = inside.len().max(1) as f32;
                    let moved =
                        inside.iter().filter(|&&i| !on_object(g.means[i])).count() as f32 / n;
                    let still = inside
                        .iter()
                        .filter(|&&i| !on_object(canon.means[i]))
                        .count() as f32
                        / n;
                    off.push((v.time, moved, still));
                }
                off.sort_by(|a, b| a.0.total_cmp(&b.0));
                let mean = |k: usize| {
                    off.iter()
                        .map(|o| if k == 1 { o.1 } else { o.2 })
                        .sum::<f32>()
                        / off.len().max(1) as f32
                };
                let per_time: Vec<String> = off
                    .iter()
                    .map(|o| format!("{:.2}:{:.2}/{:.2}", o.0, o.1, o.2))
                    .collect();
                eprintln!(
                    "it {done}: region off the ground-truth silhouette, deformed / canonical: mean {:.3} / {:.3}; per time {}",
                    mean(1),
                    mean(2),
                    per_time.join(" ")
                );
                (inside.len(), mean_move)
            }
            None => (0, f32::NAN),
        };
        let mean_psnr = |views: &evogs_train::data::SplitViews,
                         run: &mut LoadedRun|
         -> Result<f64, Box<dyn std::error::Error>> {
            let mut s = 0.0;
            for v in &views.views {
                let g = if deforms {
                    run.deformed(v.time)?
                } else {
                    run.canonical.clone()
                };
                let o = run.raster.forward(g.view(), &v.camera, &opts)?;
                let c: Vec<[f32; 3]> = o
                    .color
                    .iter()
                    .map(|c| c.map(|x| x.clamp(0.0, 1.0)))
                    .collect();
                let size = ImageSize::new(v.image.width as usize, v.image.height as usize);
                s += psnr(size, &c, &v.image.pixels)?;
            }
            Ok(s / views.views.len() as f64)
        };
        let subset = evogs_train::data::SplitViews {
            split: Split::Train,
            views: train_views.views.iter().step_by(5).cloned().collect(),
        };
        let all_train = mean_psnr(if analyse_only { &train_views } else { &subset }, &mut run)?;
        let rep = mean_psnr(&report_views, &mut run)?;
        println!(
            "{done}\t{secs:.0}\t{:.2}\t{:.3e}\t{upd:.3e}\t{n_g}\t{:.4}\t{:.4}\t{:.4}\t{:.4}\t{:.4}\t{:.4}\t{region_n}\t{region_move:.4}\t{all_train:.2}\t{rep:.2}",
            psnr_sum / n.max(1) as f64,
            grad_sum / gn.max(1) as f64,
            (rx / nn).sqrt(),
            (rr / nn).sqrt(),
            (rs / nn).sqrt(),
            q(0.5),
            q(0.9),
            q(0.99),
        );
        if analyse_only {
            break;
        }
    }
    Ok(())
}
