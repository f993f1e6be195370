//! Composite networks: the EvoGS observation network Φ and the D-3DGS deformation MLP.

use rayon::prelude::*;

use crate::encoding::bspline::{BSplineConfig, BSplineTime};
use crate::encoding::sinusoidal::Sinusoidal;
use crate::encoding::triplane::{TriPlane, TriPlaneConfig};
use crate::error::{NnError, check_len};
use crate::mlp::{Init, Mlp, MlpCache, MlpConfig};
use crate::precision::{Precision, StoreMut, StoreRef};
use crate::reduce::add_into;
use crate::simd::{Kernel, vectorised};
use crate::weights::Parameters;

/// Rows per parallel task when [`ObservationNet`] permutes rows to and from the decoder's order.
const GATHER_ROWS: usize = 1024;

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

impl ObservationConfig {
    /// The decoder: the two encoders' features in, `output` values out, starting at zero.
    fn decoder(&self) -> MlpConfig {
        let input = self.triplane.output_width() + self.bspline.width;
        MlpConfig::new(input, self.width, self.hidden_layers, self.output)
            .zero_output(true)
            .precision(self.precision)
            .seed(self.seed + 2)
    }

    /// The parameters of Φ (tri-plane, B-spline and decoder), without allocating them (checked
    /// arithmetic: an overflow is an error).
    pub fn param_count(&self) -> Result<usize, NnError> {
        [
            self.triplane.param_count()?,
            self.bspline.param_count()?,
            self.decoder().param_count()?,
        ]
        .into_iter()
        .try_fold(0usize, usize::checked_add)
        .ok_or_else(|| NnError::Config("observation network: parameter count overflows".into()))
    }
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

/// Cache of [`ObservationNet::forward`] (`default()` is empty, for `forward_into`).
///
/// The decoder runs over the rows in the tri-plane's spatial order (see
/// [`ObservationNet::forward`]): `order[i]` is the input row of decoder row `i`, and the cached
/// positions and times are stored in that order; `rank[r]` is the decoder row of input row `r`.
#[derive(Clone, Debug, Default)]
pub struct ObservationCache {
    order: Vec<usize>,
    rank: Vec<usize>,
    positions: Vec<f32>,
    times: Vec<f32>,
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
    /// Builds Φ. Its tri-plane is spatial (time goes through the B-spline): a tri-plane with a
    /// time axis is an error.
    pub fn new(config: ObservationConfig) -> Result<Self, NnError> {
        if config.triplane.time.is_some() {
            return Err(NnError::Config(
                "observation network: the tri-plane has a time axis (time goes through the B-spline)"
                    .into(),
            ));
        }
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
        let mlp = config.decoder().build()?;
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

    /// Evaluates Φ at `rows` positions (rows × 3) and times (rows). The encoders write straight
    /// into the decoder's input blocks (no intermediate feature matrix).
    ///
    /// Rows are processed in a spatial order (cells of the normalised box in Morton order, input
    /// order inside a cell), so that consecutive rows sample, and in backward scatter gradients
    /// into, nearby texels: with rows in arbitrary order every texel access of the tri-plane
    /// misses the cache. The outputs and gradients are returned in input order; each row's
    /// output does not depend on the order, the parameter gradients' f32 sums are taken in that
    /// (deterministic) order.
    pub fn forward(
        &self,
        positions: &[f32],
        times: &[f32],
        rows: usize,
    ) -> Result<(Vec<f32>, ObservationCache), NnError> {
        let mut cache = ObservationCache::default();
        let out = self.forward_into(positions, times, rows, &mut cache)?;
        Ok((out, cache))
    }

    /// [`ObservationNet::forward`] into an existing cache whose buffers are reused.
    pub fn forward_into(
        &self,
        positions: &[f32],
        times: &[f32],
        rows: usize,
        cache: &mut ObservationCache,
    ) -> Result<Vec<f32>, NnError> {
        check_len("observation times", rows, times.len())?;
        self.triplane.check_positions(positions, rows)?;
        BSplineTime::check_times(times)?;
        let planes = self.triplane.planes_f32();
        let ctrl = self.bspline.controls_f32();
        let c = self.triplane.config().channels;
        let ObservationCache {
            order,
            rank,
            positions: sorted_positions,
            times: sorted_times,
            mlp,
        } = cache;
        self.triplane.spatial_order(positions, order);
        rank.resize(rows, 0);
        for (i, &r) in order.iter().enumerate() {
            rank[r] = i;
        }
        // The rows in decoder order, gathered in parallel (every value is written).
        sorted_positions.resize(rows * 3, 0.0);
        sorted_positions
            .par_chunks_mut(3)
            .zip(order.par_iter())
            .with_min_len(GATHER_ROWS)
            .for_each(|(dst, &r)| dst.copy_from_slice(&positions[r * 3..r * 3 + 3]));
        sorted_times.clear();
        sorted_times.par_extend(order.par_iter().map(|&r| times[r]));
        let (positions, times) = (&sorted_positions[..], &sorted_times[..]);
        // One time for every row (a training step's frame): its encoding, computed once.
        let time_row = uniform_time(times).map(|t| {
            let mut row = vec![0f32; self.bspline.output_width()];
            self.bspline.encode_row_into(&ctrl, t, &mut row);
            row
        });
        self.mlp.forward_cached(
            rows,
            |r0, nr, buf| {
                vectorised(EncodeRows {
                    net: self,
                    planes: &planes,
                    ctrl: &ctrl,
                    positions: &positions[r0 * 3..(r0 + nr) * 3],
                    times: &times[r0..r0 + nr],
                    time_row: time_row.as_deref(),
                    out: buf,
                    feat: &mut vec![0f32; 3 * c],
                });
            },
            mlp,
        );
        let d = self.mlp.output_width();
        let sorted_out = mlp.output();
        let mut out = vec![0f32; rows * d];
        out.par_chunks_mut(d.max(1))
            .zip(rank.par_iter())
            .with_min_len(GATHER_ROWS)
            .for_each(|(dst, &i)| sorted_out.slice(i * d, d).read_into(dst));
        Ok(out)
    }

    /// Backward from dL/d(output) (rows × D). The encoders take their gradients block by block
    /// from the decoder's input gradient.
    pub fn backward(
        &self,
        cache: &ObservationCache,
        d_out: &[f32],
        want_position_grad: bool,
    ) -> Result<ObservationGrads, NnError> {
        let rows = cache.mlp.rows();
        let d = self.mlp.output_width();
        check_len("observation output gradient", rows * d, d_out.len())?;
        if cache.order.len() != rows || cache.rank.len() != rows {
            return Err(NnError::Config(
                "observation cache does not hold a forward pass".into(),
            ));
        }
        let mut sorted_d_out = vec![0f32; rows * d];
        sorted_d_out
            .par_chunks_mut(d.max(1))
            .zip(cache.order.par_iter())
            .with_min_len(GATHER_ROWS)
            .for_each(|(dst, &r)| dst.copy_from_slice(&d_out[r * d..(r + 1) * d]));
        let planes = self.triplane.planes_f32();
        let ctrl = self.bspline.controls_f32();
        let (wx, wt) = (self.triplane.output_width(), self.bspline.output_width());
        let c = self.triplane.config().channels;
        let (np, nb) = (self.triplane.param_count(), self.bspline.param_count());
        type Acc = (Vec<f32>, Vec<f32>, Vec<(usize, Vec<f32>)>);
        let (mlp, (tp, bs, pos_blocks)) = self.mlp.backward_with(
            &cache.mlp,
            &sorted_d_out,
            || -> Acc { (vec![0f32; np], vec![0f32; nb], Vec::new()) },
            |acc: &mut Acc, r0, dx| {
                let nr = dx.len() / (wx + wt);
                let mut dp = vec![0f32; nr * 3];
                vectorised(BackwardRows {
                    net: self,
                    planes: &planes,
                    ctrl: &ctrl,
                    positions: &cache.positions[r0 * 3..(r0 + nr) * 3],
                    times: &cache.times[r0..r0 + nr],
                    d_features: dx,
                    d_planes: &mut acc.0,
                    d_controls: &mut acc.1,
                    d_positions: &mut dp,
                    feat: &mut vec![0f32; 3 * c],
                    dfeat: &mut vec![0f32; 3 * c],
                });
                if want_position_grad {
                    acc.2.push((r0, dp));
                }
            },
            |a: Acc, b: Acc| {
                let mut list = a.2;
                list.extend(b.2);
                (add_into(a.0, b.0), add_into(a.1, b.1), list)
            },
        )?;
        let positions = want_position_grad.then(|| {
            // The blocks in decoder order, then each input row's gathered in parallel.
            let mut sorted = vec![0f32; rows * 3];
            for (r0, block) in pos_blocks {
                sorted[r0 * 3..r0 * 3 + block.len()].copy_from_slice(&block);
            }
            let mut out = vec![0f32; rows * 3];
            out.par_chunks_mut(3)
                .zip(cache.rank.par_iter())
                .with_min_len(GATHER_ROWS)
                .for_each(|(dst, &i)| dst.copy_from_slice(&sorted[i * 3..i * 3 + 3]));
            out
        });
        Ok(ObservationGrads {
            triplane: tp,
            bspline: bs,
            mlp,
            positions,
        })
    }
}

/// Encodes a block of rows (positions and times) into the decoder's input block `out`.
struct EncodeRows<'a> {
    net: &'a ObservationNet,
    planes: &'a [f32],
    ctrl: &'a [f32],
    positions: &'a [f32],
    times: &'a [f32],
    /// The encoding of every row's time, when all rows share one (see [`uniform_time`]).
    time_row: Option<&'a [f32]>,
    out: &'a mut [f32],
    feat: &'a mut [f32],
}

impl Kernel for EncodeRows<'_> {
    type Output = ();
    #[inline(always)]
    fn run(self) {
        let wx = self.net.triplane.output_width();
        let width = wx + self.net.bspline.output_width();
        for ((row, p), &t) in self
            .out
            .chunks_exact_mut(width)
            .zip(self.positions.chunks_exact(3))
            .zip(self.times)
        {
            let (fx, ft) = row.split_at_mut(wx);
            self.net
                .triplane
                .encode_row_into(self.planes, p, fx, self.feat);
            match self.time_row {
                Some(enc) => ft.copy_from_slice(enc),
                None => self.net.bspline.encode_row_into(self.ctrl, t, ft),
            }
        }
    }
}

