//! nerfstudio datasets (`transforms.json`, what `ns-process-data` and brush write), read as
//! nerfstudio's `nerfstudio_dataparser.py` reads them, with the differences listed below:
//!
//! ```text
//! DIR/transforms.json     intrinsics, camera_model, frames [{file_path, transform_matrix, time?}]
//! DIR/<file_path>         the images (any folder)
//! DIR/<ply_file_path>     optional initial points (x y z red green blue)
//! ```
//!
//! - Intrinsics `fl_x`, `fl_y`, `cx`, `cy`, `w`, `h`: each at the top level (shared by every
//!   frame) or in every frame. Distortion `k1 k2 k3 k4 p1 p2` or `distortion_params` (those six
//!   in that order): at the top level when any of `k1 k2 k3 p1 p2 distortion_params` is there,
//!   else per frame; missing coefficients are 0 (nerfstudio's rules).
//! - `camera_model`: `OPENCV` (the default) and the other perspective models keep `k1 k2 k3`
//!   and `p1 p2`; `OPENCV_FISHEYE` keeps `k1..k4` as fisheye coefficients. Distortion is kept in
//!   [`CameraInfo`] and reported, never applied (render undistorted images, e.g. COLMAP's
//!   `image_undistorter` output, for a sharp result). Equirectangular, omnidirectional and
//!   orthographic models are errors.
//! - `transform_matrix`: camera-to-world in OpenGL axes (3×4 or 4×4), converted to OpenCV axes
//!   as the D-NeRF reader does; principal point `cx, cy` in pixels as written.
//! - Frames are sorted by image path (nerfstudio sorts by file name). Time: the frame's `time`
//!   (in [0, 1]) when every frame has one; when none has, [`TimeFrom`] over the image paths
//!   (relative to DIR); some with and some without is an error.
//! - Split: `train_filenames` / `val_filenames` / `test_filenames` when present (names relative
//!   to DIR; each must be a frame; `train_filenames` required once any is given, and not empty).
//!   Otherwise nerfstudio's default `fraction` rule: `ceil(0.9·N)` training frames at
//!   `floor(linspace(0, N − 1, ceil(0.9·N)))`, the rest test (nerfstudio's val and test).
//! - Points: `ply_file_path` when given (already in the stored coordinates, as
//!   `ns-process-data` writes it). Otherwise, when `colmap/sparse/0` exists, its `points3D`
//!   mapped by `applied_transform` (3×4, COLMAP → stored coordinates; absent: nerfstudio's
//!   legacy `[[0,1,0,0],[1,0,0,0],[0,0,-1,0]]`), as `ns-process-data` would have written them.
//! - Not done: nerfstudio's own re-orientation, centring and scaling of the poses
//!   (`orientation_method`, `center_method`, `auto_scale_poses`) and its automatic
//!   `images_N` downscale: cameras stay in the file's coordinates, like the COLMAP reader's, and
//!   the trainer's `--downscale` resizes.

use std::path::{Path, PathBuf};

use glam::{DMat3, DVec3, Vec3};

use crate::IoError;
use crate::camera_info::{CameraInfo, Distortion};
use crate::camera_json::image_side;
use crate::colmap;
use crate::dataset_types::{Dataset, Format, Frame, PointCloud};
use crate::dnerf::camera_from_opengl_c2w;
use crate::frame_time::{TimeFrom, times_from_names};
use crate::json_fields::{Fields, ROTATION_TOLERANCE, load_json, rotation_error};
use crate::ply::read_point_cloud;

/// The transforms file of a nerfstudio dataset directory.
pub const TRANSFORMS_FILE: &str = "transforms.json";

/// nerfstudio's training fraction when no split lists are given (`train_split_fraction`).
pub const TRAIN_FRACTION: f64 = 0.9;

/// The `applied_transform` nerfstudio assumes for datasets from COLMAP written before the field
/// existed (COLMAP → stored coordinates).
pub const LEGACY_APPLIED_TRANSFORM: [[f64; 4]; 3] = [
    [0.0, 1.0, 0.0, 0.0],
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 0.0, -1.0, 0.0],
];

/// How distortion coefficients are read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Lens {
    /// OpenCV's radial-tangential model (and its special cases).
    Perspective,
    /// OpenCV's equidistant fisheye model.
    Fisheye,
}

