//! The MLP on device buffers: [`GpuMlp`], the WGSL twin of [`Mlp::forward`] and
//! [`Mlp::backward`] in f32 (`mlp.wgsl`, one layer per dispatch).
//!
//! A [`DeviceMlp`] is a network's shape and its flat parameter buffer on the device (uploaded
//! once, updated in place by [`GpuAdam`](super::GpuAdam)); an [`MlpWorkspace`] holds the
//! buffers of one row count: every layer's output (the backward's cache), the two ping-pong
//! gradient buffers, the input gradient, the parameter gradient and the per-chunk partial sums
//! of the weight gradient, and each layer's uniform, written once. [`GpuMlp::encode_forward`]
//! and [`GpuMlp::encode_backward`] record the passes on buffers already on the device;
//! [`GpuMlp::forward_backward`] uploads, runs both and reads back, for tests and for callers
//! that are not resident yet.
//!
//! The three products (forward, input gradient, weight gradient) are tiled 16 × 16 through
//! workgroup memory, each value's terms added in order of the summed index; their plain forms
//! (one invocation per value) stay beside them ([`MlpKernels`]). The weight gradient
//! is summed in chunks of [`CHUNK_ROWS`] rows, then over the chunks in order: a run repeats
//! itself bit for bit.
//!
//! What it is not: f16 storage (a network stored in f16 is refused), or the CPU's reference
//! (that is [`Mlp`]).

use gpu_core::buffers::{read_back, storage, storage_init, uniform, write};
use gpu_core::encode::{bind, dispatch, dispatch_xyz, groups_1d, tile_grid};
use gpu_core::{GpuContext, GpuError, wgsl_mirror};

use crate::activation::Activation;
use crate::mlp::{LayerShape, Mlp, MlpGrads};
use crate::precision::StoreRef;

pub(crate) const MLP_WGSL: &str = include_str!("mlp.wgsl");

/// Rows per chunk of the weight gradient's first sum (the CPU's backward block length).
pub const CHUNK_ROWS: u32 = crate::mlp::BACKWARD_BLOCK as u32;

wgsl_mirror! {
    /// Mirror of `Params` in `mlp.wgsl` (a test checks names, types, offsets and size).
    #[repr(C)]
    #[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
    pub(crate) struct LayerParams {
        pub rows: u32,
        pub width_a: u32,
        pub width_b: u32,
        pub outputs: u32,
        pub weight_offset: u32,
        pub activation: u32,
        pub mode_a: u32,
        pub chunk_rows: u32,
        pub chunks: u32,
        pub stride_outputs: u32,
        pub stride_inputs: u32,
        pub stride_partials: u32,
        pub stride_reduce: u32,
        pub pad0: u32,
        pub pad1: u32,
        pub pad2: u32,
    }
}

/// `mode_a` of `input_grad`: what becomes of the gradient of the layer's first input.
const MODE_SKIP: u32 = 0;
const MODE_WRITE: u32 = 1;
const MODE_ADD: u32 = 2;

fn activation_code(a: Activation) -> u32 {
    match a {
        Activation::Identity => 0,
        Activation::Relu => 1,
        Activation::Sigmoid => 2,
    }
}

fn too_large(what: &str) -> GpuError {
    GpuError::new("buffers", format!("MLP {what}: more than 2³² values"))
}

fn u32_of(n: usize, what: &str) -> Result<u32, GpuError> {
    u32::try_from(n).map_err(|_| too_large(what))
}

/// A network's shape and its f32 parameters on the device.
#[derive(Debug)]
pub struct DeviceMlp {
    layers: Vec<LayerShape>,
    activations: Vec<Activation>,
    input: usize,
    output: usize,
    param_count: usize,
    /// The flat parameter buffer, laid out as [`Mlp::params`].
    pub params: wgpu::Buffer,
}

impl DeviceMlp {
    /// Uploads `mlp`'s shape and parameters. A network stored in f16 is refused.
    pub fn upload(ctx: &GpuContext, mlp: &Mlp) -> Result<Self, GpuError> {
        let StoreRef::F32(values) = mlp.params() else {
            return Err(GpuError::new(
                "buffers",
                "the GPU MLP stores f32 only; this network stores f16",
            ));
        };
        let config = mlp.config();
        let last = mlp.layers().len() - 1;
        let activations = (0..mlp.layers().len())
            .map(|l| {
                if l == last {
                    config.output_activation
                } else {
                    config.hidden_activation
                }
            })
            .collect();
        u32_of(mlp.param_count(), "parameters")?;
        Ok(Self {
            layers: mlp.layers().to_vec(),
            activations,
            input: mlp.input_width(),
            output: mlp.output_width(),
            param_count: mlp.param_count(),
            params: storage_init(ctx, "mlp parameters", bytemuck::cast_slice(values))?,
        })
    }

