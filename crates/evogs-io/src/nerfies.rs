//! Nerfies-layout datasets (HyperNeRF `vrig-*`/`interp-*`/`misc-*`, NeRF-DS), read as
//! Deformable-3D-Gaussians' `readNerfiesInfo` / `readNerfiesCameras` does
//! (ingra14m/Deformable-3D-Gaussians, `scene/dataset_readers.py`):
//!
//! ```text
//! DIR/dataset.json      {"ids": [...], "train_ids": [...], "val_ids": [...]}
//! DIR/metadata.json     {"<id>": {"time_id": n, "camera_id": n, ...}, ...}   (or "warp_id")
//! DIR/scene.json        {"scale": s, "center": [x, y, z], "near": n, "far": f}
//! DIR/camera/<id>.json  nerfies camera JSON (DESIGN §1.3), at full resolution
//! DIR/rgb/<N>x/<id>.png images downscaled by N
//! DIR/points.npy        (P, 3) float array, optional
//! ```
//!
//! - Split and downscale from the directory name, as D-3DGS: `vrig*` → `train_ids`/`val_ids` at
//!   4x; `NeRF*` (NeRF-DS) → `train_ids`/`val_ids` at 1x; `interp*` → every 4th of `ids` from 0
//!   for training and from 2 for testing, at 2x; otherwise every 4th of `ids` for training, no
//!   test frames, at 2x. [`LoadOptions`] can override both.
//! - Time: `time_id` (or `warp_id` when there is no `time_id`) divided by its maximum over the
//!   selected frames (0 for every frame when that maximum is 0).
//! - Cameras: focal length, principal point, skew and image size scaled by 1/N (image size
//!   rounded; the image file must have that size to a pixel, and its exact size is used);
//!   positions normalised as `(C − center) · scale`, orientation unchanged.
//! - Points: `(p − center) · scale`; `points.npy` has no colours, and D-3DGS gives them SH
//!   values of `rand/255`, i.e. colours within 0.002 of 0.5: here exactly 0.5 grey.

use std::path::Path;

use glam::Vec3;
use serde_json::Value;

use crate::camera_info::CameraInfo;
use crate::dataset_types::{
    Dataset, Format, Frame, LoadOptions, NerfiesSplit, Normalisation, PointCloud,
};
use crate::json_fields::{Fields, load_json};
use crate::npy::read_npy;
use crate::{IoError, read_nerfies_camera};

/// The split rule and downscale D-3DGS picks from a scene directory's name.
pub fn nerfies_defaults(dir: &Path) -> (NerfiesSplit, u32) {
    // Canonicalised so that `.` or a trailing `..` still give the folder's own name.
    let dir = dir.canonicalize().unwrap_or_else(|_| dir.to_path_buf());
    let name = dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    if name.starts_with("vrig") {
        (NerfiesSplit::TrainVal, 4)
    } else if name.starts_with("NeRF") {
        (NerfiesSplit::TrainVal, 1)
    } else if name.starts_with("interp") {
        (NerfiesSplit::Interp, 2)
    } else {
        (NerfiesSplit::EveryFourth, 2)
    }
}

fn id_list(fields: &Fields<'_>, key: &str) -> Result<Vec<String>, IoError> {
    fields
        .array(key)?
        .iter()
        .enumerate()
        .map(|(i, v)| {
            v.as_str()
                .map(str::to_owned)
                .ok_or_else(|| fields.error(&format!("{key}[{i}]"), "expected a string id"))
        })
        .collect()
}

