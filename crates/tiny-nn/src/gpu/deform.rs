//! D-3DGS's deformation network on the device: [`GpuDeformNet`], the twin of [`DeformNet`]'s
//! forward and backward (the sinusoidal encoding of position and time in `deform.wgsl`, then
//! [`GpuMlp`](super::GpuMlp)), with the gradient to the positions.
//!
//! [`DeformWorkspace`] holds one row count's buffers: the encoded rows (rows × 76 for D-3DGS),
//! the MLP's workspace and the positions' gradient. [`GpuDeformNet::encode_forward`] and
//! [`GpuDeformNet::encode_backward`] record on device buffers; [`GpuDeformNet::forward_backward`]
//! uploads, runs both and reads back, for tests and callers not resident yet.
//!
//! Precision: the encoding's sines and cosines take arguments reduced to [−π, π] first (WGSL
//! bounds their accuracy there only); positions up to ±800 reduce exactly (`deform.wgsl`
//! says how). The tests measure the rest against the CPU.

use std::sync::Arc;

use gpu_core::buffers::{read_back, storage, storage_init, uniform, write};
use gpu_core::encode::{bind, dispatch, groups_1d, submit};
use gpu_core::{GpuContext, GpuError, wgsl_mirror};

use super::adam::{AdamBuffers, AdamLayout, GpuAdam};
use super::mlp::{DeviceMlp, GpuMlp, MlpWorkspace};
use crate::adam::{AdamGroup, AdamUpdate};
use crate::error::{NnError, check_len};
use crate::nets::{DeformGrads, DeformNet};
use crate::precision::StoreMut;

pub(crate) const DEFORM_WGSL: &str = include_str!("deform.wgsl");

wgsl_mirror! {
    /// Mirror of `Params` in `deform.wgsl` (a test checks names, types, offsets and size).
    #[repr(C)]
    #[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
    pub(crate) struct EncodeParams {
        pub rows: u32,
        pub xyz_freqs: u32,
        pub t_freqs: u32,
        pub width: u32,
        pub row_stride: u32,
        pub pad0: u32,
        pub pad1: u32,
        pub pad2: u32,
    }
}

/// A [`DeformNet`] on the device: its encodings' frequencies and its MLP.
#[derive(Debug)]
pub struct DeviceDeformNet {
    xyz_freqs: u32,
    t_freqs: u32,
    /// The MLP, parameters on the device.
    pub mlp: DeviceMlp,
}

impl DeviceDeformNet {
    /// Uploads `net` (its MLP stored in f32).
    pub fn upload(ctx: &GpuContext, net: &DeformNet) -> Result<Self, GpuError> {
        let (xyz, t) = net.encodings();
        if xyz.input_width() != 3 || t.input_width() != 1 {
            return Err(GpuError::new(
                "buffers",
                "the GPU deformation network encodes xyz and t only",
            ));
        }
        Ok(Self {
            xyz_freqs: xyz.freqs() as u32,
            t_freqs: t.freqs() as u32,
            mlp: DeviceMlp::upload(ctx, &net.mlp)?,
        })
    }

    /// Width of an encoded row, `3 (1 + 2 L_xyz) + 1 + 2 L_t`.
    pub fn encoded_width(&self) -> u32 {
        3 * (1 + 2 * self.xyz_freqs) + 1 + 2 * self.t_freqs
    }
}

/// The device buffers of one row count of a [`DeviceDeformNet`].
#[derive(Debug)]
pub struct DeformWorkspace {
    rows: u32,
    want_positions: bool,
    encoded: wgpu::Buffer,
    /// The MLP's buffers; its last activation is the network's output (rows × outputs).
    pub mlp: MlpWorkspace,
    /// `∂L/∂positions` (rows × 3), written by a backward that asks for it.
    pub d_positions: wgpu::Buffer,
    params: wgpu::Buffer,
    encode_groups: (u32, u32),
    grad_params: wgpu::Buffer,
    grad_groups: (u32, u32),
}

