// Tile intersections. After the depth sort: the tile counts in depth order (to be scanned), then
// one (tile, Gaussian) pair per touched tile written at the Gaussian's scanned offset, so that
// pairs come out in depth order; after the stable sort by tile, each tile's range in the list.

@group(0) @binding(2) var<storage, read> splats: array<Splat>;
@group(0) @binding(3) var<storage, read> sorted_ids: array<u32>;
@group(0) @binding(4) var<storage, read> tile_counts: array<u32>;
@group(0) @binding(5) var<storage, read_write> offsets: array<u32>;
@group(0) @binding(6) var<storage, read_write> isect_keys: array<u32>;
@group(0) @binding(7) var<storage, read_write> isect_ids: array<u32>;

fn flat_id(gid: vec3<u32>, nwg: vec3<u32>) -> u32 {
    return gid.x + gid.y * nwg.x * 256u;
}

@compute @workgroup_size(256)
fn gather_counts(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let r = flat_id(gid, nwg);
    if r < frame.n {
        offsets[r] = tile_counts[sorted_ids[r]];
    }
}

@compute @workgroup_size(256)
fn emit(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let r = flat_id(gid, nwg);
    if r >= frame.n {
        return;
    }
    let id = sorted_ids[r];
    if tile_counts[id] == 0u {
        return;
    }
    let s = splats[id];
    var off = offsets[r];
    for (var ty = s.y0 / TILE; ty <= s.y1 / TILE; ty++) {
        for (var tx = s.x0 / TILE; tx <= s.x1 / TILE; tx++) {
            if touches_tile(frame, s, tx, ty) {
                isect_keys[off] = ty * frame.tiles_x + tx;
                isect_ids[off] = id;
                off += 1u;
            }
        }
    }
}
