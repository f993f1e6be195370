//! A self-contained way to run [`RadixSorter`] (and the prefix sum it runs) from the unit tests
//! and the `gpu_sort` bench, with their own device, upload,
//! sort, read back. Compiled for the tests and with the cargo feature `test-support` only.

use wgpu::util::DeviceExt;

use super::RadixSorter;
use crate::context::GpuContext;
use crate::error::GpuError;
use crate::scan::level_lengths;

/// Pairs resident on the device for repeated sorting (the bench).
struct Loaded {
    n: u32,
    keys: wgpu::Buffer,
    values: wgpu::Buffer,
    original_keys: wgpu::Buffer,
    original_values: wgpu::Buffer,
}

/// A device plus a [`RadixSorter`] (hidden test and bench hook, not a public API).
#[doc(hidden)]
pub struct SortHarness {
    ctx: GpuContext,
    sorter: RadixSorter,
    loaded: Option<Loaded>,
}

impl SortHarness {
    /// Opens a device ([`GpuContext::new`]) and builds a sorter on it.
    pub fn new() -> Result<Self, GpuError> {
        Self::build(None)
    }

    /// As [`SortHarness::new`], with at most `max_groups_per_dim` workgroups along a dispatch's
    /// x axis, to exercise the 2D grid on small inputs.
    pub fn with_max_groups_per_dim(max_groups_per_dim: u32) -> Result<Self, GpuError> {
        Self::build(Some(max_groups_per_dim))
    }

    fn build(max_groups_per_dim: Option<u32>) -> Result<Self, GpuError> {
        let ctx = GpuContext::new()?;
        let sorter = match max_groups_per_dim {
            Some(m) => RadixSorter::with_max_groups_per_dim(&ctx.device, m),
            None => RadixSorter::new(&ctx.device),
        };
        Ok(Self {
            ctx,
            sorter,
            loaded: None,
        })
    }

    /// The adapter's name, as the driver reports it.
    pub fn adapter_name(&self) -> &str {
        &self.ctx.summary.name
    }

