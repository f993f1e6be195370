//! Every EvoGS switch of `evogs train` parses and reaches the run config (table-driven), bad
//! values are refused naming the setting, and the flags cannot be mixed with `--resume`.

use clap::Parser;
use evogs_backbones::{DensifyPolicy, EvoSettings, Gain, HistoryMode, Layout, Precision, Storage};
use evogs_cli::train_cmd::config_from_args;
use evogs_cli::{Cli, Command};
use evogs_train::{Method, TrainConfig};

fn config(flags: &[&str]) -> anyhow::Result<TrainConfig> {
    let mut argv = vec!["evogs", "train", "--data", "d", "--out", "o"];
    if !flags.contains(&"--method") {
        argv.extend_from_slice(&["--method", "evogs"]);
    }
    argv.extend_from_slice(flags);
    let cli = Cli::try_parse_from(argv)?;
    match cli.command {
        Command::Train(args) => config_from_args(&args),
        _ => unreachable!("parsed a train command"),
    }
}

#[test]
fn each_switch_reaches_the_config() {
    let comps = |pos, rot, scale| Layout {
        position: pos,
        rotation: rot,
        scale,
        opacity: false,
        colour: false,
    };
    type Check = fn(&EvoSettings) -> String;
    let table: Vec<(&[&str], Check, String)> = vec![
        (
            &["--gain", "learned"],
            |e| format!("{:?}", e.evo.gain),
            format!("{:?}", Gain::Learned),
        ),
        (
            &["--gain", "0"],
            |e| format!("{:?}", e.evo.gain),
            format!("{:?}", Gain::Fixed(0.0)),
        ),
        (
            &["--gain", "0.5"],
            |e| format!("{:?}", e.evo.gain),
            format!("{:?}", Gain::Fixed(0.5)),
        ),
        (
            &["--gain", "1"],
            |e| format!("{:?}", e.evo.gain),
            format!("{:?}", Gain::Fixed(1.0)),
        ),
        (
            &["--history", "buffer"],
            |e| e.evo.history.to_string(),
            HistoryMode::Buffer.to_string(),
        ),
        (
            &["--history", "requery"],
            |e| e.evo.history.to_string(),
            HistoryMode::Requery.to_string(),
        ),
        (
            &["--densify", "standard"],
            |e| e.densify.to_string(),
            DensifyPolicy::Standard.to_string(),
        ),
        (
            &["--densify", "trigger"],
            |e| e.densify.to_string(),
            DensifyPolicy::Trigger.to_string(),
        ),
        (
            &["--densify", "trigger+deform"],
            |e| e.densify.to_string(),
            DensifyPolicy::TriggerDeform.to_string(),
        ),
        (
            &["--buffer", "f32"],
            |e| e.evo.storage.to_string(),
            Storage::F32.to_string(),
        ),
        (
            &["--buffer", "f16"],
            |e| e.evo.storage.to_string(),
            Storage::F16.to_string(),
        ),
        (
            &["--net-precision", "f32"],
            |e| e.net_precision.to_string(),
            Precision::F32.to_string(),
        ),
        (
            &["--net-precision", "f16"],
            |e| e.net_precision.to_string(),
            Precision::F16.to_string(),
        ),
        (
            &["--components", "pos,rot,scale"],
            |e| format!("{:?}", e.evo.layout),
            format!("{:?}", comps(true, true, true)),
        ),
        (
            &["--components", "pos"],
            |e| format!("{:?}", e.evo.layout),
            format!("{:?}", comps(true, false, false)),
        ),
        (
            &["--components", "rotation,scale"],
            |e| format!("{:?}", e.evo.layout),
            format!("{:?}", comps(false, true, true)),
        ),
        (
            &["--components", "pos,rot,scale,opacity,colour"],
            |e| format!("{:?}", e.evo.layout),
            format!(
                "{:?}",
                Layout {
                    opacity: true,
                    colour: true,
                    ..comps(true, true, true)
                }
            ),
        ),
        (
            &["--grid-lr-scale", "10"],
            |e| e.grid_lr_scale.to_string(),
            10f32.to_string(),
        ),
        (
            &["--motion-floor", "5e-4"],
            |e| e.evo.motion_floor.to_string(),
            5e-4f32.to_string(),
        ),
        (
            &["--bspline-controls", "48"],
            |e| e.bspline_controls.to_string(),
            48.to_string(),
        ),
        (
            &["--bspline-width", "32"],
            |e| e.bspline_width.to_string(),
            32.to_string(),
        ),
        (
            &["--triplane-resolutions", "64,128"],
            |e| format!("{:?}", e.triplane_resolutions),
            format!("{:?}", [64, 128]),
        ),
        (
            &["--triplane-combine", "product"],
            |e| e.triplane_combine.to_string(),
            "product".to_string(),
        ),
        (
            &["--triplane-channels", "12"],
            |e| e.triplane_channels.to_string(),
            12.to_string(),
        ),
    ];
    for (flags, get, want) in table {
        let c = config(flags).unwrap_or_else(|e| panic!("{flags:?}: {e:#}"));
        assert_eq!(c.method, Method::Evogs);
        assert_eq!(get(&c.backbones.evogs), want, "{flags:?}");
        // The run's config.json records it and reads it back.
        let back: TrainConfig = serde_json::from_str(&serde_json::to_string(&c).unwrap()).unwrap();
        assert_eq!(back, c, "{flags:?}");
    }
    // The network's width is the run's, not EvoGS's (Φ decodes at half of it).
    assert_eq!(config(&["--net-width", "128"]).unwrap().net.width, 128);
    // The network rate's decay is counted on the run's schedule, after `--iterations` scaled
    // the preset's.
    for method in ["baseline", "evogs"] {
        let c = config(&[
            "--method",
            method,
            "--preset",
            "dnerf",
            "--net-lr-decay",
            "12000",
        ]);
        assert_eq!(c.unwrap().lr.deform_max_steps, 12_000, "{method}");
    }
    let c = config(&["--preset", "dnerf", "--iterations", "6000"]).unwrap();
    assert_eq!(c.lr.deform_max_steps, 20_000);
    let c = config(&[
        "--preset",
        "dnerf",
        "--iterations",
        "6000",
        "--net-lr-decay",
        "6000",
    ]);
    assert_eq!(c.unwrap().lr.deform_max_steps, 6_000);
    assert_eq!(
        config(&["--preset", "dnerf"]).unwrap().net.width,
        TrainConfig::preset(evogs_train::Preset::Dnerf).net.width
    );
    // Without flags: the method's defaults.
    assert_eq!(config(&[]).unwrap().backbones.evogs, EvoSettings::default());
}

