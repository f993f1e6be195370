// The backend's one device-wide prefix sum (gpu/scan.rs): exclusive, of `data[0..params.len]`
// in place, hierarchical in 1024-element chunks (256 invocations x 4 consecutive elements).
// `scan_chunks` scans each chunk and writes its total to `sums[chunk]`; once `sums` is scanned
// (recursively, by the same kernels), `add_chunk_offsets` adds `sums[chunk]` to the chunk.
// Workgroups are laid out on a 2D grid (x then y) so that more than 65535 chunks can be
// dispatched; the linear chunk index is `id.x + id.y * grid.x`, and a workgroup past the last
// chunk returns at once.

// Mirrored by `ScanParams` in gpu/scan.rs (gpu/layout.rs checks that the layouts agree).
struct ScanParams {
    // Number of elements of `data`.
    len: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> params: ScanParams;
@group(0) @binding(1) var<storage, read_write> data: array<u32>;
@group(0) @binding(2) var<storage, read_write> sums: array<u32>;

const WG: u32 = 256u;
const PER: u32 = 4u;
const BLOCK: u32 = 1024u;

var<workgroup> s_scan: array<u32, WG>;

// Exclusive prefix sum of `v` over the workgroup's invocations (Hillis-Steele). Returns
// (sum of `v` over invocations before `lid`, sum over all). Call from uniform control flow.
fn workgroup_exclusive_scan(lid: u32, v: u32) -> vec2<u32> {
    s_scan[lid] = v;
    workgroupBarrier();
    for (var off = 1u; off < WG; off = off << 1u) {
        var t = 0u;
        if (lid >= off) {
            t = s_scan[lid - off];
        }
        workgroupBarrier();
        s_scan[lid] = s_scan[lid] + t;
        workgroupBarrier();
    }
    let inclusive = s_scan[lid];
    let total = s_scan[WG - 1u];
    workgroupBarrier();
    return vec2<u32>(inclusive - v, total);
}

fn chunk_index(id: vec3<u32>, grid: vec3<u32>) -> u32 {
    return id.x + id.y * grid.x;
}

@compute @workgroup_size(256)
fn scan_chunks(
    @builtin(workgroup_id) id: vec3<u32>,
    @builtin(num_workgroups) grid: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let chunk = chunk_index(id, grid);
    if (chunk >= (params.len + BLOCK - 1u) / BLOCK) {
        return;
    }
    let base = chunk * BLOCK + lid * PER;
    var v: array<u32, 4>;
    var own = 0u;
    for (var j = 0u; j < PER; j++) {
        v[j] = 0u;
        if (base + j < params.len) {
            v[j] = data[base + j];
        }
        own += v[j];
    }
    let scan = workgroup_exclusive_scan(lid, own);
    var run = scan.x;
    for (var j = 0u; j < PER; j++) {
        if (base + j < params.len) {
            data[base + j] = run;
        }
        run += v[j];
    }
    if (lid == 0u) {
        sums[chunk] = scan.y;
    }
}

@compute @workgroup_size(256)
fn add_chunk_offsets(
    @builtin(workgroup_id) id: vec3<u32>,
    @builtin(num_workgroups) grid: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let chunk = chunk_index(id, grid);
    if (chunk >= (params.len + BLOCK - 1u) / BLOCK) {
        return;
    }
    let add = sums[chunk];
    let base = chunk * BLOCK;
    for (var j = 0u; j < PER; j++) {
        let i = base + j * WG + lid;
        if (i < params.len) {
            data[i] += add;
        }
    }
}
