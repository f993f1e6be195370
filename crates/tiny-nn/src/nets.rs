//! Composite networks: the EvoGS observation network Φ and the D-3DGS deformation MLP.

use crate::encoding::bspline::{BSplineCache, BSplineConfig, BSplineTime};
use crate::encoding::sinusoidal::Sinusoidal;
use crate::encoding::triplane::{TriPlane, TriPlaneCache, TriPlaneConfig};
use crate::error::{NnError, check_len};
use crate::mlp::{Mlp, MlpCache, MlpConfig};
use crate::precision::{Precision, StoreMut, StoreRef};
use crate::weights::Parameters;

/// Settings of the EvoGS observation network Φ: `[tri-plane(x), B-spline(t)] → MLP → D`.
#[derive(Clone, Debug, PartialEq)]
pub struct ObservationConfig {
    /// Spatial encoder.
    pub triplane: TriPlaneConfig,
    /// Temporal encoder.
    pub bspline: BSplineConfig,
    /// Decoder hidden width.
    pub width: usize,
    /// Decoder hidden layers.
    pub hidden_layers: usize,
    /// Output width D.
    pub output: usize,
    /// Storage precision of all three parts (overrides the encoders' own settings).
    pub precision: Precision,
    /// Seed (the parts use seed, seed + 1, seed + 2).
    pub seed: u64,
}

/// The observation network Φ. Its decoder's output layer starts at zero, so Φ starts at 0.
#[derive(Clone, Debug)]
pub struct ObservationNet {
    /// Spatial encoder.
    pub triplane: TriPlane,
    /// Temporal encoder.
    pub bspline: BSplineTime,
    /// Decoder.
    pub mlp: Mlp,
}

/// Cache of [`ObservationNet::forward`].
#[derive(Clone, Debug)]
pub struct ObservationCache {
    triplane: TriPlaneCache,
    bspline: BSplineCache,
    mlp: MlpCache,
}

impl ObservationCache {
    /// f16 saturations of the decoder's forward pass.
    pub fn saturations(&self) -> u64 {
        self.mlp.saturations()
    }
}

/// Gradients of [`ObservationNet::backward`].
#[derive(Clone, Debug, PartialEq)]
pub struct ObservationGrads {
    /// dL/d(tri-plane parameters).
    pub triplane: Vec<f32>,
    /// dL/d(B-spline control vectors).
    pub bspline: Vec<f32>,
    /// dL/d(decoder parameters).
    pub mlp: Vec<f32>,
    /// dL/d(positions) (when asked for).
    pub positions: Option<Vec<f32>>,
}

impl ObservationNet {
    /// Builds Φ.
    pub fn new(config: ObservationConfig) -> Result<Self, NnError> {
        let triplane = config
            .triplane
            .clone()
            .precision(config.precision)
            .seed(config.seed)
            .build()?;
        let bspline = config
            .bspline
            .clone()
            .precision(config.precision)
            .seed(config.seed + 1)
            .build()?;
        let input = triplane.output_width() + bspline.output_width();
        let mlp = MlpConfig::new(input, config.width, config.hidden_layers, config.output)
            .zero_output(true)
            .precision(config.precision)
            .seed(config.seed + 2)
            .build()?;
        Ok(Self {
            triplane,
            bspline,
            mlp,
        })
    }

    /// Multiply-adds of the decoder per row.
    pub fn macs_per_row(&self) -> usize {
        self.mlp.macs_per_row()
    }

