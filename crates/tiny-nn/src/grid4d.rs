//! The deformation field of Grid4D: a 4D decomposed hash encoding, a decoder with directional
//! attention, and separate heads, with Grid4D's smoothness regulariser.
//!
//! What it is (Xu et al., "Grid4D: 4D Decomposed Hash Encoding for High-Fidelity Dynamic Gaussian
//! Splatting", NeurIPS 2024; the authors' code `JiaweiXu8/Grid4D`, `scene/network.py` `Grid4D`,
//! `DeformNetwork`, `scene/deform_model.py` `DeformModel.step`):
//! - **Encoding.** A point `(x, y, z)` at time `t` is encoded by four [`HashGrid`]s over the box
//!   `[-bound, bound]` on every axis: one spatial 3D grid of `(x, y, z)` and three temporal 3D
//!   grids of `(x, y, t')`, `(y, z, t')`, `(x, z, t')`, where `t' = (2t − 1) · bound · span`
//!   (Grid4D: `t = (t · 2 · bound − bound) · 0.9`, so a sequence `t ∈ [0, 1]` spans 90 % of the
//!   time axis). The spatial features `s` (`L_s · F`) and the three temporal grids' features
//!   concatenated, `e` (`3 · L_t · F`), are the decoder's two inputs.
//! - **Decoder.** Directional attention on the spatial features: `a = 2 σ(W_s s + b_s) − 1`
//!   (`directional = false`: `a = σ(…)`); the temporal features through `ReLU(W_t e + b_t)`; their
//!   product `h = a ⊙ ReLU(W_t e + b_t)` goes through `depth` layers `ReLU(W h + b)` (Grid4D's
//!   D-NeRF setting: none).
//! - **Heads.** One linear layer per output component on `h` ([`Grid4dHead`]). The position
//!   head is Grid4D's `gaussian_warp`: 7 values plus the bias `[1, 0, 0, 0, 0, 0, 0]` are a
//!   quaternion `q` (real part first) and a translation `τ`, and the moved mean is
//!   `R(q) x + τ`, with `R(q)` the rotation of the normalised `q` (`quaternion_to_matrix`); the
//!   field outputs the additive delta `R(q) x + τ − x`, which the renderer adds to the mean
//!   (the same position). Rotation (4), scale (3), and for EvoGS's optional components opacity
//!   (1) and colour (3) are plain linear heads.
//! - **Smoothness** ([`Grid4dNet::smoothness`]): on a random subset of the rows, the squared
//!   change of the spatial features under a small random move of `(x, y, z)`, and of the
//!   temporal features under a small random move of `(x, y, z, t')`, each averaged over the
//!   subset and weighted (`reg_spatial`, `reg_temporal` of `DeformModel.step`; `train.py` adds
//!   `mean(reg) · lambda`). Its gradient flows to the tables through both encodings.
//!
//! What it is not: the trainer's part (learning rates, warm-up, when to regularise): that is the
//! backbone's. Inputs outside the box encode to zeros (Grid4D's kernel, [`Outside::Zero`]).
//!
//! Deviations: Grid4D's encoder casts its inputs to f16 (`custom_fwd(cast_inputs=torch.half)`);
//! here inputs stay f32. PyTorch's `quaternion_to_matrix` divides by `|q|²`, which is 0 for a zero
//! quaternion; here `|q|²` is floored at [`MIN_QUAT_NORM2`].

use crate::Parameters;
use crate::activation::Activation;
use crate::encoding::hashgrid::{HashGrid, HashGridCache, HashGridConfig, Interpolation, Outside};
use crate::error::{NnError, check_len};
use crate::mlp::{Mlp, MlpCache, MlpConfig};
use crate::precision::{Precision, StoreMut, StoreRef};

/// Floor of `|q|²` in the warp's rotation (see the module's deviations).
pub const MIN_QUAT_NORM2: f32 = 1e-12;
/// Width of the position head's linear layer (quaternion 4, translation 3).
const WARP_WIDTH: usize = 7;

/// One output component of the field, in output-row order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Grid4dHead {
    /// Grid4D's rigid warp (7 linear outputs), output as the position delta (3).
    Position,
    /// Rotation delta (4).
    Rotation,
    /// Scale delta (3).
    Scale,
    /// Opacity delta (1; EvoGS's optional component).
    Opacity,
    /// Colour delta (3; EvoGS's optional component).
    Colour,
}

impl Grid4dHead {
    /// Values of this component in an output row.
    pub fn width(self) -> usize {
        match self {
            Grid4dHead::Position | Grid4dHead::Scale | Grid4dHead::Colour => 3,
            Grid4dHead::Rotation => 4,
            Grid4dHead::Opacity => 1,
        }
    }
    /// Width of the head's linear layer.
    fn linear_width(self) -> usize {
        match self {
            Grid4dHead::Position => WARP_WIDTH,
            h => h.width(),
        }
    }
    /// The parameter buffer's name.
    pub fn name(self) -> &'static str {
        match self {
            Grid4dHead::Position => "head_position",
            Grid4dHead::Rotation => "head_rotation",
            Grid4dHead::Scale => "head_scale",
            Grid4dHead::Opacity => "head_opacity",
            Grid4dHead::Colour => "head_colour",
        }
    }
}

