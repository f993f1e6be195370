//! Camera quantities shared by every Gaussian of a frame, in f64, for both backends.

use glam::{DMat3, DVec3, Vec3};

use crate::camera::Camera;
use crate::constants::TILE;

/// Camera quantities shared by every Gaussian of a frame. The per-Gaussian geometry runs in
/// f64 (it is cheap, and `det(Σ2d)` of thin Gaussians cancels badly in f32); per-pixel work runs
/// in f32 on the resulting [`Splat`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct Frame {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub width: u32,
    pub height: u32,
    /// Clamp range of x/z and y/z for the Jacobian.
    pub lim_x: [f64; 2],
    pub lim_y: [f64; 2],
    pub w: DMat3,
    pub t: DVec3,
    /// Camera centre (f32: the SH view direction is computed in f32).
    pub center: Vec3,
    pub tiles_x: u32,
    pub tiles_y: u32,
}

impl Frame {
    pub fn new(cam: &Camera) -> Self {
        let (fx, fy) = (f64::from(cam.fx), f64::from(cam.fy));
        let (cx, cy) = (f64::from(cam.cx), f64::from(cam.cy));
        let (width, height) = (f64::from(cam.width), f64::from(cam.height));
        let tan_x = 0.5 * width / fx;
        let tan_y = 0.5 * height / fy;
        Self {
            fx,
            fy,
            cx,
            cy,
            width: cam.width,
            height: cam.height,
            lim_x: [-(cx / fx + 0.3 * tan_x), (width - cx) / fx + 0.3 * tan_x],
            lim_y: [-(cy / fy + 0.3 * tan_y), (height - cy) / fy + 0.3 * tan_y],
            w: cam.rotation.as_dmat3(),
            t: cam.translation.as_dvec3(),
            center: cam.center(),
            tiles_x: cam.width.div_ceil(TILE),
            tiles_y: cam.height.div_ceil(TILE),
        }
    }
}