impl DeformWorkspace {
    /// Buffers for `rows` rows of `net`, for backward passes that make the positions' gradient
    /// when `want_positions`.
    pub fn new(
        ctx: &GpuContext,
        net: &DeviceDeformNet,
        rows: usize,
        want_positions: bool,
    ) -> Result<Self, GpuError> {
        let too_large = || GpuError::new("buffers", format!("{rows} rows: too many values"));
        let rows32 = u32::try_from(rows).map_err(|_| too_large())?;
        let width = net.encoded_width();
        let values = rows32.checked_mul(width).ok_or_else(too_large)?;
        let coords = rows32.checked_mul(3).ok_or_else(too_large)?;
        let max_dim = ctx.device.limits().max_compute_workgroups_per_dimension;
        let (encode_groups, grad_groups) = (groups_1d(values, max_dim), groups_1d(coords, max_dim));
        let params = |groups: (u32, u32)| EncodeParams {
            rows: rows32,
            xyz_freqs: net.xyz_freqs,
            t_freqs: net.t_freqs,
            width,
            row_stride: 256 * groups.0,
            ..EncodeParams::default()
        };
        Ok(Self {
            rows: rows32,
            want_positions,
            encoded: storage(ctx, "deform encoded", 4 * u64::from(values))?,
            mlp: MlpWorkspace::new(ctx, &net.mlp, rows, want_positions)?,
            d_positions: storage(ctx, "deform position gradient", 4 * u64::from(coords))?,
            params: uniform(
                ctx,
                "deform encode",
                bytemuck::bytes_of(&params(encode_groups)),
            ),
            encode_groups,
            grad_params: uniform(
                ctx,
                "deform position gradient",
                bytemuck::bytes_of(&params(grad_groups)),
            ),
            grad_groups,
        })
    }

    /// The row count these buffers are for.
    pub fn rows(&self) -> usize {
        self.rows as usize
    }
}

/// The encoding's kernels and the MLP's, compiled once per device.
#[derive(Debug)]
pub struct GpuDeformNet {
    encode: wgpu::ComputePipeline,
    position_grad: wgpu::ComputePipeline,
    /// The MLP's kernels.
    pub mlp: GpuMlp,
}

impl GpuDeformNet {
    /// Compiles the kernels on `ctx`'s device.
    pub fn new(ctx: &GpuContext) -> Result<Self, GpuError> {
        let device = &ctx.device;
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("deform encoding"),
            source: wgpu::ShaderSource::Wgsl(DEFORM_WGSL.into()),
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
        let (encode, position_grad) = (pipeline("encode"), pipeline("position_grad"));
        if let Some(err) = pollster::block_on(scope.pop()) {
            return Err(GpuError::new("pipelines", err.to_string()));
        }
        Ok(Self {
            encode,
            position_grad,
            mlp: GpuMlp::new(ctx)?,
        })
    }

    /// Records the forward pass at `positions` (rows × 3) and `times` (rows), on the device:
    /// the output is `ws.mlp.acts`'s last buffer (rows × outputs).
    pub fn encode_forward(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        net: &DeviceDeformNet,
        ws: &DeformWorkspace,
        positions: &wgpu::Buffer,
        times: &wgpu::Buffer,
    ) {
        let group = bind(
            ctx,
            &self.encode,
            &[
                (0, &ws.params),
                (1, positions),
                (2, times),
                (3, &ws.encoded),
            ],
        );
        dispatch(ctx, encoder, &self.encode, &group, ws.encode_groups);
        self.mlp
            .encode_forward(ctx, encoder, &net.mlp, &ws.mlp, &ws.encoded);
    }

    /// Records the backward pass after [`encode_forward`](Self::encode_forward) at the same
    /// `positions`: `d_out` (rows × outputs) is `∂L/∂output`; writes the MLP's parameter
    /// gradient (`ws.mlp.d_params`) and, when the workspace was made for it, `ws.d_positions`.
    pub fn encode_backward(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        net: &DeviceDeformNet,
        ws: &DeformWorkspace,
        positions: &wgpu::Buffer,
        d_out: &wgpu::Buffer,
    ) {
        self.mlp
            .encode_backward(ctx, encoder, &net.mlp, &ws.mlp, &ws.encoded, d_out);
        if !ws.want_positions {
            return;
        }
        let group = bind(
            ctx,
            &self.position_grad,
            &[
                (0, &ws.grad_params),
                (1, positions),
                (4, &ws.mlp.d_input),
                (5, &ws.d_positions),
            ],
        );
        dispatch(ctx, encoder, &self.position_grad, &group, ws.grad_groups);
    }

