// One linear layer of tiny-nn's MLP on the device (`gpu::GpuMlp`), forward and backward: the
// WGSL twin of `Mlp::forward` / `Mlp::backward` (crates/tiny-nn/src/mlp.rs) in f32.
//
// Layout as on the CPU: rows are samples, row-major; the layer's weights `W` (input × output,
// row-major) and then its bias `b` sit at `weight_offset` in the network's flat parameter buffer.
// The layer's input row is `[a_row, b_row]`: `a` alone (`width_b = 0`) for an ordinary layer,
// the network input and the previous layer's output for the layer after D-3DGS's skip.
//
// Kernels:
// - `forward`:      y = act(Σ_i in_i W_io + b_o).
// - `delta`:        dz = dy · act'(y), in place in `dy` (the derivative from the output, as the CPU).
// - `input_grad`:   d_in_i = Σ_o dz_o W_io, split into `d_a` (written, added to, or skipped as
//                   `mode_a` says) and `d_b`.
// - `weight_partials`: per chunk of `chunk_rows` rows, Σ_r in_ri dz_ro for every weight and
//                   Σ_r dz_ro for every bias (the bias as a weight of an input that is 1).
// - `weight_reduce`: the chunks' partial sums added in chunk order into `d_params`.
// The three products are tiled: a 16 × 16 workgroup computes a 16 × 16 block of its result,
// one value per invocation, reading 16 × 16 blocks of both operands through workgroup memory,
// and adds the terms of each value in increasing order of the summed index, as a plain loop
// would. Their grids: x over the result's columns, y (then z) over its rows; `weight_partials`
// has the chunk in z. Beside each, its plain form (`*_plain`: one invocation per value, the
// operands read from global memory, the same terms in the same order), which `GpuMlp` runs
// when asked: the faster of the two depends on the device (issue W measures both).
// `delta`, `weight_reduce` and the plain kernels are one invocation per value, flat index
// `id.x + id.y * stride_<values>`.
// Every sum runs in a fixed order, so a run repeats itself bit for bit; the order is not the CPU
// gemm's, so values differ from the CPU by f32 rounding (the tests say how much).