/// Grid4D's smoothness regulariser settings (`DeformModel`'s arguments).
#[derive(Clone, Debug, PartialEq)]
pub struct Grid4dSmoothness {
    /// Weight of the spatial term (`lambda_spatial_tv`).
    pub spatial_weight: f32,
    /// Weight of the temporal term (`lambda_temporal_tv`).
    pub temporal_weight: f32,
    /// Fraction of the rows each term samples (`*_downsample_ratio`; at least one row).
    pub sample_ratio: f32,
    /// Half-width of the uniform move of `(x, y, z)` for the spatial term
    /// (`spatial_perturb_range`).
    pub spatial_range: [f32; 3],
    /// Half-width of the uniform move of `(x, y, z, t')` for the temporal term
    /// (`temporal_perturb_range`, `t'` in the encoder's time units).
    pub temporal_range: [f32; 4],
}

impl Grid4dSmoothness {
    /// Grid4D's D-NeRF settings (`arguments/dnerf/*.py`): both weights 0.5, 10 % of the rows,
    /// moves of 1e-2 in space and 1e-3 in time.
    pub fn dnerf() -> Self {
        Self {
            spatial_weight: 0.5,
            temporal_weight: 0.5,
            sample_ratio: 0.1,
            spatial_range: [1e-2; 3],
            temporal_range: [1e-2, 1e-2, 1e-2, 1e-3],
        }
    }
    /// Rows sampled out of `rows` (`int(max(1, rows · ratio))`; 0 without rows).
    pub fn samples(&self, rows: usize) -> usize {
        if rows == 0 {
            0
        } else {
            ((rows as f64 * self.sample_ratio as f64) as usize).clamp(1, rows)
        }
    }
}

/// Settings of a [`Grid4dNet`].
#[derive(Clone, Debug, PartialEq)]
pub struct Grid4dConfig {
    /// The spatial grid over `(x, y, z)` (3 dims).
    pub spatial: HashGridConfig,
    /// The temporal grids' settings (3 dims, axis 2 is time); the three grids `xyt`, `yzt`,
    /// `xzt` use its seed + 1, + 2, + 3.
    pub temporal: HashGridConfig,
    /// Fraction of the time axis `[-bound, bound]` the times `[0, 1]` span (Grid4D: 0.9), with
    /// `bound` the temporal grid's upper time bound.
    pub time_span: f32,
    /// Width `W` of the decoder (Grid4D's `width`).
    pub width: usize,
    /// Layers `ReLU(W h + b)` after the attention product (Grid4D's `depth`).
    pub depth: usize,
    /// `a = 2σ − 1` (directional) or `σ`.
    pub directional: bool,
    /// Output components, in output-row order (each at most once).
    pub heads: Vec<Grid4dHead>,
    /// Start the heads' weights and biases at zero (EvoGS's Φ starts at a zero observation;
    /// Grid4D: PyTorch's default).
    pub zero_heads: bool,
    /// The smoothness regulariser.
    pub smoothness: Grid4dSmoothness,
    /// Storage precision of the MLPs (the grids keep their own).
    pub precision: Precision,
    /// Seed of the MLPs (seed, seed + 1, …).
    pub seed: u64,
}

impl Grid4dConfig {
    /// Grid4D's D-NeRF field (`arguments/dnerf/*.py` `grid_args`, `network_args`) over
    /// `[-bound, bound]` (Grid4D: 1.6): spatial grid of 16 levels × 2 features, resolutions
    /// 16 → 2048, tables of 2^19; temporal grids of 32 levels × 2, resolutions 8 → (32, 32, 16),
    /// 2^19; decoder width 256, depth 0, directional attention; position, rotation and scale
    /// heads; smoothness [`Grid4dSmoothness::dnerf`]. Tables start uniform in ±1e-4 with
    /// smoothstep weights and zero features outside the box (Grid4D's `hashencoder`).
    pub fn dnerf(bound: f32, seed: u64) -> Self {
        let grid = |dims, levels, base: &[f32], finest: &[f32]| {
            HashGridConfig::new(dims, levels, 2, 19, base[0], finest[0])
                .resolutions(base, finest)
                .bounds(&[-bound; 3], &[bound; 3])
                .interpolation(Interpolation::Smoothstep)
                .outside(Outside::Zero)
        };
        Self {
            spatial: grid(3, 16, &[16.0; 3], &[2048.0; 3]).seed(seed ^ 0x5A),
            temporal: grid(3, 32, &[8.0; 3], &[32.0, 32.0, 16.0]).seed(seed ^ 0x7E),
            time_span: 0.9,
            width: 256,
            depth: 0,
            directional: true,
            heads: vec![
                Grid4dHead::Position,
                Grid4dHead::Rotation,
                Grid4dHead::Scale,
            ],
            zero_heads: false,
            smoothness: Grid4dSmoothness::dnerf(),
            precision: Precision::F32,
            seed,
        }
    }

