//! Batched multi-layer perceptron: forward with a cache, backward to inputs and parameters.
//!
//! Layout: rows are samples; every matrix is row-major N × width. Layer `l` computes
//! `y = act(x · W + b)` with `W` stored row-major as `in × out`. Parameters of all layers live in
//! one flat buffer, per layer `W` then `b`, so one optimiser group covers a network.
//!
//! With a skip after hidden layer `s` (D-3DGS: `skip_after = Some(4)` with 8 hidden layers), the
//! next layer's input is the concatenation `[x, h_s]` (network input first, as D-3DGS's
//! `torch.cat([x_emb, h])`).
//!
//! Rows are processed in blocks of [`ROW_BLOCK`] ([`BACKWARD_BLOCK`] backward) in parallel
//! (rayon); each block runs the whole
//! network with single-threaded `gemm` calls on f32 scratch, so the matrix work is fused with the
//! bias, the activation and the conversion to storage precision.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use crate::reduce::{add_into, fold_in_order};

use crate::activation::Activation;
use crate::error::{NnError, check_len};
use crate::linalg::{matmul, matmul_a_bt, matmul_at_b};
use crate::precision::{Precision, Store, StoreMut, StoreRef};
use gemm::Parallelism;

/// Rows per parallel block.
pub const ROW_BLOCK: usize = 256;

/// Rows per parallel block in the backward pass (longer blocks give the weight-gradient
/// products a longer inner dimension).
pub const BACKWARD_BLOCK: usize = 1024;

/// How the hidden layers of an [`Mlp`] start (the output layer: [`MlpConfig::zero_output`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Init {
    /// PyTorch's `nn.Linear` default on every layer, `W, b ~ U(-1/√in, 1/√in)` (D-3DGS). Each
    /// ReLU layer then keeps about 1/6 of its input's second moment, so after 8 layers the output
    /// hardly depends on the input until training has grown the weights.
    #[default]
    Torch,
    /// He (Kaiming-uniform for ReLU) hidden layers, `W ~ U(-√(6/in), √(6/in))`, `b = 0`: the
    /// activations keep their second moment through depth, so the output depends on the input
    /// from the first step. The output layer is still PyTorch's default (or zero).
    He,
}

/// Shape and settings of an [`Mlp`]. Build with [`MlpConfig::new`] and the chained setters.
#[derive(Clone, Debug, PartialEq)]
pub struct MlpConfig {
    /// Input width.
    pub input: usize,
    /// Width of every hidden layer.
    pub width: usize,
    /// Number of hidden layers (each Linear + `hidden_activation`); 0 gives one linear layer.
    pub hidden_layers: usize,
    /// Output width.
    pub output: usize,
    /// Activation after every hidden layer.
    pub hidden_activation: Activation,
    /// Activation after the output layer.
    pub output_activation: Activation,
    /// Re-concatenate the input after this hidden layer (0-based).
    pub skip_after: Option<usize>,
    /// Start the output layer's weights and bias at zero.
    pub zero_output: bool,
    /// Initialisation of the hidden layers.
    pub init: Init,
    /// Storage precision of parameters and activations.
    pub precision: Precision,
    /// Seed of the deterministic initialisation.
    pub seed: u64,
}