    /// Forward and backward of `net` over `rows` rows on the device, as [`DeformNet::forward`]
    /// and [`DeformNet::backward`] give them: uploads, runs, reads back.
    #[allow(clippy::too_many_arguments)]
    pub fn forward_backward(
        &self,
        ctx: &GpuContext,
        net: &DeformNet,
        positions: &[f32],
        times: &[f32],
        rows: usize,
        d_out: &[f32],
        want_positions: bool,
    ) -> Result<(Vec<f32>, DeformGrads), GpuError> {
        let outputs = net.mlp.output_width();
        if Some(positions.len()) != rows.checked_mul(3)
            || times.len() != rows
            || Some(d_out.len()) != rows.checked_mul(outputs)
        {
            return Err(GpuError::new(
                "buffers",
                format!(
                    "deformation network over {rows} rows: {} position values, {} times and {} \
                     output gradients given",
                    positions.len(),
                    times.len(),
                    d_out.len()
                ),
            ));
        }
        let device_net = DeviceDeformNet::upload(ctx, net)?;
        let ws = DeformWorkspace::new(ctx, &device_net, rows, want_positions)?;
        let p = storage_init(ctx, "positions", bytemuck::cast_slice(positions))?;
        let t = storage_init(ctx, "times", bytemuck::cast_slice(times))?;
        let dy = storage_init(ctx, "deform output gradient", bytemuck::cast_slice(d_out))?;
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        self.encode_forward(ctx, &mut encoder, &device_net, &ws, &p, &t);
        self.encode_backward(ctx, &mut encoder, &device_net, &ws, &p, &dy);
        let bytes = |n: usize| 4 * n as u64;
        let out = ws.mlp.acts.last().unwrap_or(&ws.d_positions);
        let mut regions = vec![
            (out, 0, bytes(rows * outputs)),
            (&ws.mlp.d_params, 0, bytes(device_net.mlp.param_count())),
        ];
        if want_positions {
            regions.push((&ws.d_positions, 0, bytes(rows * 3)));
        }
        let back = read_back(ctx, encoder, &regions)?;
        let f32s = |b: &[u8]| bytemuck::pod_collect_to_vec::<u8, f32>(b);
        Ok((
            f32s(&back[0]),
            DeformGrads {
                mlp: f32s(&back[1]),
                positions: want_positions.then(|| f32s(&back[2])),
            },
        ))
    }
}

/// The device buffers of one row count, with the inputs a [`DeformRunner`] writes.
#[derive(Debug)]
struct RunnerRows {
    ws: DeformWorkspace,
    positions: wgpu::Buffer,
    times: wgpu::Buffer,
    d_out: wgpu::Buffer,
}

/// Checks that `moments` holds one m and one v per parameter of a network of `params`.
fn check_moments(moments: &AdamGroup, params: usize) -> Result<(), NnError> {
    for (which, len) in [("m", moments.m.len()), ("v", moments.v.len())] {
        check_len(
            &format!("Adam group `{}` {which}", moments.name),
            params,
            len,
        )?;
    }
    Ok(())
}

/// The Adam moments of a [`DeformRunner`]'s parameters on the device, once it steps them there.
#[derive(Debug)]
struct DeviceMoments {
    m: wgpu::Buffer,
    v: wgpu::Buffer,
    /// The gradient of a backward over no rows (zeros), made when first needed.
    zeros: Option<wgpu::Buffer>,
}

