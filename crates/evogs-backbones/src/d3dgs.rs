//! The D-3DGS backbone (`--backbone d3dgs`, the default): Deformable-3D-Gaussians' deformation
//! MLP ([`D3dgsBackbone`]) and its shape ([`NetSettings`], [`NetInit`]).
//!
//! Its rows are the network's three heads, position, rotation and scale
//! ([`splat_core::Layout::GEOMETRY`]), handed to the trainer as the network writes them.

use std::path::Path;

use serde::{Deserialize, Serialize};
use splat_core::GaussiansView;
use tiny_nn::{DeformCache, DeformConfig, DeformNet, Parameters, Precision, StoreMut, StoreRef};

use crate::backbone::{Backbone, fill_inputs, no_training_forward};
use crate::error::BackboneError;

/// How the deformation network's parameters start.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum NetInit {
    /// D-3DGS: PyTorch's default on every layer, heads included.
    #[default]
    Torch,
    /// He hidden layers (zero bias) and zero heads: the deformation starts at exactly zero and
    /// depends on its input through all 8 layers from the first step (see [`tiny_nn::Init`]).
    He,
}

/// The D-3DGS deformation network's shape.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct NetSettings {
    /// Hidden width (D-3DGS: 256).
    pub width: usize,
    /// Hidden layers (8).
    pub depth: usize,
    /// Skip connection after this hidden layer (4).
    pub skip_after: Option<usize>,
    /// Frequencies of the position encoding (10).
    pub xyz_freqs: usize,
    /// Frequencies of the time encoding (6 for synthetic scenes).
    pub t_freqs: usize,
    /// Initialisation (runs written before it existed read as D-3DGS's).
    #[serde(default)]
    pub init: NetInit,
}

/// D-3DGS's deformation network (`utils/time_utils.py` `DeformNetwork`: sinusoidal encodings of
/// xyz (10 frequencies) and t (6 for synthetic scenes), 8 ReLU layers with the input re-joined
/// after layer 4, linear heads for position, rotation and scale), as `tiny_nn::DeformNet`.
pub struct D3dgsBackbone {
    net: DeformNet,
    cache: Option<DeformCache>,
    positions: Vec<f32>,
    times: Vec<f32>,
    /// The network's device form after [`Backbone::use_device`]: forward, backward and the
    /// optimiser's steps run there, and from the first step its parameters and moments live
    /// there ([`Backbone::sync_to_host`] copies them here).
    #[cfg(feature = "wgpu")]
    device: Option<tiny_nn::gpu::DeformRunner>,
}

impl D3dgsBackbone {
    /// The network of the given shape, initialised from `seed`.
    pub fn new(settings: &NetSettings, seed: u64) -> Result<Self, BackboneError> {
        let net = DeformNet::new(Self::config(settings, seed))?;
        Ok(Self {
            net,
            cache: None,
            positions: Vec::new(),
            times: Vec::new(),
            #[cfg(feature = "wgpu")]
            device: None,
        })
    }
}

impl D3dgsBackbone {
    /// The network [`D3dgsBackbone::new`] builds.
    pub(crate) fn config(settings: &NetSettings, seed: u64) -> DeformConfig {
        DeformConfig {
            width: settings.width,
            depth: settings.depth,
            skip_after: settings.skip_after,
            xyz_freqs: settings.xyz_freqs,
            t_freqs: settings.t_freqs,
            init: match settings.init {
                NetInit::Torch => tiny_nn::Init::Torch,
                NetInit::He => tiny_nn::Init::He,
            },
            zero_heads: settings.init == NetInit::He,
            precision: Precision::F32,
            seed,
        }
    }
}

impl D3dgsBackbone {
    /// The backward on the device form, when the network runs there (its gradient stays
    /// there); `false` on the CPU.
    fn device_backward(&mut self, d_deform: &[f32]) -> Result<bool, BackboneError> {
        #[cfg(feature = "wgpu")]
        if let Some(device) = &mut self.device {
            device.backward_on_device(d_deform)?;
            return Ok(true);
        }
        let _ = d_deform;
        Ok(false)
    }

