//! A pinhole [`Camera`] with the parts of a real camera model it cannot express: skew and lens
//! distortion. They are kept so nothing is silently dropped, and reported as warnings.

use splat_core::Camera;

/// Lens distortion coefficients (nerfies / OpenCV convention).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Distortion {
    /// Radial `k1, k2, k3` of the OpenCV (Brown) model.
    pub radial: [f32; 3],
    /// Tangential `p1, p2`.
    pub tangential: [f32; 2],
    /// `k1..k4` of OpenCV's equidistant fisheye model (nerfstudio's `OPENCV_FISHEYE`, COLMAP's
    /// `OPENCV_FISHEYE`); zero for the other models.
    pub fisheye: [f32; 4],
}

impl Distortion {
    /// True when every coefficient is zero.
    pub fn is_zero(&self) -> bool {
        self.radial
            .iter()
            .chain(&self.tangential)
            .chain(&self.fisheye)
            .all(|&k| k == 0.0)
    }
}

/// A camera as read from a file: the pinhole [`Camera`] the rasterizer uses, plus skew and
/// distortion, which rendering ignores (DESIGN §1.2: rendering is pinhole).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraInfo {
    /// The pinhole camera.
    pub camera: Camera,
    /// Skew: adds `skew · y/z` to u in the full model; ignored by the pinhole rasterizer.
    pub skew: f32,
    /// Lens distortion; ignored by the pinhole rasterizer.
    pub distortion: Distortion,
}

impl CameraInfo {
    /// A camera with no skew and no distortion.
    pub fn pinhole(camera: Camera) -> Self {
        Self {
            camera,
            skew: 0.0,
            distortion: Distortion::default(),
        }
    }

    /// True when skew and distortion are zero, so the pinhole camera is the whole model.
    pub fn is_pinhole(&self) -> bool {
        self.skew == 0.0 && self.distortion.is_zero()
    }

    /// A one-line warning when the camera has skew or distortion that pinhole rendering ignores.
    pub fn warning(&self) -> Option<String> {
        if self.is_pinhole() {
            return None;
        }
        let mut parts = Vec::new();
        if self.skew != 0.0 {
            parts.push(format!("skew {}", self.skew));
        }
        let d = &self.distortion;
        if d.fisheye.iter().any(|&k| k != 0.0) {
            parts.push(format!("fisheye distortion {:?}", d.fisheye));
        }
        if d.radial.iter().chain(&d.tangential).any(|&k| k != 0.0) {
            parts.push(format!(
                "radial distortion {:?}, tangential distortion {:?}",
                d.radial, d.tangential
            ));
        }
        Some(format!(
            "{} ignored: rendering uses the pinhole model",
            parts.join(" and ")
        ))
    }
}

/// One warning for a set of cameras (a dataset), when any has skew or distortion: how many, and
/// the first one's values. `None` when every camera is pinhole.
pub fn warning_for_all(cameras: &[CameraInfo]) -> Option<String> {
    let affected: Vec<&CameraInfo> = cameras.iter().filter(|c| !c.is_pinhole()).collect();
    let first = affected.first()?.warning()?;
    Some(format!(
        "{} of {} cameras have skew or distortion (first: {first})",
        affected.len(),
        cameras.len()
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn one_warning_for_many_cameras() {
        let pinhole =
            CameraInfo::pinhole(Camera::look_at(4, 4, 1.0, Vec3::ONE, Vec3::ZERO, Vec3::Z));
        assert_eq!(warning_for_all(&[pinhole; 3]), None);
        let distorted = CameraInfo {
            distortion: Distortion {
                radial: [0.0, 0.2, 0.0],
                ..Distortion::default()
            },
            ..pinhole
        };
        let text = warning_for_all(&[pinhole, distorted, distorted]).unwrap();
        assert!(text.starts_with("2 of 3 cameras"), "{text}");
        assert!(text.contains("0.2") && !text.contains('\n'), "{text}");
    }
}
