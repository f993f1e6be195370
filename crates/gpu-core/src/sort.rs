//! A stable GPU LSD radix sort of `u32` keys carrying `u32` values.
//!
//! Digits are 4 bits wide; only the `ceil(key_bits / 4)` passes the key width needs run, and the
//! last one only looks at the bits that remain. Each pass runs three kernels on 1024-element
//! blocks (256 invocations × 4 elements):
//! 1. `count`: each block's 16-bin digit histogram, stored bin-major (`counts[bin · blocks +
//!    block]`);
//! 2. the device-wide prefix sum ([`crate::PrefixSum`]) of `counts` (2 levels up to 2^26 keys, 3 up to
//!    2^36), after which `counts[bin · blocks + block]` is where that block's first element of
//!    that bin goes;
//! 3. `scatter`: each block ranks its elements stably within their digit (a workgroup prefix sum
//!    of per-invocation digit counts, 16 counters packed two per u32) and writes them to their
//!    global places.
//!
//! Passes alternate between the caller's buffers and the sorter's scratch pair; after an odd
//! number of passes the result is copied back. Workgroups are dispatched on a 2D grid, so the
//! 65535-per-dimension limit does not bound `n`; the binding-size limits of the device do
//! (`4·n` bytes per key or value binding).
//!
//! No subgroup operations are used, so it runs on every adapter (lavapipe included).

#[cfg(any(test, feature = "test-support"))]
mod harness;

use std::num::NonZeroU64;
use std::sync::{Arc, Mutex};

#[cfg(any(test, feature = "test-support"))]
pub use harness::SortHarness;

use crate::buffers::{dynamic_uniform_entry, pooled_uniform, storage_entry, words};
use crate::context::{GpuContext, TrafficCounter};
use crate::encode::dispatch_grid;
use crate::scan::{self, PrefixSum, ScanPlan};

/// Elements per workgroup (block) in every kernel (`BLOCK` of sort_common.wgsl).
pub(crate) const BLOCK: u32 = 1024;
/// Bits per radix digit.
const DIGIT_BITS: u32 = 4;
/// Histogram bins per block (`BINS` of sort_common.wgsl).
pub(crate) const BINS: u32 = 1 << DIGIT_BITS;

const COMMON_WGSL: &str = include_str!("shaders/sort_common.wgsl");
const COUNT_WGSL: &str = include_str!("shaders/sort_count.wgsl");
const SCATTER_WGSL: &str = include_str!("shaders/sort_scatter.wgsl");

wgsl_mirror! {
    /// Per-pass parameters, as the WGSL `Params` struct of `shaders/sort_common.wgsl`.
    #[repr(C)]
    #[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
    pub(crate) struct Params {
        /// Number of (key, value) pairs.
        pub n: u32,
        /// Lowest key bit of this pass's digit.
        pub shift: u32,
        /// Width of this pass's digit, 1..=4.
        pub bits: u32,
        /// Number of 1024-element blocks of the keys.
        pub num_blocks: u32,
    }
}

/// Bytes of one [`Params`] record.
const PARAMS_SIZE: u64 = std::mem::size_of::<Params>() as u64;

/// Buffers the sorter owns, sized for `capacity` pairs.
struct Scratch {
    capacity: u32,
    keys: wgpu::Buffer,
    values: wgpu::Buffer,
    /// `levels[0]` holds the digit counts (16 per block); `levels[i + 1]` the chunk totals of
    /// `levels[i]`; the last one has a single element.
    levels: Vec<wgpu::Buffer>,
}

/// What one recorded sort holds until its encoder is submitted: its parameter records and its
/// scan's, from the context's [`pool`](crate::pool), written through the queue (dropped earlier,
/// they could be handed to another sort and written over before this one's work runs).
#[must_use = "hold the record until the sort's encoder is submitted"]
pub struct SortRecord {
    _held: Option<(Arc<wgpu::Buffer>, ScanPlan)>,
}

/// A stable LSD radix sorter of (u32 key, u32 value) pairs on the GPU.
pub struct RadixSorter {
    count: wgpu::ComputePipeline,
    scatter: wgpu::ComputePipeline,
    count_layout: wgpu::BindGroupLayout,
    scatter_layout: wgpu::BindGroupLayout,
    /// Byte stride between `Params` records (the uniform dynamic-offset alignment).
    params_stride: u64,
    /// Largest workgroup count per dispatch dimension.
    max_groups_per_dim: u32,
    /// The prefix sum of the digit counts (shared with the forward pass's tile counts).
    scan: PrefixSum,
    scratch: Mutex<Option<Scratch>>,
}