impl MlpConfig {
    /// `input → [width; hidden_layers] → output`, ReLU hidden, identity output, no skip,
    /// PyTorch-default initialisation, f32, seed 0.
    pub fn new(input: usize, width: usize, hidden_layers: usize, output: usize) -> Self {
        Self {
            input,
            width,
            hidden_layers,
            output,
            hidden_activation: Activation::Relu,
            output_activation: Activation::Identity,
            skip_after: None,
            zero_output: false,
            init: Init::Torch,
            precision: Precision::F32,
            seed: 0,
        }
    }
    /// Sets the hidden activation.
    #[must_use]
    pub fn hidden_activation(mut self, a: Activation) -> Self {
        self.hidden_activation = a;
        self
    }
    /// Sets the output activation.
    #[must_use]
    pub fn output_activation(mut self, a: Activation) -> Self {
        self.output_activation = a;
        self
    }
    /// Re-concatenates the input after hidden layer `layer` (0-based).
    #[must_use]
    pub fn skip_after(mut self, layer: usize) -> Self {
        self.skip_after = Some(layer);
        self
    }
    /// Starts the output layer at zero.
    #[must_use]
    pub fn zero_output(mut self, zero: bool) -> Self {
        self.zero_output = zero;
        self
    }
    /// Sets the hidden layers' initialisation.
    #[must_use]
    pub fn init(mut self, init: Init) -> Self {
        self.init = init;
        self
    }
    /// Sets the storage precision.
    #[must_use]
    pub fn precision(mut self, p: Precision) -> Self {
        self.precision = p;
        self
    }
    /// Sets the initialisation seed.
    #[must_use]
    pub fn seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }
    /// Builds the network.
    pub fn build(self) -> Result<Mlp, NnError> {
        Mlp::new(self)
    }

    /// The parameters the network will have, without allocating them (sizes multiply with
    /// checked arithmetic: an overflow is an error). The same layout [`Mlp::new`] builds.
    pub fn param_count(&self) -> Result<usize, NnError> {
        Ok(self.layout()?.1)
    }

    /// Checks the shape and lays the layers out in the flat parameter buffer: the layers and
    /// the buffer's length.
    fn layout(&self) -> Result<(Vec<LayerShape>, usize), NnError> {
        if self.input == 0 || self.output == 0 {
            return Err(NnError::Config(
                "MLP input and output widths must be > 0".into(),
            ));
        }
        if self.hidden_layers > 0 && self.width == 0 {
            return Err(NnError::Config("MLP hidden width must be > 0".into()));
        }
        if let Some(s) = self.skip_after
            && s >= self.hidden_layers
        {
            return Err(NnError::Config(format!(
                "skip_after = {s} but the MLP has {} hidden layers",
                self.hidden_layers
            )));
        }
        let too_large = || NnError::Config("MLP parameter count overflows".into());
        let mut layers = Vec::with_capacity(self.hidden_layers.saturating_add(1).min(1 << 16));
        let mut offset: usize = 0;
        for l in 0..=self.hidden_layers {
            let skip_input = l > 0 && self.skip_after == Some(l - 1);
            let input = match (l, skip_input) {
                (0, _) => self.input,
                (_, true) => self.width.checked_add(self.input).ok_or_else(too_large)?,
                _ => self.width,
            };
            let output = if l == self.hidden_layers {
                self.output
            } else {
                self.width
            };
            let weights = input.checked_mul(output).ok_or_else(too_large)?;
            layers.push(LayerShape {
                input,
                output,
                weight_offset: offset,
                bias_offset: offset.checked_add(weights).ok_or_else(too_large)?,
                skip_input,
            });
            offset = weights
                .checked_add(output)
                .and_then(|n| n.checked_add(offset))
                .ok_or_else(too_large)?;
        }
        Ok((layers, offset))
    }
}

/// One linear layer's place in the flat parameter buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LayerShape {
    /// Input width (includes the skip input where there is one).
    pub input: usize,
    /// Output width.
    pub output: usize,
    /// Offset of `W` (row-major `input × output`) in the parameter buffer.
    pub weight_offset: usize,
    /// Offset of `b` (`output` values) in the parameter buffer.
    pub bias_offset: usize,
    /// True when this layer's input is `[x, h]` (the skip).
    pub skip_input: bool,
}

/// A batched MLP. See the module docs for the layout.
#[derive(Clone, Debug)]
pub struct Mlp {
    config: MlpConfig,
    layers: Vec<LayerShape>,
    params: Store,
}

/// What [`Mlp::forward`] keeps for [`Mlp::backward`]: the input and every layer's output, in the
/// network's storage precision. `MlpCache::default()` is an empty cache for
/// [`Mlp::forward_into`].
#[derive(Clone, Debug, Default)]
pub struct MlpCache {
    rows: usize,
    input: Store,
    acts: Vec<Store>,
    saturated: u64,
}