/// A [`DeformNet`]'s forward and backward on the device for a caller whose inputs and outputs
/// live on the host (the trainer's D-3DGS backbone): the twin of [`DeformNet::forward_into`]
/// and [`DeformNet::backward`] without the positions' gradient, with the same input checks and
/// errors.
///
/// The device keeps the network's shape, the workspace of the last row count (made again when
/// the count changes, e.g. after densification) and, after a training forward, the activations
/// the backward needs. Each forward writes the positions and times and reads the rows back.
///
/// Two ways to train, one per caller:
/// - **The host's optimiser** ([`DeformRunner::backward`]): each forward writes the network's
///   current parameters (the host's optimiser changed them), each backward writes `∂L/∂output`
///   and reads the parameters' gradient back.
/// - **Resident** ([`DeformRunner::backward_on_device`], then [`DeformRunner::step`]): the
///   gradient stays on the device and Adam updates the parameters there, with moments that
///   live there from the first step on (uploaded from the host's group then). From that step
///   the device's parameters are the current ones: forwards write none, and
///   [`DeformRunner::read_to_host`] copies parameters and moments back when the host needs
///   them (a checkpoint, a check for non-finite values). [`DeformRunner::forget`] hands the
///   truth back to the host (it changed the parameters or the moments itself).
///
/// What each call moves is counted on the context ([`GpuContext::traffic`]).
#[derive(Debug)]
pub struct DeformRunner {
    ctx: Arc<GpuContext>,
    kernels: GpuDeformNet,
    net: Option<DeviceDeformNet>,
    rows: Option<RunnerRows>,
    /// Rows of the last forward when it was a training one (its activations are on the device).
    trained: Option<usize>,
    /// Rows of the last [`DeformRunner::backward_on_device`] since that training forward: its
    /// gradient is on the device for [`DeformRunner::step`].
    grad_rows: Option<usize>,
    /// Adam's kernel, compiled at the first [`DeformRunner::step`].
    adam: Option<GpuAdam>,
    /// The moments, present once the parameters are stepped on the device (then the device's
    /// parameters are the current ones).
    moments: Option<DeviceMoments>,
}

impl DeformRunner {
    /// Compiles the kernels on `ctx`'s device.
    pub fn new(ctx: Arc<GpuContext>) -> Result<Self, NnError> {
        let kernels = GpuDeformNet::new(&ctx)?;
        Ok(Self {
            ctx,
            kernels,
            net: None,
            rows: None,
            trained: None,
            grad_rows: None,
            adam: None,
            moments: None,
        })
    }

    /// Whether the parameters are stepped on the device, so that the device's are the current
    /// ones (after the first [`DeformRunner::step`], until [`DeformRunner::forget`]).
    pub fn resident(&self) -> bool {
        self.moments.is_some()
    }

    /// Hands the parameters back to the host: the next forward writes `net`'s parameters, the
    /// next [`DeformRunner::step`] uploads the host's moments. For a caller that changed either
    /// on the host (a loaded checkpoint or weight file); what the device held and was not read
    /// back ([`DeformRunner::read_to_host`]) is dropped.
    pub fn forget(&mut self) {
        self.moments = None;
        self.net = None;
        self.rows = None;
        self.trained = None;
        self.grad_rows = None;
    }

    /// The device context it runs on.
    pub fn context(&self) -> &Arc<GpuContext> {
        &self.ctx
    }

    /// [`DeformNet::forward_into`] of `net` on the device: `rows` positions (rows × 3) and
    /// times (rows) to the output rows (rows × outputs) in `out`, whatever it held. `training`
    /// keeps the activations for [`DeformRunner::backward`]; any other forward drops them.
    pub fn forward_into(
        &mut self,
        net: &DeformNet,
        positions: &[f32],
        times: &[f32],
        rows: usize,
        training: bool,
        out: &mut Vec<f32>,
    ) -> Result<(), NnError> {
        self.trained = None;
        self.grad_rows = None;
        DeformNet::check_inputs(positions, times, rows)?;
        let ctx = Arc::clone(&self.ctx);
        let (xyz, t) = net.encodings();
        let fits = self.net.as_ref().is_some_and(|d| {
            d.mlp.same_shape(&net.mlp)
                && d.xyz_freqs as usize == xyz.freqs()
                && d.t_freqs as usize == t.freqs()
        });
        if fits {
            // Resident, the device's parameters are the current ones.
            if let Some(device_net) = self.net.as_ref().filter(|_| self.moments.is_none()) {
                device_net.mlp.write_params(&ctx, &net.mlp)?;
            }
        } else if self.moments.is_some() {
            return Err(NnError::Config(
                "the network changed shape while its parameters are stepped on the device \
                 (forget them first)"
                    .to_string(),
            ));
        } else {
            self.rows = None;
            self.net = Some(DeviceDeformNet::upload(&ctx, net)?);
        }
        let Some(device_net) = &self.net else {
            unreachable!("the network was uploaded above");
        };
        out.clear();
        if rows == 0 {
            self.trained = training.then_some(0);
            return Ok(());
        }
        if self.rows.as_ref().is_none_or(|r| r.ws.rows() != rows) {
            self.rows = None;
            let outputs = device_net.mlp.output_width();
            let bytes = |n: usize| 4 * n as u64;
            self.rows = Some(RunnerRows {
                ws: DeformWorkspace::new(&ctx, device_net, rows, false)?,
                positions: storage(&ctx, "runner positions", bytes(rows * 3))?,
                times: storage(&ctx, "runner times", bytes(rows))?,
                d_out: storage(&ctx, "runner output gradient", bytes(rows * outputs))?,
            });
        }
        let Some(buffers) = &self.rows else {
            unreachable!("the workspace was made above");
        };
        write(&ctx, &buffers.positions, 0, bytemuck::cast_slice(positions))?;
        write(&ctx, &buffers.times, 0, bytemuck::cast_slice(times))?;
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        self.kernels.encode_forward(
            &ctx,
            &mut encoder,
            device_net,
            &buffers.ws,
            &buffers.positions,
            &buffers.times,
        );
        let output = buffers.ws.mlp.acts.last().unwrap_or(&buffers.d_out);
        let bytes = 4 * (rows * device_net.mlp.output_width()) as u64;
        let back = read_back(&ctx, encoder, &[(output, 0, bytes)])?;
        out.extend_from_slice(bytemuck::cast_slice::<u8, f32>(&back[0]));
        self.trained = training.then_some(rows);
        Ok(())
    }