#[test]
fn bad_switch_values_name_the_setting() {
    // Parsed by clap into the library types: the message names the flag, the value and what the
    // flag accepts, on one line.
    for (flags, expected) in [
        (&["--gain", "2"][..], "a number in [0, 1]"),
        (&["--gain", "fast"][..], "a number in [0, 1]"),
        (&["--history", "cache"][..], "buffer, requery"),
        (
            &["--densify", "deform"][..],
            "standard, trigger, trigger+deform",
        ),
        (&["--buffer", "f8"][..], "f32, f16"),
        (&["--net-precision", "bf16"][..], "f32, f16"),
        (&["--triplane-combine", "sum"][..], "concat, product"),
        (&["--components", "pos,pos"][..], "listed twice"),
        (
            &["--components", "velocity"][..],
            "pos, rot, scale, opacity, colour",
        ),
        (&["--preset", "huge"][..], "paper, cpu, tiny, dnerf or scgs"),
        (&["--method", "evo"][..], "baseline or evogs"),
        (&["--background", "grey"][..], "white, black or random"),
        (&["--net-lr-decay", "0"][..], "expected a whole number >= 1"),
    ] {
        let e = config(flags).unwrap_err();
        let e = e
            .downcast_ref::<clap::Error>()
            .unwrap_or_else(|| panic!("{flags:?}: not refused by clap: {e:#}"));
        assert_eq!(
            e.kind(),
            clap::error::ErrorKind::ValueValidation,
            "{flags:?}"
        );
        let message = e.to_string();
        let first = message.lines().next().unwrap();
        assert!(
            first.contains(flags[0]) && first.contains(flags[1]) && first.contains(expected),
            "{flags:?}: {message}"
        );
    }
    // Ranges that depend on the setting are checked with the whole config, naming its field.
    for (flags, field) in [
        (&["--motion-floor", "-1"][..], "evogs.motion_floor"),
        (&["--grid-lr-scale", "0"][..], "evogs.grid_lr_scale"),
        (&["--bspline-controls", "3"][..], "evogs.bspline"),
        (&["--bspline-width", "0"][..], "evogs.bspline"),
        (
            &["--triplane-resolutions", "64,1"][..],
            "evogs.triplane_resolutions",
        ),
        (&["--triplane-channels", "0"][..], "evogs.triplane"),
    ] {
        let e = format!("{:#}", config(flags).unwrap_err());
        assert!(e.contains(&format!("`{field}`")), "{flags:?}: {e}");
    }
    // The baseline's network has geometric heads only: opacity and colour are refused for it.
    let cli = Cli::try_parse_from([
        "evogs",
        "train",
        "--data",
        "d",
        "--out",
        "o",
        "--method",
        "baseline",
        "--components",
        "pos,rot,scale,colour",
    ])
    .unwrap();
    let Command::Train(args) = cli.command else {
        unreachable!("parsed a train command")
    };
    let e = format!("{:#}", config_from_args(&args).unwrap_err());
    assert!(
        e.contains("`evogs.components`") && e.contains("--method evogs"),
        "{e}"
    );
    let e = Cli::try_parse_from(["evogs", "train", "--out", "o", "--resume", "--gain", "0"])
        .unwrap_err()
        .to_string();
    assert!(e.contains("--gain"), "{e}");
    let e = Cli::try_parse_from([
        "evogs",
        "train",
        "--out",
        "o",
        "--resume",
        "--net-lr-decay",
        "9",
    ])
    .unwrap_err()
    .to_string();
    assert!(e.contains("--net-lr-decay"), "{e}");
}