fn lens_of(top: &Fields<'_>) -> Result<Lens, IoError> {
    if top.optional("camera_model").is_none() {
        return Ok(Lens::Perspective);
    }
    let name = top.string("camera_model")?;
    match name {
        "SIMPLE_PINHOLE" | "PINHOLE" | "SIMPLE_RADIAL" | "RADIAL" | "OPENCV" => {
            Ok(Lens::Perspective)
        }
        "OPENCV_FISHEYE" => Ok(Lens::Fisheye),
        other => Err(top.error(
            "camera_model",
            format!(
                "`{other}` is not supported; supported: SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, \
                 RADIAL, OPENCV, OPENCV_FISHEYE"
            ),
        )),
    }
}

/// The distortion of `fields` (the top level or a frame) under `lens`.
fn distortion_of(fields: &Fields<'_>, lens: Lens) -> Result<Distortion, IoError> {
    // [k1, k2, k3, k4, p1, p2], as nerfstudio's `get_distortion_params`.
    let k = match fields.optional_numbers("distortion_params", 6..=6)? {
        Some(params) => params,
        None => ["k1", "k2", "k3", "k4", "p1", "p2"]
            .iter()
            .map(|key| Ok(fields.optional_number(key)?.unwrap_or(0.0)))
            .collect::<Result<Vec<f64>, IoError>>()?,
    };
    let k = k.iter().map(|&v| v as f32).collect::<Vec<f32>>();
    Ok(match lens {
        Lens::Perspective => {
            if k[3] != 0.0 {
                let key = if fields.optional("distortion_params").is_some() {
                    "distortion_params[3]"
                } else {
                    "k4"
                };
                return Err(fields.error(
                    key,
                    "k4 is read only for OPENCV_FISHEYE; a perspective camera_model keeps k1 k2 \
                     k3 p1 p2",
                ));
            }
            Distortion {
                radial: [k[0], k[1], k[2]],
                tangential: [k[4], k[5]],
                ..Distortion::default()
            }
        }
        Lens::Fisheye => Distortion {
            fisheye: [k[0], k[1], k[2], k[3]],
            tangential: [k[4], k[5]],
            ..Distortion::default()
        },
    })
}

/// One frame as read, before times and splits.
struct Parsed {
    image_path: PathBuf,
    /// The image path relative to the dataset directory, for times from names.
    relative: String,
    time: Option<f64>,
    camera: CameraInfo,
}

/// `key` from the frame when the top level does not have it.
fn pick<'a, 'b>(top: &'b Fields<'a>, frame: &'b Fields<'a>, key: &str) -> &'b Fields<'a> {
    if top.optional(key).is_some() {
        top
    } else {
        frame
    }
}

fn parse_frame(
    dir: &Path,
    top: &Fields<'_>,
    frame: &Fields<'_>,
    lens: Lens,
    shared_distortion: Option<Distortion>,
) -> Result<Parsed, IoError> {
    let file_path = frame.string("file_path")?;
    let image_path = dir.join(file_path);
    if !image_path.is_file() {
        return Err(frame.error(
            "file_path",
            format!("image {} does not exist", image_path.display()),
        ));
    }
    let number = |key: &str| pick(top, frame, key).number(key);
    let side = |key: &str| {
        let fields = pick(top, frame, key);
        image_side(fields, key, fields.number(key)?)
    };
    let (width, height) = (side("w")?, side("h")?);
    let (fx, fy, cx, cy) = (
        number("fl_x")?,
        number("fl_y")?,
        number("cx")?,
        number("cy")?,
    );
    for (key, value) in [("fl_x", fx), ("fl_y", fy)] {
        if value <= 0.0 {
            return Err(pick(top, frame, key).error(key, format!("{value} is not positive")));
        }
    }
    let m = frame.matrix("transform_matrix", 3..=4, 4)?;
    let c2w = [0, 1, 2].map(|r| [m[r][0], m[r][1], m[r][2], m[r][3]]);
    let err = rotation_error(&[0, 1, 2].map(|r| [c2w[r][0], c2w[r][1], c2w[r][2]]));
    if err > ROTATION_TOLERANCE {
        return Err(frame.error(
            "transform_matrix",
            format!("rotation part is not a rotation (R·Rᵀ − I reaches {err:.3e}, or det <= 0)"),
        ));
    }
    let mut camera = camera_from_opengl_c2w(&c2w, width, height, fx, fy);
    camera.cx = cx as f32;
    camera.cy = cy as f32;
    let distortion = match shared_distortion {
        Some(d) => d,
        None => distortion_of(frame, lens)?,
    };
    let time = frame.optional_number("time")?;
    if let Some(t) = time
        && !(0.0..=1.0).contains(&t)
    {
        return Err(frame.error("time", format!("{t} is outside [0, 1]")));
    }
    Ok(Parsed {
        image_path,
        relative: file_path.trim_start_matches("./").to_string(),
        time,
        camera: CameraInfo {
            camera,
            skew: 0.0,
            distortion,
        },
    })
}