    /// [`DeformNet::backward`] (without the positions' gradient) after a training
    /// [`DeformRunner::forward_into`]: `d_out` (rows × outputs) is `∂L/∂output`; returns the
    /// MLP's parameter gradient in [`Mlp::params`](crate::Mlp::params)'s layout.
    pub fn backward(&mut self, d_out: &[f32]) -> Result<Vec<f32>, NnError> {
        if self.moments.is_some() {
            return Err(NnError::Config(
                "the parameters are stepped on the device: their gradient stays there \
                 (backward_on_device)"
                    .to_string(),
            ));
        }
        let params = self.checked_backward(d_out)?;
        let Some(encoder) = self.encode_backward(d_out)? else {
            return Ok(vec![0.0; params]);
        };
        let Some(buffers) = &self.rows else {
            unreachable!("a backward over rows has their buffers");
        };
        let back = read_back(
            &self.ctx,
            encoder,
            &[(&buffers.ws.mlp.d_params, 0, 4 * params as u64)],
        )?;
        Ok(bytemuck::pod_collect_to_vec(&back[0]))
    }

    /// [`DeformRunner::backward`] whose gradient stays on the device, for the
    /// [`DeformRunner::step`] that follows: writes `∂L/∂output` and submits, without a wait or
    /// a read-back.
    pub fn backward_on_device(&mut self, d_out: &[f32]) -> Result<(), NnError> {
        self.checked_backward(d_out)?;
        if let Some(encoder) = self.encode_backward(d_out)? {
            submit(&self.ctx, encoder);
        }
        self.grad_rows = self.trained;
        Ok(())
    }

    /// Checks a backward's `d_out` against the last training forward; the parameter count.
    fn checked_backward(&self, d_out: &[f32]) -> Result<usize, NnError> {
        let (Some(rows), Some(device_net)) = (self.trained, &self.net) else {
            return Err(NnError::Config(
                "deformation backward without a training forward".to_string(),
            ));
        };
        let outputs = device_net.mlp.output_width();
        check_len("deformation output gradient", rows * outputs, d_out.len())?;
        Ok(device_net.mlp.param_count())
    }

    /// Writes `d_out` and records the backward (after [`DeformRunner::checked_backward`]);
    /// `None` for a forward over no rows (the gradient is zero).
    fn encode_backward(&self, d_out: &[f32]) -> Result<Option<wgpu::CommandEncoder>, NnError> {
        let (Some(rows), Some(device_net)) = (self.trained, &self.net) else {
            return Err(NnError::Config(
                "deformation backward without a training forward".to_string(),
            ));
        };
        let Some(buffers) = self.rows.as_ref().filter(|_| rows > 0) else {
            return Ok(None);
        };
        let ctx = &self.ctx;
        write(ctx, &buffers.d_out, 0, bytemuck::cast_slice(d_out))?;
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        self.kernels.encode_backward(
            ctx,
            &mut encoder,
            device_net,
            &buffers.ws,
            &buffers.positions,
            &buffers.d_out,
        );
        Ok(Some(encoder))
    }

