//! The device-wide prefix sum: an exclusive scan of `u32`s in place, used by the radix sort (its
//! digit counts, [`crate::RadixSorter`]) and by the rasterizer's forward pass in `splat-raster`
//! (the tile counts in depth order, whose total is the number of tile-Gaussian pairs).
//!
//! Hierarchical in 1024-element chunks (256 invocations × 4 elements, `shaders/scan.wgsl`):
//! level 0 is the data; `scan_chunks` scans each chunk of level `i` and writes the chunk totals
//! to level `i + 1`, down to a level of one element, the grand total; then `add_chunk_offsets`
//! adds the scanned totals back up, level by level. Two levels cover up to 2^20 elements, three
//! up to 2^30. Workgroups are dispatched on a 2D grid, so the 65535-per-dimension limit does not
//! bound the length.
//!
//! What it is not: a workgroup-level scan for other kernels (the sort's scatter ranks its digits
//! with its own packed scan).

use std::num::NonZeroU64;
use std::sync::Arc;

use crate::buffers::{dynamic_uniform_entry, pooled_uniform, storage_entry, words};
use crate::context::{GpuContext, TrafficCounter};
use crate::encode::dispatch_grid;

/// Elements per chunk (one workgroup).
pub(crate) const BLOCK: u32 = 1024;

const SCAN_WGSL: &str = include_str!("shaders/scan.wgsl");

wgsl_mirror! {
    /// The uniform of one scan level (`ScanParams` in `shaders/scan.wgsl`).
    #[repr(C)]
    #[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
    pub(crate) struct ScanParams {
        /// Number of elements of the level.
        pub len: u32,
        pub pad0: u32,
        pub pad1: u32,
        pub pad2: u32,
    }
}

/// Bytes of one [`ScanParams`] record.
const PARAMS_SIZE: u64 = std::mem::size_of::<ScanParams>() as u64;

/// Lengths of the levels of a scan of `len` elements: `len`, then each level's chunk totals,
/// down to a single element (at least two levels; the last holds the grand total).
pub fn level_lengths(len: u32) -> Vec<u32> {
    let mut lens = vec![len.max(1)];
    loop {
        let next = lens.last().expect("non-empty").div_ceil(BLOCK);
        lens.push(next);
        if next == 1 {
            return lens;
        }
    }
}

/// The scan's pipelines, compiled once.
pub struct PrefixSum {
    scan_chunks: wgpu::ComputePipeline,
    add_chunk_offsets: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    /// Byte stride between [`ScanParams`] records (the uniform dynamic-offset alignment).
    params_stride: u64,
    /// Largest workgroup count per dispatch dimension.
    max_groups_per_dim: u32,
}

/// One scan's bind groups and parameters, ready to be recorded (any number of times). Hold it
/// until the encoder it was recorded into is submitted: its parameter record comes from the
/// context's [`pool`](crate::pool), written through the queue, and dropped earlier it could be
/// handed to another plan and written over before this one's work runs.
#[must_use = "hold the plan until its work is submitted"]
pub struct ScanPlan {
    /// The records, one per level (held: see the type's doc).
    _params: Arc<wgpu::Buffer>,
    lens: Vec<u32>,
    /// Level `i` scanned into level `i + 1`.
    groups: Vec<wgpu::BindGroup>,
}

