//! Adam on device buffers: [`GpuAdam`], the WGSL twin of [`Adam::step`] and
//! [`Adam::step_columns`] (`adam.wgsl`, one invocation per moment).
//!
//! The host [`Adam`] keeps what is per group and per step (the schedule, the step count, β1, β2,
//! ε): [`Adam::next_update`] counts an update and gives its constants ([`AdamUpdate`]), and
//! [`GpuAdam::encode`] records the element-wise update on buffers already on the device. So a
//! resident training loop moves 48 bytes per group and step (the constants), nothing else.
//! [`GpuAdam::step`] and [`GpuAdam::step_columns`] do the same on host slices (upload, run, read
//! back into the slices and the group's moments), with the CPU methods' signatures, for tests
//! and for callers whose parameters are not resident yet.

use gpu_core::buffers::{read_back, storage_init, uniform};
use gpu_core::encode::{bind, dispatch, groups_1d};
use gpu_core::{GpuContext, GpuError, wgsl_mirror};

use crate::adam::{Adam, AdamUpdate, GroupId};

pub(crate) const ADAM_WGSL: &str = include_str!("adam.wgsl");

wgsl_mirror! {
    /// Mirror of `Params` in `adam.wgsl` (a test checks names, types, offsets and size).
    #[repr(C)]
    #[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
    pub(crate) struct AdamParams {
        pub count: u32,
        pub stride: u32,
        pub start: u32,
        pub width: u32,
        pub b1: f32,
        pub b2: f32,
        pub eps: f32,
        pub step_size: f32,
        pub bc2_sqrt: f32,
        pub row_stride: u32,
        pub pad0: u32,
        pub pad1: u32,
    }
}

/// Where a group's values sit in its parameter and gradient buffers: `rows` rows of `stride`
/// values, of which the group updates the `width` columns from `start` (its moments hold
/// `rows × width` values). A plain group is [`AdamLayout::plain`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AdamLayout {
    /// Rows of the parameter buffer.
    pub rows: u32,
    /// Values per row of the parameter and gradient buffers.
    pub stride: u32,
    /// First column of the group in each row.
    pub start: u32,
    /// Columns of the group (values per row of its moments).
    pub width: u32,
}

impl AdamLayout {
    /// A group of `len` values updated as one buffer ([`Adam::step`]).
    pub fn plain(len: u32) -> Self {
        Self {
            rows: len,
            stride: 1,
            start: 0,
            width: 1,
        }
    }

    /// Moments, and parameters updated, per call: `rows × width`, or `None` when that does not
    /// fit a `u32`.
    pub fn count(&self) -> Option<u32> {
        self.rows.checked_mul(self.width)
    }
}

/// The device buffers of one group's step: parameters and gradients as [`AdamLayout`] says,
/// the two moments `rows × width` values each (all f32).
#[derive(Clone, Copy, Debug)]
pub struct AdamBuffers<'a> {
    /// Parameters, updated in place.
    pub params: &'a wgpu::Buffer,
    /// Gradients, read.
    pub grads: &'a wgpu::Buffer,
    /// First moments, updated in place.
    pub m: &'a wgpu::Buffer,
    /// Second moments, updated in place.
    pub v: &'a wgpu::Buffer,
}

/// The Adam kernel, compiled once per device.
#[derive(Debug)]
pub struct GpuAdam {
    pipeline: wgpu::ComputePipeline,
}

fn config_error(message: String) -> GpuError {
    GpuError::new("adam", message)
}