    /// One Adam update of the parameters on the device with the gradient of the last
    /// [`DeformRunner::backward_on_device`] and the constants `update` (from
    /// [`Adam::next_update`](crate::Adam::next_update) of the network's group, `moments`). The
    /// first step uploads that group's moments; later ones use the device's (the host's are then
    /// as of the last [`DeformRunner::read_to_host`]). Submits, without a wait: what it moves is
    /// the update's constants.
    pub fn step(&mut self, update: &AdamUpdate, moments: &AdamGroup) -> Result<(), NnError> {
        let (Some(rows), Some(device_net)) = (self.grad_rows.take(), &self.net) else {
            return Err(NnError::Config(
                "a device step without a backward on the device".to_string(),
            ));
        };
        let ctx = &self.ctx;
        let params = device_net.mlp.param_count();
        let count =
            u32::try_from(params).map_err(|_| NnError::Config(format!("{params} parameters")))?;
        if self.adam.is_none() {
            self.adam = Some(GpuAdam::new(ctx)?);
        }
        if self.moments.is_none() {
            check_moments(moments, params)?;
            self.moments = Some(DeviceMoments {
                m: storage_init(ctx, "deform adam m", bytemuck::cast_slice(&moments.m))?,
                v: storage_init(ctx, "deform adam v", bytemuck::cast_slice(&moments.v))?,
                zeros: None,
            });
        }
        let (Some(adam), Some(device_moments)) = (&self.adam, &mut self.moments) else {
            unreachable!("made above");
        };
        let grads = match self.rows.as_ref().filter(|_| rows > 0) {
            Some(buffers) => &buffers.ws.mlp.d_params,
            None => {
                if device_moments.zeros.is_none() {
                    device_moments.zeros =
                        Some(storage(ctx, "deform zero gradient", 4 * u64::from(count))?);
                }
                let Some(zeros) = &device_moments.zeros else {
                    unreachable!("made above");
                };
                zeros
            }
        };
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        let bufs = AdamBuffers {
            params: &device_net.mlp.params,
            grads,
            m: &device_moments.m,
            v: &device_moments.v,
        };
        adam.encode(ctx, &mut encoder, update, AdamLayout::plain(count), bufs)?;
        submit(ctx, encoder);
        Ok(())
    }

    /// Copies the device's parameters into `net` and its moments into `moments` (the network's
    /// Adam group) when they are stepped on the device ([`DeformRunner::resident`]); nothing
    /// otherwise (the host's are the current ones). One read-back and a wait.
    pub fn read_to_host(
        &self,
        net: &mut DeformNet,
        moments: &mut AdamGroup,
    ) -> Result<(), NnError> {
        let (Some(device_net), Some(device_moments)) = (&self.net, &self.moments) else {
            return Ok(());
        };
        let params = device_net.mlp.param_count();
        check_moments(moments, params)?;
        if !device_net.mlp.same_shape(&net.mlp) {
            return Err(NnError::Config(
                "the network's shape differs from the one on the device".to_string(),
            ));
        }
        let bytes = 4 * params as u64;
        let encoder = self.ctx.device.create_command_encoder(&Default::default());
        let back = read_back(
            &self.ctx,
            encoder,
            &[
                (&device_net.mlp.params, 0, bytes),
                (&device_moments.m, 0, bytes),
                (&device_moments.v, 0, bytes),
            ],
        )?;
        let StoreMut::F32(values) = net.mlp.params_mut() else {
            return Err(NnError::Config(
                "the GPU network stores f32 only; this network stores f16".to_string(),
            ));
        };
        // Collected rather than cast: the read-back's bytes carry no f32 alignment.
        let f32s = |b: &[u8]| bytemuck::pod_collect_to_vec::<u8, f32>(b);
        values.copy_from_slice(&f32s(&back[0]));
        moments.m = f32s(&back[1]);
        moments.v = f32s(&back[2]);
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
            EncodeParams::FIELDS,
            size_of::<EncodeParams>(),
            DEFORM_WGSL,
            "Params",
        );
    }
}
