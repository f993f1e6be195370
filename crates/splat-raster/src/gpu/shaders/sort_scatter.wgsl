// Radix sort pass 3: stable scatter. Each workgroup sorts its block's digits locally with one
// stable 1-bit split per digit bit (a workgroup prefix sum each), so that the block's elements are
// in (digit, original position) order; an element's rank among the block's elements of its digit
// is then its local position minus the local start of its digit, and its output index is the
// scanned global offset of (digit, block) plus that rank. Elements past `n` in the last block take
// the largest digit: being last in the block, the stable splits keep them after every real element,
// so they never shift a real element's rank, and they are not written.

@group(0) @binding(1) var<storage, read> keys_in: array<u32>;
@group(0) @binding(2) var<storage, read> values_in: array<u32>;
@group(0) @binding(3) var<storage, read> offsets: array<u32>;
@group(0) @binding(4) var<storage, read_write> keys_out: array<u32>;
@group(0) @binding(5) var<storage, read_write> values_out: array<u32>;

// Per local slot: digit << 16 | original local index (0..1024).
var<workgroup> s_item: array<u32, BLOCK>;
var<workgroup> s_start: array<u32, BINS>;

@compute @workgroup_size(256)
fn scatter(
    @builtin(workgroup_id) id: vec3<u32>,
    @builtin(num_workgroups) grid: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let block = block_index(id, grid);
    if (block >= params.num_blocks) {
        return;
    }
    let base = block * BLOCK;
    let max_digit = (1u << params.bits) - 1u;
    for (var j = 0u; j < PER; j++) {
        let local = lid * PER + j;
        var d = max_digit;
        if (base + local < params.n) {
            d = digit_of(keys_in[base + local]);
        }
        s_item[local] = (d << 16u) | local;
    }
    workgroupBarrier();

    for (var b = 0u; b < params.bits; b++) {
        var items: array<u32, 4>;
        var zeros = 0u;
        for (var j = 0u; j < PER; j++) {
            items[j] = s_item[lid * PER + j];
            zeros += 1u - ((items[j] >> (16u + b)) & 1u);
        }
        // Every read of s_item above happens before the scan's first barrier.
        let scan = workgroup_exclusive_scan(lid, zeros);
        var zeros_before = scan.x;
        for (var j = 0u; j < PER; j++) {
            let pos = lid * PER + j;
            var dst: u32;
            if (((items[j] >> (16u + b)) & 1u) == 0u) {
                dst = zeros_before;
                zeros_before += 1u;
            } else {
                dst = scan.y + (pos - zeros_before);
            }
            s_item[dst] = items[j];
        }
        workgroupBarrier();
    }

    for (var j = 0u; j < PER; j++) {
        let pos = lid * PER + j;
        let d = s_item[pos] >> 16u;
        if (pos == 0u || (s_item[pos - 1u] >> 16u) != d) {
            s_start[d] = pos;
        }
    }
    workgroupBarrier();

    for (var j = 0u; j < PER; j++) {
        let pos = lid * PER + j;
        let item = s_item[pos];
        let d = item >> 16u;
        let src = base + (item & 0xffffu);
        if (src < params.n) {
            let dst = offsets[d * params.num_blocks + block] + pos - s_start[d];
            keys_out[dst] = keys_in[src];
            values_out[dst] = values_in[src];
        }
    }
}
