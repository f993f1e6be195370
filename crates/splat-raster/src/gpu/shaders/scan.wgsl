// Exclusive prefix sum of `data[0..count]` in place, in three dispatches: each workgroup scans a
// block of 1024 values and records the block's total; one workgroup scans the block totals
// (writing the grand total at `block_sums[n_blocks]`); every value then adds its block's offset.

struct ScanParams {
    count: u32,
    n_blocks: u32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> scan: ScanParams;
@group(0) @binding(1) var<storage, read_write> data: array<u32>;
@group(0) @binding(2) var<storage, read_write> block_sums: array<u32>;

const PER_THREAD: u32 = 4u;
const BLOCK: u32 = 1024u;

var<workgroup> partial: array<u32, 256>;

// Inclusive Hillis-Steele scan of `partial` over the workgroup; returns this lane's value.
fn workgroup_inclusive_scan(lid: u32, value: u32) -> u32 {
    partial[lid] = value;
    workgroupBarrier();
    for (var off = 1u; off < 256u; off = off * 2u) {
        var add = 0u;
        if lid >= off {
            add = partial[lid - off];
        }
        workgroupBarrier();
        partial[lid] += add;
        workgroupBarrier();
    }
    return partial[lid];
}

@compute @workgroup_size(256)
fn scan_blocks(@builtin(local_invocation_index) lid: u32, @builtin(workgroup_id) wg: vec3<u32>,
               @builtin(num_workgroups) nwg: vec3<u32>) {
    let block = wg.x + wg.y * nwg.x;
    let base = block * BLOCK + lid * PER_THREAD;
    var vals: array<u32, 4>;
    var sum = 0u;
    for (var k = 0u; k < PER_THREAD; k++) {
        let idx = base + k;
        var v = 0u;
        if idx < scan.count {
            v = data[idx];
        }
        vals[k] = v;
        sum += v;
    }
    let inclusive = workgroup_inclusive_scan(lid, sum);
    var run = inclusive - sum;
    for (var k = 0u; k < PER_THREAD; k++) {
        let idx = base + k;
        if idx < scan.count {
            data[idx] = run;
        }
        run += vals[k];
    }
    if lid == 255u && block < scan.n_blocks {
        block_sums[block] = inclusive;
    }
}

@compute @workgroup_size(256)
fn scan_sums(@builtin(local_invocation_index) lid: u32) {
    var carry = 0u;
    let chunks = (scan.n_blocks + 255u) / 256u;
    for (var ch = 0u; ch < chunks; ch++) {
        let idx = ch * 256u + lid;
        var v = 0u;
        if idx < scan.n_blocks {
            v = block_sums[idx];
        }
        let inclusive = workgroup_inclusive_scan(lid, v);
        if idx < scan.n_blocks {
            block_sums[idx] = carry + inclusive - v;
        }
        workgroupBarrier();
        carry += partial[255];
        workgroupBarrier();
    }
    if lid == 0u {
        block_sums[scan.n_blocks] = carry;
    }
}

@compute @workgroup_size(256)
fn scan_add(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let idx = gid.x + gid.y * nwg.x * 256u;
    if idx < scan.count {
        data[idx] += block_sums[idx / BLOCK];
    }
}
