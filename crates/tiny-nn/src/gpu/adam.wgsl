// Adam on device buffers (tiny-nn's `gpu::GpuAdam`): the WGSL twin of `Adam::step` and
// `Adam::step_columns` (crates/tiny-nn/src/adam.rs), one invocation per moment.
//
// Moment `i` belongs to row `i / width`, column `i % width` of the group; its parameter and
// gradient sit at `row * stride + start + column` of the (possibly wider) parameter rows. A
// plain group is `stride = width = 1`, `start = 0`. The constants come from `Adam::next_update`:
//   m ← b1 m + (1 − b1) g,  v ← b2 v + (1 − b2) g²,  θ ← θ − step_size · m / (√v / bc2_sqrt + eps)
// in the CPU's order of operations (a driver may still contract a product and a sum into one
// fused multiply-add; the tests' tolerances allow for it).

struct Params {
    count: u32,
    stride: u32,
    start: u32,
    width: u32,
    b1: f32,
    b2: f32,
    eps: f32,
    step_size: f32,
    bc2_sqrt: f32,
    row_stride: u32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read_write> params: array<f32>;
@group(0) @binding(2) var<storage, read> grads: array<f32>;
@group(0) @binding(3) var<storage, read_write> m: array<f32>;
@group(0) @binding(4) var<storage, read_write> v: array<f32>;

@compute @workgroup_size(256)
fn step(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x + id.y * p.row_stride;
    if i >= p.count {
        return;
    }
    let j = (i / p.width) * p.stride + p.start + i % p.width;
    let g = grads[j];
    let m1 = p.b1 * m[i] + (1.0 - p.b1) * g;
    let v1 = p.b2 * v[i] + (1.0 - p.b2) * g * g;
    m[i] = m1;
    v[i] = v1;
    params[j] = params[j] - p.step_size * m1 / (sqrt(v1) / p.bc2_sqrt + p.eps);
}
