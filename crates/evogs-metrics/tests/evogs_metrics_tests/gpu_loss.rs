//! The GPU loss (`evogs_metrics::gpu`) against its CPU twin [`LossWorkspace`] (f32, the training
//! loss) and the plain reference [`photometric_loss`] (f64): random images of several sizes
//! (odd ones, one smaller than the window, one large enough for several reduction workgroups),
//! values outside [0, 1] as a renderer produces, and the hard cases (identical images, constant
//! black, one pixel).
//!
//! Tolerances: the loss's terms within 2e-6 absolute of the f64 reference (their sums run in f64
//! over f32 per-element values; measured errors are about 1e-7); the gradient
//! `|g − c| ≤ 1e-3 · max(|c|, s, 1e-3 / n)` with `s` the root mean square of the CPU gradient and
//! `n` the number of values (the entries are of order 0.2 / n; f32 sums of the window in another
//! order than the CPU's move the small ones by rounding of the large terms that cancel in them,
//! and where the exact gradient is 0, identical images, both give rounding noise far below
//! 1e-6 / n). A missing adapter fails these tests (CI pins
//! lavapipe); it is not a skip.

use std::sync::OnceLock;

use evogs_metrics::gpu::GpuLoss;
use evogs_metrics::{ImageSize, LossWorkspace, photometric_loss};
use gpu_core::GpuContext;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn gpu() -> &'static (GpuContext, GpuLoss) {
    static GPU: OnceLock<(GpuContext, GpuLoss)> = OnceLock::new();
    GPU.get_or_init(|| {
        let ctx = GpuContext::new().unwrap_or_else(|e| {
            panic!("the GPU loss needs an adapter (CI installs lavapipe): {e}")
        });
        let loss = GpuLoss::new(&ctx).unwrap();
        (ctx, loss)
    })
}

fn image(rng: &mut ChaCha8Rng, n: usize, lo: f32, hi: f32) -> Vec<[f32; 3]> {
    (0..n)
        .map(|_| std::array::from_fn(|_| rng.random_range(lo..hi)))
        .collect()
}

fn check(size: ImageSize, rendered: &[[f32; 3]], target: &[[f32; 3]]) {
    let (ctx, loss) = gpu();
    let (got, grad) = loss.compute(ctx, size, rendered, target).unwrap();
    let mut cpu = LossWorkspace::<f32>::new();
    let want = cpu.compute(size, rendered, target).unwrap();
    let to64 = |im: &[[f32; 3]]| -> Vec<[f64; 3]> { im.iter().map(|p| p.map(f64::from)).collect() };
    let exact = photometric_loss(size, &to64(rendered), &to64(target)).unwrap();
    let what = format!("{}×{}", size.width, size.height);
    for (name, g, c) in [
        ("loss", got.loss, exact.loss),
        ("l1", got.l1, exact.l1),
        ("ssim", got.ssim, exact.ssim),
        ("mse", got.mse, want.mse),
    ] {
        assert!(
            (g - c).abs() <= 2e-6,
            "{what} {name}: gpu {g} vs reference {c}"
        );
    }
    let c = cpu.gradient();
    let rms = (c
        .iter()
        .flatten()
        .map(|v| f64::from(*v).powi(2))
        .sum::<f64>()
        / (3 * c.len()).max(1) as f64)
        .sqrt();
    for (i, (g, c)) in grad.iter().zip(c).enumerate() {
        for k in 0..3 {
            let (g, c) = (f64::from(g[k]), f64::from(c[k]));
            let floor = 1e-3 / (3 * size.pixels()) as f64;
            let tol = 1e-3 * c.abs().max(rms).max(floor);
            assert!(
                (g - c).abs() <= tol,
                "{what} gradient at pixel {i} channel {k}: gpu {g} vs cpu {c} (tolerance {tol})"
            );
        }
    }
}

#[test]
fn random_images_match_the_cpu_loss() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for (w, h) in [(1, 1), (7, 5), (16, 16), (61, 47), (200, 150)] {
        let size = ImageSize::new(w, h);
        let target = image(&mut rng, w * h, 0.0, 1.0);
        // A render near the target (as in training) and one far from it, beyond [0, 1].
        let near: Vec<[f32; 3]> = target
            .iter()
            .map(|p| p.map(|v| v + rng.random_range(-0.05f32..0.05)))
            .collect();
        check(size, &near, &target);
        check(size, &image(&mut rng, w * h, -0.2, 1.3), &target);
    }
}