impl MlpCache {
    /// Number of rows of the forward pass.
    pub fn rows(&self) -> usize {
        self.rows
    }
    /// The outputs of the forward pass (rows × output, storage precision).
    pub(crate) fn output(&self) -> StoreRef<'_> {
        self.acts.last().map_or(StoreRef::F32(&[]), Store::as_ref)
    }
    /// Values that saturated at ±65504 when stored in f16 during the forward pass (always 0 for
    /// f32 storage).
    pub fn saturations(&self) -> u64 {
        self.saturated
    }
}

/// Gradients from [`Mlp::backward`].
#[derive(Clone, Debug, PartialEq)]
pub struct MlpGrads {
    /// dL/dθ, laid out as the parameter buffer (f32).
    pub params: Vec<f32>,
    /// dL/dx, N × input (present when asked for).
    pub input: Option<Vec<f32>>,
}

impl Mlp {
    /// Builds and initialises a network from a ChaCha8 stream seeded by `config.seed`: every
    /// layer `W, b ~ U(-1/√in, 1/√in)` (PyTorch's `nn.Linear` default), or the hidden layers He
    /// with zero bias ([`Init::He`]); the output layer is zero when `config.zero_output`.
    pub fn new(config: MlpConfig) -> Result<Self, NnError> {
        let (layers, offset) = config.layout()?;
        let mut values = vec![0f32; offset];
        let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
        for (l, shape) in layers.iter().enumerate() {
            if l == config.hidden_layers && config.zero_output {
                continue;
            }
            let he = config.init == Init::He && l < config.hidden_layers;
            let bound = if he {
                (6.0 / shape.input as f32).sqrt()
            } else {
                1.0 / (shape.input as f32).sqrt()
            };
            // He: weights only, the bias stays zero.
            let end = if he {
                shape.bias_offset
            } else {
                shape.bias_offset + shape.output
            };
            for v in &mut values[shape.weight_offset..end] {
                *v = rng.random_range(-bound..bound);
            }
        }
        let (params, _) = Store::from_f32(config.precision, &values);
        Ok(Self {
            config,
            layers,
            params,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &MlpConfig {
        &self.config
    }
    /// Input width.
    pub fn input_width(&self) -> usize {
        self.config.input
    }
    /// Output width.
    pub fn output_width(&self) -> usize {
        self.config.output
    }
    /// Storage precision.
    pub fn precision(&self) -> Precision {
        self.config.precision
    }
    /// The linear layers in order.
    pub fn layers(&self) -> &[LayerShape] {
        &self.layers
    }
    /// Number of parameters.
    pub fn param_count(&self) -> usize {
        self.params.len()
    }
    /// The flat parameter buffer (read-only).
    pub fn params(&self) -> StoreRef<'_> {
        self.params.as_ref()
    }
    /// The flat parameter buffer, for an optimiser step.
    pub fn params_mut(&mut self) -> StoreMut<'_> {
        self.params.as_mut()
    }
    /// Replaces every parameter from f32 values (rounded, saturating, for f16); returns the
    /// number of saturated values.
    pub fn set_params(&mut self, values: &[f32]) -> Result<u64, NnError> {
        check_len("MLP parameters", self.params.len(), values.len())?;
        Ok(self.params.as_mut().write_from(values))
    }
    /// Multiply-adds of one forward pass over one row (×2 for FLOPs).
    pub fn macs_per_row(&self) -> usize {
        self.layers.iter().map(|l| l.input * l.output).sum()
    }
    /// Forward pass over `rows` rows of `x` (row-major rows × input). Returns the outputs
    /// (rows × output, rounded to f16 values in f16 storage) and the cache for backward.
    pub fn forward(&self, x: &[f32], rows: usize) -> Result<(Vec<f32>, MlpCache), NnError> {
        check_len("MLP input", rows * self.config.input, x.len())?;
        let ni = self.config.input;
        Ok(self.forward_with(rows, |r0, nr, buf| {
            buf.copy_from_slice(&x[r0 * ni..(r0 + nr) * ni]);
        }))
    }

    /// Forward pass whose input rows are produced block by block: `fill(r0, nr, buf)` writes rows
    /// `r0..r0 + nr` (row-major, `nr × input`) into `buf`. Lets an encoder feed the network
    /// without materialising its whole output. Blocks run in parallel.
    pub fn forward_with<F>(&self, rows: usize, fill: F) -> (Vec<f32>, MlpCache)
    where
        F: Fn(usize, usize, &mut [f32]) + Sync,
    {
        let mut cache = MlpCache::default();
        let out = self.forward_into(rows, fill, &mut cache);
        (out, cache)
    }

    /// [`Mlp::forward_with`] writing into an existing cache, whose buffers are reused (a training
    /// loop that keeps its cache avoids reallocating, and page-faulting, hundreds of MB per
    /// step). Any cache may be passed; it is overwritten.
    pub fn forward_into<F>(&self, rows: usize, fill: F, cache: &mut MlpCache) -> Vec<f32>
    where
        F: Fn(usize, usize, &mut [f32]) + Sync,
    {
        self.forward_cached(rows, fill, cache);
        cache.acts.last().map(Store::to_f32_vec).unwrap_or_default()
    }

    /// [`Mlp::forward_into`] without copying the outputs out of the cache (read them with
    /// [`MlpCache::output`]).
    pub(crate) fn forward_cached<F>(&self, rows: usize, fill: F, cache: &mut MlpCache)
    where
        F: Fn(usize, usize, &mut [f32]) + Sync,
    {
        let p = self.config.precision;
        let ni = self.config.input;
        let weights = self.params.as_f32();
        cache.rows = rows;
        cache.input.resize_for(p, rows * ni);
        cache
            .acts
            .resize_with(self.layers.len(), || Store::zeros(p, 0));
        for (act, layer) in cache.acts.iter_mut().zip(&self.layers) {
            act.resize_for(p, rows * layer.output);
        }
        let MlpCache { input, acts, .. } = cache;
        let n_blocks = rows.div_ceil(ROW_BLOCK);
        let mut blocks: Vec<Vec<StoreMut<'_>>> = (0..n_blocks).map(|_| Vec::new()).collect();
        for (b, part) in input.chunks_mut(ROW_BLOCK * ni).into_iter().enumerate() {
            blocks[b].push(part);
        }
        for (act, layer) in acts.iter_mut().zip(&self.layers) {
            for (b, part) in act
                .chunks_mut(ROW_BLOCK * layer.output)
                .into_iter()
                .enumerate()
            {
                blocks[b].push(part);
            }
        }
        let saturated: u64 = blocks
            .into_par_iter()
            .enumerate()
            .map_init(Scratch::default, |scr, (b, parts)| {
                let r0 = b * ROW_BLOCK;
                let nr = ROW_BLOCK.min(rows - r0);
                match f32_parts(parts) {
                    Ok(mut parts) => {
                        fill(r0, nr, parts[0]);
                        self.forward_block_f32(&weights, scr, nr, parts);
                        0
                    }
                    Err(parts) => {
                        scr.x.resize(nr * ni, 0.0);
                        fill(r0, nr, &mut scr.x);
                        self.forward_block(&weights, scr, nr, parts)
                    }
                }
            })
            .sum();
        cache.saturated = saturated;
    }

    /// Runs every layer on one block of `nr` rows; `parts[0]` is the input's storage, then one
    /// per layer. Returns the saturation count.
    fn forward_block(
        &self,
        w: &[f32],
        scr: &mut Scratch,
        nr: usize,
        mut parts: Vec<StoreMut<'_>>,
    ) -> u64 {
        let ni = self.config.input;
        let Scratch {
            x, cur, next, cat, ..
        } = scr;
        let mut sat = store_rounded(&mut parts[0], x);
        let last = self.layers.len() - 1;
        for (l, layer) in self.layers.iter().enumerate() {
            let input: &[f32] = if l == 0 {
                x
            } else if layer.skip_input {
                concat_rows(x, ni, cur, layer.input - ni, nr, cat);
                cat
            } else {
                cur
            };
            next.resize(nr * layer.output, 0.0);
            matmul(
                next,
                input,
                &w[layer.weight_offset..layer.bias_offset],
                (nr, layer.input, layer.output),
                false,
                Parallelism::None,
            );
            let bias = &w[layer.bias_offset..layer.bias_offset + layer.output];
            self.activation(l == last).apply_with_bias(next, bias);
            sat += store_rounded(&mut parts[l + 1], next);
            std::mem::swap(cur, next);
        }
        sat
    }

    /// The activation after layer `l`: the output activation for the last layer.
    fn activation(&self, last: bool) -> Activation {
        if last {
            self.config.output_activation
        } else {
            self.config.hidden_activation
        }
    }

    /// [`Mlp::forward_block`] for f32 storage: every product writes straight into the cache's
    /// block (`parts[0]` already holds the input), bias and activation are applied there in one
    /// pass, and the next layer reads it from there; no scratch copies.
    fn forward_block_f32(
        &self,
        w: &[f32],
        scr: &mut Scratch,
        nr: usize,
        mut parts: Vec<&mut [f32]>,
    ) {
        let ni = self.config.input;
        let last = self.layers.len() - 1;
        for (l, layer) in self.layers.iter().enumerate() {
            let (done, rest) = parts.split_at_mut(l + 1);
            let out = &mut *rest[0];
            let input: &[f32] = if layer.skip_input {
                concat_rows(done[0], ni, done[l], layer.input - ni, nr, &mut scr.cat);
                &scr.cat
            } else {
                done[l]
            };
            matmul(
                out,
                input,
                &w[layer.weight_offset..layer.bias_offset],
                (nr, layer.input, layer.output),
                false,
                Parallelism::None,
            );
            let bias = &w[layer.bias_offset..layer.bias_offset + layer.output];
            self.activation(l == last).apply_with_bias(out, bias);
        }
    }

    /// Checks that `cache` and `d_out` fit this network.
    fn check_backward(&self, cache: &MlpCache, d_out: &[f32]) -> Result<(), NnError> {
        check_len(
            "MLP output gradient",
            cache.rows * self.config.output,
            d_out.len(),
        )?;
        if cache.acts.len() != self.layers.len()
            || cache.input.len() != cache.rows * self.config.input
            || cache.input.precision() != self.config.precision
            || cache
                .acts
                .iter()
                .zip(&self.layers)
                .any(|(a, l)| a.len() != cache.rows * l.output)
        {
            return Err(NnError::Config(
                "MLP cache does not belong to this network".into(),
            ));
        }
        Ok(())
    }

    /// Backward pass: `d_out` is dL/dy (rows × output). Returns dL/dθ and, when
    /// `want_input_grad`, dL/dx. Gradients are f32 whatever the storage precision.
    pub fn backward(
        &self,
        cache: &MlpCache,
        d_out: &[f32],
        want_input_grad: bool,
    ) -> Result<MlpGrads, NnError> {
        self.check_backward(cache, d_out)?;
        let rows = cache.rows;
        let ni = self.config.input;
        let weights = self.params.as_f32();
        let mut d_input = want_input_grad.then(|| vec![0f32; rows * ni]);
        let n_blocks = rows.div_ceil(BACKWARD_BLOCK);
        let dx_blocks: Vec<Option<&mut [f32]>> = match d_input.as_mut() {
            Some(v) => v.chunks_mut(BACKWARD_BLOCK * ni).map(Some).collect(),
            None => (0..n_blocks).map(|_| None).collect(),
        };
        let params = self.backward_blocks(
            &weights,
            cache,
            d_out,
            dx_blocks,
            want_input_grad,
            || (),
            |(), _, dst, dx| {
                if let (Some(dst), Some(dx)) = (dst, dx) {
                    dst.copy_from_slice(dx);
                }
            },
            |(), ()| (),
        );
        Ok(MlpGrads {
            params: params.0,
            input: d_input,
        })
    }

    /// Backward pass that hands each block's input gradient to `consume(acc, r0, dx)` (dx is
    /// `nr × input`, row-major) instead of materialising it; `acc` is a per-task accumulator made
    /// by `init` and merged by `merge`. Returns dL/dθ and the merged accumulator. Lets an encoder
    /// take its gradient block by block.
    pub fn backward_with<A, I, C, M>(
        &self,
        cache: &MlpCache,
        d_out: &[f32],
        init: I,
        consume: C,
        merge: M,
    ) -> Result<(Vec<f32>, A), NnError>
    where
        A: Send,
        I: Fn() -> A + Sync + Send,
        C: Fn(&mut A, usize, &[f32]) + Sync + Send,
        M: Fn(A, A) -> A + Sync + Send,
    {
        self.check_backward(cache, d_out)?;
        let weights = self.params.as_f32();
        let n_blocks = cache.rows.div_ceil(BACKWARD_BLOCK);
        let blocks: Vec<Option<&mut [f32]>> = (0..n_blocks).map(|_| None).collect();
        Ok(self.backward_blocks(
            &weights,
            cache,
            d_out,
            blocks,
            true,
            init,
            |acc, r0, _, dx| {
                if let Some(dx) = dx {
                    consume(acc, r0, dx);
                }
            },
            merge,
        ))
    }

    /// The parallel driver of both backward entry points: `sink(acc, r0, dst, dx)` receives each
    /// block's destination (if any) and input gradient (computed when `want_dx`).
    #[allow(clippy::too_many_arguments)]
    fn backward_blocks<A, I, S, M>(
        &self,
        weights: &[f32],
        cache: &MlpCache,
        d_out: &[f32],
        dsts: Vec<Option<&mut [f32]>>,
        want_dx: bool,
        init: I,
        sink: S,
        merge: M,
    ) -> (Vec<f32>, A)
    where
        A: Send,
        I: Fn() -> A + Sync + Send,
        S: Fn(&mut A, usize, Option<&mut [f32]>, Option<&[f32]>) + Sync + Send,
        M: Fn(A, A) -> A + Sync + Send,
    {
        let rows = cache.rows;
        let n_params = self.params.len();
        let (grads, acc, _) = fold_in_order(
            dsts,
            || (vec![0f32; n_params], init(), Scratch::default()),
            |(mut grads, mut acc, mut scr), (b, dst)| {
                let r0 = b * BACKWARD_BLOCK;
                let nr = BACKWARD_BLOCK.min(rows - r0);
                self.backward_block(weights, cache, d_out, r0, nr, &mut grads, want_dx, &mut scr);
                sink(&mut acc, r0, dst, want_dx.then_some(&scr.dx[..]));
                (grads, acc, scr)
            },
            |(ga, aa, scr), (gb, ab, _)| (add_into(ga, gb), merge(aa, ab), scr),
        );
        (grads, acc)
    }

    /// Backward over one block; accumulates dL/dθ into `grads` and, when `want_dx`, leaves
    /// dL/dx of the block in `scr.dx`.
    #[allow(clippy::too_many_arguments)]
    fn backward_block(
        &self,
        w: &[f32],
        cache: &MlpCache,
        d_out: &[f32],
        r0: usize,
        nr: usize,
        grads: &mut [f32],
        want_dx: bool,
        scr: &mut Scratch,
    ) {
        let ni = self.config.input;
        let last = self.layers.len() - 1;
        let Scratch {
            x,
            cur: g,
            next: da,
            cat: a,
            y,
            dx,
        } = scr;
        let x = cache.input.as_ref().slice(r0 * ni, nr * ni).view_f32(x);
        g.clear();
        g.extend_from_slice(&d_out[r0 * self.config.output..(r0 + nr) * self.config.output]);
        // dx receives the skip layer's share first (if any), then layer 0's product, which
        // gemm adds into it; without a skip, layer 0's product is written straight into it.
        let mut dx_written = false;
        if want_dx {
            dx.resize(nr * ni, 0.0);
        }
        for l in (0..self.layers.len()).rev() {
            let layer = self.layers[l];
            let yv = cache.acts[l]
                .as_ref()
                .slice(r0 * layer.output, nr * layer.output)
                .view_f32(y);
            self.activation(l == last).backward_from_output(yv, g);
            // Layer input: x, the previous activation, or [x, previous activation].
            let input: &[f32] = if l == 0 {
                x
            } else {
                let prev = self.layers[l - 1].output;
                let h = cache.acts[l - 1]
                    .as_ref()
                    .slice(r0 * prev, nr * prev)
                    .view_f32(y);
                if layer.skip_input {
                    concat_rows(x, ni, h, prev, nr, a);
                    a
                } else {
                    h
                }
            };
            matmul_at_b(
                &mut grads[layer.weight_offset..layer.bias_offset],
                input,
                g,
                (layer.input, nr, layer.output),
                true,
                Parallelism::None,
            );
            let db = &mut grads[layer.bias_offset..layer.bias_offset + layer.output];
            for row in g.chunks_exact(layer.output) {
                db.iter_mut().zip(row).for_each(|(d, v)| *d += v);
            }
            if l == 0 && !want_dx {
                break;
            }
            let wl = &w[layer.weight_offset..layer.bias_offset];
            let shape = (nr, layer.output, layer.input);
            if l == 0 {
                matmul_a_bt(dx, g, wl, shape, dx_written, Parallelism::None);
                continue;
            }
            da.resize(nr * layer.input, 0.0);
            matmul_a_bt(da, g, wl, shape, false, Parallelism::None);
            if layer.skip_input {
                let prev = layer.input - ni;
                g.resize(nr * prev, 0.0);
                for r in 0..nr {
                    let src = &da[r * layer.input..(r + 1) * layer.input];
                    if want_dx {
                        dx[r * ni..(r + 1) * ni].copy_from_slice(&src[..ni]);
                    }
                    g[r * prev..(r + 1) * prev].copy_from_slice(&src[ni..]);
                }
                dx_written = want_dx;
            } else {
                std::mem::swap(g, da);
            }
        }
    }
}

/// Per-task scratch buffers, reused across the row blocks one task processes.
#[derive(Default)]
struct Scratch {
    x: Vec<f32>,
    cur: Vec<f32>,
    next: Vec<f32>,
    cat: Vec<f32>,
    y: Vec<f32>,
    dx: Vec<f32>,
}

/// The block's storage parts as f32 slices when they are all f32 (the network's precision is
/// one switch, so they are all or none), else the parts unchanged.
fn f32_parts(parts: Vec<StoreMut<'_>>) -> Result<Vec<&mut [f32]>, Vec<StoreMut<'_>>> {
    if !parts.iter().all(|p| matches!(p, StoreMut::F32(_))) {
        return Err(parts);
    }
    Ok(parts
        .into_iter()
        .filter_map(|p| match p {
            StoreMut::F32(s) => Some(s),
            StoreMut::F16(_) => None,
        })
        .collect())
}

/// Writes `vals` into `store` and, for f16, rounds `vals` to the stored values so the next layer
/// sees exactly what backward will read. Returns the saturation count.
fn store_rounded(store: &mut StoreMut<'_>, vals: &mut [f32]) -> u64 {
    let sat = store.write_from(vals);
    if let StoreMut::F16(_) = store {
        store.as_ref().read_into(vals);
    }
    sat
}

/// Row-wise concatenation `[a, b]` of `nr` rows of widths `wa` and `wb`.
fn concat_rows(a: &[f32], wa: usize, b: &[f32], wb: usize, nr: usize, out: &mut Vec<f32>) {
    out.clear();
    // One allocation at most (not a doubling per row when the buffer is new).
    out.reserve(nr * (wa + wb));
    for r in 0..nr {
        out.extend_from_slice(&a[r * wa..(r + 1) * wa]);
        out.extend_from_slice(&b[r * wb..(r + 1) * wb]);
    }
}

impl crate::weights::Parameters for Mlp {
    fn named_params(&self) -> Vec<(String, StoreRef<'_>)> {
        vec![("params".to_string(), self.params.as_ref())]
    }
    fn named_params_mut(&mut self) -> Vec<(String, StoreMut<'_>)> {
        vec![("params".to_string(), self.params.as_mut())]
    }
}