/// Lengths of the scan levels for `n` pairs: the digit counts, then each level's chunk totals,
/// down to a single element.
fn level_lengths(n: u32) -> Vec<u32> {
    scan::level_lengths(BINS * n.div_ceil(BLOCK).max(1))
}

fn storage_buffer(device: &wgpu::Device, label: &str, words: u32) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: 4 * u64::from(words.max(1)),
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

impl RadixSorter {
    /// Compiles the sort's kernels (and its prefix sum) on `device`, dispatching up to the
    /// device's workgroup limit per dimension.
    pub fn new(device: &wgpu::Device) -> Self {
        Self::with_max_groups_per_dim(device, device.limits().max_compute_workgroups_per_dimension)
    }

    /// As [`RadixSorter::new`], dispatching at most `max_groups_per_dim` workgroups along x (the
    /// tests lower it to exercise the 2D grid with small inputs).
    pub fn with_max_groups_per_dim(device: &wgpu::Device, max_groups_per_dim: u32) -> Self {
        let pipeline = |layout: &wgpu::BindGroupLayout, body: &str, entry: &str, label: &str| {
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(label),
                source: wgpu::ShaderSource::Wgsl(format!("{COMMON_WGSL}\n{body}").into()),
            });
            let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(label),
                bind_group_layouts: &[Some(layout)],
                immediate_size: 0,
            });
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(label),
                layout: Some(&pipeline_layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        let layout = |label: &str, entries: &[wgpu::BindGroupLayoutEntry]| {
            device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(label),
                entries,
            })
        };
        let count_layout = layout(
            "radix sort count",
            &[
                dynamic_uniform_entry(PARAMS_SIZE),
                storage_entry(1, true),
                storage_entry(2, false),
            ],
        );
        let scatter_layout = layout(
            "radix sort scatter",
            &[
                dynamic_uniform_entry(PARAMS_SIZE),
                storage_entry(1, true),
                storage_entry(2, true),
                storage_entry(3, true),
                storage_entry(4, false),
                storage_entry(5, false),
            ],
        );
        let align = u64::from(device.limits().min_uniform_buffer_offset_alignment);
        Self {
            count: pipeline(&count_layout, COUNT_WGSL, "count", "radix sort count"),
            scatter: pipeline(
                &scatter_layout,
                SCATTER_WGSL,
                "scatter",
                "radix sort scatter",
            ),
            count_layout,
            scatter_layout,
            params_stride: PARAMS_SIZE.div_ceil(align) * align,
            max_groups_per_dim: max_groups_per_dim.max(1),
            scan: PrefixSum::new(device, max_groups_per_dim),
            scratch: Mutex::new(None),
        }
    }

    /// Stable ascending sort of the first `n` (key, value) u32 pairs by the low `key_bits` bits of
    /// the key (1..=32). `keys`/`values` are STORAGE|COPY_SRC|COPY_DST buffers of at least n u32;
    /// the sorted result ends in the same buffers. Scratch buffers are owned by the sorter and
    /// grown as needed. Hold the returned [`SortRecord`] until `encoder` is submitted (its
    /// parameter records come from the context's pool, as a [`ScanPlan`]'s).
    ///
    /// # Panics
    /// If `key_bits` is outside 1..=32 or a buffer holds fewer than `n` u32 (caller bugs).
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        keys: &wgpu::Buffer,
        values: &wgpu::Buffer,
        n: u32,
        key_bits: u32,
    ) -> SortRecord {
        assert!(
            (1..=32).contains(&key_bits),
            "RadixSorter::encode: key_bits must be in 1..=32, got {key_bits}"
        );
        let bytes = 4 * u64::from(n);
        assert!(
            keys.size() >= bytes && values.size() >= bytes,
            "RadixSorter::encode: keys ({} B) and values ({} B) must hold n = {n} u32",
            keys.size(),
            values.size()
        );
        if n == 0 {
            return SortRecord { _held: None };
        }
        let device = &ctx.device;
        let traffic = &ctx.traffic;
        let mut guard = self.scratch.lock().unwrap_or_else(|e| e.into_inner());
        if guard.as_ref().is_none_or(|s| s.capacity < n) {
            // Grow by half again (amortised), but never past the device's buffer size limit.
            let max_words = u32::try_from(device.limits().max_buffer_size / 4).unwrap_or(u32::MAX);
            let grown = guard
                .as_ref()
                .map_or(0, |s| s.capacity.saturating_add(s.capacity / 2));
            let capacity = n.max(grown.min(max_words));
            let levels = level_lengths(capacity);
            for _ in 0..2 + levels.len() {
                traffic.buffer();
            }
            *guard = Some(Scratch {
                capacity,
                keys: storage_buffer(device, "radix sort keys scratch", capacity),
                values: storage_buffer(device, "radix sort values scratch", capacity),
                levels: levels
                    .into_iter()
                    .map(|len| storage_buffer(device, "radix sort counts", len))
                    .collect(),
            });
        }
        let scratch = guard.as_ref().expect("scratch allocated above");

        let num_blocks = n.div_ceil(BLOCK);
        let passes = key_bits.div_ceil(DIGIT_BITS);
        let lens = level_lengths(n);

        // One Params record per digit pass.
        let mut records = Vec::new();
        for pass in 0..passes {
            let shift = pass * DIGIT_BITS;
            records.push(Params {
                n,
                shift,
                bits: (key_bits - shift).min(DIGIT_BITS),
                num_blocks,
            });
        }
        let stride = self.params_stride as usize;
        let mut bytes = vec![0u8; stride * records.len()];
        for (i, r) in records.iter().enumerate() {
            bytes[i * stride..i * stride + PARAMS_SIZE as usize]
                .copy_from_slice(bytemuck::bytes_of(r));
        }
        let params = pooled_uniform(ctx, "radix sort params", &bytes);
        let params_binding = wgpu::BindingResource::Buffer(wgpu::BufferBinding {
            buffer: &params,
            offset: 0,
            size: NonZeroU64::new(PARAMS_SIZE),
        });
        let pass_offset = |pass: u32| (u64::from(pass) * self.params_stride) as u32;

        // Ping-pong: even passes read the caller's buffers, odd passes the scratch pair.
        let pairs = [(keys, values), (&scratch.keys, &scratch.values)];
        let bind = |layout: &wgpu::BindGroupLayout, resources: &[wgpu::BindingResource<'_>]| {
            let entries: Vec<_> = resources
                .iter()
                .enumerate()
                .map(|(i, r)| wgpu::BindGroupEntry {
                    binding: i as u32,
                    resource: r.clone(),
                })
                .collect();
            traffic.bind_groups(1);
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("radix sort"),
                layout,
                entries: &entries,
            })
        };
        let count_groups: Vec<_> = pairs
            .iter()
            .map(|(k, _)| {
                bind(
                    &self.count_layout,
                    &[
                        params_binding.clone(),
                        words(k, n),
                        words(&scratch.levels[0], lens[0]),
                    ],
                )
            })
            .collect();
        let scatter_groups: Vec<_> = (0..2)
            .map(|from| {
                let (ki, vi) = pairs[from];
                let (ko, vo) = pairs[1 - from];
                bind(
                    &self.scatter_layout,
                    &[
                        params_binding.clone(),
                        words(ki, n),
                        words(vi, n),
                        words(&scratch.levels[0], lens[0]),
                        words(ko, n),
                        words(vo, n),
                    ],
                )
            })
            .collect();
        let levels: Vec<&wgpu::Buffer> = scratch.levels.iter().take(lens.len()).collect();
        let scan_plan: ScanPlan = self.scan.plan(ctx, &levels, &lens);

        {
            let mut cpass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("radix sort"),
                timestamp_writes: None,
            });
            for pass in 0..passes {
                let from = (pass % 2) as usize;
                cpass.set_pipeline(&self.count);
                cpass.set_bind_group(0, &count_groups[from], &[pass_offset(pass)]);
                self.dispatch(traffic, &mut cpass, num_blocks);

                self.scan.record(traffic, &mut cpass, &scan_plan);

                cpass.set_pipeline(&self.scatter);
                cpass.set_bind_group(0, &scatter_groups[from], &[pass_offset(pass)]);
                self.dispatch(traffic, &mut cpass, num_blocks);
            }
        }
        if passes % 2 == 1 {
            encoder.copy_buffer_to_buffer(&scratch.keys, 0, keys, 0, 4 * u64::from(n));
            encoder.copy_buffer_to_buffer(&scratch.values, 0, values, 0, 4 * u64::from(n));
        }
        SortRecord {
            _held: Some((params, scan_plan)),
        }
    }

    /// The prefix sum the sorter runs, for the other scans of the backend.
    pub fn prefix_sum(&self) -> &PrefixSum {
        &self.scan
    }

    /// Dispatches `groups` workgroups on a 2D grid; the kernels skip the ones past `groups`.
    fn dispatch(&self, traffic: &TrafficCounter, cpass: &mut wgpu::ComputePass<'_>, groups: u32) {
        dispatch_grid(traffic, cpass, groups, self.max_groups_per_dim);
    }
}

#[cfg(test)]
mod tests;
