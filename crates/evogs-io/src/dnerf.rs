//! D-NeRF / Blender datasets (DESIGN §1.4): `transforms_{train,test,val}.json` with a frame list of
//! `file_path`, `time` and `transform_matrix` (camera-to-world, OpenGL axes). Cameras are
//! converted to OpenCV axes by flipping the camera's y and z axes; `fx = fy = 0.5·W /
//! tan(0.5·camera_angle_x)`, principal point at the image centre. Image sizes come from the
//! top-level `w`/`h` keys when present, otherwise from each image file's header. The writer of the
//! same layout is [`write_dnerf_split`] (module [`write`](mod@write)).

use glam::{Mat3, Vec3};
use splat_core::Camera;
use splat_core::one_word::{OneWord, unknown_message};
use std::path::{Path, PathBuf};

use crate::IoError;
use crate::camera_json::image_side;
use crate::json_fields::{Fields, ROTATION_TOLERANCE, load_json, rotation_error};

pub mod write;

pub use write::{DnerfImage, dnerf_camera_angle_x, opengl_c2w, write_dnerf_split};

/// A dataset split, spelled `train`, `test` or `val` (its [`Display`](std::fmt::Display) and
/// [`FromStr`](std::str::FromStr)).
#[derive(strum::Display, strum::EnumString, strum::IntoStaticStr, strum::VariantNames)]
#[strum(serialize_all = "lowercase", parse_err_ty = String, parse_err_fn = unknown_message::<Self>)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Split {
    /// `transforms_train.json`.
    Train,
    /// `transforms_test.json`.
    Test,
    /// `transforms_val.json`.
    Val,
}

impl Split {
    /// All splits.
    pub const ALL: [Split; 3] = [Split::Train, Split::Test, Split::Val];

    /// The split's name as used in file names.
    pub fn name(self) -> &'static str {
        self.into()
    }

    /// The split's transforms file in a dataset directory.
    pub fn transforms_path(self, root: &Path) -> PathBuf {
        root.join(format!("transforms_{}.json", self.name()))
    }
}

/// [`Split`]'s `from_str` error: "unknown split `x`; expected train, test or val".
impl OneWord for Split {
    const FIELD: &'static str = "split";
}

/// One frame: an image, its time and its camera.
#[derive(Clone, Debug, PartialEq)]
pub struct DnerfFrame {
    /// The image file (the `file_path` resolved against the dataset directory, `.png` added
    /// when it has no extension).
    pub image_path: PathBuf,
    /// Time in [0, 1].
    pub time: f32,
    /// The camera, OpenCV axes, at the image's full size.
    pub camera: Camera,
}

/// Converts a camera-to-world matrix in OpenGL axes (rows of a 3×4 or 4×4 matrix) to a
/// world-to-camera [`Camera`] in OpenCV axes, with the principal point at the image centre.
pub fn camera_from_opengl_c2w(
    c2w: &[[f64; 4]; 3],
    width: u32,
    height: u32,
    fx: f64,
    fy: f64,
) -> Camera {
    // Columns 0..3 of c2w are the camera's x, y, z axes in world (OpenGL); OpenCV's y and z are
    // their negatives. R's rows are the OpenCV axes.
    let axis = |j: usize, sign: f64| {
        Vec3::new(
            (sign * c2w[0][j]) as f32,
            (sign * c2w[1][j]) as f32,
            (sign * c2w[2][j]) as f32,
        )
    };
    let rotation = Mat3::from_cols(axis(0, 1.0), axis(1, -1.0), axis(2, -1.0)).transpose();
    let centre = [c2w[0][3], c2w[1][3], c2w[2][3]];
    // t = −R C in f64.
    let rows = [
        [c2w[0][0], c2w[1][0], c2w[2][0]],
        [-c2w[0][1], -c2w[1][1], -c2w[2][1]],
        [-c2w[0][2], -c2w[1][2], -c2w[2][2]],
    ];
    let t = rows.map(|r| -(r[0] * centre[0] + r[1] * centre[1] + r[2] * centre[2]) as f32);
    Camera {
        width,
        height,
        fx: fx as f32,
        fy: fy as f32,
        cx: 0.5 * width as f32,
        cy: 0.5 * height as f32,
        rotation,
        translation: Vec3::from_array(t),
    }
}

