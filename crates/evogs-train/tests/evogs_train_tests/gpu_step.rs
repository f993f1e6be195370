//! One whole training step on wgpu (the rasterizer, the loss and the D-3DGS network on the
//! device, the network's gradient, Adam step and moments and the loss's image, target and
//! gradient resident there; lavapipe in CI) against the same
//! step on the CPU, from the same state: the loss, every Adam moment of every group (the six
//! per-Gaussian groups and the network's, read back) and every parameter after the step.
//!
//! Tolerances. The moments are `(1 − β1) g` and `(1 − β2) g²`, so they carry the gradients'
//! differences: the rasterizer's parity contract (ARCHITECTURE §4, gradients within
//! `1e-3 · max(|c|, s)`, `s` the root mean square of that kind) passed through the loss and, for
//! the network, through its own f32 sums (2e-5, `tiny-nn`'s `gpu_deform.rs`): `m` within
//! `1e-3 · max(|c|, s)` and `v` within `2.1e-3 · max(|c|, s)²`, each in its own units. A first
//! Adam step moves each parameter by `lr · g / (|g| + ε)`, `±lr` for any gradient far above
//! ε = 1e-15, so where the CPU's gradient is above 1 % of its group's root mean square (there
//! the tolerance above keeps the sign) the parameters agree to f32 rounding, `1e-6 · max(|p|,
//! lr)`; below it the sign may flip and the two may differ by up to `2 lr`.

use crate::common;

use evogs_io::Split;
use evogs_train::data::load_split;
use evogs_train::{Background, Method, Preset, TrainConfig, Trainer};
use splat_raster::{BackendChoice, Gaussians};
use tiny_nn::{AdamGroup, StoreRef};

fn rms(values: &[f32]) -> f32 {
    (values.iter().map(|&x| f64::from(x).powi(2)).sum::<f64>() / values.len().max(1) as f64).sqrt()
        as f32
}

/// Checks the moments of one group against the CPU's.
fn moments_close(gpu: &AdamGroup, cpu: &AdamGroup) {
    assert_eq!((&gpu.name, gpu.step), (&cpu.name, cpu.step));
    assert_eq!(gpu.m.len(), cpu.m.len(), "{}", cpu.name);
    let s = rms(&cpu.m);
    for (i, (&g, &c)) in gpu.m.iter().zip(&cpu.m).enumerate() {
        let tol = 1e-3 * c.abs().max(s);
        assert!(
            (g - c).abs() <= tol,
            "{}.m[{i}]: {g} vs {c} (±{tol})",
            cpu.name
        );
    }
    let (b1, b2) = (0.9f32, 0.999f32);
    let g_rms = s / (1.0 - b1);
    for (i, (&g, &c)) in gpu.v.iter().zip(&cpu.v).enumerate() {
        let grad = (c / (1.0 - b2)).sqrt();
        let tol = (1.0 - b2) * 2.1e-3 * grad.max(g_rms).powi(2);
        assert!(
            (g - c).abs() <= tol,
            "{}.v[{i}]: {g} vs {c} (±{tol})",
            cpu.name
        );
    }
}

/// Checks parameters after the step against the CPU's, entry by entry with its moment `m`
/// (the CPU's) and the group's largest move on the CPU (its lr).
fn params_close(what: &str, gpu: &[f32], cpu: &[f32], before: &[f32], m: &[f32]) -> usize {
    assert_eq!(
        (gpu.len(), cpu.len(), m.len()),
        (before.len(), before.len(), before.len())
    );
    let lr = cpu
        .iter()
        .zip(before)
        .map(|(c, b)| (c - b).abs())
        .fold(0.0f32, f32::max);
    let s = rms(m);
    let mut flips = 0;
    for (i, (&g, &c)) in gpu.iter().zip(cpu).enumerate() {
        let tol = if m[i].abs() >= 0.01 * s {
            1e-6 * c.abs().max(lr)
        } else {
            flips += usize::from((g - c).abs() > 1e-6 * c.abs().max(lr));
            2.0 * lr + 1e-6 * c.abs()
        };
        assert!((g - c).abs() <= tol, "{what}[{i}]: {g} vs {c} (±{tol})");
    }
    flips
}

/// The backbone's parameters as the host holds them.
fn host_copy(t: &Trainer) -> Vec<Vec<f32>> {
    t.backbone()
        .params()
        .into_iter()
        .map(|(_, p)| match p {
            StoreRef::F32(v) => v.to_vec(),
            StoreRef::F16(_) => panic!("an f32 network"),
        })
        .collect()
}