    /// Values in an output row (the heads' widths summed).
    pub fn output_width(&self) -> usize {
        self.heads.iter().map(|h| h.width()).sum()
    }

    /// The decoder's networks, seeded seed + 1, + 2, … in the order attention, temporal
    /// layer, trunk, heads.
    fn mlps(&self) -> Grid4dMlps {
        let w = self.width;
        let mut seed = self.seed;
        let mut next_seed = || {
            seed = seed.wrapping_add(1);
            seed
        };
        let attention = MlpConfig::new(self.spatial.output_width(), w, 0, w)
            .output_activation(Activation::Sigmoid)
            .precision(self.precision)
            .seed(next_seed());
        let temporal = MlpConfig::new(3 * self.temporal.output_width(), w, 0, w)
            .output_activation(Activation::Relu)
            .precision(self.precision)
            .seed(next_seed());
        let trunk = (self.depth > 0).then(|| {
            MlpConfig::new(w, w, self.depth - 1, w)
                .output_activation(Activation::Relu)
                .precision(self.precision)
                .seed(next_seed())
        });
        let heads = self
            .heads
            .iter()
            .map(|h| {
                MlpConfig::new(w, w, 0, h.linear_width())
                    .zero_output(self.zero_heads)
                    .precision(self.precision)
                    .seed(next_seed())
            })
            .collect();
        Grid4dMlps {
            attention,
            temporal,
            trunk,
            heads,
        }
    }

    /// The field's parameters (the four grids and the decoder), without allocating them
    /// (checked arithmetic: an overflow is an error).
    pub fn param_count(&self) -> Result<usize, NnError> {
        let mlps = self.mlps();
        let grids = [
            self.spatial.param_count()?,
            self.temporal.param_count()?,
            self.temporal.param_count()?,
            self.temporal.param_count()?,
        ];
        let mut nets = vec![mlps.attention.param_count()?, mlps.temporal.param_count()?];
        if let Some(trunk) = &mlps.trunk {
            nets.push(trunk.param_count()?);
        }
        for head in &mlps.heads {
            nets.push(head.param_count()?);
        }
        grids
            .into_iter()
            .chain(nets)
            .try_fold(0usize, usize::checked_add)
            .ok_or_else(|| NnError::Config("Grid4D field: parameter count overflows".into()))
    }
}

/// The decoder networks of a [`Grid4dNet`], before they are built.
struct Grid4dMlps {
    attention: MlpConfig,
    temporal: MlpConfig,
    trunk: Option<MlpConfig>,
    heads: Vec<MlpConfig>,
}

/// The Grid4D deformation field.
#[derive(Clone, Debug)]
pub struct Grid4dNet {
    config: Grid4dConfig,
    /// The spatial grid `xyz`.
    pub spatial: HashGrid,
    /// The temporal grids `xyt`, `yzt`, `xzt`.
    pub temporal: [HashGrid; 3],
    /// `W_s`, `b_s` with the sigmoid.
    pub attention: Mlp,
    /// `W_t`, `b_t` with the ReLU.
    pub temporal_mlp: Mlp,
    /// The `depth` layers after the product (absent at depth 0).
    pub trunk: Option<Mlp>,
    /// One linear layer per head, in output order.
    pub heads: Vec<Mlp>,
}

/// Cache of [`Grid4dNet::forward`].
#[derive(Clone, Debug, Default)]
pub struct Grid4dCache {
    rows: usize,
    positions: Vec<f32>,
    /// Encoder inputs `(x, y, z, t')` per row.
    xyzt: Vec<f32>,
    spatial: Option<HashGridCache>,
    temporal: Vec<HashGridCache>,
    attention: Option<MlpCache>,
    /// `2σ − 1` (or `σ`).
    a: Vec<f32>,
    temporal_mlp: Option<MlpCache>,
    /// `ReLU(W_t e + b_t)`.
    r: Vec<f32>,
    trunk: Option<MlpCache>,
    heads: Vec<MlpCache>,
    /// The position head's linear outputs (7 per row), when it has one.
    warp: Vec<f32>,
}

impl Grid4dCache {
    /// Rows of the forward pass.
    pub fn rows(&self) -> usize {
        self.rows
    }
    /// The encoder inputs `(x, y, z, t')`, rows × 4.
    pub fn encoder_inputs(&self) -> &[f32] {
        &self.xyzt
    }
}

/// Gradients of [`Grid4dNet::backward`], one buffer per [`Parameters`] entry, same order.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid4dGrads {
    /// dL/d(spatial table).
    pub spatial: Vec<f32>,
    /// dL/d(temporal tables) `xyt`, `yzt`, `xzt`.
    pub temporal: [Vec<f32>; 3],
    /// dL/d(attention layer).
    pub attention: Vec<f32>,
    /// dL/d(temporal layer).
    pub temporal_mlp: Vec<f32>,
    /// dL/d(trunk) (empty at depth 0).
    pub trunk: Vec<f32>,
    /// dL/d(heads), output order.
    pub heads: Vec<Vec<f32>>,
}