struct Params {
    rows: u32,
    width_a: u32,
    width_b: u32,
    outputs: u32,
    weight_offset: u32,
    activation: u32,
    mode_a: u32,
    chunk_rows: u32,
    chunks: u32,
    stride_outputs: u32,
    stride_inputs: u32,
    stride_partials: u32,
    stride_reduce: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

const IDENTITY: u32 = 0u;
const RELU: u32 = 1u;
const SIGMOID: u32 = 2u;

const SKIP: u32 = 0u;
const WRITE: u32 = 1u;
const ADD: u32 = 2u;

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read> weights: array<f32>;
@group(0) @binding(2) var<storage, read> in_a: array<f32>;
@group(0) @binding(3) var<storage, read> in_b: array<f32>;
@group(0) @binding(4) var<storage, read_write> out: array<f32>;
@group(0) @binding(5) var<storage, read_write> dy: array<f32>;
@group(0) @binding(6) var<storage, read_write> d_a: array<f32>;
@group(0) @binding(7) var<storage, read_write> d_b: array<f32>;
@group(0) @binding(8) var<storage, read_write> partials: array<f32>;
@group(0) @binding(9) var<storage, read_write> d_params: array<f32>;

fn flat(id: vec3<u32>, row_stride: u32) -> u32 {
    return id.x + id.y * row_stride;
}

fn input_value(r: u32, i: u32) -> f32 {
    if i < p.width_a {
        return in_a[r * p.width_a + i];
    }
    return in_b[r * p.width_b + i - p.width_a];
}

const TILE: u32 = 16u;

// One 16 × 16 block of each operand: `tile_a[row * TILE + k]`, `tile_b[k * TILE + column]`.
var<workgroup> tile_a: array<f32, 256>;
var<workgroup> tile_b: array<f32, 256>;

/// First result row of the workgroup's block, its row blocks over y then z.
fn block_row(wid: vec3<u32>, nwg: vec3<u32>) -> u32 {
    return (wid.y + wid.z * nwg.y) * TILE;
}

/// The block's shared part of `Σ_{k < len} A(m, k) B(k, n)` after both tiles are loaded: this
/// invocation's terms `k0 .. k0 + min(TILE, len − k0)` added to `s` in order.
fn tile_terms(s: f32, lid: vec3<u32>, k0: u32, len: u32) -> f32 {
    var acc = s;
    let kn = min(TILE, len - k0);
    for (var k = 0u; k < kn; k++) {
        acc += tile_a[lid.y * TILE + k] * tile_b[k * TILE + lid.x];
    }
    return acc;
}

@compute @workgroup_size(16, 16)
fn forward(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
) {
    let inputs = p.width_a + p.width_b;
    let m0 = block_row(wid, nwg);
    let n = wid.x * TILE + lid.x;
    var s = 0.0;
    for (var k0 = 0u; k0 < inputs; k0 += TILE) {
        let ka = k0 + lid.x;
        var a = 0.0;
        if m0 + lid.y < p.rows && ka < inputs {
            a = input_value(m0 + lid.y, ka);
        }
        tile_a[lid.y * TILE + lid.x] = a;
        let kb = k0 + lid.y;
        var b = 0.0;
        if kb < inputs && n < p.outputs {
            b = weights[p.weight_offset + kb * p.outputs + n];
        }
        tile_b[lid.y * TILE + lid.x] = b;
        workgroupBarrier();
        s = tile_terms(s, lid, k0, inputs);
        workgroupBarrier();
    }
    let m = m0 + lid.y;
    if m >= p.rows || n >= p.outputs {
        return;
    }
    let z = s + weights[p.weight_offset + inputs * p.outputs + n];
    var y = z;
    if p.activation == RELU {
        y = max(z, 0.0);
    } else if p.activation == SIGMOID {
        y = 1.0 / (1.0 + exp(-z));
    }
    out[m * p.outputs + n] = y;
}

@compute @workgroup_size(256)
fn delta(@builtin(global_invocation_id) id: vec3<u32>) {
    let k = flat(id, p.stride_outputs);
    if k >= p.rows * p.outputs {
        return;
    }
    let y = out[k];
    if p.activation == RELU {
        if y <= 0.0 {
            dy[k] = 0.0;
        }
    } else if p.activation == SIGMOID {
        dy[k] = dy[k] * (y * (1.0 - y));
    }
}

@compute @workgroup_size(16, 16)
fn input_grad(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
) {
    let inputs = p.width_a + p.width_b;
    let m0 = block_row(wid, nwg);
    let i = wid.x * TILE + lid.x;
    var s = 0.0;
    for (var k0 = 0u; k0 < p.outputs; k0 += TILE) {
        let ka = k0 + lid.x;
        var a = 0.0;
        if m0 + lid.y < p.rows && ka < p.outputs {
            a = dy[(m0 + lid.y) * p.outputs + ka];
        }
        tile_a[lid.y * TILE + lid.x] = a;
        let kb = k0 + lid.y;
        var b = 0.0;
        if kb < p.outputs && i < inputs {
            b = weights[p.weight_offset + i * p.outputs + kb];
        }
        tile_b[lid.y * TILE + lid.x] = b;
        workgroupBarrier();
        s = tile_terms(s, lid, k0, p.outputs);
        workgroupBarrier();
    }
    let r = m0 + lid.y;
    if r >= p.rows || i >= inputs {
        return;
    }
    if i < p.width_a {
        let j = r * p.width_a + i;
        if p.mode_a == WRITE {
            d_a[j] = s;
        } else if p.mode_a == ADD {
            d_a[j] = d_a[j] + s;
        }
    } else {
        d_b[r * p.width_b + i - p.width_a] = s;
    }
}

@compute @workgroup_size(16, 16)
fn weight_partials(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
) {
    // Result rows are the inputs and then the bias (an input that is 1), columns the outputs,
    // the sum over the chunk's rows; the chunk is z.
    let inputs = p.width_a + p.width_b;
    let r0 = wid.z * p.chunk_rows;
    let len = min(p.chunk_rows, p.rows - r0);
    let i0 = wid.y * TILE;
    let o = wid.x * TILE + lid.x;
    var s = 0.0;
    for (var k0 = 0u; k0 < len; k0 += TILE) {
        let ka = k0 + lid.x;
        let ia = i0 + lid.y;
        var a = 0.0;
        if ka < len && ia < inputs {
            a = input_value(r0 + ka, ia);
        } else if ka < len && ia == inputs {
            a = 1.0;
        }
        tile_a[lid.y * TILE + lid.x] = a;
        let kb = k0 + lid.y;
        var b = 0.0;
        if kb < len && o < p.outputs {
            b = dy[(r0 + kb) * p.outputs + o];
        }
        tile_b[lid.y * TILE + lid.x] = b;
        workgroupBarrier();
        s = tile_terms(s, lid, k0, len);
        workgroupBarrier();
    }
    let i = i0 + lid.y;
    if i > inputs || o >= p.outputs {
        return;
    }
    partials[wid.z * (inputs + 1u) * p.outputs + i * p.outputs + o] = s;
}

@compute @workgroup_size(256)
fn weight_reduce(@builtin(global_invocation_id) id: vec3<u32>) {
    let per_chunk = (p.width_a + p.width_b + 1u) * p.outputs;
    let w = flat(id, p.stride_reduce);
    if w >= per_chunk {
        return;
    }
    var s = 0.0;
    for (var c = 0u; c < p.chunks; c++) {
        s += partials[c * per_chunk + w];
    }
    d_params[p.weight_offset + w] = s;
}

@compute @workgroup_size(256)
fn forward_plain(@builtin(global_invocation_id) id: vec3<u32>) {
    let k = flat(id, p.stride_outputs);
    if k >= p.rows * p.outputs {
        return;
    }
    let r = k / p.outputs;
    let o = k % p.outputs;
    let inputs = p.width_a + p.width_b;
    var s = 0.0;
    for (var i = 0u; i < inputs; i++) {
        s += input_value(r, i) * weights[p.weight_offset + i * p.outputs + o];
    }
    let z = s + weights[p.weight_offset + inputs * p.outputs + o];
    var y = z;
    if p.activation == RELU {
        y = max(z, 0.0);
    } else if p.activation == SIGMOID {
        y = 1.0 / (1.0 + exp(-z));
    }
    out[k] = y;
}

@compute @workgroup_size(256)
fn input_grad_plain(@builtin(global_invocation_id) id: vec3<u32>) {
    let inputs = p.width_a + p.width_b;
    let k = flat(id, p.stride_inputs);
    if k >= p.rows * inputs {
        return;
    }
    let r = k / inputs;
    let i = k % inputs;
    var s = 0.0;
    for (var o = 0u; o < p.outputs; o++) {
        s += dy[r * p.outputs + o] * weights[p.weight_offset + i * p.outputs + o];
    }
    if i < p.width_a {
        let j = r * p.width_a + i;
        if p.mode_a == WRITE {
            d_a[j] = s;
        } else if p.mode_a == ADD {
            d_a[j] = d_a[j] + s;
        }
    } else {
        d_b[r * p.width_b + i - p.width_a] = s;
    }
}

@compute @workgroup_size(256)
fn weight_partials_plain(@builtin(global_invocation_id) id: vec3<u32>) {
    let inputs = p.width_a + p.width_b;
    let per_chunk = (inputs + 1u) * p.outputs;
    let k = flat(id, p.stride_partials);
    if k >= p.chunks * per_chunk {
        return;
    }
    let c = k / per_chunk;
    let w = k % per_chunk;
    let i = w / p.outputs;
    let o = w % p.outputs;
    let r0 = c * p.chunk_rows;
    let r1 = min(r0 + p.chunk_rows, p.rows);
    var s = 0.0;
    if i < inputs {
        for (var r = r0; r < r1; r++) {
            s += input_value(r, i) * dy[r * p.outputs + o];
        }
    } else {
        for (var r = r0; r < r1; r++) {
            s += dy[r * p.outputs + o];
        }
    }
    partials[k] = s;
}
