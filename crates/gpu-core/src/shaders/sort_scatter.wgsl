// Radix sort pass 3: stable scatter. Invocation `lid` owns the block's elements 4·lid..4·lid+3,
// so block order is (invocation, element) order. Each invocation counts its digits into 16
// counters packed two per u32 (16 bits each: a count never exceeds the block's 1024 elements);
// an inclusive prefix sum of these packed vectors over the workgroup (Hillis-Steele, lane-wise
// additions never carry across the 16-bit halves) gives, per digit, how many elements of that
// digit come before the invocation's. An element's output index is the scanned global offset of
// (digit, block), plus that count, plus the elements of its digit earlier in its own four.
// Elements past `n` in the last block are neither counted nor written.

@group(0) @binding(1) var<storage, read> keys_in: array<u32>;
@group(0) @binding(2) var<storage, read> values_in: array<u32>;
@group(0) @binding(3) var<storage, read> offsets: array<u32>;
@group(0) @binding(4) var<storage, read_write> keys_out: array<u32>;
@group(0) @binding(5) var<storage, read_write> values_out: array<u32>;

const WORDS: u32 = BINS / 2u;

var<workgroup> s_counts: array<array<u32, WORDS>, WG>;

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
    let first = block * BLOCK + lid * PER;
    var own: array<u32, WORDS>;
    for (var w = 0u; w < WORDS; w++) {
        own[w] = 0u;
    }
    for (var j = 0u; j < PER; j++) {
        if (first + j < params.n) {
            let d = digit_of(keys_in[first + j]);
            own[d >> 1u] += 1u << ((d & 1u) * 16u);
        }
    }
    s_counts[lid] = own;
    workgroupBarrier();
    for (var off = 1u; off < WG; off = off << 1u) {
        var t: array<u32, WORDS>;
        if (lid >= off) {
            t = s_counts[lid - off];
        } else {
            for (var w = 0u; w < WORDS; w++) {
                t[w] = 0u;
            }
        }
        workgroupBarrier();
        for (var w = 0u; w < WORDS; w++) {
            s_counts[lid][w] += t[w];
        }
        workgroupBarrier();
    }
    // Exclusive counts before this invocation, then bumped as its own elements are placed.
    var before = s_counts[lid];
    for (var w = 0u; w < WORDS; w++) {
        before[w] -= own[w];
    }
    for (var j = 0u; j < PER; j++) {
        let i = first + j;
        if (i < params.n) {
            let key = keys_in[i];
            let d = digit_of(key);
            let shift = (d & 1u) * 16u;
            let rank = (before[d >> 1u] >> shift) & 0xffffu;
            before[d >> 1u] += 1u << shift;
            let dst = offsets[d * params.num_blocks + block] + rank;
            keys_out[dst] = key;
            values_out[dst] = values_in[i];
        }
    }
}
