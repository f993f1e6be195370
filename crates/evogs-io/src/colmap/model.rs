//! The COLMAP model's records and their conversion to [`CameraInfo`].

use std::path::PathBuf;

use glam::{DQuat, Mat3, Vec3};
use splat_core::Camera;

use crate::IoError;
use crate::camera_info::{CameraInfo, Distortion};
use crate::camera_json::MAX_IMAGE_SIDE;

/// The camera models this crate reads (COLMAP's `CAMERA_MODEL_DEFINITIONS`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CameraModel {
    /// Id 0: `f, cx, cy`.
    SimplePinhole,
    /// Id 1: `fx, fy, cx, cy`.
    Pinhole,
    /// Id 2: `f, cx, cy, k`.
    SimpleRadial,
    /// Id 4: `fx, fy, cx, cy, k1, k2, p1, p2`.
    Opencv,
}

/// COLMAP's model names by id (0..=10), for error messages about unsupported ones.
const MODEL_NAMES: [&str; 11] = [
    "SIMPLE_PINHOLE",
    "PINHOLE",
    "SIMPLE_RADIAL",
    "RADIAL",
    "OPENCV",
    "OPENCV_FISHEYE",
    "FULL_OPENCV",
    "FOV",
    "SIMPLE_RADIAL_FISHEYE",
    "RADIAL_FISHEYE",
    "THIN_PRISM_FISHEYE",
];

const SUPPORTED: &str = "supported: SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, OPENCV";

impl CameraModel {
    /// The model with COLMAP id `id`, or a description of why it is not supported.
    pub fn from_id(id: i32) -> Result<Self, String> {
        match id {
            0 => Ok(Self::SimplePinhole),
            1 => Ok(Self::Pinhole),
            2 => Ok(Self::SimpleRadial),
            4 => Ok(Self::Opencv),
            _ => Err(
                match usize::try_from(id).ok().and_then(|i| MODEL_NAMES.get(i)) {
                    Some(name) => {
                        format!("camera model {name} (id {id}) is not supported; {SUPPORTED}")
                    }
                    None => format!("camera model id {id} is unknown; {SUPPORTED}"),
                },
            ),
        }
    }

    /// The model named `name` (as in `cameras.txt`), or why it is not supported.
    pub fn from_name(name: &str) -> Result<Self, String> {
        match MODEL_NAMES.iter().position(|&n| n == name) {
            Some(id) => Self::from_id(id as i32),
            None => Err(format!("camera model `{name}` is unknown; {SUPPORTED}")),
        }
    }

    /// The COLMAP id.
    pub fn id(self) -> i32 {
        match self {
            Self::SimplePinhole => 0,
            Self::Pinhole => 1,
            Self::SimpleRadial => 2,
            Self::Opencv => 4,
        }
    }

    /// The COLMAP name.
    pub fn name(self) -> &'static str {
        MODEL_NAMES[self.id() as usize]
    }

    /// How many parameters the model has.
    pub fn param_count(self) -> usize {
        match self {
            Self::SimplePinhole => 3,
            Self::Pinhole | Self::SimpleRadial => 4,
            Self::Opencv => 8,
        }
    }
}

/// A COLMAP camera (intrinsics).
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapCamera {
    /// `CAMERA_ID`.
    pub id: u32,
    /// The model.
    pub model: CameraModel,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// The model's parameters, `model.param_count()` of them.
    pub params: Vec<f64>,
}

impl ColmapCamera {
    /// Checks sizes and parameters; `problem` describes the first bad one.
    pub(crate) fn validate(&self) -> Result<(), String> {
        for (name, v) in [("width", self.width), ("height", self.height)] {
            if v == 0 || v > MAX_IMAGE_SIDE {
                return Err(format!("{name} {v} is not in 1..={MAX_IMAGE_SIDE}"));
            }
        }
        if self.params.len() != self.model.param_count() {
            return Err(format!(
                "{} has {} parameters, found {}",
                self.model.name(),
                self.model.param_count(),
                self.params.len()
            ));
        }
        if self.params.iter().any(|v| !v.is_finite()) {
            return Err("a parameter is not finite".into());
        }
        let focal_count = match self.model {
            CameraModel::Pinhole | CameraModel::Opencv => 2,
            _ => 1,
        };
        if self.params[..focal_count].iter().any(|&f| f <= 0.0) {
            return Err("focal length is not positive".into());
        }
        Ok(())
    }

