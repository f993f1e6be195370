// Backward compositing: one 16x16 workgroup per tile, one thread per pixel, walking the tile's
// list back to front from the largest last contributor, in shared-memory batches of 128. Per pixel the
// arithmetic of composite.rs `backward_tile` (T recovered by division, the outputs behind each
// entry carried along); each pixel's contribution to a Gaussian's record gradient is added to
// `grads` (10 floats per Gaussian: u, v, a, b, c, opacity, r, g, b, z) with `grad_add`, which the
// pipeline defines either with native f32 atomics or a compare-exchange loop (see atomics_*.wgsl).

@group(0) @binding(2) var<storage, read> splats: array<Splat>;
@group(0) @binding(3) var<storage, read> isect_ids: array<u32>;
@group(0) @binding(4) var<storage, read> ranges: array<u32>;
@group(0) @binding(5) var<storage, read> final_t: array<f32>;
@group(0) @binding(6) var<storage, read> last_pos: array<u32>;
@group(0) @binding(7) var<storage, read> d_color: array<f32>;
@group(0) @binding(8) var<storage, read> d_alpha: array<f32>;
@group(0) @binding(9) var<storage, read> d_depth: array<f32>;
// binding 10: `grads`, declared by the atomics snippet.

const BATCH: u32 = 128u;

var<workgroup> batch: array<Splat, BATCH>;
var<workgroup> batch_ids: array<u32, BATCH>;
var<workgroup> max_last: atomic<u32>;
var<workgroup> max_last_plain: u32;

@compute @workgroup_size(16, 16)
fn rasterize_backward(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid3: vec3<u32>,
                      @builtin(local_invocation_index) lid: u32) {
    let tile = wg.y * frame.tiles_x + wg.x;
    let x = wg.x * TILE + lid3.x;
    let y = wg.y * TILE + lid3.y;
    let inside = x < frame.width && y < frame.height;
    let px = f32(x) + 0.5;
    let py = f32(y) + 0.5;
    let lane = tile * 256u + lid;
    let start = ranges[2u * tile];
    var t = final_t[lane];
    var last = 0u;
    var dl: array<f32, 5>;
    var behind: array<f32, 5>;
    for (var k = 0u; k < 5u; k++) {
        dl[k] = 0.0;
        behind[k] = 0.0;
    }
    if lid == 0u {
        atomicStore(&max_last, 0u);
    }
    workgroupBarrier();
    if inside {
        last = last_pos[lane];
        let p = y * frame.width + x;
        dl[0] = d_color[3u * p];
        dl[1] = d_color[3u * p + 1u];
        dl[2] = d_color[3u * p + 2u];
        if frame.use_d_alpha != 0u {
            dl[3] = d_alpha[p];
        }
        if frame.use_d_depth != 0u {
            dl[4] = d_depth[p];
        }
        behind[0] = frame.bg0;
        behind[1] = frame.bg1;
        behind[2] = frame.bg2;
        atomicMax(&max_last, last);
    }
    workgroupBarrier();
    if lid == 0u {
        max_last_plain = atomicLoad(&max_last);
    }
    let total = workgroupUniformLoad(&max_last_plain);
    let n_batches = (total + BATCH - 1u) / BATCH;
    for (var b = 0u; b < n_batches; b++) {
        let hi = total - b * BATCH;
        let lo = hi - min(BATCH, hi);
        if lid < BATCH && lo + lid < hi {
            let id = isect_ids[start + lo + lid];
            batch_ids[lid] = id;
            batch[lid] = splats[id];
        }
        workgroupBarrier();
        for (var kk = 0u; kk < hi - lo; kk++) {
            let k = hi - lo - 1u - kk;
            let j = lo + k;
            if j >= last {
                continue;
            }
            let s = batch[k];
            if x < s.x0 || x > s.x1 || y < s.y0 || y > s.y1 {
                continue;
            }
            let dx = px - s.u;
            let dy = py - s.v;
            let sig = 0.5 * (s.a * dx * dx + s.c * dy * dy) + s.b * dx * dy;
            if !(sig <= s.sigma_cut) {
                continue;
            }
            let g = exp(-sig);
            let alpha = min(s.opacity * g, ALPHA_MAX);
            if !(sig >= 0.0 && alpha >= ALPHA_MIN) {
                continue;
            }
            let capped = s.opacity * g > ALPHA_MAX;
            let tj = t / (1.0 - alpha);
            t = tj;
            let w = alpha * tj;
            var feat = array<f32, 5>(s.r, s.g, s.bl, 1.0, s.z);
            var d_a = 0.0;
            for (var c = 0u; c < 5u; c++) {
                d_a += (feat[c] - behind[c]) * dl[c];
                behind[c] = alpha * feat[c] + (1.0 - alpha) * behind[c];
            }
            d_a *= tj;
            let base = batch_ids[k] * 10u;
            grad_add(base + 6u, w * dl[0]);
            grad_add(base + 7u, w * dl[1]);
            grad_add(base + 8u, w * dl[2]);
            grad_add(base + 9u, w * dl[4]);
            if capped {
                continue;
            }
            grad_add(base + 5u, d_a * g);
            let d_sig = -d_a * alpha;
            grad_add(base + 2u, d_sig * 0.5 * dx * dx);
            grad_add(base + 3u, d_sig * dx * dy);
            grad_add(base + 4u, d_sig * 0.5 * dy * dy);
            grad_add(base + 0u, -d_sig * (s.a * dx + s.b * dy));
            grad_add(base + 1u, -d_sig * (s.b * dx + s.c * dy));
        }
        workgroupBarrier();
    }
}