/// nerfstudio's `get_train_eval_split_fraction`: training indices
/// `floor(linspace(0, n − 1, ceil(n · fraction)))`; the rest are eval indices.
pub fn fraction_split(n: usize, fraction: f64) -> (Vec<usize>, Vec<usize>) {
    let train_count = ((n as f64 * fraction).ceil() as usize).min(n);
    let train: Vec<usize> = match train_count {
        0 => Vec::new(),
        1 => vec![0],
        count => {
            // numpy: step = (stop − start) / (num − 1), y = arange(num) · step, y[-1] = stop.
            let step = (n - 1) as f64 / (count - 1) as f64;
            (0..count)
                .map(|i| {
                    if i == count - 1 {
                        n - 1
                    } else {
                        (i as f64 * step).floor() as usize
                    }
                })
                .collect()
        }
    };
    let eval = (0..n).filter(|i| !train.contains(i)).collect();
    (train, eval)
}

/// The frame indices a split list names (`key`, e.g. `train_filenames`), in frame order.
fn listed(
    top: &Fields<'_>,
    dir: &Path,
    key: &str,
    frames: &[Parsed],
) -> Result<Option<Vec<usize>>, IoError> {
    if top.optional(key).is_none() {
        return Ok(None);
    }
    let mut indices = Vec::new();
    for (i, entry) in top.array(key)?.iter().enumerate() {
        let field = format!("{key}[{i}]");
        let name = entry
            .as_str()
            .ok_or_else(|| top.error(&field, "expected a string"))?;
        let path = dir.join(name);
        let index = frames
            .iter()
            .position(|f| f.image_path == path)
            .ok_or_else(|| top.error(&field, format!("`{name}` is not a frame's file_path")))?;
        indices.push(index);
    }
    indices.sort_unstable();
    indices.dedup();
    Ok(Some(indices))
}

/// A 3×4 (or 4×4) affine matrix, e.g. `applied_transform`.
fn affine(top: &Fields<'_>, key: &str) -> Result<Option<[[f64; 4]; 3]>, IoError> {
    if top.optional(key).is_none() {
        return Ok(None);
    }
    let m = top.matrix(key, 3..=4, 4)?;
    Ok(Some(
        [0, 1, 2].map(|r| [m[r][0], m[r][1], m[r][2], m[r][3]]),
    ))
}

fn points_of(
    dir: &Path,
    top: &Fields<'_>,
    applied: Option<[[f64; 4]; 3]>,
) -> Result<Option<PointCloud>, IoError> {
    if top.optional("ply_file_path").is_some() {
        let path = dir.join(top.string("ply_file_path")?);
        if !path.is_file() {
            return Err(top.error(
                "ply_file_path",
                format!("{} does not exist", path.display()),
            ));
        }
        return read_point_cloud(&path).map(Some);
    }
    let sparse = dir.join("colmap").join("sparse").join("0");
    if !sparse.is_dir() {
        return Ok(None);
    }
    let model = colmap::read_colmap_model(&sparse)?;
    let m = applied.unwrap_or(LEGACY_APPLIED_TRANSFORM);
    let linear = DMat3::from_cols_array_2d(&[0, 1, 2].map(|c| [m[0][c], m[1][c], m[2][c]]));
    let shift = DVec3::new(m[0][3], m[1][3], m[2][3]);
    Ok(Some(PointCloud {
        positions: model
            .points
            .iter()
            .map(|p| (linear * DVec3::from_array(p.xyz) + shift).as_vec3())
            .collect(),
        colours: model
            .points
            .iter()
            .map(|p| Vec3::from_array(p.rgb.map(|v| f32::from(v) / 255.0)))
            .collect(),
    }))
}