    /// The host's parameters become the current ones (they are about to change here): the
    /// device form, if any, writes them at its next forward and uploads the moments at its next
    /// step.
    fn host_is_current(&mut self) {
        #[cfg(feature = "wgpu")]
        if let Some(device) = &mut self.device {
            device.forget();
        }
    }
}

impl Backbone for D3dgsBackbone {
    fn name(&self) -> &'static str {
        "d3dgs"
    }

    fn forward_into(
        &mut self,
        canonical: GaussiansView<'_>,
        time: f32,
        training: bool,
        out: &mut Vec<f32>,
    ) -> Result<(), BackboneError> {
        let n = canonical.len();
        fill_inputs(canonical, time, &mut self.positions, &mut self.times);
        #[cfg(feature = "wgpu")]
        if let Some(device) = &mut self.device {
            device.forward_into(&self.net, &self.positions, &self.times, n, training, out)?;
            return Ok(());
        }
        let mut cache = self.cache.take().unwrap_or_default();
        let geometry = self
            .net
            .forward_into(&self.positions, &self.times, n, &mut cache)?;
        if training {
            self.cache = Some(cache);
        }
        // The network's heads are the rows: position, rotation, scale (`Layout::GEOMETRY`).
        *out = geometry;
        Ok(())
    }

    fn backward_into(
        &mut self,
        d_deform: &[f32],
        out: &mut Vec<Vec<f32>>,
    ) -> Result<(), BackboneError> {
        if self.device_backward(d_deform)? {
            out.clear();
            return Ok(());
        }
        let cache = self.cache.as_ref().ok_or_else(no_training_forward)?;
        let grads = self.net.backward(cache, d_deform, false)?.mlp;
        out.truncate(1);
        match out.first_mut() {
            Some(g) => *g = grads,
            None => out.push(grads),
        }
        Ok(())
    }

    #[cfg(feature = "wgpu")]
    fn use_device(
        &mut self,
        ctx: &std::sync::Arc<gpu_core::GpuContext>,
    ) -> Result<bool, BackboneError> {
        self.device = Some(tiny_nn::gpu::DeformRunner::new(std::sync::Arc::clone(ctx))?);
        self.cache = None;
        Ok(true)
    }

    fn step_on_device(
        &mut self,
        updates: &[tiny_nn::AdamUpdate],
        moments: &[&tiny_nn::AdamGroup],
    ) -> Result<(), BackboneError> {
        #[cfg(feature = "wgpu")]
        if let Some(device) = &mut self.device {
            let ([update], [group]) = (updates, moments) else {
                return Err(BackboneError::config(
                    "backbone",
                    format!(
                        "one parameter buffer; {} updates and {} moment groups",
                        updates.len(),
                        moments.len()
                    ),
                ));
            };
            device.step(update, group)?;
            return Ok(());
        }
        let _ = (updates, moments);
        Err(BackboneError::config(
            "net_backend",
            "the d3dgs backbone's network runs on the host",
        ))
    }

    fn sync_to_host(
        &mut self,
        moments: &mut [&mut tiny_nn::AdamGroup],
    ) -> Result<(), BackboneError> {
        #[cfg(feature = "wgpu")]
        if let Some(device) = &self.device {
            let [group] = moments else {
                return Err(BackboneError::config(
                    "backbone",
                    format!("one parameter buffer; {} moment groups", moments.len()),
                ));
            };
            device.read_to_host(&mut self.net, group)?;
        }
        let _ = moments;
        Ok(())
    }

    fn params(&self) -> Vec<(String, StoreRef<'_>)> {
        self.net.named_params()
    }

    /// The host's parameters, which become the current ones: on a device, what it held and
    /// [`Backbone::sync_to_host`] did not copy here is dropped.
    fn params_mut(&mut self) -> Vec<(String, StoreMut<'_>)> {
        self.host_is_current();
        self.net.named_params_mut()
    }

    fn save(&self, path: &Path) -> Result<(), BackboneError> {
        Ok(tiny_nn::weights::save(path, &self.net)?)
    }

    fn load(&mut self, path: &Path) -> Result<(), BackboneError> {
        self.host_is_current();
        Ok(tiny_nn::weights::load(path, &mut self.net)?)
    }
}
