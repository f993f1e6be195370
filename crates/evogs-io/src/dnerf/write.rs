//! Writing a D-NeRF split: `DIR/<split>/r_NNN.png` (RGBA, 8 bit, straight alpha) and
//! `DIR/transforms_<split>.json` (`camera_angle_x`; frames: `file_path`, `time`,
//! `transform_matrix`), the layout [`read_dnerf_split`](super::read_dnerf_split) reads. Every
//! file is written atomically.
//!
//! What it is not: a dataset converter. Whatever else a scene holds beside its images (a point
//! cloud, ground truth) is for its writer to add.

use std::io::Write;
use std::path::Path;

use serde_json::json;
use splat_core::Camera;

use super::Split;
use crate::IoError;
use crate::atomic::write_atomically;
use crate::image_io::to_u8;

/// One image of a split to write: its time, its camera and its pixels.
#[derive(Clone, Copy, Debug)]
pub struct DnerfImage<'a> {
    /// Time in [0, 1].
    pub time: f32,
    /// The camera (OpenCV axes); its `width × height` is the image's size.
    pub camera: &'a Camera,
    /// Colour premultiplied by `alpha` (rendered over black), row-major.
    pub color: &'a [[f32; 3]],
    /// Accumulated opacity, row-major.
    pub alpha: &'a [f32],
}

/// The camera's `transform_matrix` for D-NeRF: camera-to-world in OpenGL axes (columns: camera
/// +x, +y (up), +z (backwards) in world, and the centre), rows of a 4×4 matrix. The inverse of
/// [`camera_from_opengl_c2w`](super::camera_from_opengl_c2w).
pub fn opengl_c2w(camera: &Camera) -> [[f64; 4]; 4] {
    let r = camera.rotation;
    // Rows of R are the OpenCV axes in world; OpenGL's y and z are their negatives.
    let x = r.row(0).as_dvec3();
    let y = -r.row(1).as_dvec3();
    let z = -r.row(2).as_dvec3();
    let c = camera.center().as_dvec3();
    [
        [x.x, y.x, z.x, c.x],
        [x.y, y.y, z.y, c.y],
        [x.z, y.z, z.z, c.z],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

/// D-NeRF's `camera_angle_x` of a camera: `2·atan(0.5·W / fx)`.
pub fn dnerf_camera_angle_x(camera: &Camera) -> f64 {
    2.0 * (0.5 * f64::from(camera.width) / f64::from(camera.fx)).atan()
}

/// Encodes an image as an RGBA PNG with straight alpha: `color / alpha` (0 where `alpha` ≤ 1e-6),
/// each channel through [`to_u8`].
fn encode_rgba(path: &Path, image: &DnerfImage<'_>) -> Result<Vec<u8>, IoError> {
    let (w, h) = (image.camera.width, image.camera.height);
    let pixels = w as usize * h as usize;
    if image.color.len() != pixels || image.alpha.len() != pixels {
        return Err(IoError::InvalidData {
            path: path.to_path_buf(),
            problem: format!(
                "{} colours and {} alphas for a {w}×{h} camera",
                image.color.len(),
                image.alpha.len()
            ),
        });
    }
    let mut bytes = Vec::with_capacity(pixels * 4);
    for (c, &a) in image.color.iter().zip(image.alpha) {
        let straight = |v: f32| if a > 1e-6 { v / a } else { 0.0 };
        bytes.extend([
            to_u8(straight(c[0])),
            to_u8(straight(c[1])),
            to_u8(straight(c[2])),
            to_u8(a),
        ]);
    }
    let rgba = image::RgbaImage::from_raw(w, h, bytes).ok_or_else(|| IoError::InvalidData {
        path: path.to_path_buf(),
        problem: "pixel buffer does not match the camera size".into(),
    })?;
    let mut png = Vec::new();
    rgba.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .map_err(|cause| IoError::Image {
            path: path.to_path_buf(),
            cause,
        })?;
    Ok(png)
}

fn write_bytes(path: &Path, bytes: &[u8]) -> Result<(), IoError> {
    write_atomically(path, |w| {
        w.write_all(bytes).map_err(|e| IoError::io(path, e))
    })
}

/// Writes one split of a D-NeRF dataset into `dir` (created if missing): image `i` as
/// `dir/<split>/r_{i:03}.png` and the split's `transforms_<split>.json` with `camera_angle_x`
/// (the caller's, e.g. [`dnerf_camera_angle_x`] of the first camera) and one frame per image.
pub fn write_dnerf_split(
    dir: &Path,
    split: Split,
    images: &[DnerfImage<'_>],
    camera_angle_x: f64,
) -> Result<(), IoError> {
    let sub = dir.join(split.name());
    std::fs::create_dir_all(&sub).map_err(|e| IoError::io(&sub, e))?;
    let mut entries = Vec::with_capacity(images.len());
    for (i, image) in images.iter().enumerate() {
        let stem = format!("r_{i:03}");
        let path = sub.join(format!("{stem}.png"));
        write_bytes(&path, &encode_rgba(&path, image)?)?;
        entries.push(json!({
            "file_path": format!("./{}/{stem}", split.name()),
            "time": image.time,
            "transform_matrix": opengl_c2w(image.camera),
        }));
    }
    let doc = json!({ "camera_angle_x": camera_angle_x, "frames": entries });
    let path = split.transforms_path(dir);
    let text = serde_json::to_string_pretty(&doc).map_err(|cause| IoError::Json {
        path: path.clone(),
        cause,
    })?;
    write_bytes(&path, text.as_bytes())
}
