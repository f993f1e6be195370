//! The deformation field of 4DGaussians: a HexPlane over `(x, y, z, t)`, a feature layer and
//! separate heads for position, rotation and scale.
//!
//! What it is (`hustvl/4DGaussians` `scene/deformation.py` `Deformation`, with its D-NeRF
//! settings `arguments/dnerf/dnerf_default.py`): the HexPlane's features `h0` (product of the six
//! planes per scale, scales concatenated, [`TriPlane`] with a [`TimeAxis`]) go through
//! `feature_out`, one linear layer `h = W h0 + b` (`defor_depth = 0`); each head is
//! `ReLU → Linear(W, W) → ReLU → Linear(W, out)` on `h`. Since every head starts with the same
//! ReLU, the feature layer here is an [`Mlp`] with a ReLU output activation and each head an
//! [`Mlp`] with one ReLU hidden layer: the same function. Output rows are
//! `[position 3, rotation 4, scale 3]` ([`HEX_OUTPUT`]), the deltas 4DGaussians adds to the
//! mean, the raw quaternion and the log-scale (`no_do` and `no_dshs` are its D-NeRF defaults:
//! opacity and colour are not deformed).
//! What it is not: the backbone's training logic (regulariser weights, learning rates, the
//! coarse stage) — that is the trainer's; the network only evaluates the regularisers of its
//! planes ([`HexDeformNet::regularise`]).
//!
//! Deviation: 4DGaussians initialises the linear weights with Xavier-uniform (`initialize_weights`;
//! its biases keep PyTorch's default); here every layer has PyTorch's default `U(±1/√in)`
//! ([`Mlp`]).

use crate::encoding::triplane::{PlaneRegulariser, TimeAxis, TriPlane, TriPlaneConfig};
use crate::error::{NnError, check_len};
use crate::mlp::{Mlp, MlpCache, MlpConfig};
use crate::precision::{Precision, StoreMut, StoreRef};
use crate::{Activation, Parameters, PlaneCombine};

/// Width of an output row: position 3, rotation 4, scale 3.
pub const HEX_OUTPUT: usize = 10;
/// The heads' output widths, in output-row order.
const HEADS: [usize; 3] = [3, 4, 3];
/// The heads' names, in output-row order.
const HEAD_NAMES: [&str; 3] = ["head_position", "head_rotation", "head_scale"];

/// Settings of a [`HexDeformNet`].
#[derive(Clone, Debug, PartialEq)]
pub struct HexDeformConfig {
    /// The HexPlane (must have a time axis and combine by product).
    pub hexplane: TriPlaneConfig,
    /// Width `W` of the feature layer and the heads (4DGaussians' `net_width`, 64 for D-NeRF).
    pub width: usize,
    /// Storage precision of the MLPs (the HexPlane keeps its own setting).
    pub precision: Precision,
    /// Seed (the HexPlane has its own; the MLPs use seed, seed + 1, …).
    pub seed: u64,
}

impl HexDeformConfig {
    /// 4DGaussians' D-NeRF field over the box `[min, max]`, time in `[0, 1]`: 32 channels, space
    /// resolutions 64 · [1, 2], 25 time texels, width 64 (`arguments/__init__.py`
    /// `kplanes_config`, `dnerf_default.py` `multires = [1, 2]`, `net_width = 64`).
    ///
    /// The time axis spans `[-1, 1]`: 4DGaussians concatenates the raw time `t ∈ [0, 1]` to the
    /// normalised position and samples with `grid_sample`, whose coordinates are in `[-1, 1]`,
    /// so a D-NeRF sequence uses the upper half of the time texels. We keep that.
    pub fn dnerf(box_min: [f32; 3], box_max: [f32; 3], seed: u64) -> Self {
        Self {
            hexplane: TriPlaneConfig::new(32, &[64, 128], PlaneCombine::Product)
                .bounds(box_min, box_max)
                .time(TimeAxis::new(25, -1.0, 1.0))
                .seed(seed),
            width: 64,
            precision: Precision::F32,
            seed,
        }
    }
}

