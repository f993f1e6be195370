//! The constants of the real spherical harmonics up to degree 3 (Sloan basis order, the values of
//! the 3DGS reference implementation), and the conversion between an RGB colour and the degree-0
//! (DC) coefficient that renders it. The basis functions and their gradients live with the
//! rasterizer that evaluates them.

/// Degree-0 constant, `1 / (2 sqrt(pi))`.
pub const SH_C0: f32 = 0.282_094_8;
/// Degree-1 constant.
pub const SH_C1: f32 = 0.488_602_52;
/// Degree-2 constants.
pub const SH_C2: [f32; 5] = [
    1.092_548_5,
    -1.092_548_5,
    0.315_391_57,
    -1.092_548_5,
    0.546_274_24,
];
/// Degree-3 constants.
pub const SH_C3: [f32; 7] = [
    -0.590_043_6,
    2.890_611_4,
    -0.457_045_8,
    0.373_176_33,
    -0.457_045_8,
    1.445_305_7,
    -0.590_043_6,
];

/// The DC coefficient that renders colour `rgb` (degree 0: `colour = SH_C0 · dc + 0.5`).
pub fn dc_from_rgb(rgb: f32) -> f32 {
    (rgb - 0.5) / SH_C0
}

/// The colour a DC coefficient renders, before clamping: `SH_C0 · dc + 0.5`.
pub fn rgb_from_dc(dc: f32) -> f32 {
    dc * SH_C0 + 0.5
}
