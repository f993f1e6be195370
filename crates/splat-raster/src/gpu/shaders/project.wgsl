// Projection (one thread per Gaussian): culling as in cpu/project.rs, counted per reason, the
// compositing record, the screen radius, the number of tiles touched and the depth sort key.

@group(0) @binding(2) var<storage, read_write> splats: array<Splat>;
@group(0) @binding(3) var<storage, read_write> radii: array<f32>;
@group(0) @binding(4) var<storage, read_write> depth_keys: array<u32>;
@group(0) @binding(5) var<storage, read_write> sort_ids: array<u32>;
@group(0) @binding(6) var<storage, read_write> tile_counts: array<u32>;
// [drawn, non-finite, zero quaternion, low opacity, behind near plane, degenerate, off screen].
@group(0) @binding(7) var<storage, read_write> stats: array<atomic<u32>, 8>;

struct Projected {
    reason: u32,
    splat: Splat,
    radius: f32,
    tiles: u32,
}

fn project_one(i: u32) -> Projected {
    var out: Projected;
    let g = geometry(i);
    out.reason = g.reason;
    if g.reason != 0u {
        return out;
    }
    let u = frame.fx * g.rx + frame.cx;
    let v = frame.fy * g.ry + frame.cy;
    if !(finite(u) && finite(v) && finite(g.z)) {
        out.reason = CULL_OFF_SCREEN;
        return out;
    }
    let a = (g.cn + DILATION * g.ik2) / g.dk;
    let b = -g.bn / g.dk;
    let c = (g.an + DILATION * g.ik2) / g.dk;
    if !(finite(a) && finite(b) && finite(c)) {
        out.reason = CULL_DEGENERATE;
        return out;
    }
    let s_max = max(log(255.0 * g.opacity), 0.0);
    let sigma_cut = s_max * 1.001 + 1e-3;
    let ext_x = sqrt(2.0 * sigma_cut) * axis_sigma(g.t0) + 1e-2;
    let ext_y = sqrt(2.0 * sigma_cut) * axis_sigma(g.t1) + 1e-2;
    let x_lo = max(ceil(u - ext_x - 0.5), 0.0);
    let x_hi = min(floor(u + ext_x - 0.5), f32(frame.width) - 1.0);
    let y_lo = max(ceil(v - ext_y - 0.5), 0.0);
    let y_hi = min(floor(v + ext_y - 0.5), f32(frame.height) - 1.0);
    if !(x_lo <= x_hi && y_lo <= y_hi) {
        out.reason = CULL_OFF_SCREEN;
        return out;
    }
    let mid = 0.5 * (g.an + g.cn);
    let half = 0.5 * (g.an - g.cn);
    let lambda = mid + sqrt(half * half + g.bn * g.bn) + DILATION * g.ik2;
    var radius = 3.0 * sqrt(lambda) * g.k;
    if !finite(radius) {
        radius = F32_MAX;
    }
    let mean = vec3<f32>(param(i, 0u), param(i, 1u), param(i, 2u));
    let rgb = max(raw_color(i, unit(view_dir(mean))), vec3<f32>(0.0));
    if !(finite3(rgb) && rgb.x <= MAX_COLOR && rgb.y <= MAX_COLOR && rgb.z <= MAX_COLOR) {
        out.reason = CULL_NON_FINITE;
        return out;
    }
    var s: Splat;
    s.u = u;
    s.v = v;
    s.a = a;
    s.b = b;
    s.c = c;
    s.opacity = g.opacity;
    s.sigma_cut = sigma_cut;
    s.z = g.z;
    s.r = rgb.x;
    s.g = rgb.y;
    s.bl = rgb.z;
    s.x0 = u32(x_lo);
    s.y0 = u32(y_lo);
    s.x1 = u32(x_hi);
    s.y1 = u32(y_hi);
    s.pad = 0u;
    var tiles = 0u;
    for (var ty = s.y0 / TILE; ty <= s.y1 / TILE; ty++) {
        for (var tx = s.x0 / TILE; tx <= s.x1 / TILE; tx++) {
            if touches_tile(frame, s, tx, ty) {
                tiles += 1u;
            }
        }
    }
    if tiles == 0u {
        out.reason = CULL_OFF_SCREEN;
        return out;
    }
    out.splat = s;
    out.radius = radius;
    out.tiles = tiles;
    return out;
}

@compute @workgroup_size(256)
fn project(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = gid.x + gid.y * nwg.x * 256u;
    if i >= frame.n {
        return;
    }
    let p = project_one(i);
    sort_ids[i] = i;
    if p.reason != 0u {
        var empty: Splat;
        splats[i] = empty;
        radii[i] = 0.0;
        depth_keys[i] = 0xffffffffu;
        tile_counts[i] = 0u;
        atomicAdd(&stats[p.reason], 1u);
        return;
    }
    splats[i] = p.splat;
    radii[i] = p.radius;
    // z > 0 is finite and positive: its bit pattern orders like the number.
    depth_keys[i] = bitcast<u32>(p.splat.z);
    tile_counts[i] = p.tiles;
    atomicAdd(&stats[0], 1u);
}