/// Reads a nerfstudio dataset directory (see the module docs); `time_from` gives times when the
/// frames have no `time`.
pub fn read_nerfstudio_dataset(dir: &Path, time_from: TimeFrom) -> Result<Dataset, IoError> {
    let path = dir.join(TRANSFORMS_FILE);
    let value = load_json(&path)?;
    let top = Fields::object(&path, &value, "")?;
    let lens = lens_of(&top)?;
    let shared = ["k1", "k2", "k3", "p1", "p2", "distortion_params"]
        .iter()
        .any(|key| top.optional(key).is_some());
    let shared_distortion = if shared {
        Some(distortion_of(&top, lens)?)
    } else {
        None
    };
    let applied = affine(&top, "applied_transform")?;
    let mut frames = Vec::new();
    for (i, frame) in top.array("frames")?.iter().enumerate() {
        let fields = Fields::object(&path, frame, &format!("frames[{i}]"))?;
        frames.push(parse_frame(dir, &top, &fields, lens, shared_distortion)?);
    }
    if frames.is_empty() {
        return Err(top.error("frames", "no frames"));
    }
    frames.sort_by(|a, b| a.image_path.cmp(&b.image_path));
    // Times: all given, or none given and taken from the names.
    let timed = frames.iter().filter(|f| f.time.is_some()).count();
    let times: Vec<f32> = if timed == frames.len() {
        frames
            .iter()
            .map(|f| f.time.unwrap_or(0.0) as f32)
            .collect()
    } else if timed == 0 {
        let names: Vec<&str> = frames.iter().map(|f| f.relative.as_str()).collect();
        times_from_names(&names, time_from)
            .map_err(|(index, problem)| top.error(&format!("frames[{index}].file_path"), problem))?
    } else {
        let missing = frames.iter().position(|f| f.time.is_none()).unwrap_or(0);
        return Err(top.error(
            "frames",
            format!(
                "{timed} of {} frames have a `time`; {} has none (give every frame a time, or \
                 none)",
                frames.len(),
                frames[missing].relative
            ),
        ));
    };
    let lists = [
        listed(&top, dir, "train_filenames", &frames)?,
        listed(&top, dir, "val_filenames", &frames)?,
        listed(&top, dir, "test_filenames", &frames)?,
    ];
    let [train, val, test] = match lists {
        [None, None, None] => {
            let (train, eval) = fraction_split(frames.len(), TRAIN_FRACTION);
            [train, Vec::new(), eval]
        }
        [None, ..] => {
            return Err(top.error(
                "train_filenames",
                "missing while val_filenames or test_filenames is given",
            ));
        }
        [Some(train), ..] if train.is_empty() => {
            return Err(top.error("train_filenames", "names no frame: nothing to train on"));
        }
        [Some(train), val, test] => [train, val.unwrap_or_default(), test.unwrap_or_default()],
    };
    let points = points_of(dir, &top, applied)?;
    let take = |indices: &[usize]| -> Vec<Frame> {
        indices
            .iter()
            .map(|&i| Frame {
                image_path: frames[i].image_path.clone(),
                time: times[i],
                camera: frames[i].camera,
            })
            .collect()
    };
    Ok(Dataset {
        format: Format::Nerfstudio,
        train: take(&train),
        test: take(&test),
        val: take(&val),
        points,
        normalisation: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fraction_split_matches_numpy_linspace() {
        // nerfstudio on 10 images: ceil(9.0) = 9 training frames, linspace(0, 9, 9) floored.
        let (train, eval) = fraction_split(10, 0.9);
        assert_eq!(train, vec![0, 1, 2, 3, 4, 5, 6, 7, 9]);
        assert_eq!(eval, vec![8]);
        // 20 images: 18 training frames, step 19/17: 9·19/17 = 10.06 skips 9; 16·19/17 =
        // 17.88, then the end point 19, skips 18.
        let (train, eval) = fraction_split(20, 0.9);
        assert_eq!(train.len(), 18);
        assert_eq!(eval, vec![9, 18]);
        assert_eq!(fraction_split(1, 0.9), (vec![0], vec![]));
        assert_eq!(fraction_split(2, 0.9), (vec![0, 1], vec![]));
        assert_eq!(fraction_split(0, 0.9), (vec![], vec![]));
    }
}
