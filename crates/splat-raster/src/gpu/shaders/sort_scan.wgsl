// Radix sort pass 2: exclusive prefix sum of `data[0..len]` in place, in 1024-element chunks.
// `scan_chunks` scans each chunk and writes its total to `sums[chunk]`; once `sums` is scanned
// (recursively, by the same kernels), `add_chunk_offsets` adds `sums[chunk]` to the chunk.

@group(0) @binding(1) var<storage, read_write> data: array<u32>;
@group(0) @binding(2) var<storage, read_write> sums: array<u32>;

@compute @workgroup_size(256)
fn scan_chunks(
    @builtin(workgroup_id) id: vec3<u32>,
    @builtin(num_workgroups) grid: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let chunk = block_index(id, grid);
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
    let chunk = block_index(id, grid);
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
