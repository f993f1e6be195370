//! `splat-core`: the plain types every crate of evogs shares.
//!
//! What it is: [`Gaussians`] / [`GaussiansView`] (structure-of-arrays raw parameters) with the
//! activations that give them meaning ([`sigmoid`], [`logit`]), the pinhole [`Camera`] (OpenCV
//! axes), the spherical-harmonics constants ([`sh`]), the row plans that keep every per-Gaussian
//! array aligned when Gaussians are pruned, cloned or split ([`RowPlan`], [`NewRows`]), and the
//! deformation row: its [`Layout`] (which components a deformation vector holds, in which order),
//! applying rows to the Gaussians and their gradient back ([`DeformedGeometry`],
//! [`deformation_gradient_into`]), the gradients of the raw parameters ([`GaussianGrads`]), and
//! the one message for a setting spelled by a word that names no value ([`one_word`]).
//!
//! What it is not: a renderer (`splat-raster`), a file reader (`evogs-io`), a deformation model
//! or a trainer. It has no GPU dependency, so that the file formats, densification and the
//! evolution state can share these types without compiling wgpu.

pub mod activation;
pub mod camera;
pub mod deform;
pub mod deformed;
pub mod gaussians;
pub mod one_word;
pub mod rows;
pub mod sh;

pub use activation::{logit, sigmoid};
pub use camera::Camera;
pub use deform::{Component, Layout, LayoutParseError};
pub use deformed::{DeformedGeometry, deformation_gradient, deformation_gradient_into};
pub use gaussians::{GaussianGrads, Gaussians, GaussiansView, ShapeError, sh_coeff_count};
pub use one_word::{OneWord, unknown_message};
pub use rows::{FollowsRowPlan, NewRows, RowPlan, RowPlanError};
