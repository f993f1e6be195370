// Shared by the radix sort kernels (prepended to each of them by `sort.rs`).
//
// A block is 1024 elements: 256 invocations x 4 consecutive elements each. Workgroups are laid out
// on a 2D grid (x then y) so that more than 65535 blocks can be dispatched; the linear block index
// is `id.x + id.y * grid.x`, and a workgroup past the last block returns at once.

struct Params {
    // Number of (key, value) pairs.
    n: u32,
    // Lowest key bit of this pass's digit.
    shift: u32,
    // Width of this pass's digit, 1..=4.
    bits: u32,
    // Number of 1024-element blocks of the keys.
    num_blocks: u32,
    // Length of the array a scan kernel works on.
    len: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

const WG: u32 = 256u;
const PER: u32 = 4u;
const BLOCK: u32 = 1024u;
const BINS: u32 = 16u;

@group(0) @binding(0) var<uniform> params: Params;

fn block_index(id: vec3<u32>, grid: vec3<u32>) -> u32 {
    return id.x + id.y * grid.x;
}

fn digit_of(key: u32) -> u32 {
    return (key >> params.shift) & ((1u << params.bits) - 1u);
}

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
