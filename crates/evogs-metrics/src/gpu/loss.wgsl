// The training loss 0.8·L1 + 0.2·(1 − SSIM) and its gradient on the GPU (DESIGN §7.1), the twin
// of `fast_loss.rs` / `loss.rs` (the reference). Images are interleaved RGB f32, element
// i = 3·(y·W + x) + c; every kernel runs one invocation per element (one per channel of a pixel).
// The SSIM window is separable and zero-padded: horizontal passes write per-row sums, vertical
// passes finish them. Formulas as in `ssim.rs`'s module doc.

struct Params {
    width: u32,
    height: u32,
    // 3 · width · height.
    count: u32,
    // Invocations per row of the 2D dispatch grid (groups along x · 256).
    row_stride: u32,
    // 0.8 / count and 0.2 / count.
    l1_step: f32,
    ssim_step: f32,
    c1: f32,
    c2: f32,
    // Workgroups of `reduce` (its grid may hold more; those add nothing).
    reduce_groups: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

const RADIUS: i32 = 5;
const WORKGROUP: u32 = 256u;
// Elements each invocation of `reduce` adds before the workgroup's tree.
const PER_THREAD: u32 = 16u;

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read> taps: array<f32, 11>;
@group(0) @binding(2) var<storage, read> x: array<f32>;
@group(0) @binding(3) var<storage, read> y: array<f32>;
// Five planes of `count` (moments, then sensitivities in their first three).
@group(0) @binding(4) var<storage, read_write> h: array<f32>;
@group(0) @binding(5) var<storage, read_write> v: array<f32>;
// The gradient (`grad`), or the partial sums (`reduce`: three per workgroup).
@group(0) @binding(6) var<storage, read_write> out: array<f32>;

fn element(id: vec3<u32>) -> u32 {
    return id.x + id.y * p.row_stride;
}

// The element `dx` pixels along the row from `i`, or -1 outside the image.
fn along_row(i: u32, dx: i32) -> i32 {
    let pixel = i / 3u;
    let px = i32(pixel % p.width) + dx;
    if px < 0 || px >= i32(p.width) {
        return -1;
    }
    return i32(i) + 3 * dx;
}

// The element `dy` rows from `i`, or -1 outside the image.
fn along_column(i: u32, dy: i32) -> i32 {
    let pixel = i / 3u;
    let py = i32(pixel / p.width) + dy;
    if py < 0 || py >= i32(p.height) {
        return -1;
    }
    return i32(i) + 3 * dy * i32(p.width);
}

// Horizontal sums of x, y, x², y², xy into the five planes of `h`.
@compute @workgroup_size(256)
fn blur_moments_h(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = element(id);
    if i >= p.count {
        return;
    }
    var s = array<f32, 5>(0.0, 0.0, 0.0, 0.0, 0.0);
    for (var k = -RADIUS; k <= RADIUS; k++) {
        let j = along_row(i, k);
        if j < 0 {
            continue;
        }
        let w = taps[k + RADIUS];
        let a = x[j];
        let b = y[j];
        let wa = w * a;
        let wb = w * b;
        s[0] += wa;
        s[1] += wb;
        s[2] += wa * a;
        s[3] += wb * b;
        s[4] += wa * b;
    }
    for (var m = 0u; m < 5u; m++) {
        h[m * p.count + i] = s[m];
    }
}

// Vertical sums of the moments, then the SSIM map and its three sensitivities: S into plane 3
// of `v`, ∂S/∂μx, ∂S/∂E[x²], ∂S/∂E[xy] into planes 0, 1, 2.
@compute @workgroup_size(256)
fn ssim_map(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = element(id);
    if i >= p.count {
        return;
    }
    var s = array<f32, 5>(0.0, 0.0, 0.0, 0.0, 0.0);
    for (var k = -RADIUS; k <= RADIUS; k++) {
        let j = along_column(i, k);
        if j < 0 {
            continue;
        }
        let w = taps[k + RADIUS];
        for (var m = 0u; m < 5u; m++) {
            s[m] += w * h[m * p.count + u32(j)];
        }
    }
    let mx = s[0];
    let my = s[1];
    let sxx = s[2] - mx * mx;
    let syy = s[3] - my * my;
    let sxy = s[4] - mx * my;
    let a1 = 2.0 * mx * my + p.c1;
    let a2 = 2.0 * sxy + p.c2;
    let b1 = mx * mx + my * my + p.c1;
    let b2 = sxx + syy + p.c2;
    let ssim = a1 * a2 / (b1 * b2);
    v[i] = 2.0 * my * (a2 - a1) / (b1 * b2) - 2.0 * mx * ssim * (1.0 / b1 - 1.0 / b2);
    v[p.count + i] = -ssim / b2;
    v[2u * p.count + i] = 2.0 * a1 / (b1 * b2);
    v[3u * p.count + i] = ssim;
}

// Horizontal sums of the three sensitivities (planes 0–2 of `v`) into planes 0–2 of `h`.
@compute @workgroup_size(256)
fn blur_sensitivities_h(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = element(id);
    if i >= p.count {
        return;
    }
    var s = array<f32, 3>(0.0, 0.0, 0.0);
    for (var k = -RADIUS; k <= RADIUS; k++) {
        let j = along_row(i, k);
        if j < 0 {
            continue;
        }
        let w = taps[k + RADIUS];
        for (var m = 0u; m < 3u; m++) {
            s[m] += w * v[m * p.count + u32(j)];
        }
    }
    for (var m = 0u; m < 3u; m++) {
        h[m * p.count + i] = s[m];
    }
}

// Vertical sums of the blurred sensitivities and the gradient:
// ∂loss/∂x = −0.2/n · (G a + 2x G b + y G c) + 0.8/n · sign(x − y).
@compute @workgroup_size(256)
fn gradient(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = element(id);
    if i >= p.count {
        return;
    }
    var s = array<f32, 3>(0.0, 0.0, 0.0);
    for (var k = -RADIUS; k <= RADIUS; k++) {
        let j = along_column(i, k);
        if j < 0 {
            continue;
        }
        let w = taps[k + RADIUS];
        for (var m = 0u; m < 3u; m++) {
            s[m] += w * h[m * p.count + u32(j)];
        }
    }
    let a = x[i];
    let b = y[i];
    let d = a - b;
    var l1 = 0.0;
    if d > 0.0 {
        l1 = p.l1_step;
    } else if d < 0.0 {
        l1 = -p.l1_step;
    }
    out[i] = -p.ssim_step * (s[0] + 2.0 * a * s[1] + b * s[2]) + l1;
}

var<workgroup> partial: array<vec3<f32>, 256>;

// Sums of S (plane 3 of `v`), |x − y| and (x − y)² over each workgroup's block of
// 256 · PER_THREAD elements, in a fixed order (each invocation its run, then a tree), into
// `out[3·group + 0..3]`.
@compute @workgroup_size(256)
fn reduce(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let group = wid.x + wid.y * groups.x;
    let first = (group * WORKGROUP + lid) * PER_THREAD;
    var s = vec3<f32>(0.0, 0.0, 0.0);
    for (var k = 0u; k < PER_THREAD; k++) {
        let i = first + k;
        if group < p.reduce_groups && i < p.count {
            let d = x[i] - y[i];
            s += vec3<f32>(v[3u * p.count + i], abs(d), d * d);
        }
    }
    partial[lid] = s;
    workgroupBarrier();
    for (var span = WORKGROUP / 2u; span > 0u; span /= 2u) {
        if lid < span {
            partial[lid] += partial[lid + span];
        }
        workgroupBarrier();
    }
    if lid == 0u && group < p.reduce_groups {
        out[3u * group] = partial[0].x;
        out[3u * group + 1u] = partial[0].y;
        out[3u * group + 2u] = partial[0].z;
    }
}
