//! The nerfies camera JSON (HyperNeRF, NeRF-DS), DESIGN §1.3: `orientation` is R (rows are the camera
//! axes in world), `position` is the centre C, `focal_length` is fx, `fy = focal_length ·
//! pixel_aspect_ratio`, `principal_point` is (cx, cy), `image_size` is [w, h]; `skew`,
//! `radial_distortion` and `tangential_distortion` are kept in [`CameraInfo`].

use std::io::Write;
use std::path::Path;

use glam::{Mat3, Vec3};
use serde::Serialize;
use splat_core::Camera;

use crate::IoError;
use crate::atomic::write_atomically;
use crate::camera_info::{CameraInfo, Distortion};
use crate::json_fields::{Fields, ROTATION_TOLERANCE, load_json, rotation_error};

/// Images wider or taller than this are rejected as a sign of a corrupt file.
pub const MAX_IMAGE_SIDE: u32 = 1 << 16;

/// Reads a nerfies camera JSON file.
pub fn read_nerfies_camera(path: &Path) -> Result<CameraInfo, IoError> {
    let value = load_json(path)?;
    let fields = Fields::object(path, &value, "")?;
    parse_nerfies(&fields)
}

/// One camera of a camera path: a nerfies camera and the scene time it shows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimedCamera {
    /// The camera (skew and distortion kept, ignored by rendering).
    pub info: CameraInfo,
    /// The scene time (training times lie in [0, 1]).
    pub time: f32,
}

/// Reads a camera path: a JSON array of nerfies camera objects, each with a finite `time`
/// (`[{"orientation": …, "position": …, …, "time": 0.25}, …]`), at least one. Errors name the
/// element, e.g. `[2].time`.
pub fn read_camera_path(path: &Path) -> Result<Vec<TimedCamera>, IoError> {
    let value = load_json(path)?;
    let serde_json::Value::Array(items) = &value else {
        return Err(IoError::field(
            path,
            "(root)",
            "expected an array of nerfies cameras with times",
        ));
    };
    if items.is_empty() {
        return Err(IoError::field(path, "(root)", "the camera path is empty"));
    }
    items
        .iter()
        .enumerate()
        .map(|(k, item)| {
            let fields = Fields::object(path, item, &format!("[{k}]"))?;
            let info = parse_nerfies(&fields)?;
            let time = fields.number("time")? as f32;
            if !time.is_finite() {
                return Err(fields.error("time", "not a finite f32"));
            }
            Ok(TimedCamera { info, time })
        })
        .collect()
}

/// An image size field `[w, h]` as whole numbers in `1..=MAX_IMAGE_SIDE`.
pub(crate) fn image_side(fields: &Fields<'_>, key: &str, value: f64) -> Result<u32, IoError> {
    if value.fract() != 0.0 || value < 1.0 || value > MAX_IMAGE_SIDE as f64 {
        return Err(fields.error(
            key,
            format!("{value} is not a whole number of pixels in 1..={MAX_IMAGE_SIDE}"),
        ));
    }
    Ok(value as u32)
}