    /// Evaluates Φ at `rows` positions (rows × 3) and times (rows).
    pub fn forward(
        &self,
        positions: &[f32],
        times: &[f32],
        rows: usize,
    ) -> Result<(Vec<f32>, ObservationCache), NnError> {
        check_len("observation times", rows, times.len())?;
        let (fx, tc) = self.triplane.forward(positions, rows)?;
        let (ft, bc) = self.bspline.forward(times)?;
        let (wx, wt) = (self.triplane.output_width(), self.bspline.output_width());
        let mut input = Vec::with_capacity(rows * (wx + wt));
        for r in 0..rows {
            input.extend_from_slice(&fx[r * wx..(r + 1) * wx]);
            input.extend_from_slice(&ft[r * wt..(r + 1) * wt]);
        }
        let (out, mc) = self.mlp.forward(&input, rows)?;
        Ok((
            out,
            ObservationCache {
                triplane: tc,
                bspline: bc,
                mlp: mc,
            },
        ))
    }

    /// Backward from dL/d(output) (rows × D).
    pub fn backward(
        &self,
        cache: &ObservationCache,
        d_out: &[f32],
        want_position_grad: bool,
    ) -> Result<ObservationGrads, NnError> {
        let rows = cache.mlp.rows();
        let g = self.mlp.backward(&cache.mlp, d_out, true)?;
        let d_in = g.input.unwrap_or_default();
        let (wx, wt) = (self.triplane.output_width(), self.bspline.output_width());
        let mut dx = Vec::with_capacity(rows * wx);
        let mut dt = Vec::with_capacity(rows * wt);
        for row in d_in.chunks_exact(wx + wt) {
            dx.extend_from_slice(&row[..wx]);
            dt.extend_from_slice(&row[wx..]);
        }
        let tg = self
            .triplane
            .backward(&cache.triplane, &dx, want_position_grad)?;
        let bg = self.bspline.backward(&cache.bspline, &dt, false)?;
        Ok(ObservationGrads {
            triplane: tg.params,
            bspline: bg.params,
            mlp: g.params,
            positions: tg.positions,
        })
    }
}

fn prefixed<T>(prefix: &'static str, v: Vec<(String, T)>) -> impl Iterator<Item = (String, T)> {
    v.into_iter()
        .map(move |(n, s)| (format!("{prefix}.{n}"), s))
}

impl Parameters for ObservationNet {
    fn named_params(&self) -> Vec<(String, StoreRef<'_>)> {
        prefixed("triplane", self.triplane.named_params())
            .chain(prefixed("bspline", self.bspline.named_params()))
            .chain(prefixed("mlp", self.mlp.named_params()))
            .collect()
    }
    fn named_params_mut(&mut self) -> Vec<(String, StoreMut<'_>)> {
        let Self {
            triplane,
            bspline,
            mlp,
        } = self;
        prefixed("triplane", triplane.named_params_mut())
            .chain(prefixed("bspline", bspline.named_params_mut()))
            .chain(prefixed("mlp", mlp.named_params_mut()))
            .collect()
    }
}

/// Settings of the D-3DGS deformation network.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeformConfig {
    /// Hidden width (256 in D-3DGS).
    pub width: usize,
    /// Hidden layers (8 in D-3DGS).
    pub depth: usize,
    /// Re-concatenate the encoded input after this hidden layer (4 in D-3DGS).
    pub skip_after: Option<usize>,
    /// Frequencies of the xyz encoding (10).
    pub xyz_freqs: usize,
    /// Frequencies of the time encoding (6 for synthetic scenes, 10 for real ones).
    pub t_freqs: usize,
    /// Storage precision.
    pub precision: Precision,
    /// Seed.
    pub seed: u64,
}

impl DeformConfig {
    /// D-3DGS's reference setting: width 256, depth 8, skip after layer 4, L = 10 and 6.
    pub fn d3dgs() -> Self {
        Self {
            width: 256,
            depth: 8,
            skip_after: Some(4),
            xyz_freqs: 10,
            t_freqs: 6,
            precision: Precision::F32,
            seed: 0,
        }
    }
}

