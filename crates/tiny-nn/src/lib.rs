//! `tiny-nn`: tiny batched neural networks on the CPU, with f32 or f16 storage.
//!
//! What it is: batched forward and backward passes over N rows (row-major `N × width` f32 slices
//! at the API) for multi-layer perceptrons ([`Mlp`]), input encoders with gradients (sinusoidal,
//! tri-plane, uniform cubic B-spline over time), the Adam optimiser with the 3DGS learning-rate
//! schedule and per-row moment edits ([`Adam`]), and bit-exact safetensors weights files. Matrix
//! products go through the `gemm` crate in f32; rows are split into blocks processed in parallel
//! with rayon. Each network stores its parameters and cached activations in f32 or f16
//! ([`Precision`]), one switch per network, always accumulating in f32; f16 storage saturates at
//! ±65504 instead of overflowing and counts saturations.
//!
//! What it is not: an autodiff framework (each module has a hand-written backward), a GPU
//! backend, or a trainer. Losses, schedules of training and data live in other crates.
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
pub mod linalg;
pub mod mlp;
pub mod nets;
pub mod precision;
pub mod weights;

pub use activation::Activation;
pub use adam::{Adam, AdamGroup, ExponentialLr, GroupId, LrSchedule};
pub use encoding::bspline::{BSplineCache, BSplineConfig, BSplineGrads, BSplineTime};
pub use encoding::sinusoidal::Sinusoidal;
pub use encoding::triplane::{
    PlaneCombine, TriPlane, TriPlaneCache, TriPlaneConfig, TriPlaneGrads,
};
pub use error::NnError;
pub use mlp::{LayerShape, Mlp, MlpCache, MlpConfig, MlpGrads};
pub use nets::{
    DeformCache, DeformConfig, DeformGrads, DeformNet, ObservationCache, ObservationConfig,
    ObservationGrads, ObservationNet,
};
pub use precision::{F16_MAX, Precision, Store, StoreMut, StoreRef};
pub use weights::Parameters;