impl PrefixSum {
    /// Compiles the scan, dispatching at most `max_groups_per_dim` workgroups along x.
    pub fn new(device: &wgpu::Device, max_groups_per_dim: u32) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("prefix sum"),
            source: wgpu::ShaderSource::Wgsl(SCAN_WGSL.into()),
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("prefix sum"),
            entries: &[
                dynamic_uniform_entry(PARAMS_SIZE),
                storage_entry(1, false),
                storage_entry(2, false),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("prefix sum"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = |entry: &str| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(&pipeline_layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        let align = u64::from(device.limits().min_uniform_buffer_offset_alignment);
        Self {
            scan_chunks: pipeline("scan_chunks"),
            add_chunk_offsets: pipeline("add_chunk_offsets"),
            layout,
            params_stride: PARAMS_SIZE.div_ceil(align) * align,
            max_groups_per_dim: max_groups_per_dim.max(1),
        }
    }

    /// A scan of `levels[0]` over the lengths `lens` (from [`level_lengths`]): `levels[i]` holds
    /// at least `lens[i]` u32 (STORAGE buffers); the upper levels are scratch, and after the scan
    /// the last one's single element is the grand total.
    ///
    /// # Panics
    /// If `levels` and `lens` differ in length or there are fewer than two levels (caller bugs).
    pub fn plan(&self, ctx: &GpuContext, levels: &[&wgpu::Buffer], lens: &[u32]) -> ScanPlan {
        assert!(
            levels.len() == lens.len() && lens.len() >= 2,
            "PrefixSum::plan: {} buffers for {} levels",
            levels.len(),
            lens.len()
        );
        let stride = self.params_stride as usize;
        let mut bytes = vec![0u8; stride * lens.len()];
        for (i, &len) in lens.iter().enumerate() {
            let record = ScanParams {
                len,
                ..ScanParams::default()
            };
            bytes[i * stride..i * stride + PARAMS_SIZE as usize]
                .copy_from_slice(bytemuck::bytes_of(&record));
        }
        let device = &ctx.device;
        ctx.traffic.bind_groups(lens.len() as u64 - 1);
        let params = pooled_uniform(ctx, "prefix sum params", &bytes);
        let groups = (0..lens.len() - 1)
            .map(|level| {
                device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("prefix sum"),
                    layout: &self.layout,
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 0,
                            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                                buffer: &params,
                                offset: 0,
                                size: NonZeroU64::new(PARAMS_SIZE),
                            }),
                        },
                        wgpu::BindGroupEntry {
                            binding: 1,
                            resource: words(levels[level], lens[level]),
                        },
                        wgpu::BindGroupEntry {
                            binding: 2,
                            resource: words(levels[level + 1], lens[level + 1]),
                        },
                    ],
                })
            })
            .collect();
        ScanPlan {
            _params: params,
            lens: lens.to_vec(),
            groups,
        }
    }

    /// Records `plan` into a compute pass: scan down the levels, then add the scanned chunk
    /// totals back up.
    pub fn record(
        &self,
        traffic: &TrafficCounter,
        cpass: &mut wgpu::ComputePass<'_>,
        plan: &ScanPlan,
    ) {
        let offset = |level: usize| (level as u64 * self.params_stride) as u32;
        for (level, group) in plan.groups.iter().enumerate() {
            cpass.set_pipeline(&self.scan_chunks);
            cpass.set_bind_group(0, group, &[offset(level)]);
            dispatch_grid(
                traffic,
                cpass,
                plan.lens[level + 1],
                self.max_groups_per_dim,
            );
        }
        for (level, group) in plan.groups.iter().enumerate().rev() {
            // The top level is a single chunk: its total is not an offset.
            if plan.lens[level + 1] > 1 {
                cpass.set_pipeline(&self.add_chunk_offsets);
                cpass.set_bind_group(0, group, &[offset(level)]);
                dispatch_grid(
                    traffic,
                    cpass,
                    plan.lens[level + 1],
                    self.max_groups_per_dim,
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {
    // The scan on the GPU is tested through the sort's harness, which runs it on its own device,
    // in the sort's tests (`sort/tests.rs`): the sort builds on this module, not the reverse.

    use super::level_lengths;

    #[test]
    fn levels_end_in_one_total() {
        assert_eq!(level_lengths(0), vec![1, 1]);
        assert_eq!(level_lengths(1), vec![1, 1]);
        assert_eq!(level_lengths(1024), vec![1024, 1]);
        assert_eq!(level_lengths(1025), vec![1025, 2, 1]);
        assert_eq!(level_lengths(1 << 20), vec![1 << 20, 1024, 1]);
        assert_eq!(
            level_lengths(u32::MAX),
            vec![u32::MAX, 1 << 22, 1 << 12, 4, 1]
        );
    }
}
