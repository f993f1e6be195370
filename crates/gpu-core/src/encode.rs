//! Recording dispatches: workgroup grids that respect the per-dimension limit, one-dispatch
//! compute passes and whole-buffer bind groups, each counted on the context's
//! [`TrafficCounter`].

use crate::context::{GpuContext, TrafficCounter};

/// Dispatches `groups` workgroups on a 2D grid at most `max_per_dim` wide; kernels recover the
/// linear index as `id.x + id.y * grid.x` and skip the ones past `groups`.
pub fn dispatch_grid(
    traffic: &TrafficCounter,
    cpass: &mut wgpu::ComputePass<'_>,
    groups: u32,
    max_per_dim: u32,
) {
    traffic.dispatches(1);
    let x = groups.min(max_per_dim).max(1);
    cpass.dispatch_workgroups(x, groups.div_ceil(x), 1);
}

/// Workgroup counts for `items` threads in workgroups of 256, split over x and y when x would
/// exceed the per-dimension limit (kernels recover the flat index as `x + y * nx * 256`).
pub fn groups_1d(items: u32, max_per_dim: u32) -> (u32, u32) {
    let groups = items.div_ceil(256).max(1);
    if groups <= max_per_dim {
        (groups, 1)
    } else {
        let y = groups.div_ceil(max_per_dim);
        (groups.div_ceil(y), y)
    }
}

/// Submits the work recorded in `encoder` without waiting for it (counted as one submit): the
/// device runs it before any later submission on the same queue, so a later read-back sees it.
pub fn submit(ctx: &GpuContext, encoder: wgpu::CommandEncoder) {
    ctx.traffic.submit();
    ctx.queue.submit([encoder.finish()]);
}

/// Records one dispatch of `pipeline` with `bind_group`.
pub fn dispatch(
    ctx: &GpuContext,
    encoder: &mut wgpu::CommandEncoder,
    pipeline: &wgpu::ComputePipeline,
    bind_group: &wgpu::BindGroup,
    groups: (u32, u32),
) {
    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: None,
        timestamp_writes: None,
    });
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, bind_group, &[]);
    pass.dispatch_workgroups(groups.0, groups.1, 1);
    ctx.traffic.dispatches(1);
}

/// Records one dispatch of `pipeline` with `bind_group` on a three-dimensional grid of
/// `groups` workgroups (each at most the device's per-dimension limit; see [`tile_grid`]).
pub fn dispatch_xyz(
    ctx: &GpuContext,
    encoder: &mut wgpu::CommandEncoder,
    pipeline: &wgpu::ComputePipeline,
    bind_group: &wgpu::BindGroup,
    groups: [u32; 3],
) {
    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: None,
        timestamp_writes: None,
    });
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, bind_group, &[]);
    pass.dispatch_workgroups(groups[0], groups[1], groups[2]);
    ctx.traffic.dispatches(1);
}

/// The grid of a tiled kernel: `columns` workgroups in x and `rows` workgroups folded over y and
/// z, y at most `max_per_dim` (kernels recover the row block as `id.y + id.z * grid.y` and skip
/// the ones past `rows`). At least one workgroup in each dimension.
pub fn tile_grid(columns: u32, rows: u32, max_per_dim: u32) -> [u32; 3] {
    let y = rows.clamp(1, max_per_dim.max(1));
    [columns.max(1), y, rows.div_ceil(y).max(1)]
}

/// A bind group for group 0 of `pipeline` from `(binding, buffer)` pairs.
pub fn bind(
    ctx: &GpuContext,
    pipeline: &wgpu::ComputePipeline,
    entries: &[(u32, &wgpu::Buffer)],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry<'_>> = entries
        .iter()
        .map(|&(binding, buffer)| wgpu::BindGroupEntry {
            binding,
            resource: buffer.as_entire_binding(),
        })
        .collect();
    ctx.traffic.bind_groups(1);
    ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout: &pipeline.get_bind_group_layout(0),
        entries: &entries,
    })
}

#[cfg(test)]
mod tests {
    use super::{groups_1d, tile_grid};

    #[test]
    fn tile_grids_cover_every_row_block_within_the_limit() {
        for (rows, max) in [
            (0, 65535),
            (1, 65535),
            (6_250, 65535),
            (70_000, 65535),
            (10, 3),
        ] {
            let [x, y, z] = tile_grid(4, rows, max);
            assert_eq!(x, 4);
            assert!(y <= max && y >= 1 && z >= 1, "{rows} {max}: {y}x{z}");
            assert!(
                u64::from(y) * u64::from(z) >= u64::from(rows),
                "{rows} {max}"
            );
            assert!(
                u64::from(y) * u64::from(z - 1) < u64::from(rows.max(1)),
                "{rows} {max}"
            );
        }
    }

    #[test]
    fn one_dimensional_grids_cover_every_item_within_the_limit() {
        for (items, max) in [
            (0, 65535),
            (1, 65535),
            (256, 4),
            (257, 4),
            (100_000, 7),
            (1 << 30, 65535),
        ] {
            let (x, y) = groups_1d(items, max);
            assert!(x <= max && x >= 1 && y >= 1, "{items} {max}: {x}x{y}");
            assert!(
                u64::from(x) * u64::from(y) * 256 >= u64::from(items),
                "{items} {max}"
            );
            // No more than one extra row of workgroups.
            assert!(
                u64::from(x) * u64::from(y - 1) * 256 < u64::from(items.max(1)),
                "{items} {max}"
            );
        }
    }
}
