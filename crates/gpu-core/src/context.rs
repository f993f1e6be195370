//! Adapter and device acquisition: a [`GpuContext`] holds the device, its queue, what the adapter
//! is (hardware or software), which optional features it offers, and the host–device traffic
//! recorded on it ([`TrafficCounter`]).

use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::GpuError;
use crate::pool::BufferPool;
use crate::timestamps::Timestamps;
use crate::traffic::Traffic;

/// What the chosen adapter is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AdapterSummary {
    /// Adapter name as the driver reports it (e.g. `llvmpipe (LLVM 19.1.7, 256 bits)`).
    pub name: String,
    /// Graphics API backend (`Vulkan`, `Metal`, ...).
    pub backend: String,
    /// Driver name and version.
    pub driver: String,
    /// True for a hardware GPU (integrated, discrete or virtual); false for a software
    /// rasterizer (`wgpu::DeviceType::Cpu`, e.g. Mesa's lavapipe) or an unknown device type.
    pub hardware: bool,
    /// Whether the adapter offers native `atomic<f32>` add (`SHADER_FLOAT32_ATOMIC`).
    pub float32_atomics: bool,
}

impl std::fmt::Display for AdapterSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} ({}, {}, {})",
            self.name,
            self.backend,
            if self.hardware {
                "hardware"
            } else {
                "software"
            },
            if self.float32_atomics {
                "f32 atomics"
            } else {
                "no f32 atomics"
            }
        )
    }
}

/// A wgpu device and queue with what the adapter offers.
#[derive(Debug)]
pub struct GpuContext {
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    pub(crate) summary: AdapterSummary,
    /// Distinguishes contexts, so that a forward output made on one device is not handed to the
    /// backward pass of another.
    pub(crate) id: u64,
    /// Host–device traffic recorded on this context ([`GpuContext::traffic`]).
    pub traffic: TrafficCounter,
    /// Buffers kept between calls ([`crate::buffers::pooled_storage`] and its siblings).
    pub pool: BufferPool,
    /// GPU timestamps of labelled spans, where the adapter writes them inside encoders
    /// ([`crate::timestamps`]); `None` where it does not.
    pub timestamps: Option<Timestamps>,
}

/// Running [`Traffic`] totals of one context, added to by the helpers that upload, read back,
/// submit, dispatch and create buffers or bind groups (relaxed atomics: the totals are read
/// between calls, never used to order work).
#[derive(Debug, Default)]
pub struct TrafficCounter {
    bytes_up: AtomicU64,
    bytes_down: AtomicU64,
    submits: AtomicU64,
    waits: AtomicU64,
    dispatches: AtomicU64,
    buffers_created: AtomicU64,
    bind_groups_created: AtomicU64,
}

impl TrafficCounter {
    fn add(counter: &AtomicU64, n: u64) {
        counter.fetch_add(n, Ordering::Relaxed);
    }

    /// `bytes` written into a device buffer by the host.
    pub fn upload(&self, bytes: u64) {
        Self::add(&self.bytes_up, bytes);
    }

    /// `bytes` read back after one submit and one wait.
    pub fn read_back(&self, bytes: u64) {
        Self::add(&self.bytes_down, bytes);
        Self::add(&self.submits, 1);
        Self::add(&self.waits, 1);
    }

    /// One command buffer submitted without waiting for it.
    pub fn submit(&self) {
        Self::add(&self.submits, 1);
    }

    /// `n` compute dispatches recorded.
    pub fn dispatches(&self, n: u64) {
        Self::add(&self.dispatches, n);
    }

    /// One device buffer created.
    pub fn buffer(&self) {
        Self::add(&self.buffers_created, 1);
    }

    /// `n` bind groups created.
    pub fn bind_groups(&self, n: u64) {
        Self::add(&self.bind_groups_created, n);
    }

    /// The totals so far.
    pub fn snapshot(&self) -> Traffic {
        let get = |c: &AtomicU64| c.load(Ordering::Relaxed);
        Traffic {
            bytes_up: get(&self.bytes_up),
            bytes_down: get(&self.bytes_down),
            submits: get(&self.submits),
            waits: get(&self.waits),
            dispatches: get(&self.dispatches),
            buffers_created: get(&self.buffers_created),
            bind_groups_created: get(&self.bind_groups_created),
        }
    }
}