/// Backward of the encoders over a block of rows: adds the plane and control gradients into
/// `d_planes` and `d_controls`, writes the position gradients into `d_positions` (rows × 3).
struct BackwardRows<'a> {
    net: &'a ObservationNet,
    planes: &'a [f32],
    ctrl: &'a [f32],
    positions: &'a [f32],
    times: &'a [f32],
    d_features: &'a [f32],
    d_planes: &'a mut [f32],
    d_controls: &'a mut [f32],
    d_positions: &'a mut [f32],
    feat: &'a mut [f32],
    dfeat: &'a mut [f32],
}

impl Kernel for BackwardRows<'_> {
    type Output = ();
    #[inline(always)]
    fn run(self) {
        let wx = self.net.triplane.output_width();
        let width = wx + self.net.bspline.output_width();
        for (((g, p), &t), dp) in self
            .d_features
            .chunks_exact(width)
            .zip(self.positions.chunks_exact(3))
            .zip(self.times)
            .zip(self.d_positions.chunks_exact_mut(3))
        {
            self.net.triplane.backward_row_into(
                self.planes,
                p,
                &g[..wx],
                self.d_planes,
                self.feat,
                self.dfeat,
                dp,
            );
            self.net
                .bspline
                .backward_row_into(self.ctrl, t, &g[wx..], self.d_controls);
        }
    }
}

