//! The GPU MLP and Adam (`tiny_nn::gpu`, cargo feature `wgpu`) on buffers resident on the
//! device: D-3DGS's deformation network (76 inputs, 8 × 256 with the skip after layer 4, 10
//! outputs), forward + backward with the input's gradient, at 10 000 and 100 000 rows, with the
//! products tiled and plain (`MlpKernels`); Adam's
//! step over that network's parameters and over 100 000 Gaussians' 59 values. Each sample
//! records the passes, submits them and waits for the device (no transfer but the submit);
//! the bind groups are made per call, as the kernels do today. Beside them the CPU's
//! `Mlp::forward` + `Mlp::backward` at 10 000 rows (all threads), the reference the GPU path
//! replaces. On lavapipe (software Vulkan) the GPU figures are a sanity check, not GPU
//! performance, and the MLP runs 1 000 rows only.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use gpu_core::GpuContext;
use gpu_core::buffers::storage_init;
use tiny_nn::gpu::{AdamBuffers, AdamLayout, DeviceMlp, GpuAdam, GpuMlp, MlpKernels, MlpWorkspace};
use tiny_nn::{Adam, LrSchedule, MlpConfig};

fn vals(n: usize, seed: u64) -> Vec<f32> {
    let mut x = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(1);
    (0..n)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
        })
        .collect()
}

fn wait(ctx: &GpuContext, encoder: wgpu::CommandEncoder) {
    ctx.queue.submit([encoder.finish()]);
    ctx.device
        .poll(wgpu::PollType::wait_indefinitely())
        .expect("the device answers");
}

fn bench(c: &mut Criterion) {
    let ctx = GpuContext::new().expect("the GPU bench needs an adapter");
    eprintln!("adapter: {}", ctx.adapter());
    let mut kernel = GpuMlp::new(&ctx).unwrap();
    let adam_kernel = GpuAdam::new(&ctx).unwrap();
    let mlp = MlpConfig::new(76, 256, 8, 10)
        .skip_after(4)
        .seed(1)
        .build()
        .unwrap();
    let net = DeviceMlp::upload(&ctx, &mlp).unwrap();
    let mut g = c.benchmark_group("gpu_nets");
    g.sample_size(10);
    // On a software adapter one 10 000-row step takes about two minutes (lavapipe, two cores):
    // a 1 000-row case runs there instead, to show the bench works.
    let sizes: &[usize] = if ctx.adapter().hardware {
        &[10_000, 100_000]
    } else {
        &[1_000]
    };
    for &rows in sizes {
        let ws = MlpWorkspace::new(&ctx, &net, rows, true).unwrap();
        let x = storage_init(&ctx, "x", bytemuck::cast_slice(&vals(rows * 76, 2))).unwrap();
        let dy = storage_init(&ctx, "dy", bytemuck::cast_slice(&vals(rows * 10, 3))).unwrap();
        g.throughput(Throughput::Elements(rows as u64));
        for form in [MlpKernels::Tiled, MlpKernels::Plain] {
            kernel.kernels = form;
            let name = format!("d3dgs_mlp_fwd_bwd_gpu_{form:?}/{}k", rows / 1000);
            g.bench_function(name.to_lowercase(), |b| {
                b.iter(|| {
                    let mut encoder = ctx.device.create_command_encoder(&Default::default());
                    kernel.encode_forward(&ctx, &mut encoder, &net, &ws, &x);
                    kernel.encode_backward(&ctx, &mut encoder, &net, &ws, &x, &dy);
                    wait(&ctx, encoder);
                });
            });
        }
    }
    let rows = 10_000;
    let x = vals(rows * 76, 2);
    let dy = vals(rows * 10, 3);
    g.throughput(Throughput::Elements(rows as u64));
    g.bench_function("d3dgs_mlp_fwd_bwd_cpu/10k", |b| {
        b.iter(|| {
            let (_, cache) = mlp.forward(&x, rows).unwrap();
            mlp.backward(&cache, &dy, true).unwrap()
        });
    });
    for (name, len) in [
        ("adam_gpu/d3dgs_mlp", mlp.param_count()),
        ("adam_gpu/100k_gaussians_59", 100_000 * 59),
    ] {
        let mut adam = Adam::new();
        let id = adam
            .add_group("g", len, 1, LrSchedule::Constant(1e-3))
            .unwrap();
        let buf = |seed| storage_init(&ctx, "adam", bytemuck::cast_slice(&vals(len, seed)));
        let (p, gr, m, v) = (
            buf(4).unwrap(),
            buf(5).unwrap(),
            buf(6).unwrap(),
            buf(7).unwrap(),
        );
        let layout = AdamLayout::plain(len as u32);
        g.throughput(Throughput::Elements(len as u64));
        g.bench_function(name, |b| {
            b.iter(|| {
                let update = adam.next_update(id, 0).unwrap();
                let mut encoder = ctx.device.create_command_encoder(&Default::default());
                let bufs = AdamBuffers {
                    params: &p,
                    grads: &gr,
                    m: &m,
                    v: &v,
                };
                adam_kernel
                    .encode(&ctx, &mut encoder, &update, layout, bufs)
                    .unwrap();
                wait(&ctx, encoder);
            });
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