impl HexDeformConfig {
    /// The feature layer (the HexPlane's features in) and the position, rotation and scale
    /// heads.
    fn mlps(&self) -> [MlpConfig; 4] {
        let w = self.width;
        let trunk = MlpConfig::new(self.hexplane.output_width(), w, 0, w)
            .output_activation(Activation::Relu)
            .precision(self.precision)
            .seed(self.seed);
        let head = |i: usize| {
            MlpConfig::new(w, w, 1, HEADS[i])
                .precision(self.precision)
                .seed(self.seed + 1 + i as u64)
        };
        [trunk, head(0), head(1), head(2)]
    }

    /// The field's parameters (HexPlane and MLPs), without allocating them (checked
    /// arithmetic: an overflow is an error).
    pub fn param_count(&self) -> Result<usize, NnError> {
        let mut total = self.hexplane.param_count()?;
        for mlp in self.mlps() {
            total = total.checked_add(mlp.param_count()?).ok_or_else(|| {
                NnError::Config("4DGaussians field: parameter count overflows".into())
            })?;
        }
        Ok(total)
    }
}

/// The 4DGaussians deformation field.
#[derive(Clone, Debug)]
pub struct HexDeformNet {
    /// The HexPlane.
    pub hexplane: TriPlane,
    /// `feature_out` followed by the heads' shared ReLU.
    pub trunk: Mlp,
    /// Position, rotation and scale heads.
    pub heads: [Mlp; 3],
}

/// Cache of [`HexDeformNet::forward`].
#[derive(Clone, Debug)]
pub struct HexDeformCache {
    rows: usize,
    hexplane: crate::TriPlaneCache,
    trunk: MlpCache,
    heads: Vec<MlpCache>,
}

/// Gradients of [`HexDeformNet::backward`], one buffer per [`Parameters`] entry, same order.
#[derive(Clone, Debug, PartialEq)]
pub struct HexDeformGrads {
    /// dL/d(planes).
    pub hexplane: Vec<f32>,
    /// dL/d(feature layer).
    pub trunk: Vec<f32>,
    /// dL/d(heads), position, rotation, scale.
    pub heads: [Vec<f32>; 3],
}

impl HexDeformNet {
    /// Builds the field. Errors when the HexPlane has no time axis or does not multiply its
    /// planes, or on a zero width.
    pub fn new(config: HexDeformConfig) -> Result<Self, NnError> {
        if config.hexplane.time.is_none() || config.hexplane.combine != PlaneCombine::Product {
            return Err(NnError::Config(
                "4DGaussians field: the HexPlane needs a time axis and the product combination"
                    .into(),
            ));
        }
        if config.width == 0 {
            return Err(NnError::Config("4DGaussians field: width 0".into()));
        }
        let [trunk, h0, h1, h2] = config.mlps();
        Ok(Self {
            hexplane: config.hexplane.build()?,
            trunk: trunk.build()?,
            heads: [h0.build()?, h1.build()?, h2.build()?],
        })
    }

    /// Deformations of `rows` points: `positions` rows × 3, `times` one per row. Returns rows ×
    /// [`HEX_OUTPUT`].
    pub fn forward(
        &self,
        positions: &[f32],
        times: &[f32],
        rows: usize,
    ) -> Result<(Vec<f32>, HexDeformCache), NnError> {
        check_len("4DGaussians field positions", rows * 3, positions.len())?;
        check_len("4DGaussians field times", rows, times.len())?;
        let inputs: Vec<f32> = positions
            .chunks_exact(3)
            .zip(times)
            .flat_map(|(p, &t)| [p[0], p[1], p[2], t])
            .collect();
        let (features, hexplane) = self.hexplane.forward(&inputs, rows)?;
        let (h, trunk) = self.trunk.forward(&features, rows)?;
        let mut out = vec![0f32; rows * HEX_OUTPUT];
        let mut heads = Vec::with_capacity(3);
        let mut col = 0;
        for (head, &width) in self.heads.iter().zip(&HEADS) {
            let (y, cache) = head.forward(&h, rows)?;
            for (orow, yrow) in out.chunks_exact_mut(HEX_OUTPUT).zip(y.chunks_exact(width)) {
                orow[col..col + width].copy_from_slice(yrow);
            }
            heads.push(cache);
            col += width;
        }
        Ok((
            out,
            HexDeformCache {
                rows,
                hexplane,
                trunk,
                heads,
            },
        ))
    }