    /// Number of parameters.
    pub fn param_count(&self) -> usize {
        self.param_count
    }

    /// Width of an output row.
    pub fn output_width(&self) -> usize {
        self.output
    }

    /// Whether `mlp` has this network's shape (layers and activations), so that its parameters
    /// can be written here ([`DeviceMlp::write_params`]).
    pub fn same_shape(&self, mlp: &Mlp) -> bool {
        let config = mlp.config();
        let last = mlp.layers().len().saturating_sub(1);
        self.layers == mlp.layers()
            && self.activations.iter().enumerate().all(|(l, &a)| {
                a == if l == last {
                    config.output_activation
                } else {
                    config.hidden_activation
                }
            })
    }

    /// Writes `mlp`'s parameters over the device's (an upload of 4 bytes per parameter, no new
    /// buffer): a network of another shape ([`DeviceMlp::same_shape`]) or stored in f16 is an
    /// error.
    pub fn write_params(&self, ctx: &GpuContext, mlp: &Mlp) -> Result<(), GpuError> {
        let StoreRef::F32(values) = mlp.params() else {
            return Err(GpuError::new(
                "buffers",
                "the GPU MLP stores f32 only; this network stores f16",
            ));
        };
        if !self.same_shape(mlp) {
            return Err(GpuError::new(
                "buffers",
                "the network's shape differs from the one on the device",
            ));
        }
        write(ctx, &self.params, 0, bytemuck::cast_slice(values))
    }
}

/// The device buffers of one row count of one network's shape.
#[derive(Debug)]
pub struct MlpWorkspace {
    rows: u32,
    chunks: u32,
    want_input: bool,
    /// Every layer's output (rows × its outputs); the last is the network's output.
    pub acts: Vec<wgpu::Buffer>,
    /// Gradients flowing back between layers (rows × the widest layer, twice).
    grads: [wgpu::Buffer; 2],
    /// `∂L/∂input` (rows × input), written by a backward that asks for it.
    pub d_input: wgpu::Buffer,
    /// `∂L/∂θ`, laid out as the parameter buffer.
    pub d_params: wgpu::Buffer,
    partials: wgpu::Buffer,
    /// Stand-ins bound where a layer has no second input or no input gradient is wanted.
    unused: [wgpu::Buffer; 2],
    uniforms: Vec<wgpu::Buffer>,
    groups: Vec<LayerGroups>,
}

/// Workgroup grids of one layer's kernels.
#[derive(Clone, Copy, Debug)]
struct LayerGroups {
    /// `delta`, one invocation per output value.
    outputs: (u32, u32),
    /// `weight_reduce`, one invocation per parameter of the layer.
    reduce: (u32, u32),
    /// The tiled products.
    forward: [u32; 3],
    inputs: [u32; 3],
    partials: [u32; 3],
    /// The plain products of the input gradient and the weight gradient's partial sums (the
    /// plain forward has `outputs`' grid).
    inputs_flat: (u32, u32),
    partials_flat: (u32, u32),
}

/// Side of the tiled kernels' blocks (`TILE` of mlp.wgsl).
const TILE: u32 = 16;

