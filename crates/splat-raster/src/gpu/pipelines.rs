//! The compute pipelines of the backend, compiled once per rasterizer from the WGSL sources in
//! `shaders/` (the shared `common.wgsl` is prepended to the per-Gaussian and per-tile kernels).

use crate::error::RasterError;

const COMMON: &str = include_str!("shaders/common.wgsl");
const PROJECT: &str = include_str!("shaders/project.wgsl");
const EMIT: &str = include_str!("shaders/emit.wgsl");
const RANGES: &str = include_str!("shaders/ranges.wgsl");
const RASTER_FWD: &str = include_str!("shaders/raster_fwd.wgsl");
const RASTER_BWD: &str = include_str!("shaders/raster_bwd.wgsl");
const ATOMICS_NATIVE: &str = include_str!("shaders/atomics_native.wgsl");
const ATOMICS_CAS: &str = include_str!("shaders/atomics_cas.wgsl");
const PROJECT_BWD: &str = include_str!("shaders/project_bwd.wgsl");

/// How the backward compositing adds per-pixel gradients into per-Gaussian sums.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AtomicMode {
    /// `atomicAdd` on `atomic<f32>` (device feature `SHADER_FLOAT32_ATOMIC`).
    NativeF32,
    /// A compare-exchange loop on `atomic<u32>` bit patterns (any adapter).
    CompareExchange,
}

#[derive(Debug)]
pub(crate) struct Pipelines {
    pub project: wgpu::ComputePipeline,
    pub gather_counts: wgpu::ComputePipeline,
    pub emit: wgpu::ComputePipeline,
    pub tile_ranges: wgpu::ComputePipeline,
    pub rasterize: wgpu::ComputePipeline,
    pub rasterize_backward: wgpu::ComputePipeline,
    pub project_backward: wgpu::ComputePipeline,
}

fn pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    entry: &'static str,
) -> wgpu::ComputePipeline {
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(entry),
        layout: None,
        module,
        entry_point: Some(entry),
        compilation_options: wgpu::PipelineCompilationOptions::default(),
        cache: None,
    })
}

impl Pipelines {
    /// Compiles every kernel; a shader or pipeline the device rejects is an error.
    pub fn new(device: &wgpu::Device, atomics: AtomicMode) -> Result<Self, RasterError> {
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = |label: &'static str, parts: &[&str]| {
            device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(label),
                source: wgpu::ShaderSource::Wgsl(parts.concat().into()),
            })
        };
        let project = module("project", &[COMMON, PROJECT]);
        let emit = module("emit", &[COMMON, EMIT]);
        let ranges = module("ranges", &[COMMON, RANGES]);
        let raster_fwd = module("rasterize", &[COMMON, RASTER_FWD]);
        let atomics_src = match atomics {
            AtomicMode::NativeF32 => ATOMICS_NATIVE,
            AtomicMode::CompareExchange => ATOMICS_CAS,
        };
        let raster_bwd = module("rasterize_backward", &[COMMON, atomics_src, RASTER_BWD]);
        let project_bwd = module("project_backward", &[COMMON, PROJECT_BWD]);
        let out = Self {
            project: pipeline(device, &project, "project"),
            gather_counts: pipeline(device, &emit, "gather_counts"),
            emit: pipeline(device, &emit, "emit"),
            tile_ranges: pipeline(device, &ranges, "tile_ranges"),
            rasterize: pipeline(device, &raster_fwd, "rasterize"),
            rasterize_backward: pipeline(device, &raster_bwd, "rasterize_backward"),
            project_backward: pipeline(device, &project_bwd, "project_backward"),
        };
        if let Some(err) = pollster::block_on(scope.pop()) {
            return Err(RasterError::Gpu {
                stage: "pipelines",
                message: err.to_string(),
            });
        }
        Ok(out)
    }
}