impl Grid4dGrads {
    /// The buffers in [`Parameters`] order.
    pub fn into_buffers(self) -> Vec<Vec<f32>> {
        let mut v = vec![self.spatial];
        v.extend(self.temporal);
        v.push(self.attention);
        v.push(self.temporal_mlp);
        if !self.trunk.is_empty() {
            v.push(self.trunk);
        }
        v.extend(self.heads);
        v
    }
}

/// Which coordinates of `(x, y, z, t')` each temporal grid reads.
const TEMPORAL_AXES: [[usize; 3]; 3] = [[0, 1, 3], [1, 2, 3], [0, 2, 3]];
/// The temporal grids' names.
const TEMPORAL_NAMES: [&str; 3] = ["grid_xyt", "grid_yzt", "grid_xzt"];

/// `R(q) x − x` for the unnormalised quaternion `q = (r, i, j, k)` (`quaternion_to_matrix`),
/// with `M(q) x` and `s = 2 / |q|²` so that `R(q) x − x = s · M(q) x`.
#[inline]
fn rotate_delta(q: [f32; 4], x: [f32; 3]) -> ([f32; 3], [f32; 3], f32) {
    let [r, i, j, k] = q;
    let n = (r * r + i * i + j * j + k * k).max(MIN_QUAT_NORM2);
    let s = 2.0 / n;
    let m = [
        [-(j * j + k * k), i * j - k * r, i * k + j * r],
        [i * j + k * r, -(i * i + k * k), j * k - i * r],
        [i * k - j * r, j * k + i * r, -(i * i + j * j)],
    ];
    let v = [0, 1, 2].map(|p| m[p][0] * x[0] + m[p][1] * x[1] + m[p][2] * x[2]);
    (v.map(|e| s * e), v, n)
}

/// dL/dq of `s · M(q) x` given `g = dL/d(delta)`: `s · gᵀ(∂M/∂q_a)x − s · (2 q_a / |q|²) · g·v`.
#[inline]
fn rotate_delta_backward(q: [f32; 4], x: [f32; 3], g: [f32; 3]) -> [f32; 4] {
    let [r, i, j, k] = q;
    let (_, v, n) = rotate_delta(q, x);
    let s = 2.0 / n;
    // gᵀ (∂M/∂q_a) x = Σ_pq g_p x_q ∂M_pq/∂q_a.
    let o = |p: usize, c: usize| g[p] * x[c];
    let d_r = -k * o(0, 1) + j * o(0, 2) + k * o(1, 0) - i * o(1, 2) - j * o(2, 0) + i * o(2, 1);
    let d_i = j * o(0, 1) + k * o(0, 2) + j * o(1, 0) - 2.0 * i * o(1, 1) - r * o(1, 2)
        + k * o(2, 0)
        + r * o(2, 1)
        - 2.0 * i * o(2, 2);
    let d_j = -2.0 * j * o(0, 0) + i * o(0, 1) + r * o(0, 2) + i * o(1, 0) + k * o(1, 2)
        - r * o(2, 0)
        + k * o(2, 1)
        - 2.0 * j * o(2, 2);
    let d_k = -2.0 * k * o(0, 0) - r * o(0, 1) + i * o(0, 2) + r * o(1, 0) - 2.0 * k * o(1, 1)
        + j * o(1, 2)
        + i * o(2, 0)
        + j * o(2, 1);
    let gv = g[0] * v[0] + g[1] * v[1] + g[2] * v[2];
    // Below the floor |q|² is a constant: no normalisation term.
    let floored = r * r + i * i + j * j + k * k < MIN_QUAT_NORM2;
    let d = [d_r, d_i, d_j, d_k];
    let q = [r, i, j, k];
    std::array::from_fn(|a| {
        let norm_term = if floored { 0.0 } else { 2.0 * q[a] / n * gv };
        s * (d[a] - norm_term)
    })
}

