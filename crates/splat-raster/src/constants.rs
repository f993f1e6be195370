//! The constants of the rasterizer's definition (DESIGN §3), shared by both backends. The wgpu
//! kernels declare the same values in `gpu/shaders/common.wgsl`; a test (below) reads that file
//! and checks that they agree.

/// Dilation added to the diagonal of the projected covariance.
pub const DILATION: f32 = 0.3;
/// Gaussians at camera-space `z <= NEAR_PLANE` are culled.
pub const NEAR_PLANE: f32 = 0.01;
/// Blending threshold: a pixel is blended only when `α >= ALPHA_MIN`.
pub const ALPHA_MIN: f32 = 1.0 / 255.0;
/// Cap on a single Gaussian's alpha.
pub const ALPHA_MAX: f32 = 0.99;
/// A pixel stops when its transmittance would fall below this.
pub const T_MIN: f32 = 1e-4;
/// A quaternion with `|q|² < QUAT_NORM2_MIN` counts as zero.
pub const QUAT_NORM2_MIN: f32 = 1e-12;
/// A Gaussian whose SH colour exceeds this (from finite but extreme coefficients) is culled as
/// non-finite, so that sums of colours can never overflow to infinity.
pub const MAX_COLOR: f32 = 1e18;
/// Tile side in pixels.
pub const TILE: u32 = 16;

#[cfg(test)]
mod tests {
    use super::*;
    use gpu_core::wgsl_text::const_value;

    /// The kernels' declarations (read as text: no GPU or `wgpu` feature needed).
    const COMMON_WGSL: &str = include_str!("gpu/shaders/common.wgsl");

    fn wgsl_const(name: &str) -> f64 {
        const_value(COMMON_WGSL, name)
    }

    #[test]
    fn the_kernels_declare_the_same_constants() {
        let floats = [
            ("DILATION", DILATION),
            ("NEAR_PLANE", NEAR_PLANE),
            ("ALPHA_MIN", ALPHA_MIN),
            ("ALPHA_MAX", ALPHA_MAX),
            ("T_MIN", T_MIN),
            ("QUAT_NORM2_MIN", QUAT_NORM2_MIN),
            ("MAX_COLOR", MAX_COLOR),
        ];
        for (name, value) in floats {
            assert_eq!(wgsl_const(name) as f32, value, "{name}");
        }
        assert_eq!(wgsl_const("TILE"), f64::from(TILE), "TILE");
    }
}