fn parse_nerfies(fields: &Fields<'_>) -> Result<CameraInfo, IoError> {
    let m = fields.matrix("orientation", 3..=3, 3)?;
    let rows = [
        [m[0][0], m[0][1], m[0][2]],
        [m[1][0], m[1][1], m[1][2]],
        [m[2][0], m[2][1], m[2][2]],
    ];
    let err = rotation_error(&rows);
    if err > ROTATION_TOLERANCE {
        return Err(fields.error(
            "orientation",
            format!("not a rotation matrix (R·Rᵀ − I reaches {err:.3e}, or det(R) <= 0)"),
        ));
    }
    let position = fields.numbers("position", 3..=3)?;
    let focal = fields.number("focal_length")?;
    if focal <= 0.0 {
        return Err(fields.error("focal_length", format!("{focal} is not positive")));
    }
    let aspect = fields.optional_number("pixel_aspect_ratio")?.unwrap_or(1.0);
    if aspect <= 0.0 {
        return Err(fields.error("pixel_aspect_ratio", format!("{aspect} is not positive")));
    }
    let principal = fields.numbers("principal_point", 2..=2)?;
    let size = fields.numbers("image_size", 2..=2)?;
    let width = image_side(fields, "image_size[0]", size[0])?;
    let height = image_side(fields, "image_size[1]", size[1])?;
    let skew = fields.optional_number("skew")?.unwrap_or(0.0);
    let radial = fields
        .optional_numbers("radial_distortion", 0..=3)?
        .unwrap_or_default();
    let tangential = fields
        .optional_numbers("tangential_distortion", 0..=2)?
        .unwrap_or_default();
    let mut distortion = Distortion::default();
    for (k, v) in distortion.radial.iter_mut().zip(&radial) {
        *k = *v as f32;
    }
    for (k, v) in distortion.tangential.iter_mut().zip(&tangential) {
        *k = *v as f32;
    }
    // t = −R C, in f64 so that a written camera reads back to the same f32 translation.
    let t: Vec<f64> = rows
        .iter()
        .map(|r| -(r[0] * position[0] + r[1] * position[1] + r[2] * position[2]))
        .collect();
    let rotation = Mat3::from_cols_array_2d(&rows.map(|r| r.map(|v| v as f32))).transpose();
    let camera = Camera {
        width,
        height,
        fx: focal as f32,
        // fx is stored in f32; the aspect ratio applies to that value.
        fy: (f64::from(focal as f32) * aspect) as f32,
        cx: principal[0] as f32,
        cy: principal[1] as f32,
        rotation,
        translation: Vec3::new(t[0] as f32, t[1] as f32, t[2] as f32),
    };
    Ok(CameraInfo {
        camera,
        skew: skew as f32,
        distortion,
    })
}

/// The nerfies JSON layout as written: f32 values print in their shortest form, the centre and
/// the aspect ratio in f64 so that the camera reads back to the same f32 values.
#[derive(Serialize)]
struct NerfiesOut {
    orientation: [[f32; 3]; 3],
    position: [f64; 3],
    focal_length: f32,
    principal_point: [f32; 2],
    skew: f32,
    pixel_aspect_ratio: f64,
    radial_distortion: [f32; 3],
    tangential_distortion: [f32; 2],
    image_size: [u32; 2],
}

/// The nerfies JSON text of a camera (pretty-printed, trailing newline).
pub fn nerfies_camera_json(info: &CameraInfo) -> String {
    let c = &info.camera;
    let rows = [0, 1, 2].map(|i| c.rotation.row(i).to_array());
    // C = −Rᵀ t in f64.
    let t = c.translation.to_array().map(f64::from);
    let position = [0, 1, 2].map(|j| -(0..3).map(|i| f64::from(rows[i][j]) * t[i]).sum::<f64>());
    let out = NerfiesOut {
        orientation: rows,
        position,
        focal_length: c.fx,
        principal_point: [c.cx, c.cy],
        skew: info.skew,
        pixel_aspect_ratio: f64::from(c.fy) / f64::from(c.fx),
        radial_distortion: info.distortion.radial,
        tangential_distortion: info.distortion.tangential,
        image_size: [c.width, c.height],
    };
    let mut text = serde_json::to_string_pretty(&out).unwrap_or_default();
    text.push('\n');
    text
}

/// Writes a nerfies camera JSON file atomically.
pub fn write_nerfies_camera(path: &Path, info: &CameraInfo) -> Result<(), IoError> {
    let c = &info.camera;
    let finite = [c.fx, c.fy, c.cx, c.cy, info.skew]
        .iter()
        .chain(c.rotation.to_cols_array().iter())
        .chain(c.translation.to_array().iter())
        .chain(info.distortion.radial.iter())
        .chain(info.distortion.tangential.iter())
        .all(|v| v.is_finite());
    if !finite || c.fx <= 0.0 || c.fy <= 0.0 || c.width == 0 || c.height == 0 {
        return Err(IoError::InvalidData {
            path: path.to_path_buf(),
            problem: "camera has a non-finite value, a non-positive focal length or an empty image"
                .into(),
        });
    }
    if info.distortion.fisheye.iter().any(|&k| k != 0.0) {
        return Err(IoError::InvalidData {
            path: path.to_path_buf(),
            problem: "the nerfies camera format has no fisheye distortion".into(),
        });
    }
    let text = nerfies_camera_json(info);
    write_atomically(path, |w| {
        w.write_all(text.as_bytes())
            .map_err(|e| IoError::io(path, e))
    })
}
