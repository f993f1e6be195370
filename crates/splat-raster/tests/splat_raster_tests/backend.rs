//! Choosing the backend at run time: names, `cpu`, `wgpu` and `auto` (on this machine's adapter,
//! which in CI is the software driver lavapipe, so `auto` must fall back to the CPU and say why).

#![cfg(feature = "wgpu")]

use glam::Vec3;
use splat_raster::{
    BackendChoice, BackendKind, Camera, CpuRasterizer, Gaussians, GpuContext, RasterError,
    Rasterizer, RenderOptions, select_rasterizer, sh_coeff_count,
};

#[test]
fn names_round_trip_and_unknown_names_are_errors() {
    for c in BackendChoice::ALL {
        assert_eq!(c.name().parse::<BackendChoice>().unwrap(), c);
        assert_eq!(c.to_string(), c.name());
    }
    assert_eq!(BackendChoice::default(), BackendChoice::Cpu);
    let e = "gpu".parse::<BackendChoice>().unwrap_err();
    assert!(
        matches!(&e, RasterError::UnknownBackend { name, .. } if name == "gpu"),
        "{e:?}"
    );
    assert_eq!(
        e.to_string(),
        "unknown backend `gpu`; expected cpu, wgpu or auto"
    );
}

#[test]
fn cpu_is_the_cpu_backend() {
    let (_, info) = select_rasterizer(BackendChoice::Cpu).unwrap();
    assert_eq!(info.kind, BackendKind::Cpu);
    assert_eq!(info.adapter, None);
    assert_eq!(info.to_string(), "backend: cpu (asked: cpu)");
}

fn scene() -> (Gaussians, Camera) {
    let mut g = Gaussians::with_degree(0);
    for i in 0..20 {
        let x = (i as f32 / 10.0) - 1.0;
        g.means.push([x, 0.3 * x, 0.0]);
        g.log_scales.push([-2.0, -2.5, -2.2]);
        g.rotations.push([1.0, 0.1 * x, 0.0, 0.2]);
        g.opacity_logits.push(1.0);
        for _ in 0..sh_coeff_count(0) {
            g.sh.extend([0.5 * x, 0.2, -0.3]);
        }
    }
    let cam = Camera::look_at(40, 30, 0.8, Vec3::new(0.0, -4.0, 0.5), Vec3::ZERO, Vec3::Z);
    (g, cam)
}

#[test]
fn wgpu_runs_on_any_adapter_and_matches_the_cpu() {
    let (raster, info) = select_rasterizer(BackendChoice::Wgpu)
        .unwrap_or_else(|e| panic!("--backend wgpu needs an adapter (CI installs lavapipe): {e}"));
    assert_eq!(info.kind, BackendKind::Wgpu);
    let adapter = info.adapter.clone().expect("names the adapter");
    let line = info.to_string();
    assert!(line.starts_with("backend: wgpu on "), "{line}");
    assert!(line.contains(&adapter), "{line}");
    let (g, cam) = scene();
    let opts = RenderOptions::default();
    let gpu = raster.forward(g.view(), &cam, &opts).unwrap();
    let cpu = CpuRasterizer::new().forward(g.view(), &cam, &opts).unwrap();
    for (a, b) in gpu.color.iter().zip(&cpu.color) {
        for k in 0..3 {
            assert!((a[k] - b[k]).abs() <= 1e-4, "{a:?} vs {b:?}");
        }
    }
}

#[test]
fn auto_takes_wgpu_only_on_hardware_and_says_why() {
    let ctx = GpuContext::new()
        .unwrap_or_else(|e| panic!("this test needs an adapter (CI installs lavapipe): {e}"));
    let summary = ctx.adapter().clone();
    drop(ctx);
    let (_, info) = select_rasterizer(BackendChoice::Auto).unwrap();
    assert_eq!(info.choice, BackendChoice::Auto);
    assert_eq!(info.adapter.as_deref(), Some(summary.to_string().as_str()));
    let line = info.to_string();
    if summary.hardware {
        assert_eq!(info.kind, BackendKind::Wgpu, "{line}");
        assert!(line.contains("auto: hardware adapter"), "{line}");
    } else {
        // lavapipe: software, so the CPU backend, and the line names the adapter.
        assert_eq!(info.kind, BackendKind::Cpu, "{line}");
        assert!(line.starts_with("backend: cpu (auto: adapter "), "{line}");
        assert!(line.contains(&summary.name), "{line}");
        assert!(line.contains("software"), "{line}");
    }
}