    fn upload(&self, label: &str, data: &[u32]) -> wgpu::Buffer {
        // A zero-sized buffer cannot be bound: always at least one word.
        let contents: &[u32] = if data.is_empty() { &[0] } else { data };
        self.ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytemuck::cast_slice(contents),
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
            })
    }

    fn read_back(&self, buffer: &wgpu::Buffer, n: usize) -> Vec<u32> {
        if n == 0 {
            return Vec::new();
        }
        let bytes = 4 * n as u64;
        let staging = self.ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("sort read-back"),
            size: bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
        encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, bytes);
        self.ctx.queue.submit([encoder.finish()]);
        let (tx, rx) = std::sync::mpsc::channel();
        staging.map_async(wgpu::MapMode::Read, .., move |r| {
            // The receiver waits below; a send error cannot happen while it does.
            let _ = tx.send(r);
        });
        self.ctx
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .expect("wgpu device poll");
        rx.recv()
            .expect("map callback ran")
            .expect("mapping the read-back buffer");
        let out =
            bytemuck::cast_slice(&staging.get_mapped_range(..).expect("mapped range")).to_vec();
        staging.unmap();
        out
    }

    /// Sorts `(keys[i], values[i])` stably by the low `key_bits` bits of the keys on the GPU and
    /// returns the sorted keys and values.
    pub fn sort(&self, keys: &[u32], values: &[u32], key_bits: u32) -> (Vec<u32>, Vec<u32>) {
        assert_eq!(keys.len(), values.len(), "one value per key");
        let n = u32::try_from(keys.len()).expect("at most u32::MAX pairs");
        let k = self.upload("sort keys", keys);
        let v = self.upload("sort values", values);
        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
        let record = self
            .sorter
            .encode(&self.ctx, &mut encoder, &k, &v, n, key_bits);
        self.ctx.queue.submit([encoder.finish()]);
        drop(record);
        (
            self.read_back(&k, keys.len()),
            self.read_back(&v, keys.len()),
        )
    }

    /// Two sorts recorded into one encoder and submitted together (each `(keys, key_bits)`,
    /// values the positions), as the rasterizer records a sort beside other work: each sort's
    /// pooled parameter records held until the submission. The sorted keys and values of each.
    pub fn sort_two_in_one_submission(
        &self,
        a: (&[u32], u32),
        b: (&[u32], u32),
    ) -> [(Vec<u32>, Vec<u32>); 2] {
        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
        let mut buffers = Vec::new();
        let mut records = Vec::new();
        for (keys, key_bits) in [a, b] {
            let n = u32::try_from(keys.len()).expect("at most u32::MAX pairs");
            let values: Vec<u32> = (0..n).collect();
            let k = self.upload("sort keys", keys);
            let v = self.upload("sort values", &values);
            records.push(
                self.sorter
                    .encode(&self.ctx, &mut encoder, &k, &v, n, key_bits),
            );
            buffers.push((k, v, keys.len()));
        }
        self.ctx.queue.submit([encoder.finish()]);
        drop(records);
        let mut out = buffers
            .iter()
            .map(|(k, v, n)| (self.read_back(k, *n), self.read_back(v, *n)));
        [out.next().expect("a"), out.next().expect("b")]
    }

    /// The exclusive prefix sum of `data` by the backend's scan on the GPU, and the total.
    pub fn prefix_sum(&self, data: &[u32]) -> (Vec<u32>, u32) {
        let len = u32::try_from(data.len()).expect("at most u32::MAX values");
        let lens = level_lengths(len);
        let buffers: Vec<wgpu::Buffer> = lens
            .iter()
            .enumerate()
            .map(|(level, &n)| match level {
                0 => self.upload("scan data", data),
                _ => self.upload("scan sums", &vec![0; n as usize]),
            })
            .collect();
        let levels: Vec<&wgpu::Buffer> = buffers.iter().collect();
        let scan = self.sorter.prefix_sum();
        let plan = scan.plan(&self.ctx, &levels, &lens);
        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
        {
            let mut cpass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
            scan.record(&self.ctx.traffic, &mut cpass, &plan);
        }
        self.ctx.queue.submit([encoder.finish()]);
        drop(plan);
        let total = self.read_back(buffers.last().expect("two levels"), 1)[0];
        (self.read_back(&buffers[0], data.len()), total)
    }

    /// Keeps `keys`/`values` on the device for [`SortHarness::sort_loaded`].
    pub fn load(&mut self, keys: &[u32], values: &[u32]) {
        assert_eq!(keys.len(), values.len(), "one value per key");
        self.loaded = Some(Loaded {
            n: u32::try_from(keys.len()).expect("at most u32::MAX pairs"),
            keys: self.upload("sort keys", keys),
            values: self.upload("sort values", values),
            original_keys: self.upload("sort keys (original)", keys),
            original_values: self.upload("sort values (original)", values),
        });
    }

    /// Restores the loaded pairs to their original order (two buffer copies), sorts them and
    /// waits for the device.
    pub fn sort_loaded(&self, key_bits: u32) {
        let l = self.loaded.as_ref().expect("SortHarness::load first");
        let bytes = 4 * u64::from(l.n.max(1));
        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
        encoder.copy_buffer_to_buffer(&l.original_keys, 0, &l.keys, 0, bytes);
        encoder.copy_buffer_to_buffer(&l.original_values, 0, &l.values, 0, bytes);
        let record = self
            .sorter
            .encode(&self.ctx, &mut encoder, &l.keys, &l.values, l.n, key_bits);
        self.ctx.queue.submit([encoder.finish()]);
        drop(record);
        self.ctx
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .expect("wgpu device poll");
    }

    /// The loaded pairs as they are now on the device.
    pub fn read_loaded(&self) -> (Vec<u32>, Vec<u32>) {
        let l = self.loaded.as_ref().expect("SortHarness::load first");
        (
            self.read_back(&l.keys, l.n as usize),
            self.read_back(&l.values, l.n as usize),
        )
    }
}
