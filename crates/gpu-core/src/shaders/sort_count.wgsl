// Radix sort pass 1: per-block digit histograms, stored bin-major (`counts[bin * num_blocks +
// block]`) so that one exclusive scan of `counts` gives every block's output offset per bin.

@group(0) @binding(1) var<storage, read> keys: array<u32>;
@group(0) @binding(2) var<storage, read_write> counts: array<u32>;

var<workgroup> s_hist: array<atomic<u32>, BINS>;

@compute @workgroup_size(256)
fn count(
    @builtin(workgroup_id) id: vec3<u32>,
    @builtin(num_workgroups) grid: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let block = block_index(id, grid);
    if (block >= params.num_blocks) {
        return;
    }
    if (lid < BINS) {
        atomicStore(&s_hist[lid], 0u);
    }
    workgroupBarrier();
    let base = block * BLOCK;
    for (var j = 0u; j < PER; j++) {
        let i = base + j * WG + lid;
        if (i < params.n) {
            atomicAdd(&s_hist[digit_of(keys[i])], 1u);
        }
    }
    workgroupBarrier();
    if (lid < BINS) {
        counts[lid * params.num_blocks + block] = atomicLoad(&s_hist[lid]);
    }
}
