//! The per-frame uniform shared by every kernel (`Frame` in `shaders/common.wgsl`) and the
//! packing of the raw Gaussian parameters into one buffer.

use bytemuck::{Pod, Zeroable};

use crate::camera::Camera;
use crate::frame::Frame;
use crate::gaussians::GaussiansView;

/// Floats per Gaussian before the SH coefficients: mean 3, log-scale 3, quaternion 4, logit 1.
pub(crate) const PARAMS_FIXED: usize = 11;

/// Mirror of the WGSL `Frame` struct (scalars only, 40 words).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub(crate) struct FrameUniform {
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    pub lim: [f32; 4],
    /// World-to-camera rotation, row-major.
    pub w: [f32; 9],
    pub t: [f32; 3],
    pub center: [f32; 3],
    pub background: [f32; 3],
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
    pub pad: [u32; 3],
}

impl FrameUniform {
    pub fn new(cam: &Camera, n: usize, sh_stride: usize, active: u32, bg: [f32; 3]) -> Self {
        let f = Frame::new(cam);
        let w = std::array::from_fn(|k| f.w.col(k % 3)[k / 3] as f32);
        Self {
            fx: cam.fx,
            fy: cam.fy,
            cx: cam.cx,
            cy: cam.cy,
            lim: [
                f.lim_x[0] as f32,
                f.lim_x[1] as f32,
                f.lim_y[0] as f32,
                f.lim_y[1] as f32,
            ],
            w,
            t: cam.translation.to_array(),
            center: f.center.to_array(),
            background: bg,
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
