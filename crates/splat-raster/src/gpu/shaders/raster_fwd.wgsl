// Forward compositing: one 16x16 workgroup per tile, one thread per pixel, the tile's
// depth-ordered list loaded into shared memory in batches of 128 (8 KiB, well inside the 16 KiB
// of workgroup memory every adapter offers). Per pixel exactly the loop of
// composite.rs: bounding-box test, sigma cut-off, alpha with the 0.99 cap, stop before T < 1e-4.
// Per tile it also counts the work as the CPU backend does (see `Counters`).

@group(0) @binding(2) var<storage, read> splats: array<Splat>;
@group(0) @binding(3) var<storage, read> isect_ids: array<u32>;
@group(0) @binding(4) var<storage, read> ranges: array<u32>;
// Row-major images: colour (3 per pixel), alpha, depth.
@group(0) @binding(5) var<storage, read_write> out_color: array<f32>;
@group(0) @binding(6) var<storage, read_write> out_alpha: array<f32>;
@group(0) @binding(7) var<storage, read_write> out_depth: array<f32>;
// Tile-major (tile, lane): final transmittance and one past the last contributor.
@group(0) @binding(8) var<storage, read_write> final_t: array<f32>;
@group(0) @binding(9) var<storage, read_write> last_pos: array<u32>;
// Per tile: [evaluations, blended].
@group(0) @binding(10) var<storage, read_write> tile_counters: array<u32>;

const BATCH: u32 = 128u;

var<workgroup> batch: array<Splat, BATCH>;
var<workgroup> count_plain: u32;
var<workgroup> n_done: atomic<u32>;
var<workgroup> n_done_plain: u32;
var<workgroup> entries_used: atomic<u32>;
var<workgroup> entries_used_plain: u32;
var<workgroup> evaluations: atomic<u32>;
var<workgroup> blended_total: atomic<u32>;

@compute @workgroup_size(16, 16)
fn rasterize(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid3: vec3<u32>,
             @builtin(local_invocation_index) lid: u32) {
    let tile = wg.y * frame.tiles_x + wg.x;
    let x = wg.x * TILE + lid3.x;
    let y = wg.y * TILE + lid3.y;
    let inside = x < frame.width && y < frame.height;
    let px = f32(x) + 0.5;
    let py = f32(y) + 0.5;
    if lid == 0u {
        let start0 = ranges[2u * tile];
        count_plain = max(ranges[2u * tile + 1u], start0) - start0;
        atomicStore(&n_done, 0u);
        atomicStore(&entries_used, 0u);
        atomicStore(&evaluations, 0u);
        atomicStore(&blended_total, 0u);
    }
    let count = workgroupUniformLoad(&count_plain);
    let start = ranges[2u * tile];
    var done = !inside;
    if done {
        atomicAdd(&n_done, 1u);
    }
    var t = 1.0;
    var rgb = vec3<f32>(0.0);
    var depth = 0.0;
    var last = 0u;
    var stop = 0u;
    var blended = 0u;
    let n_batches = (count + BATCH - 1u) / BATCH;
    for (var b = 0u; b < n_batches; b++) {
        if lid == 0u {
            n_done_plain = atomicLoad(&n_done);
        }
        let all_done = workgroupUniformLoad(&n_done_plain);
        if all_done == 256u {
            break;
        }
        let base = b * BATCH;
        if lid < BATCH && base + lid < count {
            batch[lid] = splats[isect_ids[start + base + lid]];
        }
        workgroupBarrier();
        let in_batch = min(BATCH, count - base);
        for (var k = 0u; k < in_batch; k++) {
            if done {
                break;
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
            let alpha = min(s.opacity * exp(-sig), ALPHA_MAX);
            if !(sig >= 0.0 && alpha >= ALPHA_MIN) {
                continue;
            }
            let next = t * (1.0 - alpha);
            let pos = base + k + 1u;
            if next < T_MIN {
                done = true;
                stop = pos;
                atomicAdd(&n_done, 1u);
                break;
            }
            let w = alpha * t;
            rgb += vec3<f32>(s.r, s.g, s.bl) * w;
            depth += s.z * w;
            t = next;
            last = pos;
            blended += 1u;
        }
        workgroupBarrier();
    }
    if inside {
        let p = y * frame.width + x;
        out_color[3u * p] = rgb.x + t * frame.bg0;
        out_color[3u * p + 1u] = rgb.y + t * frame.bg1;
        out_color[3u * p + 2u] = rgb.z + t * frame.bg2;
        out_alpha[p] = 1.0 - t;
        out_depth[p] = depth;
        // Entries the CPU loop processes: up to the last pixel's stop, or all of them.
        atomicMax(&entries_used, select(count, stop, done));
        atomicAdd(&blended_total, blended);
    }
    let lane = tile * 256u + lid;
    final_t[lane] = t;
    last_pos[lane] = last;
    workgroupBarrier();
    if lid == 0u {
        entries_used_plain = atomicLoad(&entries_used);
    }
    let used = workgroupUniformLoad(&entries_used_plain);
    // Pixels of each processed entry's bounding box inside the tile.
    let rx0 = wg.x * TILE;
    let ry0 = wg.y * TILE;
    let rx1 = min(rx0 + TILE, frame.width) - 1u;
    let ry1 = min(ry0 + TILE, frame.height) - 1u;
    var evals = 0u;
    for (var j = lid; j < used; j += 256u) {
        let s = splats[isect_ids[start + j]];
        let cx0 = max(s.x0, rx0);
        let cy0 = max(s.y0, ry0);
        let cx1 = min(s.x1, rx1);
        let cy1 = min(s.y1, ry1);
        if cx0 <= cx1 && cy0 <= cy1 {
            evals += (cx1 - cx0 + 1u) * (cy1 - cy0 + 1u);
        }
    }
    atomicAdd(&evaluations, evals);
    workgroupBarrier();
    if lid == 0u {
        tile_counters[2u * tile] = atomicLoad(&evaluations);
        tile_counters[2u * tile + 1u] = atomicLoad(&blended_total);
    }
}
