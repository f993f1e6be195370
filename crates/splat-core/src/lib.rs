//! `splat-core`: the plain types every crate of evogs shares.
//!
//! What it is: [`Gaussians`] / [`GaussiansView`] (structure-of-arrays raw parameters) with the
//! activations that give them meaning ([`sigmoid`], [`logit`]), the pinhole [`Camera`] (OpenCV
//! axes), the spherical-harmonics constants ([`sh`]), the row plans that keep every per-Gaussian
//! array aligned when Gaussians are pruned, cloned or split ([`RowPlan`], [`NewRows`]), and the
//! deformation [`Layout`] (which components a deformation vector holds, in which order).
//!
//! What it is not: a renderer (`splat-raster`), a file reader (`evogs-io`), a deformation model
//! or a trainer. It has no GPU dependency, so that the file formats, densification and the
//! evolution state can share these types without compiling wgpu.

pub mod activation;
pub mod camera;
pub mod deform;
pub mod gaussians;
pub mod rows;
pub mod sh;

pub use activation::{logit, sigmoid};
pub use camera::Camera;
pub use deform::{Component, Layout, LayoutParseError};
pub use gaussians::{Gaussians, GaussiansView, ShapeError, sh_coeff_count};
pub use rows::{NewRows, RowPlan, RowPlanError};