    /// Backward from dL/d(output) (rows × [`HEX_OUTPUT`]); no gradient to the inputs (4DGaussians
    /// feeds the field the Gaussians' means, and the trainer detaches them as for D-3DGS).
    pub fn backward(
        &self,
        cache: &HexDeformCache,
        d_out: &[f32],
    ) -> Result<HexDeformGrads, NnError> {
        let rows = cache.rows;
        check_len(
            "4DGaussians field output gradient",
            rows * HEX_OUTPUT,
            d_out.len(),
        )?;
        let w = self.trunk.output_width();
        let mut d_h = vec![0f32; rows * w];
        let mut col = 0;
        let mut head_grads = Vec::with_capacity(3);
        for ((head, hc), &width) in self.heads.iter().zip(&cache.heads).zip(&HEADS) {
            let d_y: Vec<f32> = d_out
                .chunks_exact(HEX_OUTPUT)
                .flat_map(|r| r[col..col + width].iter().copied())
                .collect();
            let g = head.backward(hc, &d_y, true)?;
            let dx = g.input.unwrap_or_default();
            d_h.iter_mut().zip(&dx).for_each(|(a, b)| *a += b);
            head_grads.push(g.params);
            col += width;
        }
        let t = self.trunk.backward(&cache.trunk, &d_h, true)?;
        let d_features = t.input.unwrap_or_default();
        let p = self
            .hexplane
            .backward(&cache.hexplane, &d_features, false)?;
        let mut hg = head_grads.into_iter();
        Ok(HexDeformGrads {
            hexplane: p.params,
            trunk: t.params,
            heads: [
                hg.next().unwrap_or_default(),
                hg.next().unwrap_or_default(),
                hg.next().unwrap_or_default(),
            ],
        })
    }

    /// 4DGaussians' `compute_regulation(time_smoothness_weight, l1_time_planes, plane_tv_weight)`
    /// on the HexPlane: `space · SpaceSmoothness + time · TimeSmoothness + l1 · TimeL1`. Adds
    /// the gradient into `grads.hexplane`; returns the weighted value.
    pub fn regularise(
        &self,
        space: f32,
        time: f32,
        l1: f32,
        grads: &mut HexDeformGrads,
    ) -> Result<f64, NnError> {
        let mut total = 0.0;
        for (which, weight) in [
            (PlaneRegulariser::SpaceSmoothness, space),
            (PlaneRegulariser::TimeSmoothness, time),
            (PlaneRegulariser::TimeL1, l1),
        ] {
            if weight != 0.0 {
                total += self
                    .hexplane
                    .regularise(which, weight, &mut grads.hexplane)?;
            }
        }
        Ok(total)
    }
}

impl Parameters for HexDeformNet {
    fn named_params(&self) -> Vec<(String, StoreRef<'_>)> {
        let mut v = vec![
            ("hexplane".to_string(), self.hexplane.params()),
            ("trunk".to_string(), self.trunk.params()),
        ];
        for (name, head) in HEAD_NAMES.iter().zip(&self.heads) {
            v.push((name.to_string(), head.params()));
        }
        v
    }
    fn named_params_mut(&mut self) -> Vec<(String, StoreMut<'_>)> {
        let Self {
            hexplane,
            trunk,
            heads,
        } = self;
        let mut v = vec![
            ("hexplane".to_string(), hexplane.params_mut()),
            ("trunk".to_string(), trunk.params_mut()),
        ];
        for (name, head) in HEAD_NAMES.iter().zip(heads.iter_mut()) {
            v.push((name.to_string(), head.params_mut()));
        }
        v
    }
}