/// The time of every row when all rows have the same one (bit for bit), else None.
fn uniform_time(times: &[f32]) -> Option<f32> {
    let (&first, rest) = times.split_first()?;
    rest.iter()
        .all(|t| t.to_bits() == first.to_bits())
        .then_some(first)
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
    /// Initialisation of the hidden layers (D-3DGS: PyTorch's default).
    pub init: Init,
    /// Start the heads at zero, so the deformation starts at zero (D-3DGS: PyTorch's default).
    pub zero_heads: bool,
    /// Storage precision.
    pub precision: Precision,
    /// Seed.
    pub seed: u64,
}

impl DeformConfig {
    /// The MLP of a network with `outputs` output columns: the encoded position and time in.
    fn mlp_config(&self, outputs: usize) -> Result<MlpConfig, NnError> {
        let xyz = Sinusoidal::new(3, self.xyz_freqs)?;
        let t = Sinusoidal::new(1, self.t_freqs)?;
        let mut mc = MlpConfig::new(
            xyz.output_width() + t.output_width(),
            self.width,
            self.depth,
            outputs,
        )
        .init(self.init)
        .zero_output(self.zero_heads)
        .precision(self.precision)
        .seed(self.seed);
        if let Some(s) = self.skip_after {
            mc = mc.skip_after(s);
        }
        Ok(mc)
    }

