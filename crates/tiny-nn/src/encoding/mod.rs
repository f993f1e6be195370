//! Input encoders: fixed sinusoidal features, and learnable tri-plane and B-spline features.

pub mod bspline;
pub mod sinusoidal;
pub mod triplane;

/// Rows per parallel task in the encoders.
pub(crate) const ENC_ROWS: usize = 1024;