#[test]
fn the_dnerf_cap_follows_the_method_unless_given() {
    use evogs_train::config::{
        DNERF_GAUSSIAN_VIEW_BUDGET_EVOGS, DNERF_MAX_GAUSSIANS_BASELINE, DNERF_MAX_GAUSSIANS_EVOGS,
    };
    let cap = |flags: &[&str]| config(flags).unwrap().densify.max_gaussians;
    let budget = |flags: &[&str]| config(flags).unwrap().gaussian_view_budget;
    // EvoGS's budget per view: set by the preset, cleared by a cap given by hand (which is then
    // the cap whatever the views).
    assert_eq!(
        budget(&["--preset", "dnerf"]),
        Some(DNERF_GAUSSIAN_VIEW_BUDGET_EVOGS)
    );
    assert_eq!(budget(&["--preset", "dnerf", "--method", "baseline"]), None);
    let given = config(&["--preset", "dnerf", "--max-gaussians", "30000"]).unwrap();
    assert_eq!(given.gaussian_view_budget, None);
    assert_eq!(given.gaussian_cap(200), Some(30_000));
    let dnerf = ["--preset", "dnerf"];
    assert_eq!(
        cap(&[&dnerf[..], &["--method", "baseline"]].concat()),
        Some(DNERF_MAX_GAUSSIANS_BASELINE)
    );
    assert_eq!(cap(&dnerf), Some(DNERF_MAX_GAUSSIANS_EVOGS));
    assert_eq!(
        cap(&[&dnerf[..], &["--iterations", "3000"]].concat()),
        Some(DNERF_MAX_GAUSSIANS_EVOGS)
    );
    for method in ["baseline", "evogs"] {
        let given = [
            &dnerf[..],
            &["--method", method, "--max-gaussians", "12345"],
        ]
        .concat();
        assert_eq!(cap(&given), Some(12_345), "{method}");
        assert_eq!(cap(&["--preset", "cpu", "--method", method]), None);
    }
}

/// `--preset scgs` is SC-GS's recipe: the scgs backbone at width 64 and EvoGS's cap rule for both
/// methods; `--backbone` and `--control-width` given by hand win over it, and the other presets
/// keep d3dgs and SC-GS's own width 256.
#[test]
fn the_scgs_preset_sets_the_backbone_and_width_unless_given() {
    use evogs_train::BackboneKind;
    use evogs_train::config::DNERF_GAUSSIAN_VIEW_BUDGET_EVOGS;
    for method in ["baseline", "evogs"] {
        let c = config(&["--preset", "scgs", "--method", method]).unwrap();
        assert_eq!(c.backbone, BackboneKind::Scgs, "{method}");
        assert_eq!(
            c.backbones.scgs.width,
            evogs_train::config::SCGS_PRESET_WIDTH
        );
        assert_eq!(
            c.gaussian_view_budget,
            Some(DNERF_GAUSSIAN_VIEW_BUDGET_EVOGS)
        );
    }
    let c = config(&[
        "--preset",
        "scgs",
        "--backbone",
        "d3dgs",
        "--control-width",
        "32",
    ])
    .unwrap();
    assert_eq!(
        (c.backbone, c.backbones.scgs.width),
        (BackboneKind::D3dgs, 32)
    );
    let c = config(&["--preset", "dnerf", "--backbone", "scgs"]).unwrap();
    assert_eq!(
        (c.backbone, c.backbones.scgs.width),
        (BackboneKind::Scgs, 256)
    );
    assert_eq!(
        config(&["--preset", "dnerf"]).unwrap().backbone,
        BackboneKind::D3dgs
    );
}