impl MlpWorkspace {
    /// Buffers for `rows` rows of `net` on `ctx`, for backward passes that make the input's
    /// gradient when `want_input` (a training loop asks the same every step).
    pub fn new(
        ctx: &GpuContext,
        net: &DeviceMlp,
        rows: usize,
        want_input: bool,
    ) -> Result<Self, GpuError> {
        let skip = net.layers.iter().any(|l| l.skip_input);
        let rows32 = u32_of(rows, "rows")?;
        let chunks = rows32.div_ceil(CHUNK_ROWS).max(1);
        let max_dim = ctx.device.limits().max_compute_workgroups_per_dimension;
        let widest = net
            .layers
            .iter()
            .map(|l| l.output)
            .max()
            .unwrap_or(1)
            .max(net.input);
        let values = |width: usize, what| {
            rows.checked_mul(width)
                .filter(|&n| u32::try_from(n).is_ok())
                .map(|n| 4 * n as u64)
                .ok_or_else(|| too_large(what))
        };
        let mut acts = Vec::with_capacity(net.layers.len());
        let mut uniforms = Vec::with_capacity(net.layers.len());
        let mut groups = Vec::with_capacity(net.layers.len());
        let mut widest_layer = 0u64;
        for (l, layer) in net.layers.iter().enumerate() {
            acts.push(storage(
                ctx,
                "mlp activations",
                values(layer.output, "activations")?,
            )?);
            let (width_a, width_b) = if l == 0 {
                (net.input, 0)
            } else if layer.skip_input {
                (net.input, layer.input - net.input)
            } else {
                (layer.input, 0)
            };
            let per_chunk = (layer.input + 1) * layer.output;
            widest_layer = widest_layer.max(per_chunk as u64);
            let outputs = u32_of(rows * layer.output, "outputs")?;
            let inputs = u32_of(rows * layer.input, "inputs")?;
            let partials = u32_of(chunks as usize * per_chunk, "partial sums")?;
            let blocks = |n: usize| (n as u32).div_ceil(TILE);
            let row_blocks = rows32.div_ceil(TILE);
            let g = LayerGroups {
                outputs: groups_1d(outputs, max_dim),
                reduce: groups_1d(u32_of(per_chunk, "layer")?, max_dim),
                forward: tile_grid(blocks(layer.output), row_blocks, max_dim),
                inputs: tile_grid(blocks(layer.input), row_blocks, max_dim),
                partials: [blocks(layer.output), blocks(layer.input + 1), chunks],
                inputs_flat: groups_1d(inputs, max_dim),
                partials_flat: groups_1d(partials, max_dim),
            };
            if [g.forward, g.inputs, g.partials]
                .iter()
                .flatten()
                .any(|&n| n > max_dim)
            {
                return Err(too_large("workgroup grid"));
            }
            // Where the gradient of the layer's first input goes: the network input's gradient
            // is written by the skip layer (the backward runs from the last layer) and added to
            // by layer 0, or written by layer 0 alone; not made at all unless asked for.
            let mode_a = match (l, layer.skip_input) {
                (_, true) | (0, _) if !want_input => MODE_SKIP,
                (0, _) if skip => MODE_ADD,
                _ => MODE_WRITE,
            };
            let params = LayerParams {
                rows: rows32,
                width_a: width_a as u32,
                width_b: width_b as u32,
                outputs: layer.output as u32,
                weight_offset: u32_of(layer.weight_offset, "parameters")?,
                activation: activation_code(net.activations[l]),
                mode_a,
                chunk_rows: CHUNK_ROWS,
                chunks,
                stride_outputs: 256 * g.outputs.0,
                stride_inputs: 256 * g.inputs_flat.0,
                stride_partials: 256 * g.partials_flat.0,
                stride_reduce: 256 * g.reduce.0,
                ..LayerParams::default()
            };
            uniforms.push(uniform(ctx, "mlp layer", bytemuck::bytes_of(&params)));
            groups.push(g);
        }
        Ok(Self {
            rows: rows32,
            chunks,
            want_input,
            acts,
            grads: [
                storage(ctx, "mlp gradient", values(widest, "gradients")?)?,
                storage(ctx, "mlp gradient", values(widest, "gradients")?)?,
            ],
            d_input: storage(ctx, "mlp input gradient", values(net.input, "inputs")?)?,
            d_params: storage(ctx, "mlp parameter gradient", 4 * net.param_count as u64)?,
            partials: storage(
                ctx,
                "mlp partial sums",
                4 * widest_layer * u64::from(chunks),
            )?,
            unused: [storage(ctx, "unused", 4)?, storage(ctx, "unused", 4)?],
            uniforms,
            groups,
        })
    }

    /// The row count these buffers are for.
    pub fn rows(&self) -> usize {
        self.rows as usize
    }

    /// Whether the backward passes make the input's gradient.
    pub fn want_input(&self) -> bool {
        self.want_input
    }

    /// Chunks of the weight gradient's first sum.
    pub fn chunks(&self) -> u32 {
        self.chunks
    }
}

/// Which form of the three products [`GpuMlp`] runs: both give the same terms in the same
/// order (the same values, up to a driver's fused multiply-adds); which is faster depends on the
/// device.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MlpKernels {
    /// 16 × 16 blocks through workgroup memory (the default).
    #[default]
    Tiled,
    /// One invocation per value, operands from global memory.
    Plain,
}

