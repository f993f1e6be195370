//! `tiny-nn`: tiny batched neural networks on the CPU, with f32 or f16 storage.
//!
//! What it is: batched forward and backward passes over N rows (row-major `N × width` f32 slices
//! at the API) for multi-layer perceptrons ([`Mlp`]), input encoders with gradients (sinusoidal,
//! tri-plane / HexPlane, uniform cubic B-spline over time, multi-resolution hash grid), the Adam
//! optimiser with the 3DGS learning-rate schedule and per-row moment edits ([`Adam`]), and
//! bit-exact safetensors weights files. Matrix
//! products go through the `gemm` crate in f32; rows are split into blocks processed in parallel
//! with rayon. Each network stores its parameters and cached activations in f32 or f16
//! ([`Precision`]), one switch per network, always accumulating in f32; f16 storage saturates at
//! ±65504 instead of overflowing and counts saturations.
//!
//! What it is not: an autodiff framework (each module has a hand-written backward), a GPU
//! backend for every module (with the cargo feature `wgpu`, [`gpu`] runs the MLP and Adam on
//! the device; the encoders stay on the CPU), or a trainer. Losses, schedules of training and data live in other crates.
//!
//! # Modules
//!
//! - [`mlp`]: [`Mlp`] built from [`MlpConfig`] (hidden width and count, activations, optional
//!   D-3DGS skip, zero-initialised output layer, precision, seed). `forward` returns outputs and a
//!   [`MlpCache`]; `backward` returns [`MlpGrads`] (parameters, and inputs when asked).
//!   `forward_with` / `backward_with` let an encoder fill input blocks and consume input-gradient
//!   blocks without materialising them; `forward_into` keeps a cache's memory across steps.
//! - [`encoding`]: [`Sinusoidal`] (D-3DGS ordering), [`TriPlane`] (concat or product, gradients to
//!   planes and positions; with a [`TimeAxis`] the six-plane HexPlane of 4DGaussians and its
//!   regularisers), [`BSplineTime`] (uniform cubic, exact at t = 0 and t = 1), [`HashGrid`]
//!   (multi-resolution hash grid of Instant-NGP / Grid4D, f32 or f16 tables, deterministic
//!   gradient scatter).
//! - [`nets`]: [`ObservationNet`] (EvoGS Φ: tri-plane + B-spline → MLP, output starts at 0) and
//!   [`DeformNet`] (D-3DGS: sinusoidal xyz and t → depth-8 MLP with skip → 10 outputs).
//! - [`hexfield`]: [`HexDeformNet`] (4DGaussians: HexPlane → feature layer → position, rotation
//!   and scale heads, with the HexPlane's regularisers).
//! - [`grid4d`]: [`Grid4dNet`] (Grid4D: spatial and three temporal hash grids → directional
//!   attention → position (rigid warp), rotation and scale heads, with its smoothness
//!   regulariser).
//! - [`adam`]: [`Adam`] with groups, [`LrSchedule`] (constant or 3DGS exponential), per-row moment
//!   reset and remapping; moments are public `Vec<f32>`.
//! - `gpu` (cargo feature `wgpu`): `GpuMlp` and `GpuAdam`, the MLP's forward and backward and
//!   Adam's step on device buffers, beside their CPU twins.
//! - [`weights`]: [`weights::save`] / [`weights::load`] of any [`Parameters`] as safetensors.
//! - [`precision`], [`linalg`], [`activation`], [`error`]: storage, gemm wrappers, activations,
//!   [`NnError`].
//!
//! # Precision
//!
//! [`Precision::F16`] stores parameters and cached activations as `half::f16`; every product and
//! sum is done in f32 (blocks are widened to f32 and multiplied with gemm's f32 kernel; see
//! [`linalg`] for why gemm's own f16 path is not used). Values written to f16 storage saturate at
//! ±65504 and are counted ([`MlpCache::saturations`], and the return value of [`Adam::step`]).
//! Gradients are always f32. Adam updates f16 parameters in f32 and rounds back, so updates below
//! half an f16 ulp of a weight are lost (pure f16 storage, no f32 master copy).
//!
//! # Parallelism
//!
//! Rows are cut into blocks of [`mlp::ROW_BLOCK`] (MLP forward), [`mlp::BACKWARD_BLOCK`] (MLP
//! backward) or 1024 (encoders) processed in parallel
//! with rayon; inside a block each product is one single-threaded gemm call (in f32 storage
//! written straight into the forward cache, bias and activation applied there in one pass).
//! Parameter gradients are accumulated in a fixed grouping of blocks and summed in order, so they
//! are bit-identical for any thread count. [`ObservationNet`] runs its rows in a spatial order
//! (Morton order of tri-plane cells) so that texel reads and gradient scatters hit the cache;
//! outputs and gradients come back in input order. The encoders' row loops inside Φ are compiled
//! for AVX2 and selected at run time when the CPU has it (bit-identical to the baseline build).
//!
//! # Example: the EvoGS gain network Ψ
//!
//! `Ψ = Linear(D+3, 32) ReLU Linear(32, 32) ReLU Linear(32, 1) sigmoid` over N rows, one Adam step:
//!
//! ```
//! use tiny_nn::{Activation, Adam, LrSchedule, MlpConfig, Precision};
//!
//! let (d, n) = (10, 5);
//! let mut psi = MlpConfig::new(d + 3, 32, 2, 1)
//!     .output_activation(Activation::Sigmoid)
//!     .precision(Precision::F32)
//!     .seed(7)
//!     .build()?;
//! let x = vec![0.1f32; n * (d + 3)];
//! let (k, cache) = psi.forward(&x, n)?; // k: n × 1 values in (0, 1)
//! assert!(k.iter().all(|&v| v > 0.0 && v < 1.0));
//!
//! let d_k = vec![1.0f32; n]; // dL/dK from the caller's loss
//! let grads = psi.backward(&cache, &d_k, true)?;
//! assert_eq!(grads.input.as_ref().map(Vec::len), Some(n * (d + 3)));
//!
//! let mut adam = Adam::new();
//! let group = adam.add_group("psi", psi.param_count(), 1, LrSchedule::Constant(1e-3))?;
//! adam.step(group, 0, psi.params_mut(), &grads.params)?;
//! # Ok::<(), tiny_nn::NnError>(())
//! ```

