//! The pinhole camera of DESIGN §1.2: OpenCV axes (+x right, +y down, +z forward), world-to-camera
//! `x_cam = R x_world + t`, pixel (i, j) centred at (i + 0.5, j + 0.5).

use glam::{Mat3, Vec3};

/// A pinhole camera, world-to-camera, OpenCV axes (DESIGN §1.2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Focal length along x, in pixels.
    pub fx: f32,
    /// Focal length along y, in pixels.
    pub fy: f32,
    /// Principal point x, in pixels (pixel centres at i + 0.5).
    pub cx: f32,
    /// Principal point y, in pixels.
    pub cy: f32,
    /// World-to-camera rotation: its rows are the camera axes expressed in world coordinates.
    pub rotation: Mat3,
    /// World-to-camera translation: `x_cam = rotation * x_world + translation`.
    pub translation: Vec3,
}

impl Camera {
    /// Camera centre in world coordinates, `C = -Rᵀ t`.
    pub fn center(&self) -> Vec3 {
        -(self.rotation.transpose() * self.translation)
    }

    /// Builds a camera from its centre `C` and world-to-camera rotation `R` (`t = -R C`).
    #[allow(clippy::too_many_arguments)]
    pub fn from_center(
        width: u32,
        height: u32,
        fx: f32,
        fy: f32,
        cx: f32,
        cy: f32,
        rotation: Mat3,
        center: Vec3,
    ) -> Self {
        Self {
            width,
            height,
            fx,
            fy,
            cx,
            cy,
            rotation,
            translation: -(rotation * center),
        }
    }

    /// A camera at `eye` looking at `target`, with image-up roughly along `-up` of the world
    /// (OpenCV: +y of the image points down). Principal point at the image centre.
    pub fn look_at(width: u32, height: u32, fov_x: f32, eye: Vec3, target: Vec3, up: Vec3) -> Self {
        let forward = (target - eye).normalize();
        let right = forward.cross(up).normalize();
        let down = forward.cross(right);
        // Rows of R are the camera axes in world coordinates.
        let rotation = Mat3::from_cols(right, down, forward).transpose();
        let fx = 0.5 * width as f32 / (0.5 * fov_x).tan();
        Self::from_center(
            width,
            height,
            fx,
            fx,
            0.5 * width as f32,
            0.5 * height as f32,
            rotation,
            eye,
        )
    }

    /// World point to camera coordinates.
    pub fn world_to_camera(&self, p: Vec3) -> Vec3 {
        self.rotation * p + self.translation
    }

    /// Scales the image size and the intrinsics by `factor` (DESIGN §1.2: resizing scales fx, fy, cx,
    /// cy by the same factor). Sizes are rounded to the nearest pixel.
    #[must_use]
    pub fn scaled(&self, factor: f32) -> Self {
        Self {
            width: (self.width as f32 * factor).round().max(1.0) as u32,
            height: (self.height as f32 * factor).round().max(1.0) as u32,
            fx: self.fx * factor,
            fy: self.fy * factor,
            cx: self.cx * factor,
            cy: self.cy * factor,
            ..*self
        }
    }

    /// Number of pixels, `width * height`.
    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn look_at_projects_target_to_principal_point_and_centre_round_trips() {
        let eye = Vec3::new(1.0, 2.0, 3.0);
        let cam = Camera::look_at(64, 48, 1.0, eye, Vec3::ZERO, Vec3::Z);
        assert!((cam.center() - eye).length() < 1e-5);
        let p = cam.world_to_camera(Vec3::ZERO);
        assert!(p.x.abs() < 1e-5 && p.y.abs() < 1e-5 && p.z > 0.0);
        // World up (+z) must appear towards the top of the image (negative camera y).
        let up = cam.world_to_camera(Vec3::Z * 0.1);
        assert!(up.y < 0.0);
    }
}