#[test]
fn hard_cases_match_the_cpu_loss() {
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let size = ImageSize::new(23, 19);
    let target = image(&mut rng, size.pixels(), 0.0, 1.0);
    // Identical images: loss 0, SSIM 1, a gradient of rounding size only.
    check(size, &target, &target);
    // Constant black against black (μ = σ = 0: S = C1·C2 / (C1·C2) = 1) and against white.
    let black = vec![[0.0f32; 3]; size.pixels()];
    check(size, &black, &black);
    check(size, &black, &vec![[1.0f32; 3]; size.pixels()]);
}

#[test]
fn runs_repeat_bit_for_bit_and_are_counted() {
    // A context of its own: the other tests' calls are not counted.
    let ctx = &GpuContext::new().unwrap();
    let loss = &GpuLoss::new(ctx).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let size = ImageSize::new(97, 83);
    let (a, b) = (
        image(&mut rng, size.pixels(), 0.0, 1.0),
        image(&mut rng, size.pixels(), 0.0, 1.0),
    );
    let before = ctx.traffic();
    let first = loss.compute(ctx, size, &a, &b).unwrap();
    let counted = ctx.traffic().since(&before);
    let second = loss.compute(ctx, size, &a, &b).unwrap();
    assert_eq!(first.0, second.0);
    assert_eq!(first.1, second.1);
    // Five passes, one submit and wait; the two images up, the gradient and partial sums down.
    assert_eq!((counted.dispatches, counted.waits), (5, 1));
    let n = 12 * size.pixels() as u64;
    assert!(
        counted.bytes_up >= 2 * n && counted.bytes_down >= n,
        "{counted:?}"
    );
}

#[test]
fn a_wrong_image_size_is_an_error() {
    let (ctx, loss) = gpu();
    let err = loss
        .compute(ctx, ImageSize::new(4, 4), &[[0.0; 3]; 15], &[[0.0; 3]; 16])
        .unwrap_err();
    assert!(
        err.to_string()
            .contains("rendered: 15 pixels for a 4×4 image"),
        "{err}"
    );
}

/// `finish`, the resident form: the images already on the device, the passes recorded by
/// `encode`; it reads back the reduction's partial sums only (12 bytes per workgroup of 4 096
/// values) and gives `compute`'s terms bit for bit, with `compute`'s gradient left on the device.
#[test]
fn finish_reads_back_the_terms_only() {
    let ctx = &GpuContext::new().unwrap();
    let loss = &GpuLoss::new(ctx).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(10);
    let size = ImageSize::new(61, 47);
    let (a, b) = (
        image(&mut rng, size.pixels(), 0.0, 1.0),
        image(&mut rng, size.pixels(), 0.0, 1.0),
    );
    let (want, want_grad) = loss.compute(ctx, size, &a, &b).unwrap();
    let bufs = evogs_metrics::gpu::LossBuffers::new(ctx, size).unwrap();
    let x = gpu_core::buffers::storage_init(ctx, "a", bytemuck::cast_slice(&a)).unwrap();
    let y = gpu_core::buffers::storage_init(ctx, "b", bytemuck::cast_slice(&b)).unwrap();
    let before = ctx.traffic();
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    loss.encode(ctx, &mut encoder, &x, &y, &bufs);
    let got = loss.finish(ctx, encoder, &bufs).unwrap();
    let counted = ctx.traffic().since(&before);
    assert_eq!(got, want);
    let groups = (3 * size.pixels() as u64).div_ceil(4096);
    assert_eq!(
        (counted.bytes_up, counted.bytes_down, counted.waits),
        (0, 12 * groups, 1)
    );
    let encoder = ctx.device.create_command_encoder(&Default::default());
    let bytes = 12 * size.pixels() as u64;
    let back = gpu_core::buffers::read_back(ctx, encoder, &[(&bufs.gradient, 0, bytes)]).unwrap();
    let grad: Vec<f32> = bytemuck::pod_collect_to_vec(&back[0]);
    assert_eq!(grad, want_grad.as_flattened());
}