/// Reads a nerfies-layout dataset directory (see the module docs).
pub fn read_nerfies_dataset(dir: &Path, options: &LoadOptions) -> Result<Dataset, IoError> {
    let (auto_split, auto_downscale) = nerfies_defaults(dir);
    let split = options.nerfies_split.unwrap_or(auto_split);
    let downscale = options.nerfies_downscale.unwrap_or(auto_downscale);

    let dataset_path = dir.join("dataset.json");
    let dataset_json = load_json(&dataset_path)?;
    let dataset = Fields::object(&dataset_path, &dataset_json, "")?;
    let (train_ids, test_ids) = match split {
        NerfiesSplit::TrainVal => (
            id_list(&dataset, "train_ids")?,
            id_list(&dataset, "val_ids")?,
        ),
        NerfiesSplit::Interp => {
            let ids = id_list(&dataset, "ids")?;
            (
                ids.iter().step_by(4).cloned().collect(),
                ids.iter().skip(2).step_by(4).cloned().collect(),
            )
        }
        NerfiesSplit::EveryFourth => {
            let ids = id_list(&dataset, "ids")?;
            (ids.iter().step_by(4).cloned().collect(), Vec::new())
        }
    };
    if train_ids.is_empty() {
        return Err(dataset.error("train_ids", "no training frames selected"));
    }

    let scene_path = dir.join("scene.json");
    let scene_json = load_json(&scene_path)?;
    let scene = Fields::object(&scene_path, &scene_json, "")?;
    let scale = scene.number("scale")?;
    if scale <= 0.0 {
        return Err(scene.error("scale", format!("{scale} is not positive")));
    }
    let c = scene.numbers("center", 3..=3)?;
    let normalisation = Normalisation {
        center: Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32),
        scale: scale as f32,
    };

    let metadata_path = dir.join("metadata.json");
    let metadata_json = load_json(&metadata_path)?;
    let metadata = Fields::object(&metadata_path, &metadata_json, "")?;
    let time_of = |id: &str| -> Result<f64, IoError> {
        let entry: &Value = metadata.required(id)?;
        let fields = Fields::object(&metadata_path, entry, id)?;
        let key = if fields.optional("time_id").is_some() {
            "time_id"
        } else {
            "warp_id"
        };
        let time = fields.number(key)?;
        if time < 0.0 {
            return Err(fields.error(key, format!("{time} is negative")));
        }
        Ok(time)
    };
    let all_ids: Vec<&String> = train_ids.iter().chain(&test_ids).collect();
    let raw_times = all_ids
        .iter()
        .map(|id| time_of(id))
        .collect::<Result<Vec<f64>, IoError>>()?;
    let max_time = raw_times.iter().copied().fold(0.0, f64::max);

    let mut frames = Vec::with_capacity(all_ids.len());
    for (id, raw_time) in all_ids.iter().zip(&raw_times) {
        let camera_path = dir.join("camera").join(format!("{id}.json"));
        if !camera_path.is_file() {
            return Err(dataset.error(
                "ids",
                format!("id `{id}` has no camera file {}", camera_path.display()),
            ));
        }
        let info = read_nerfies_camera(&camera_path)?;
        let camera = normalise(downscale_camera(info, downscale), normalisation);
        let image_path = dir
            .join("rgb")
            .join(format!("{downscale}x"))
            .join(format!("{id}.png"));
        if !image_path.is_file() {
            return Err(dataset.error(
                "ids",
                format!("id `{id}` has no image {}", image_path.display()),
            ));
        }
        // The image must have the camera's (rounded) size; adopt its exact size.
        let (w, h) = image::image_dimensions(&image_path).map_err(|cause| IoError::Image {
            path: image_path.clone(),
            cause,
        })?;
        let mut camera = camera;
        let c = &mut camera.camera;
        if c.width.abs_diff(w) > 1 || c.height.abs_diff(h) > 1 {
            return Err(IoError::field(
                &camera_path,
                "image_size",
                format!(
                    "scaled by 1/{downscale} it is {}×{}, but {} is {w}×{h}",
                    c.width,
                    c.height,
                    image_path.display()
                ),
            ));
        }
        (c.width, c.height) = (w, h);
        let time = if max_time > 0.0 {
            (raw_time / max_time) as f32
        } else {
            0.0
        };
        frames.push(Frame {
            image_path,
            time,
            camera,
        });
    }
    let test = frames.split_off(train_ids.len());

    let points_path = dir.join("points.npy");
    let points = if points_path.exists() {
        let array = read_npy(&points_path)?;
        let rows = array.expect_2d(&points_path, 3)?;
        let positions: Vec<Vec3> = rows
            .iter()
            .map(|r| {
                (Vec3::new(r[0] as f32, r[1] as f32, r[2] as f32) - normalisation.center)
                    * normalisation.scale
            })
            .collect();
        if positions.iter().any(|p| !p.is_finite()) {
            return Err(IoError::field(
                &points_path,
                "data",
                "a point is not finite",
            ));
        }
        Some(PointCloud {
            colours: vec![Vec3::splat(0.5); positions.len()],
            positions,
        })
    } else {
        None
    };

    Ok(Dataset {
        format: Format::Nerfies,
        train: frames,
        test,
        val: Vec::new(),
        points,
        normalisation: Some(normalisation),
    })
}

/// Scales a full-resolution camera to images downscaled by `factor` (focal length, principal
/// point and skew by 1/factor, image size rounded, at least 1 pixel).
fn downscale_camera(mut info: CameraInfo, factor: u32) -> CameraInfo {
    if factor == 1 {
        return info;
    }
    let s = 1.0 / factor as f32;
    let c = &mut info.camera;
    c.fx *= s;
    c.fy *= s;
    c.cx *= s;
    c.cy *= s;
    c.width = ((c.width as f32 * s).round() as u32).max(1);
    c.height = ((c.height as f32 * s).round() as u32).max(1);
    info.skew *= s;
    info
}

/// Moves the camera centre to `(C − center) · scale`, keeping its orientation.
fn normalise(mut info: CameraInfo, n: Normalisation) -> CameraInfo {
    let c = &mut info.camera;
    let centre = -(c.rotation.transpose() * c.translation);
    let moved = (centre - n.center) * n.scale;
    c.translation = -(c.rotation * moved);
    info
}
