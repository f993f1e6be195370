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

    /// The kernels' declarations (read as text: no GPU or `wgpu` feature needed).
    const COMMON_WGSL: &str = include_str!("gpu/shaders/common.wgsl");

    /// The value of `const NAME: TYPE = EXPR;` in `common.wgsl`, where EXPR is a literal or
    /// `a / b` (WGSL evaluates constant expressions exactly, then converts to the type).
    fn wgsl_const(name: &str) -> f64 {
        let prefix = format!("const {name}:");
        let line = COMMON_WGSL
            .lines()
            .find(|l| l.trim_start().starts_with(&prefix))
            .unwrap_or_else(|| panic!("common.wgsl declares no `{name}`"));
        let expr = line
            .split_once('=')
            .and_then(|(_, e)| e.trim().strip_suffix(';'))
            .unwrap_or_else(|| panic!("`{line}` is not `const {name}: T = EXPR;`"));
        let literal = |s: &str| -> f64 {
            let s = s.trim();
            s.strip_suffix('u')
                .unwrap_or(s)
                .parse()
                .unwrap_or_else(|e| panic!("{name}: `{s}`: {e}"))
        };
        match expr.split_once('/') {
            Some((a, b)) => literal(a) / literal(b),
            None => literal(expr),
        }
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

    #[test]
    fn the_reader_refuses_a_missing_constant() {
        let missing = std::panic::catch_unwind(|| wgsl_const("NO_SUCH_CONSTANT"));
        assert!(missing.is_err());
    }
}