static NEXT_ID: AtomicU64 = AtomicU64::new(1);

impl GpuContext {
    /// Acquires the default adapter (high performance preference; the backends and adapter can be
    /// pinned with wgpu's environment variables, e.g. `WGPU_BACKEND=vulkan`) and a device with
    /// the features and limits the kernels need. A missing adapter or a refused device is
    /// [`GpuError`], never a panic.
    pub fn new() -> Result<Self, GpuError> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            ..Default::default()
        }))
        .map_err(|e| GpuError {
            stage: "adapter",
            message: format!(
                "no GPU adapter found ({e}); install a Vulkan driver (e.g. Mesa's lavapipe: \
                 mesa-vulkan-drivers) or use the CPU backend"
            ),
        })?;
        let info = adapter.get_info();
        let float32_atomics = adapter
            .features()
            .contains(wgpu::Features::SHADER_FLOAT32_ATOMIC);
        let mut required_features = wgpu::Features::empty();
        if float32_atomics {
            required_features |= wgpu::Features::SHADER_FLOAT32_ATOMIC;
        }
        let timestamp_features =
            wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS;
        let timestamps = adapter.features().contains(timestamp_features);
        if timestamps {
            required_features |= timestamp_features;
        }
        let adapter_limits = adapter.limits();
        let required_limits = wgpu::Limits {
            max_storage_buffers_per_shader_stage: adapter_limits
                .max_storage_buffers_per_shader_stage
                .min(16),
            max_storage_buffer_binding_size: adapter_limits.max_storage_buffer_binding_size,
            max_buffer_size: adapter_limits.max_buffer_size,
            max_compute_workgroups_per_dimension: adapter_limits
                .max_compute_workgroups_per_dimension,
            ..wgpu::Limits::default()
        };
        if required_limits.max_storage_buffers_per_shader_stage < 10 {
            return Err(GpuError {
                stage: "adapter",
                message: format!(
                    "adapter {} offers {} storage buffers per shader stage, the kernels need 10",
                    info.name, required_limits.max_storage_buffers_per_shader_stage
                ),
            });
        }
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("splat-raster"),
            required_features,
            required_limits,
            ..Default::default()
        }))
        .map_err(|e| GpuError {
            stage: "device",
            message: format!("adapter {} refused a device: {e}", info.name),
        })?;
        let summary = AdapterSummary {
            name: info.name.clone(),
            backend: format!("{:?}", info.backend),
            driver: format!("{} {}", info.driver, info.driver_info),
            hardware: matches!(
                info.device_type,
                wgpu::DeviceType::DiscreteGpu
                    | wgpu::DeviceType::IntegratedGpu
                    | wgpu::DeviceType::VirtualGpu
            ),
            float32_atomics,
        };
        let timestamps = timestamps.then(|| Timestamps::new(&device, &queue));
        Ok(Self {
            timestamps,
            device,
            queue,
            summary,
            id: NEXT_ID.fetch_add(1, Ordering::Relaxed),
            traffic: TrafficCounter::default(),
            pool: BufferPool::default(),
        })
    }

    /// Begins a timestamp span labelled `label` in `encoder` ([`Timestamps::begin`]); `None`,
    /// and nothing written, where the adapter has no timestamps.
    pub fn span_begin(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        label: &'static str,
    ) -> Option<crate::timestamps::Span> {
        self.timestamps.as_ref().map(|t| t.begin(encoder, label))
    }

    /// Ends a span of [`span_begin`](Self::span_begin) in the same encoder.
    pub fn span_end(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        span: Option<crate::timestamps::Span>,
    ) {
        if let (Some(t), Some(span)) = (&self.timestamps, span) {
            t.end(encoder, span);
        }
    }

    /// What the adapter is.
    pub fn adapter(&self) -> &AdapterSummary {
        &self.summary
    }

    /// This context's identity (unique in the process), so that device state made on one
    /// context is not handed to another.
    pub fn id(&self) -> u64 {
        self.id
    }

    /// The host–device traffic recorded on this context since it was made (every rasterizer
    /// sharing it adds to the same totals).
    pub fn traffic(&self) -> Traffic {
        self.traffic.snapshot()
    }
}