impl GpuAdam {
    /// Compiles the kernel on `ctx`'s device.
    pub fn new(ctx: &GpuContext) -> Result<Self, GpuError> {
        let device = &ctx.device;
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("adam"),
            source: wgpu::ShaderSource::Wgsl(ADAM_WGSL.into()),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("adam step"),
            layout: None,
            module: &module,
            entry_point: Some("step"),
            compilation_options: Default::default(),
            cache: None,
        });
        if let Some(err) = pollster::block_on(scope.pop()) {
            return Err(GpuError::new("pipelines", err.to_string()));
        }
        Ok(Self { pipeline })
    }

    /// Records one update with the constants `update` (from [`Adam::next_update`]) of the group
    /// laid out as `layout` in `bufs`. Nothing is recorded for a group of no values.
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        update: &AdamUpdate,
        layout: AdamLayout,
        bufs: AdamBuffers<'_>,
    ) -> Result<(), GpuError> {
        let count = layout
            .count()
            .ok_or_else(|| config_error(format!("{layout:?}: more than 2³² values")))?;
        if layout.width > 0 && layout.start + layout.width > layout.stride {
            return Err(config_error(format!(
                "{layout:?}: the columns run past the row"
            )));
        }
        if count == 0 {
            return Ok(());
        }
        let max_dim = ctx.device.limits().max_compute_workgroups_per_dimension;
        let groups = groups_1d(count, max_dim);
        let params = AdamParams {
            count,
            stride: layout.stride,
            start: layout.start,
            width: layout.width,
            b1: update.b1,
            b2: update.b2,
            eps: update.eps,
            step_size: update.step_size,
            bc2_sqrt: update.bc2_sqrt,
            row_stride: groups.0 * 256,
            ..AdamParams::default()
        };
        let params = uniform(ctx, "adam params", bytemuck::bytes_of(&params));
        let group = bind(
            ctx,
            &self.pipeline,
            &[
                (0, &params),
                (1, bufs.params),
                (2, bufs.grads),
                (3, bufs.m),
                (4, bufs.v),
            ],
        );
        dispatch(ctx, encoder, &self.pipeline, &group, groups);
        Ok(())
    }

    /// [`Adam::step`] of an f32 group on the device: uploads `params`, `grads` and the group's
    /// moments, runs one update and reads all three back in place.
    pub fn step(
        &self,
        ctx: &GpuContext,
        adam: &mut Adam,
        id: GroupId,
        iteration: i64,
        params: &mut [f32],
        grads: &[f32],
    ) -> Result<(), GpuError> {
        let len = u32::try_from(params.len())
            .map_err(|_| config_error(format!("{} parameters", params.len())))?;
        self.step_host(
            ctx,
            adam,
            id,
            iteration,
            params,
            grads,
            AdamLayout::plain(len),
        )
    }

    /// [`Adam::step_columns`] on the device: the columns `cols` of rows of `stride` values.
    #[allow(clippy::too_many_arguments)]
    pub fn step_columns(
        &self,
        ctx: &GpuContext,
        adam: &mut Adam,
        id: GroupId,
        iteration: i64,
        params: &mut [f32],
        grads: &[f32],
        stride: usize,
        cols: std::ops::Range<usize>,
    ) -> Result<(), GpuError> {
        let too_many = || config_error(format!("{} parameters", params.len()));
        let rows = u32::try_from(params.len() / stride.max(1)).map_err(|_| too_many())?;
        let layout = AdamLayout {
            rows,
            stride: u32::try_from(stride).map_err(|_| too_many())?,
            start: u32::try_from(cols.start).map_err(|_| too_many())?,
            width: u32::try_from(cols.len()).map_err(|_| too_many())?,
        };
        self.step_host(ctx, adam, id, iteration, params, grads, layout)
    }

    #[allow(clippy::too_many_arguments)]
    fn step_host(
        &self,
        ctx: &GpuContext,
        adam: &mut Adam,
        id: GroupId,
        iteration: i64,
        params: &mut [f32],
        grads: &[f32],
        layout: AdamLayout,
    ) -> Result<(), GpuError> {
        let Some(group) = adam.groups().get(id.0) else {
            return Err(config_error(format!("no Adam group {}", id.0)));
        };
        let moments = layout.count().map(|c| c as usize);
        let values = layout.rows as usize * layout.stride as usize;
        if moments != Some(group.m.len())
            || params.len() != values
            || grads.len() != values
            || (layout.width > 0 && layout.width as usize != group.row_width)
        {
            return Err(config_error(format!(
                "Adam group `{}` ({} moments in rows of {}): {layout:?} with {} parameters and {} \
                 gradients does not fit it",
                group.name,
                group.m.len(),
                group.row_width,
                params.len(),
                grads.len()
            )));
        }
        let update = adam
            .next_update(id, iteration)
            .map_err(|e| config_error(e.to_string()))?;
        let group = adam.group_mut(id);
        let p = storage_init(ctx, "adam parameters", bytemuck::cast_slice(params))?;
        let g = storage_init(ctx, "adam gradients", bytemuck::cast_slice(grads))?;
        let m = storage_init(ctx, "adam m", bytemuck::cast_slice(&group.m))?;
        let v = storage_init(ctx, "adam v", bytemuck::cast_slice(&group.v))?;
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        let bufs = AdamBuffers {
            params: &p,
            grads: &g,
            m: &m,
            v: &v,
        };
        self.encode(ctx, &mut encoder, &update, layout, bufs)?;
        let bytes = |n: usize| 4 * n as u64;
        let back = read_back(
            ctx,
            encoder,
            &[
                (&p, 0, bytes(params.len())),
                (&m, 0, bytes(group.m.len())),
                (&v, 0, bytes(group.v.len())),
            ],
        )?;
        let [p, m, v] = [0, 1, 2].map(|i| bytemuck::pod_collect_to_vec::<u8, f32>(&back[i]));
        params.copy_from_slice(&p);
        group.m = m;
        group.v = v;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gpu_core::wgsl_text::check_mirror;

    #[test]
    fn the_uniform_matches_its_wgsl_struct() {
        check_mirror(
            AdamParams::FIELDS,
            size_of::<AdamParams>(),
            ADAM_WGSL,
            "Params",
        );
    }
}