pub mod activation;
pub mod adam;
pub mod encoding;
pub mod error;
#[cfg(feature = "wgpu")]
pub mod gpu;
pub mod grid4d;
pub mod hexfield;
pub mod linalg;
pub mod mlp;
pub mod nets;
pub mod precision;
mod reduce;
mod simd;
pub mod weights;

pub use activation::Activation;
pub use adam::{Adam, AdamGroup, AdamUpdate, ExponentialLr, GroupId, LrSchedule};
pub use encoding::bspline::{BSplineCache, BSplineConfig, BSplineGrads, BSplineTime};
pub use encoding::hashgrid::{
    HashGrid, HashGridCache, HashGridConfig, HashGridGrads, HashLevel, Interpolation, Outside,
};
pub use encoding::sinusoidal::Sinusoidal;
pub use encoding::triplane::{
    PlaneCombine, PlaneCombineParseError, PlaneRegulariser, TimeAxis, TriPlane, TriPlaneCache,
    TriPlaneConfig, TriPlaneGrads,
};
pub use error::NnError;
pub use grid4d::{
    Grid4dCache, Grid4dConfig, Grid4dGrads, Grid4dHead, Grid4dNet, Grid4dSmoothness,
    is_grid4d_table,
};
pub use hexfield::{HEX_OUTPUT, HexDeformCache, HexDeformConfig, HexDeformGrads, HexDeformNet};
pub use mlp::{Init, LayerShape, Mlp, MlpCache, MlpConfig, MlpGrads};
pub use nets::{
    DeformCache, DeformConfig, DeformGrads, DeformNet, ObservationCache, ObservationConfig,
    ObservationGrads, ObservationNet,
};
pub use precision::{F16_MAX, Precision, PrecisionParseError, Store, StoreMut, StoreRef};
pub use weights::Parameters;