/// Resolves a frame's `file_path` against the dataset directory, adding `.png` when the path has
/// no extension (the D-NeRF convention).
fn resolve_image(dir: &Path, file_path: &str) -> PathBuf {
    let path = dir.join(file_path);
    if path.extension().is_some() {
        path
    } else {
        path.with_extension("png")
    }
}

/// Reads one `transforms_*.json` file; image paths are resolved against its directory and must
/// exist.
pub fn read_transforms(path: &Path) -> Result<Vec<DnerfFrame>, IoError> {
    let value = load_json(path)?;
    let top = Fields::object(path, &value, "")?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let fixed_w = top.optional_number("w")?;
    let fixed_h = top.optional_number("h")?;
    let fixed_size = match (fixed_w, fixed_h) {
        (Some(w), Some(h)) => Some((image_side(&top, "w", w)?, image_side(&top, "h", h)?)),
        (None, None) => None,
        (Some(_), None) => return Err(top.error("h", "missing while `w` is given")),
        (None, Some(_)) => return Err(top.error("w", "missing while `h` is given")),
    };
    let angle = top.number("camera_angle_x")?;
    if !(angle > 0.0 && angle < std::f64::consts::PI) {
        return Err(top.error(
            "camera_angle_x",
            format!("{angle} is not an angle in (0, π) radians"),
        ));
    }
    let frames = top.array("frames")?;
    let mut out = Vec::with_capacity(frames.len());
    for (i, frame) in frames.iter().enumerate() {
        let fields = Fields::object(path, frame, &format!("frames[{i}]"))?;
        let file_path = fields.string("file_path")?;
        let image_path = resolve_image(dir, file_path);
        if !image_path.is_file() {
            return Err(fields.error(
                "file_path",
                format!("image {} does not exist", image_path.display()),
            ));
        }
        let time = fields.number("time")?;
        if !(0.0..=1.0).contains(&time) {
            return Err(fields.error("time", format!("{time} is outside [0, 1]")));
        }
        let m = fields.matrix("transform_matrix", 3..=4, 4)?;
        let c2w = [0, 1, 2].map(|r| [m[r][0], m[r][1], m[r][2], m[r][3]]);
        let err = rotation_error(&[0, 1, 2].map(|r| [c2w[r][0], c2w[r][1], c2w[r][2]]));
        if err > ROTATION_TOLERANCE {
            return Err(fields.error(
                "transform_matrix",
                format!(
                    "rotation part is not a rotation (R·Rᵀ − I reaches {err:.3e}, or det <= 0)"
                ),
            ));
        }
        let (width, height) = match fixed_size {
            Some(size) => size,
            None => image::image_dimensions(&image_path).map_err(|cause| IoError::Image {
                path: image_path.clone(),
                cause,
            })?,
        };
        let focal = 0.5 * width as f64 / (0.5 * angle).tan();
        out.push(DnerfFrame {
            camera: camera_from_opengl_c2w(&c2w, width, height, focal, focal),
            image_path,
            time: time as f32,
        });
    }
    Ok(out)
}

/// Reads a split of a D-NeRF dataset directory (`root/transforms_<split>.json`).
pub fn read_dnerf_split(root: &Path, split: Split) -> Result<Vec<DnerfFrame>, IoError> {
    read_transforms(&split.transforms_path(root))
}

#[cfg(test)]
mod tests {
    use super::Split;

    #[test]
    fn messages_list_every_spelling() {
        assert_eq!(
            "x".parse::<Split>().unwrap_err(),
            "unknown split `x`; expected train, test or val"
        );
    }

    #[test]
    fn spellings_round_trip() {
        for split in Split::ALL {
            assert_eq!(split.to_string().parse::<Split>(), Ok(split));
            assert_eq!(split.name(), split.to_string());
        }
    }
}
