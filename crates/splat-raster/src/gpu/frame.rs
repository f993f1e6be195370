//! The per-frame uniform shared by every kernel (`Frame` in `shaders/common.wgsl`) and the
//! packing of the raw Gaussian parameters into one buffer.

use bytemuck::{Pod, Zeroable};

use crate::camera::Camera;
use crate::frame::Frame;
use crate::gaussians::GaussiansView;
use gpu_core::wgsl_mirror;

/// Floats per Gaussian before the SH coefficients: mean 3, log-scale 3, quaternion 4, logit 1.
pub(crate) const PARAMS_FIXED: usize = 11;

wgsl_mirror! {
    /// Mirror of the WGSL `Frame` struct of `shaders/common.wgsl` (scalars only, 40 words; a
    /// test checks names, types, offsets and size against the shader).
    #[repr(C)]
    #[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
    pub(crate) struct FrameUniform {
        pub fx: f32,
        pub fy: f32,
        pub cx: f32,
        pub cy: f32,
        /// Screen-space culling limits (`lim_x`, `lim_y` of [`Frame`]).
        pub lim_x0: f32,
        pub lim_x1: f32,
        pub lim_y0: f32,
        pub lim_y1: f32,
        /// World-to-camera rotation, row-major (`w<row><column>`).
        pub w00: f32,
        pub w01: f32,
        pub w02: f32,
        pub w10: f32,
        pub w11: f32,
        pub w12: f32,
        pub w20: f32,
        pub w21: f32,
        pub w22: f32,
        /// World-to-camera translation.
        pub t0: f32,
        pub t1: f32,
        pub t2: f32,
        /// Camera centre in world space.
        pub c0: f32,
        pub c1: f32,
        pub c2: f32,
        /// Background colour.
        pub bg0: f32,
        pub bg1: f32,
        pub bg2: f32,
        pub width: u32,
        pub height: u32,
        pub tiles_x: u32,
        pub tiles_y: u32,
        pub n: u32,
        pub active_degree: u32,
        pub param_stride: u32,
        pub sh_stride: u32,
        pub n_isect: u32,
        pub use_d_alpha: u32,
        pub use_d_depth: u32,
        pub pad0: u32,
        pub pad1: u32,
        pub pad2: u32,
    }
}

impl FrameUniform {
    pub fn new(cam: &Camera, n: usize, sh_stride: usize, active: u32, bg: [f32; 3]) -> Self {
        let f = Frame::new(cam);
        let w = |row: usize, col: usize| f.w.col(col)[row] as f32;
        let [t0, t1, t2] = cam.translation.to_array();
        let [c0, c1, c2] = f.center.to_array();
        let [bg0, bg1, bg2] = bg;
        Self {
            fx: cam.fx,
            fy: cam.fy,
            cx: cam.cx,
            cy: cam.cy,
            lim_x0: f.lim_x[0] as f32,
            lim_x1: f.lim_x[1] as f32,
            lim_y0: f.lim_y[0] as f32,
            lim_y1: f.lim_y[1] as f32,
            w00: w(0, 0),
            w01: w(0, 1),
            w02: w(0, 2),
            w10: w(1, 0),
            w11: w(1, 1),
            w12: w(1, 2),
            w20: w(2, 0),
            w21: w(2, 1),
            w22: w(2, 2),
            t0,
            t1,
            t2,
            c0,
            c1,
            c2,
            bg0,
            bg1,
            bg2,
            width: cam.width,
            height: cam.height,
            tiles_x: f.tiles_x,
            tiles_y: f.tiles_y,
            n: n as u32,
            active_degree: active,
            param_stride: (PARAMS_FIXED + sh_stride) as u32,
            sh_stride: sh_stride as u32,
            ..Self::default()
        }
    }

    pub fn n_tiles(&self) -> u32 {
        self.tiles_x * self.tiles_y
    }
}

/// The raw parameters, `PARAMS_FIXED + sh_stride` floats per Gaussian.
pub(crate) fn pack_params(g: &GaussiansView<'_>) -> Vec<f32> {
    let stride = g.sh_stride();
    let mut out = Vec::with_capacity(g.len() * (PARAMS_FIXED + stride));
    for i in 0..g.len() {
        out.extend_from_slice(&g.means[i]);
        out.extend_from_slice(&g.log_scales[i]);
        out.extend_from_slice(&g.rotations[i]);
        out.push(g.opacity_logits[i]);
        out.extend_from_slice(&g.sh[i * stride..(i + 1) * stride]);
    }
    out
}