impl Grid4dNet {
    /// Builds the field. Errors on grids that are not 3D, a time span outside (0, 1], a zero
    /// width, no heads or a repeated head, or a bad regulariser setting.
    pub fn new(config: Grid4dConfig) -> Result<Self, NnError> {
        let bad = |m: &str| Err(NnError::Config(format!("Grid4D field: {m}")));
        if config.spatial.dims != 3 || config.temporal.dims != 3 {
            return bad("the spatial and temporal grids take 3 coordinates");
        }
        if !(config.time_span > 0.0 && config.time_span <= 1.0) {
            return bad("time_span must lie in (0, 1]");
        }
        if config.width == 0 {
            return bad("width 0");
        }
        if config.heads.is_empty() {
            return bad("no heads");
        }
        for (i, h) in config.heads.iter().enumerate() {
            if config.heads[..i].contains(h) {
                return bad(&format!("head {h:?} twice"));
            }
        }
        let sm = &config.smoothness;
        let ranges_ok = sm
            .spatial_range
            .iter()
            .chain(&sm.temporal_range)
            .all(|v| v.is_finite() && *v >= 0.0);
        if !(sm.spatial_weight.is_finite()
            && sm.spatial_weight >= 0.0
            && sm.temporal_weight.is_finite()
            && sm.temporal_weight >= 0.0
            && sm.sample_ratio > 0.0
            && sm.sample_ratio <= 1.0
            && ranges_ok)
        {
            return bad(
                "smoothness weights and ranges must be finite and >= 0, the ratio in (0, 1]",
            );
        }
        let spatial = config.spatial.clone().build()?;
        let temporal_grid = |i: u64| {
            let c = config.temporal.clone();
            let seed = c.seed.wrapping_add(i);
            c.seed(seed).build()
        };
        let temporal = [temporal_grid(1)?, temporal_grid(2)?, temporal_grid(3)?];
        let mlps = config.mlps();
        let attention = mlps.attention.build()?;
        let temporal_mlp = mlps.temporal.build()?;
        let trunk = mlps.trunk.map(MlpConfig::build).transpose()?;
        let heads = mlps
            .heads
            .into_iter()
            .map(MlpConfig::build)
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            config,
            spatial,
            temporal,
            attention,
            temporal_mlp,
            trunk,
            heads,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &Grid4dConfig {
        &self.config
    }

    /// Values per output row.
    pub fn output_width(&self) -> usize {
        self.config.output_width()
    }

    /// The encoder's time coordinate of `t`: `(2t − 1) · bound · span`.
    pub fn encoder_time(&self, t: f32) -> f32 {
        let bound = self.config.temporal.box_max[2];
        (2.0 * t - 1.0) * bound * self.config.time_span
    }

    /// Deformations of `rows` points: `positions` rows × 3, `times` one per row. Returns rows ×
    /// [`Grid4dNet::output_width`].
    pub fn forward(
        &self,
        positions: &[f32],
        times: &[f32],
        rows: usize,
    ) -> Result<(Vec<f32>, Grid4dCache), NnError> {
        let mut cache = Grid4dCache::default();
        let out = self.forward_into(positions, times, rows, &mut cache)?;
        Ok((out, cache))
    }

    /// [`Grid4dNet::forward`] into a cache of an earlier pass (its memory is reused).
    pub fn forward_into(
        &self,
        positions: &[f32],
        times: &[f32],
        rows: usize,
        cache: &mut Grid4dCache,
    ) -> Result<Vec<f32>, NnError> {
        check_len("Grid4D field positions", rows * 3, positions.len())?;
        check_len("Grid4D field times", rows, times.len())?;
        if let Some(i) = times.iter().position(|t| !t.is_finite()) {
            return Err(NnError::Config(format!(
                "Grid4D field times: row {i} is not finite"
            )));
        }
        cache.rows = rows;
        cache.positions.clear();
        cache.positions.extend_from_slice(positions);
        cache.xyzt.clear();
        cache.xyzt.extend(
            positions
                .chunks_exact(3)
                .zip(times)
                .flat_map(|(p, &t)| [p[0], p[1], p[2], self.encoder_time(t)]),
        );
        let (s, spatial) = self.spatial.forward(positions, rows)?;
        let (e, temporal) = self.encode_temporal(&cache.xyzt, rows)?;
        let (mut a, attention) = self.attention.forward(&s, rows)?;
        if self.config.directional {
            for v in &mut a {
                *v = 2.0 * *v - 1.0;
            }
        }
        let (r, temporal_mlp) = self.temporal_mlp.forward(&e, rows)?;
        let h: Vec<f32> = a.iter().zip(&r).map(|(x, y)| x * y).collect();
        let (h, trunk) = match &self.trunk {
            Some(t) => {
                let (y, c) = t.forward(&h, rows)?;
                (y, Some(c))
            }
            None => (h, None),
        };
        let width = self.output_width();
        let mut out = vec![0f32; rows * width];
        cache.heads.clear();
        cache.warp.clear();
        let mut col = 0;
        for (head, kind) in self.heads.iter().zip(&self.config.heads) {
            let (y, c) = head.forward(&h, rows)?;
            let lw = kind.linear_width();
            if *kind == Grid4dHead::Position {
                for ((orow, y), x) in out
                    .chunks_exact_mut(width)
                    .zip(y.chunks_exact(lw))
                    .zip(positions.chunks_exact(3))
                {
                    let q = [y[0] + 1.0, y[1], y[2], y[3]];
                    let (d, _, _) = rotate_delta(q, [x[0], x[1], x[2]]);
                    for c in 0..3 {
                        orow[col + c] = d[c] + y[4 + c];
                    }
                }
                cache.warp = y;
            } else {
                for (orow, y) in out.chunks_exact_mut(width).zip(y.chunks_exact(lw)) {
                    orow[col..col + lw].copy_from_slice(y);
                }
            }
            cache.heads.push(c);
            col += kind.width();
        }
        cache.spatial = Some(spatial);
        cache.temporal = temporal;
        cache.attention = Some(attention);
        cache.a = a;
        cache.temporal_mlp = Some(temporal_mlp);
        cache.r = r;
        cache.trunk = trunk;
        Ok(out)
    }

    /// The three temporal grids' features of `xyzt` rows (rows × 4), concatenated per row.
    fn encode_temporal(
        &self,
        xyzt: &[f32],
        rows: usize,
    ) -> Result<(Vec<f32>, Vec<HashGridCache>), NnError> {
        let w = self.temporal[0].output_width();
        let mut e = vec![0f32; rows * 3 * w];
        let mut caches = Vec::with_capacity(3);
        for (g, (grid, axes)) in self.temporal.iter().zip(&TEMPORAL_AXES).enumerate() {
            let x: Vec<f32> = xyzt
                .chunks_exact(4)
                .flat_map(|p| axes.map(|a| p[a]))
                .collect();
            let (f, c) = grid.forward(&x, rows)?;
            for (erow, frow) in e.chunks_exact_mut(3 * w).zip(f.chunks_exact(w)) {
                erow[g * w..(g + 1) * w].copy_from_slice(frow);
            }
            caches.push(c);
        }
        Ok((e, caches))
    }

    /// Table gradients of the temporal grids from dL/d(e) (rows × 3 · L_t · F).
    fn temporal_backward(
        &self,
        caches: &[HashGridCache],
        d_e: &[f32],
    ) -> Result<[Vec<f32>; 3], NnError> {
        let w = self.temporal[0].output_width();
        let mut out: [Vec<f32>; 3] = Default::default();
        for (g, (grid, cache)) in self.temporal.iter().zip(caches).enumerate() {
            let d: Vec<f32> = d_e
                .chunks_exact(3 * w)
                .flat_map(|r| r[g * w..(g + 1) * w].iter().copied())
                .collect();
            out[g] = grid.backward(cache, &d, false)?.params;
        }
        Ok(out)
    }

    /// Backward from dL/d(output) (rows × [`Grid4dNet::output_width`]); no gradient to the inputs
    /// (Grid4D feeds the field the detached means, as D-3DGS).
    pub fn backward(&self, cache: &Grid4dCache, d_out: &[f32]) -> Result<Grid4dGrads, NnError> {
        let rows = cache.rows;
        let width = self.output_width();
        check_len("Grid4D field output gradient", rows * width, d_out.len())?;
        let missing = || NnError::Config("Grid4D field: backward without a forward".into());
        let w = self.config.width;
        let mut d_h = vec![0f32; rows * w];
        let mut head_grads = Vec::with_capacity(self.heads.len());
        let mut col = 0;
        for ((head, kind), hc) in self.heads.iter().zip(&self.config.heads).zip(&cache.heads) {
            let lw = kind.linear_width();
            let d_y: Vec<f32> = if *kind == Grid4dHead::Position {
                let mut d = vec![0f32; rows * lw];
                for (((drow, grow), y), x) in d
                    .chunks_exact_mut(lw)
                    .zip(d_out.chunks_exact(width))
                    .zip(cache.warp.chunks_exact(lw))
                    .zip(cache.positions.chunks_exact(3))
                {
                    let g = [grow[col], grow[col + 1], grow[col + 2]];
                    let q = [y[0] + 1.0, y[1], y[2], y[3]];
                    let dq = rotate_delta_backward(q, [x[0], x[1], x[2]], g);
                    drow[..4].copy_from_slice(&dq);
                    drow[4..].copy_from_slice(&g);
                }
                d
            } else {
                d_out
                    .chunks_exact(width)
                    .flat_map(|r| r[col..col + lw].iter().copied())
                    .collect()
            };
            let g = head.backward(hc, &d_y, true)?;
            let dx = g.input.ok_or_else(missing)?;
            d_h.iter_mut().zip(&dx).for_each(|(a, b)| *a += b);
            head_grads.push(g.params);
            col += kind.width();
        }
        let (d_prod, trunk) = match (&self.trunk, &cache.trunk) {
            (Some(t), Some(c)) => {
                let g = t.backward(c, &d_h, true)?;
                (g.input.ok_or_else(missing)?, g.params)
            }
            _ => (d_h, Vec::new()),
        };
        // h = a ⊙ r: dL/da = dL/dh ⊙ r, dL/dr = dL/dh ⊙ a; a = 2σ − 1 gives dL/dσ = 2 dL/da.
        let scale = if self.config.directional { 2.0 } else { 1.0 };
        let d_sigma: Vec<f32> = d_prod
            .iter()
            .zip(&cache.r)
            .map(|(d, r)| scale * d * r)
            .collect();
        let d_r: Vec<f32> = d_prod.iter().zip(&cache.a).map(|(d, a)| d * a).collect();
        let ga = self.attention.backward(
            cache.attention.as_ref().ok_or_else(missing)?,
            &d_sigma,
            true,
        )?;
        let gt = self.temporal_mlp.backward(
            cache.temporal_mlp.as_ref().ok_or_else(missing)?,
            &d_r,
            true,
        )?;
        let spatial = self
            .spatial
            .backward(
                cache.spatial.as_ref().ok_or_else(missing)?,
                &ga.input.ok_or_else(missing)?,
                false,
            )?
            .params;
        let temporal = self.temporal_backward(&cache.temporal, &gt.input.ok_or_else(missing)?)?;
        Ok(Grid4dGrads {
            spatial,
            temporal,
            attention: ga.params,
            temporal_mlp: gt.params,
            trunk,
            heads: head_grads,
        })
    }

    /// Grid4D's smoothness regulariser on the rows of `cache`: for the spatial term, rows
    /// `spatial_rows` moved by `spatial_jitter` (one value in [-1, 1] per row and axis, times
    /// [`Grid4dSmoothness::spatial_range`]); for the temporal term, rows `temporal_rows` moved by
    /// `temporal_jitter` (4 per row, times `temporal_range`, on `(x, y, z, t')`). Each term is
    /// `weight · mean over its rows of Σ_features (f(moved) − f(row))²`. The gradients are added
    /// to `grads`' tables; returns the weighted sum of both terms. A term with weight 0 or no rows
    /// adds nothing.
    pub fn smoothness(
        &self,
        cache: &Grid4dCache,
        spatial_rows: &[usize],
        spatial_jitter: &[f32],
        temporal_rows: &[usize],
        temporal_jitter: &[f32],
        grads: &mut Grid4dGrads,
    ) -> Result<f64, NnError> {
        let sm = &self.config.smoothness;
        check_len(
            "Grid4D spatial jitter",
            spatial_rows.len() * 3,
            spatial_jitter.len(),
        )?;
        check_len(
            "Grid4D temporal jitter",
            temporal_rows.len() * 4,
            temporal_jitter.len(),
        )?;
        if let Some(&r) = spatial_rows
            .iter()
            .chain(temporal_rows)
            .find(|&&r| r >= cache.rows)
        {
            return Err(NnError::Config(format!(
                "Grid4D smoothness: row {r} of {}",
                cache.rows
            )));
        }
        let mut total = 0f64;
        // Both encodings of a term go through one forward and one backward: the m original rows
        // first, then the m moved rows.
        let m = spatial_rows.len();
        if sm.spatial_weight > 0.0 && m > 0 {
            let mut x = Vec::with_capacity(2 * m * 3);
            for &r in spatial_rows {
                x.extend_from_slice(&cache.xyzt[r * 4..r * 4 + 3]);
            }
            for (&r, j) in spatial_rows.iter().zip(spatial_jitter.chunks_exact(3)) {
                let at = &cache.xyzt[r * 4..r * 4 + 3];
                x.extend(
                    at.iter()
                        .zip(j)
                        .zip(&sm.spatial_range)
                        .map(|((v, j), range)| v + j * range),
                );
            }
            let (f, c) = self.spatial.forward(&x, 2 * m)?;
            let (value, d) = pair_difference(&f, m, sm.spatial_weight);
            total += value;
            let g = self.spatial.backward(&c, &d, false)?.params;
            grads.spatial.iter_mut().zip(&g).for_each(|(a, b)| *a += b);
        }
        let m = temporal_rows.len();
        if sm.temporal_weight > 0.0 && m > 0 {
            let mut x = Vec::with_capacity(2 * m * 4);
            for &r in temporal_rows {
                x.extend_from_slice(&cache.xyzt[r * 4..r * 4 + 4]);
            }
            for (&r, j) in temporal_rows.iter().zip(temporal_jitter.chunks_exact(4)) {
                let at = &cache.xyzt[r * 4..r * 4 + 4];
                x.extend(
                    at.iter()
                        .zip(j)
                        .zip(&sm.temporal_range)
                        .map(|((v, j), range)| v + j * range),
                );
            }
            let (e, caches) = self.encode_temporal(&x, 2 * m)?;
            let (value, d) = pair_difference(&e, m, sm.temporal_weight);
            total += value;
            let g = self.temporal_backward(&caches, &d)?;
            for (dst, src) in grads.temporal.iter_mut().zip(&g) {
                dst.iter_mut().zip(src).for_each(|(a, b)| *a += b);
            }
        }
        Ok(total)
    }

    /// The plain f64 reference of the forward pass of one row, for tests: every parameter
    /// buffer given in f64 ([`Parameters`] order), the position `x` and time `t`.
    pub fn reference_forward(&self, params: &[Vec<f64>], x: [f64; 3], t: f64) -> Vec<f64> {
        let bound = self.config.temporal.box_max[2] as f64;
        let tt = (2.0 * t - 1.0) * bound * self.config.time_span as f64;
        let xyzt = [x[0], x[1], x[2], tt];
        let s = self.spatial.reference_encode(&params[0], &x);
        let mut e = Vec::new();
        for (g, axes) in TEMPORAL_AXES.iter().enumerate() {
            let xin = axes.map(|a| xyzt[a]);
            e.extend(self.temporal[g].reference_encode(&params[1 + g], &xin));
        }
        let linear = |p: &[f64], input: &[f64], out: usize| -> Vec<f64> {
            let n = input.len();
            (0..out)
                .map(|o| p[n * out + o] + (0..n).map(|i| input[i] * p[i * out + o]).sum::<f64>())
                .collect()
        };
        let w = self.config.width;
        let sig = linear(&params[4], &s, w);
        let a: Vec<f64> = sig
            .iter()
            .map(|v| {
                let sg = 1.0 / (1.0 + (-v).exp());
                if self.config.directional {
                    2.0 * sg - 1.0
                } else {
                    sg
                }
            })
            .collect();
        let r: Vec<f64> = linear(&params[5], &e, w)
            .into_iter()
            .map(|v| v.max(0.0))
            .collect();
        let mut h: Vec<f64> = a.iter().zip(&r).map(|(a, r)| a * r).collect();
        let mut next = 6;
        if self.config.depth > 0 {
            let p = &params[next];
            let mut at = 0;
            for _ in 0..self.config.depth {
                let len = w * w + w;
                h = linear(&p[at..at + len], &h, w)
                    .into_iter()
                    .map(|v| v.max(0.0))
                    .collect();
                at += len;
            }
            next += 1;
        }
        let mut out = Vec::new();
        for (i, kind) in self.config.heads.iter().enumerate() {
            let y = linear(&params[next + i], &h, kind.linear_width());
            if *kind == Grid4dHead::Position {
                let q = [y[0] + 1.0, y[1], y[2], y[3]];
                let n: f64 = q.iter().map(|v| v * v).sum();
                let (r, i, j, k) = (q[0], q[1], q[2], q[3]);
                let rot = [
                    [
                        1.0 - 2.0 * (j * j + k * k) / n,
                        2.0 * (i * j - k * r) / n,
                        2.0 * (i * k + j * r) / n,
                    ],
                    [
                        2.0 * (i * j + k * r) / n,
                        1.0 - 2.0 * (i * i + k * k) / n,
                        2.0 * (j * k - i * r) / n,
                    ],
                    [
                        2.0 * (i * k - j * r) / n,
                        2.0 * (j * k + i * r) / n,
                        1.0 - 2.0 * (i * i + j * j) / n,
                    ],
                ];
                for p in 0..3 {
                    let moved: f64 = (0..3).map(|c| rot[p][c] * x[c]).sum::<f64>() + y[4 + p];
                    out.push(moved - x[p]);
                }
            } else {
                out.extend(y);
            }
        }
        out
    }
}

/// `weight / m · Σ (f[m + i] − f[i])²` over the `m` pairs of rows of `f` (original rows first),
/// and its gradient with respect to `f`.
fn pair_difference(f: &[f32], m: usize, weight: f32) -> (f64, Vec<f32>) {
    let w = f.len() / (2 * m);
    let (orig, moved) = f.split_at(m * w);
    let mut d = vec![0f32; f.len()];
    let (d_orig, d_moved) = d.split_at_mut(m * w);
    let scale = weight / m as f32;
    let mut value = 0f64;
    for (((o, v), dg), dm) in orig.iter().zip(moved).zip(d_orig).zip(d_moved) {
        let diff = v - o;
        value += (diff as f64) * (diff as f64);
        *dm = 2.0 * scale * diff;
        *dg = -2.0 * scale * diff;
    }
    (value * weight as f64 / m as f64, d)
}

impl Parameters for Grid4dNet {
    fn named_params(&self) -> Vec<(String, StoreRef<'_>)> {
        let mut v = vec![("grid_xyz".to_string(), self.spatial.params())];
        for (name, g) in TEMPORAL_NAMES.iter().zip(&self.temporal) {
            v.push((name.to_string(), g.params()));
        }
        v.push(("attention".to_string(), self.attention.params()));
        v.push(("temporal".to_string(), self.temporal_mlp.params()));
        if let Some(t) = &self.trunk {
            v.push(("trunk".to_string(), t.params()));
        }
        for (kind, head) in self.config.heads.iter().zip(&self.heads) {
            v.push((kind.name().to_string(), head.params()));
        }
        v
    }
    fn named_params_mut(&mut self) -> Vec<(String, StoreMut<'_>)> {
        let Self {
            config,
            spatial,
            temporal,
            attention,
            temporal_mlp,
            trunk,
            heads,
        } = self;
        let mut v = vec![("grid_xyz".to_string(), spatial.params_mut())];
        for (name, g) in TEMPORAL_NAMES.iter().zip(temporal.iter_mut()) {
            v.push((name.to_string(), g.params_mut()));
        }
        v.push(("attention".to_string(), attention.params_mut()));
        v.push(("temporal".to_string(), temporal_mlp.params_mut()));
        if let Some(t) = trunk {
            v.push(("trunk".to_string(), t.params_mut()));
        }
        for (kind, head) in config.heads.iter().zip(heads.iter_mut()) {
            v.push((kind.name().to_string(), head.params_mut()));
        }
        v
    }
}

/// Whether a parameter buffer of [`Grid4dNet`] is one of its hash tables (Grid4D trains the
/// tables at its `grid_lr_scale`, the MLPs at its `network_lr_scale`).
pub fn is_grid4d_table(name: &str) -> bool {
    name.starts_with("grid_")
}
