// D-3DGS's input encoding on the device (`gpu::GpuDeformNet`): the WGSL twin of
// `Sinusoidal::encode_row_into` / `backward_row_into` (crates/tiny-nn/src/encoding/sinusoidal.rs)
// applied as `DeformNet` does, `[γ(x), γ(t)]` per row, γ of width `d · (1 + 2L)`:
//   [v, sin(2⁰ v), cos(2⁰ v), …, sin(2^(L−1) v), cos(2^(L−1) v)]   (blocks of d values)
//
// Sines and cosines: the argument `2^f · v` is exact in f32 (`ldexp`), then reduced to
// [−π, π] with a four-part 2π (Cody–Waite: `C1`, `C2` and `C3` have 8 significant bits, so
// their products with the turn count k are exact for |k| < 2¹⁶, arguments up to about 411 000:
// positions up to ±800 at D-3DGS's highest frequency 2⁹), and only then given to `sin` and
// `cos`, whose accuracy WGSL bounds on [−π, π] only. C1 + C2 + C3 + C4 is 2π to f64 precision.

struct Params {
    rows: u32,
    xyz_freqs: u32,
    t_freqs: u32,
    width: u32,
    row_stride: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

const INV_TWO_PI: f32 = 0.15915493667125702;
const C1: f32 = 6.28125;
const C2: f32 = 0.0019378662109375;
const C3: f32 = -2.562999725341797e-06;
const C4: f32 = 3.968374073792802e-09;

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read> positions: array<f32>;
@group(0) @binding(2) var<storage, read> times: array<f32>;
@group(0) @binding(3) var<storage, read_write> encoded: array<f32>;
@group(0) @binding(4) var<storage, read> d_encoded: array<f32>;
@group(0) @binding(5) var<storage, read_write> d_positions: array<f32>;

/// `a` reduced to [−π, π] (up to rounding) by whole turns.
fn reduce(a: f32) -> f32 {
    let k = round(a * INV_TWO_PI);
    return (((a - k * C1) - k * C2) - k * C3) - k * C4;
}

/// Value `j` of one encoded row of width `d · (1 + 2 · freqs)` of the input `v` (its column `i`).
fn encode_value(v: f32, j: u32, d: u32) -> f32 {
    if j < d {
        return v;
    }
    let block = (j - d) / d;
    let f = block / 2u;
    let r = reduce(ldexp(v, i32(f)));
    if block % 2u == 0u {
        return sin(r);
    }
    return cos(r);
}

@compute @workgroup_size(256)
fn encode(@builtin(global_invocation_id) id: vec3<u32>) {
    let k = id.x + id.y * p.row_stride;
    if k >= p.rows * p.width {
        return;
    }
    let row = k / p.width;
    let j = k % p.width;
    let wx = 3u * (1u + 2u * p.xyz_freqs);
    if j < wx {
        let i = j % 3u;
        encoded[k] = encode_value(positions[3u * row + i], j, 3u);
    } else {
        encoded[k] = encode_value(times[row], j - wx, 1u);
    }
}

@compute @workgroup_size(256)
fn position_grad(@builtin(global_invocation_id) id: vec3<u32>) {
    let k = id.x + id.y * p.row_stride;
    if k >= p.rows * 3u {
        return;
    }
    let row = k / 3u;
    let i = k % 3u;
    let v = positions[k];
    let base = row * p.width;
    var g = d_encoded[base + i];
    for (var f = 0u; f < p.xyz_freqs; f++) {
        let scale = ldexp(1.0, i32(f));
        let r = reduce(v * scale);
        let at = base + 3u * (1u + 2u * f) + i;
        g += scale * (cos(r) * d_encoded[at] - sin(r) * d_encoded[at + 3u]);
    }
    d_positions[k] = g;
}