#[test]
fn one_wgpu_step_matches_the_cpu_step_from_the_same_state() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("scene");
    common::write_scene(&data);
    let mut c = TrainConfig::preset(Preset::Tiny).with_iterations(100);
    c.method = Method::Baseline;
    c.init_points = 400;
    // The network in the first step, and no densification in it.
    c.warm_up = 0;
    let views = load_split(
        &data,
        Split::Train,
        c.time_from,
        c.background.rgb(),
        c.downscale,
    )
    .unwrap();
    let mut cpu = Trainer::new(c.clone(), views.clone()).unwrap();
    let (gpu_config, mut gpu) = {
        let mut g = c.clone();
        g.backend = BackendChoice::Wgpu;
        g.net_backend = BackendChoice::Wgpu;
        (g.clone(), Trainer::new(g, views).unwrap())
    };
    assert!(gpu.network().on_device, "{}", gpu.network());
    assert!(gpu.loss_place().on_device, "{}", gpu.loss_place());
    assert!(!cpu.loss_place().on_device, "{}", cpu.loss_place());
    assert_eq!(gpu_config.net_backend, BackendChoice::Wgpu);
    let before = cpu.state().gaussians().clone();
    let net_before = host_copy(&cpu);
    assert_eq!(gpu.state().gaussians(), &before, "the same starting state");

    let (rc, rg) = (cpu.step().unwrap(), gpu.step().unwrap());
    assert!(!rc.densified && !rg.densified);
    // On the device the network's gradient, moments and updated parameters stay there: the
    // host's copy is the one before the step until the trainer reads them back.
    assert!(rc.net_grad_norm.is_some() && rg.net_grad_norm.is_none());
    assert_eq!(host_copy(&gpu), net_before, "the step stayed on the device");
    gpu.sync_host().unwrap();
    assert_ne!(host_copy(&gpu), net_before, "read back after the step");
    assert!(
        (rc.loss - rg.loss).abs() <= 1e-4 * rc.loss,
        "loss {} vs {}",
        rg.loss,
        rc.loss
    );
    let (ac, ag) = (cpu.state().adam(), gpu.state().adam());
    assert_eq!(ac.groups().len(), ag.groups().len());
    for (g, c) in ag.groups().iter().zip(ac.groups()) {
        moments_close(g, c);
    }

    // Parameters, each array with the moments of its group (3DGS's names).
    let group = |name: &str| {
        ac.groups()
            .iter()
            .find(|g| g.name == name)
            .unwrap_or_else(|| panic!("group {name}"))
    };
    let (gc, gg) = (cpu.state().gaussians(), gpu.state().gaussians());
    let mut flips = 0;
    // The same four arrays of the Gaussians after either step and before it.
    fn arrays(g: &Gaussians) -> [&[f32]; 4] {
        [
            g.means.as_flattened(),
            g.log_scales.as_flattened(),
            g.rotations.as_flattened(),
            &g.opacity_logits,
        ]
    }
    let names = [
        ("means", "xyz"),
        ("log_scales", "scaling"),
        ("rotations", "rotation"),
        ("opacity_logits", "opacity"),
    ];
    for (((what, name), (g, c)), b) in names
        .into_iter()
        .zip(arrays(gg).into_iter().zip(arrays(gc)))
        .zip(arrays(&before))
    {
        flips += params_close(what, g, c, b, &group(name).m);
    }
    // SH: each Gaussian's DC (f_dc) then its higher bands (f_rest).
    let (dc, rest) = (group("f_dc"), group("f_rest"));
    let per = gc.sh.len() / gc.len();
    let sh_m: Vec<f32> = (0..gc.len())
        .flat_map(|i| {
            dc.m[i * 3..i * 3 + 3]
                .iter()
                .chain(&rest.m[i * (per - 3)..(i + 1) * (per - 3)])
                .copied()
        })
        .collect();
    flips += params_close("sh", &gg.sh, &gc.sh, &before.sh, &sh_m);
    // The network's buffers, each with its group (the groups after the six per-Gaussian ones,
    // in the backbone's order).
    let (nc, ng) = (cpu.backbone().params(), gpu.backbone().params());
    assert_eq!(nc.len(), net_before.len());
    for (((name, c), (_, g)), (b, group)) in nc
        .iter()
        .zip(&ng)
        .zip(net_before.iter().zip(&ac.groups()[6..]))
    {
        let (StoreRef::F32(c), StoreRef::F32(g)) = (c, g) else {
            panic!("an f32 network");
        };
        flips += params_close(name, g, c, b, &group.m);
    }
    eprintln!(
        "parameters whose gradient's sign flipped (all below 1 % of their group's rms): {flips}"
    );
}

/// With the rasterizer on wgpu and a fixed background the loss runs on the device: a step moves
/// no image between host and device. Against the same step with the loss on the host (a random
/// background, whose target is made on the host each iteration; otherwise the same bytes), it
/// uploads `12` bytes a pixel less (the colour's gradient) and reads back `20` bytes a pixel
/// less (colour, alpha, depth) but the loss's partial sums (12 bytes per 4 096 values), with
/// one wait more (the loss's read-back). evogs-io's lego fixture: 100 × 100 views.
#[test]
fn the_loss_on_the_device_moves_no_image() {
    let data =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../evogs-io/tests/data/dnerf-lego");
    let first_step = |background| {
        let mut c = TrainConfig::preset(Preset::Tiny);
        c.background = background;
        c.downscale = 1.0;
        c.init_points = 300;
        c.backend = BackendChoice::Wgpu;
        c.net_backend = BackendChoice::Cpu;
        let views = load_split(&data, Split::Train, c.time_from, background.rgb(), 1.0).unwrap();
        let mut t = Trainer::new(c, views).unwrap();
        let before = t.traffic().unwrap();
        let report = t.step().unwrap();
        assert!(!report.densified && report.loss.is_finite());
        let moved = t.traffic().unwrap().since(&before);
        (t.loss_place().clone(), moved)
    };
    let (host_place, host) = first_step(Background::Random);
    let (device_place, device) = first_step(Background::Black);
    assert!(!host_place.on_device, "{host_place}");
    assert!(device_place.on_device, "{device_place}");
    assert!(
        device_place
            .to_string()
            .starts_with("loss: wgpu (on the rasterizer's device")
    );
    let npix = 100 * 100u64;
    let groups = (3 * npix).div_ceil(4096);
    assert_eq!(
        host.bytes_up - device.bytes_up,
        12 * npix,
        "{host:?} {device:?}"
    );
    assert_eq!(
        host.bytes_down - device.bytes_down,
        20 * npix - 12 * groups,
        "{host:?} {device:?}"
    );
    assert_eq!(device.waits, host.waits + 1);
}
