//! `splat-raster`: a differentiable 3D Gaussian Splatting rasterizer.
//!
//! What it is: the forward pass (projection, tiling, depth sort, front-to-back compositing) and the
//! backward pass (gradients to every raw Gaussian parameter) of 3DGS, exactly as pinned in the
//! project's SPEC §3, over plain structure-of-arrays inputs ([`GaussiansView`]) and an OpenCV-axes
//! pinhole [`Camera`].
//!
//! What it is not: a trainer, an optimiser, a file reader or a deformation model. Those live in
//! other crates of the workspace and hand this crate slices.

pub mod camera;
pub mod gaussians;

pub use camera::Camera;
pub use gaussians::{Gaussians, GaussiansView, sh_coeff_count};