/// D-3DGS's deformation network: `[γ(x), γ(t)] → 8 × (Linear, ReLU) with the skip → heads`.
/// The three heads (position 3, rotation 4, scale 3) are one linear layer of 10 outputs here,
/// which is the same function: output columns 0..3, 3..7 and 7..10.
#[derive(Clone, Debug)]
pub struct DeformNet {
    xyz: Sinusoidal,
    t: Sinusoidal,
    /// The MLP with its heads.
    pub mlp: Mlp,
}

/// Cache of [`DeformNet::forward`].
#[derive(Clone, Debug)]
pub struct DeformCache {
    positions: Vec<f32>,
    mlp: MlpCache,
}

/// Gradients of [`DeformNet::backward`].
#[derive(Clone, Debug, PartialEq)]
pub struct DeformGrads {
    /// dL/d(MLP parameters).
    pub mlp: Vec<f32>,
    /// dL/d(positions) (when asked for).
    pub positions: Option<Vec<f32>>,
}

impl DeformNet {
    /// Output width: position 3 + rotation 4 + scale 3.
    pub const OUTPUT: usize = 10;

    /// Builds the network.
    pub fn new(config: DeformConfig) -> Result<Self, NnError> {
        let xyz = Sinusoidal::new(3, config.xyz_freqs)?;
        let t = Sinusoidal::new(1, config.t_freqs)?;
        let mut mc = MlpConfig::new(
            xyz.output_width() + t.output_width(),
            config.width,
            config.depth,
            Self::OUTPUT,
        )
        .precision(config.precision)
        .seed(config.seed);
        if let Some(s) = config.skip_after {
            mc = mc.skip_after(s);
        }
        Ok(Self {
            xyz,
            t,
            mlp: mc.build()?,
        })
    }

    /// Multiply-adds per row.
    pub fn macs_per_row(&self) -> usize {
        self.mlp.macs_per_row()
    }

    /// Evaluates at `rows` positions (rows × 3) and times (rows).
    pub fn forward(
        &self,
        positions: &[f32],
        times: &[f32],
        rows: usize,
    ) -> Result<(Vec<f32>, DeformCache), NnError> {
        check_len("deformation times", rows, times.len())?;
        let ex = self.xyz.forward(positions, rows)?;
        let et = self.t.forward(times, rows)?;
        let (wx, wt) = (self.xyz.output_width(), self.t.output_width());
        let mut input = Vec::with_capacity(rows * (wx + wt));
        for r in 0..rows {
            input.extend_from_slice(&ex[r * wx..(r + 1) * wx]);
            input.extend_from_slice(&et[r * wt..(r + 1) * wt]);
        }
        let (out, mlp) = self.mlp.forward(&input, rows)?;
        Ok((
            out,
            DeformCache {
                positions: positions.to_vec(),
                mlp,
            },
        ))
    }

    /// Backward from dL/d(output) (rows × 10).
    pub fn backward(
        &self,
        cache: &DeformCache,
        d_out: &[f32],
        want_position_grad: bool,
    ) -> Result<DeformGrads, NnError> {
        let rows = cache.mlp.rows();
        let g = self.mlp.backward(&cache.mlp, d_out, want_position_grad)?;
        let positions = match g.input {
            Some(d_in) => {
                let (wx, wt) = (self.xyz.output_width(), self.t.output_width());
                let mut dex = Vec::with_capacity(rows * wx);
                for row in d_in.chunks_exact(wx + wt) {
                    dex.extend_from_slice(&row[..wx]);
                }
                Some(self.xyz.backward(&cache.positions, &dex, rows)?)
            }
            None => None,
        };
        Ok(DeformGrads {
            mlp: g.params,
            positions,
        })
    }
}

impl Parameters for DeformNet {
    fn named_params(&self) -> Vec<(String, StoreRef<'_>)> {
        prefixed("mlp", self.mlp.named_params()).collect()
    }
    fn named_params_mut(&mut self) -> Vec<(String, StoreMut<'_>)> {
        prefixed("mlp", self.mlp.named_params_mut()).collect()
    }
}
