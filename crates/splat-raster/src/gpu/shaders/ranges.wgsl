// Per tile, the range [start, end) of its entries in the tile-sorted intersection list (the
// range buffer is cleared to zero first, so a tile without entries keeps [0, 0)).

@group(0) @binding(2) var<storage, read> isect_keys: array<u32>;
@group(0) @binding(3) var<storage, read_write> ranges: array<u32>;

@compute @workgroup_size(256)
fn tile_ranges(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = gid.x + gid.y * nwg.x * 256u;
    let n = frame.n_isect;
    if i >= n {
        return;
    }
    let t = isect_keys[i];
    if i == 0u || isect_keys[i - 1u] != t {
        ranges[2u * t] = i;
    }
    if i + 1u == n || isect_keys[i + 1u] != t {
        ranges[2u * t + 1u] = i + 1u;
    }
}