    /// The parameters of the network with `outputs` output columns
    /// ([`DeformNet::with_outputs`]), without allocating them.
    pub fn param_count(&self, outputs: usize) -> Result<usize, NnError> {
        self.mlp_config(outputs)?.param_count()
    }

    /// D-3DGS's reference setting: width 256, depth 8, skip after layer 4, L = 10 and 6.
    pub fn d3dgs() -> Self {
        Self {
            width: 256,
            depth: 8,
            skip_after: Some(4),
            xyz_freqs: 10,
            t_freqs: 6,
            init: Init::Torch,
            zero_heads: false,
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

/// Cache of [`DeformNet::forward`] (`default()` is empty, for `forward_into`).
#[derive(Clone, Debug, Default)]
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

    /// Builds the network with D-3DGS's three heads ([`DeformNet::OUTPUT`] outputs).
    pub fn new(config: DeformConfig) -> Result<Self, NnError> {
        Self::with_outputs(config, Self::OUTPUT)
    }

    /// Builds the network with `outputs` output columns (SC-GS's control-point network adds a
    /// fourth head, 14 outputs); the columns' meaning is the caller's.
    pub fn with_outputs(config: DeformConfig, outputs: usize) -> Result<Self, NnError> {
        Ok(Self {
            xyz: Sinusoidal::new(3, config.xyz_freqs)?,
            t: Sinusoidal::new(1, config.t_freqs)?,
            mlp: config.mlp_config(outputs)?.build()?,
        })
    }

    /// Multiply-adds per row.
    pub fn macs_per_row(&self) -> usize {
        self.mlp.macs_per_row()
    }

    /// The encodings of position and time, in the order their outputs enter the MLP.
    pub fn encodings(&self) -> (Sinusoidal, Sinusoidal) {
        (self.xyz, self.t)
    }

    /// Checks a forward pass's inputs: `rows` positions (rows × 3) and times (rows), every
    /// value finite (the first that is not is named by its row). The CPU and the GPU forward
    /// both start here.
    pub(crate) fn check_inputs(
        positions: &[f32],
        times: &[f32],
        rows: usize,
    ) -> Result<(), NnError> {
        check_len("deformation positions", rows * 3, positions.len())?;
        check_len("deformation times", rows, times.len())?;
        if let Some(i) = positions.iter().position(|v| !v.is_finite()) {
            return Err(NnError::Config(format!(
                "deformation positions: row {} has a non-finite coordinate",
                i / 3
            )));
        }
        if let Some(i) = times.iter().position(|v| !v.is_finite()) {
            return Err(NnError::Config(format!(
                "deformation times: row {i} is not finite"
            )));
        }
        Ok(())
    }

    /// Evaluates at `rows` positions (rows × 3) and times (rows).
    pub fn forward(
        &self,
        positions: &[f32],
        times: &[f32],
        rows: usize,
    ) -> Result<(Vec<f32>, DeformCache), NnError> {
        let mut cache = DeformCache::default();
        let out = self.forward_into(positions, times, rows, &mut cache)?;
        Ok((out, cache))
    }

    /// [`DeformNet::forward`] into an existing cache whose buffers are reused.
    pub fn forward_into(
        &self,
        positions: &[f32],
        times: &[f32],
        rows: usize,
        cache: &mut DeformCache,
    ) -> Result<Vec<f32>, NnError> {
        Self::check_inputs(positions, times, rows)?;
        let (wx, wt) = (self.xyz.output_width(), self.t.output_width());
        let out = self.mlp.forward_into(
            rows,
            |r0, _, buf| {
                for (i, row) in buf.chunks_exact_mut(wx + wt).enumerate() {
                    let r = r0 + i;
                    let (ex, et) = row.split_at_mut(wx);
                    self.xyz.encode_row_into(&positions[r * 3..r * 3 + 3], ex);
                    self.t.encode_row_into(&times[r..r + 1], et);
                }
            },
            &mut cache.mlp,
        );
        cache.positions.clear();
        cache.positions.extend_from_slice(positions);
        Ok(out)
    }

    /// Backward from dL/d(output) (rows × outputs).
    pub fn backward(
        &self,
        cache: &DeformCache,
        d_out: &[f32],
        want_position_grad: bool,
    ) -> Result<DeformGrads, NnError> {
        if !want_position_grad {
            let g = self.mlp.backward(&cache.mlp, d_out, false)?;
            return Ok(DeformGrads {
                mlp: g.params,
                positions: None,
            });
        }
        let rows = cache.mlp.rows();
        let (wx, wt) = (self.xyz.output_width(), self.t.output_width());
        type Acc = Vec<(usize, Vec<f32>)>;
        let (mlp, blocks) = self.mlp.backward_with(
            &cache.mlp,
            d_out,
            Acc::new,
            |acc: &mut Acc, r0, dx| {
                let nr = dx.len() / (wx + wt);
                let mut dp = vec![0f32; nr * 3];
                for (i, g) in dx.chunks_exact(wx + wt).enumerate() {
                    let r = r0 + i;
                    self.xyz.backward_row_into(
                        &cache.positions[r * 3..r * 3 + 3],
                        &g[..wx],
                        &mut dp[i * 3..i * 3 + 3],
                    );
                }
                acc.push((r0, dp));
            },
            |mut a: Acc, b: Acc| {
                a.extend(b);
                a
            },
        )?;
        let mut positions = vec![0f32; rows * 3];
        for (r0, block) in blocks {
            positions[r0 * 3..r0 * 3 + block.len()].copy_from_slice(&block);
        }
        Ok(DeformGrads {
            mlp,
            positions: Some(positions),
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encoding::triplane::PlaneCombine;

    /// The encoder kernels give bit-identical results compiled for AVX2 (dispatched) and for the
    /// baseline target (called directly).
    #[test]
    fn encoder_kernels_are_bit_identical_with_and_without_avx2() {
        for combine in [PlaneCombine::Product, PlaneCombine::Concat] {
            let net = ObservationNet::new(ObservationConfig {
                triplane: TriPlaneConfig::new(5, &[4, 7], combine),
                bspline: BSplineConfig::new(6, 3),
                width: 8,
                hidden_layers: 1,
                output: 2,
                precision: Precision::F32,
                seed: 5,
            })
            .unwrap();
            let rows = 37;
            let positions: Vec<f32> = (0..rows * 3)
                .map(|i| ((i * 37) % 29) as f32 / 12.0 - 1.2)
                .collect();
            let times: Vec<f32> = (0..rows).map(|i| i as f32 / (rows - 1) as f32).collect();
            let (planes, ctrl) = (net.triplane.planes_f32(), net.bspline.controls_f32());
            let c = net.triplane.config().channels;
            let width = net.triplane.output_width() + net.bspline.output_width();
            let encode = |avx: bool| {
                let mut out = vec![0f32; rows * width];
                let k = EncodeRows {
                    net: &net,
                    planes: &planes,
                    ctrl: &ctrl,
                    positions: &positions,
                    times: &times,
                    time_row: None,
                    out: &mut out,
                    feat: &mut vec![0f32; 3 * c],
                };
                if avx {
                    vectorised(k);
                } else {
                    k.run();
                }
                out
            };
            assert_eq!(encode(true), encode(false));
            let d_features: Vec<f32> = (0..rows * width)
                .map(|i| ((i * 13) % 17) as f32 / 8.0 - 1.0)
                .collect();
            let backward = |avx: bool| {
                let mut d_planes = vec![0f32; net.triplane.param_count()];
                let mut d_controls = vec![0f32; net.bspline.param_count()];
                let mut d_positions = vec![0f32; rows * 3];
                let k = BackwardRows {
                    net: &net,
                    planes: &planes,
                    ctrl: &ctrl,
                    positions: &positions,
                    times: &times,
                    d_features: &d_features,
                    d_planes: &mut d_planes,
                    d_controls: &mut d_controls,
                    d_positions: &mut d_positions,
                    feat: &mut vec![0f32; 3 * c],
                    dfeat: &mut vec![0f32; 3 * c],
                };
                if avx {
                    vectorised(k);
                } else {
                    k.run();
                }
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                (bits(&d_planes), bits(&d_controls), bits(&d_positions))
            };
            let (a, b) = (backward(true), backward(false));
            assert!(a.0.iter().any(|&x| x != 0));
            assert_eq!(a, b);
        }
    }
}
