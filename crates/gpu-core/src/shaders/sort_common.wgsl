// Shared by the radix sort kernels (prepended to each of them by `sort.rs`).
//
// A block is 1024 elements: 256 invocations x 4 consecutive elements each. Workgroups are laid out
// on a 2D grid (x then y) so that more than 65535 blocks can be dispatched; the linear block index
// is `id.x + id.y * grid.x`, and a workgroup past the last block returns at once.

// Mirrored by `Params` in gpu/sort.rs (gpu/layout.rs checks that the layouts agree).
struct Params {
    // Number of (key, value) pairs.
    n: u32,
    // Lowest key bit of this pass's digit.
    shift: u32,
    // Width of this pass's digit, 1..=4.
    bits: u32,
    // Number of 1024-element blocks of the keys.
    num_blocks: u32,
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