/// One form of the three products.
#[derive(Debug)]
struct Products {
    forward: wgpu::ComputePipeline,
    input_grad: wgpu::ComputePipeline,
    weight_partials: wgpu::ComputePipeline,
}

/// The MLP's kernels, compiled once per device.
#[derive(Debug)]
pub struct GpuMlp {
    /// The form of the products recorded from now on ([`MlpKernels::Tiled`] unless set).
    pub kernels: MlpKernels,
    tiled: Products,
    plain: Products,
    delta: wgpu::ComputePipeline,
    weight_reduce: wgpu::ComputePipeline,
}

impl GpuMlp {
    /// Compiles the kernels (both forms of the products) on `ctx`'s device.
    pub fn new(ctx: &GpuContext) -> Result<Self, GpuError> {
        let device = &ctx.device;
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("mlp"),
            source: wgpu::ShaderSource::Wgsl(MLP_WGSL.into()),
        });
        let pipeline = |entry: &str| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: None,
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        let mlp = Self {
            kernels: MlpKernels::default(),
            tiled: Products {
                forward: pipeline("forward"),
                input_grad: pipeline("input_grad"),
                weight_partials: pipeline("weight_partials"),
            },
            plain: Products {
                forward: pipeline("forward_plain"),
                input_grad: pipeline("input_grad_plain"),
                weight_partials: pipeline("weight_partials_plain"),
            },
            delta: pipeline("delta"),
            weight_reduce: pipeline("weight_reduce"),
        };
        if let Some(err) = pollster::block_on(scope.pop()) {
            return Err(GpuError::new("pipelines", err.to_string()));
        }
        Ok(mlp)
    }

    /// Records one of the products: `which` picks the pipeline of the form in use, `tiled` and
    /// `plain` its grids.
    #[allow(clippy::too_many_arguments)]
    fn product(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        which: fn(&Products) -> &wgpu::ComputePipeline,
        entries: &[(u32, &wgpu::Buffer)],
        tiled: [u32; 3],
        plain: (u32, u32),
    ) {
        match self.kernels {
            MlpKernels::Tiled => {
                let pipeline = which(&self.tiled);
                let group = bind(ctx, pipeline, entries);
                dispatch_xyz(ctx, encoder, pipeline, &group, tiled);
            }
            MlpKernels::Plain => {
                let pipeline = which(&self.plain);
                let group = bind(ctx, pipeline, entries);
                dispatch(ctx, encoder, pipeline, &group, plain);
            }
        }
    }

    /// The two inputs of layer `l`: `(a, b)`, `b` the stand-in when the layer has one input.
    fn layer_inputs<'a>(
        net: &DeviceMlp,
        ws: &'a MlpWorkspace,
        input: &'a wgpu::Buffer,
        l: usize,
    ) -> (&'a wgpu::Buffer, &'a wgpu::Buffer) {
        if l == 0 {
            (input, &ws.unused[1])
        } else if net.layers[l].skip_input {
            (input, &ws.acts[l - 1])
        } else {
            (&ws.acts[l - 1], &ws.unused[1])
        }
    }

    /// Records the forward pass of `net` over `input` (rows × input, f32, on the device) into
    /// `ws.acts`.
    pub fn encode_forward(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        net: &DeviceMlp,
        ws: &MlpWorkspace,
        input: &wgpu::Buffer,
    ) {
        for l in 0..net.layers.len() {
            let (a, b) = Self::layer_inputs(net, ws, input, l);
            let g = ws.groups[l];
            self.product(
                ctx,
                encoder,
                |p| &p.forward,
                &[
                    (0, &ws.uniforms[l]),
                    (1, &net.params),
                    (2, a),
                    (3, b),
                    (4, &ws.acts[l]),
                ],
                g.forward,
                g.outputs,
            );
        }
    }

    /// Records the backward pass after [`encode_forward`](Self::encode_forward) on the same
    /// `input`: `d_out` (rows × output) is `∂L/∂y`; writes `ws.d_params` and, when the
    /// workspace [wants it](MlpWorkspace::want_input), `ws.d_input`. `d_out` is left as it was.
    pub fn encode_backward(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        net: &DeviceMlp,
        ws: &MlpWorkspace,
        input: &wgpu::Buffer,
        d_out: &wgpu::Buffer,
    ) {
        let last = net.layers.len() - 1;
        let out_bytes = 4 * u64::from(ws.rows) * net.output as u64;
        if out_bytes > 0 {
            encoder.copy_buffer_to_buffer(d_out, 0, &ws.grads[last % 2], 0, out_bytes);
        }
        for l in (0..=last).rev() {
            let u = &ws.uniforms[l];
            let dy = &ws.grads[l % 2];
            let g = ws.groups[l];
            let delta = bind(ctx, &self.delta, &[(0, u), (4, &ws.acts[l]), (5, dy)]);
            dispatch(ctx, encoder, &self.delta, &delta, g.outputs);
            let (a, b) = Self::layer_inputs(net, ws, input, l);
            self.product(
                ctx,
                encoder,
                |p| &p.weight_partials,
                &[(0, u), (2, a), (3, b), (5, dy), (8, &ws.partials)],
                g.partials,
                g.partials_flat,
            );
            let reduce = bind(
                ctx,
                &self.weight_reduce,
                &[(0, u), (8, &ws.partials), (9, &ws.d_params)],
            );
            dispatch(ctx, encoder, &self.weight_reduce, &reduce, g.reduce);
            if l == 0 && !ws.want_input {
                continue;
            }
            // Where the gradient of the layer's inputs goes (the uniform's `mode_a` says
            // whether the first is written, added to or dropped).
            let next = &ws.grads[(l + 1) % 2];
            let (d_a, d_b) = if l == 0 {
                (&ws.d_input, &ws.unused[1])
            } else if net.layers[l].skip_input {
                let d_a = if ws.want_input {
                    &ws.d_input
                } else {
                    &ws.unused[0]
                };
                (d_a, next)
            } else {
                (next, &ws.unused[1])
            };
            self.product(
                ctx,
                encoder,
                |p| &p.input_grad,
                &[(0, u), (1, &net.params), (5, dy), (6, d_a), (7, d_b)],
                g.inputs,
                g.inputs_flat,
            );
        }
    }

    /// Forward and backward of `mlp` (f32 storage) over `rows` rows of `x` on the device, with
    /// `d_out` as `∂L/∂y`: uploads, runs [`encode_forward`](Self::encode_forward) and
    /// [`encode_backward`](Self::encode_backward), and reads back the outputs and the gradients
    /// (the input's when `want_input`), as [`Mlp::forward`] and [`Mlp::backward`] give them.
    pub fn forward_backward(
        &self,
        ctx: &GpuContext,
        mlp: &Mlp,
        x: &[f32],
        rows: usize,
        d_out: &[f32],
        want_input: bool,
    ) -> Result<(Vec<f32>, MlpGrads), GpuError> {
        let (ni, no) = (mlp.input_width(), mlp.output_width());
        if Some(x.len()) != rows.checked_mul(ni) || Some(d_out.len()) != rows.checked_mul(no) {
            return Err(GpuError::new(
                "buffers",
                format!(
                    "MLP of {ni} inputs and {no} outputs over {rows} rows: {} inputs and {} \
                     output gradients given",
                    x.len(),
                    d_out.len()
                ),
            ));
        }
        let net = DeviceMlp::upload(ctx, mlp)?;
        let ws = MlpWorkspace::new(ctx, &net, rows, want_input)?;
        let input = storage_init(ctx, "mlp input", bytemuck::cast_slice(x))?;
        let d_y = storage_init(ctx, "mlp output gradient", bytemuck::cast_slice(d_out))?;
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        self.encode_forward(ctx, &mut encoder, &net, &ws, &input);
        self.encode_backward(ctx, &mut encoder, &net, &ws, &input, &d_y);
        let bytes = |n: usize| 4 * n as u64;
        let mut regions = vec![
            (ws.acts.last().unwrap_or(&ws.d_input), 0, bytes(rows * no)),
            (&ws.d_params, 0, bytes(net.param_count)),
        ];
        if want_input {
            regions.push((&ws.d_input, 0, bytes(rows * ni)));
        }
        let back = read_back(ctx, encoder, &regions)?;
        let f32s = |b: &[u8]| bytemuck::pod_collect_to_vec::<u8, f32>(b);
        Ok((
            f32s(&back[0]),
            MlpGrads {
                params: f32s(&back[1]),
                input: want_input.then(|| f32s(&back[2])),
            },
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gpu_core::wgsl_text::check_mirror;

    #[test]
    fn the_uniform_matches_its_wgsl_struct() {
        check_mirror(
            LayerParams::FIELDS,
            size_of::<LayerParams>(),
            MLP_WGSL,
            "Params",
        );
    }
}