    /// Intrinsics `(fx, fy, cx, cy)` and distortion.
    pub fn intrinsics(&self) -> ([f64; 4], Distortion) {
        let p = &self.params;
        match self.model {
            CameraModel::SimplePinhole => ([p[0], p[0], p[1], p[2]], Distortion::default()),
            CameraModel::Pinhole => ([p[0], p[1], p[2], p[3]], Distortion::default()),
            CameraModel::SimpleRadial => (
                [p[0], p[0], p[1], p[2]],
                Distortion {
                    radial: [p[3] as f32, 0.0, 0.0],
                    ..Distortion::default()
                },
            ),
            CameraModel::Opencv => (
                [p[0], p[1], p[2], p[3]],
                Distortion {
                    radial: [p[4] as f32, p[5] as f32, 0.0],
                    tangential: [p[6] as f32, p[7] as f32],
                    ..Distortion::default()
                },
            ),
        }
    }
}

/// A registered COLMAP image (extrinsics).
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapImage {
    /// `IMAGE_ID`.
    pub id: u32,
    /// World-to-camera rotation as a quaternion (w, x, y, z).
    pub qvec: [f64; 4],
    /// World-to-camera translation.
    pub tvec: [f64; 3],
    /// The camera (intrinsics) it uses.
    pub camera_id: u32,
    /// The image file name, relative to the images folder.
    pub name: String,
}

/// A sparse 3D point.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapPoint {
    /// Position.
    pub xyz: [f64; 3],
    /// Colour, 0..=255.
    pub rgb: [u8; 3],
}

/// A whole sparse model.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapModel {
    /// Cameras (intrinsics).
    pub cameras: Vec<ColmapCamera>,
    /// Registered images.
    pub images: Vec<ColmapImage>,
    /// Sparse points.
    pub points: Vec<ColmapPoint>,
    /// The images file it was read from (for error messages).
    pub images_path: PathBuf,
}

/// The rotation matrix of a quaternion (w, x, y, z), normalised first; `None` when it is ~0 or
/// not finite.
pub fn rotation_from_qvec(q: [f64; 4]) -> Option<Mat3> {
    let quat = DQuat::from_xyzw(q[1], q[2], q[3], q[0]);
    let norm = quat.length();
    if !norm.is_finite() || norm < 1e-8 {
        return None;
    }
    Some(glam::DMat3::from_quat(quat / norm).as_mat3())
}

impl ColmapModel {
    /// The camera of an image, OpenCV axes, with distortion.
    pub fn camera_info(&self, image: &ColmapImage) -> Result<CameraInfo, IoError> {
        let field = |what: &str| format!("image {}.{what}", image.id);
        let cam = self
            .cameras
            .iter()
            .find(|c| c.id == image.camera_id)
            .ok_or_else(|| {
                IoError::field(
                    &self.images_path,
                    field("camera_id"),
                    format!("camera {} is not in the cameras file", image.camera_id),
                )
            })?;
        let rotation = rotation_from_qvec(image.qvec).ok_or_else(|| {
            IoError::field(
                &self.images_path,
                field("qvec"),
                format!("{:?} is not a usable quaternion", image.qvec),
            )
        })?;
        if image.tvec.iter().any(|v| !v.is_finite()) {
            return Err(IoError::field(
                &self.images_path,
                field("tvec"),
                "a value is not finite",
            ));
        }
        let ([fx, fy, cx, cy], distortion) = cam.intrinsics();
        Ok(CameraInfo {
            camera: Camera {
                width: cam.width,
                height: cam.height,
                fx: fx as f32,
                fy: fy as f32,
                cx: cx as f32,
                cy: cy as f32,
                rotation,
                translation: Vec3::from_array(image.tvec.map(|v| v as f32)),
            },
            skew: 0.0,
            distortion,
        })
    }
}
