//! Neu3D / DyNeRF datasets, read as 4DGaussians' `Neural3D_NDC_Dataset` (hustvl/4DGaussians,
//! `scene/neural_3D_dataset_NDC.py`, which Deformable-3D-Gaussians-style trainers follow):
//!
//! ```text
//! DIR/poses_bounds.npy          (N, 17): per camera a 3×5 matrix [R | C | hwf], then near, far
//! DIR/cam00/images/0000.png     frames of each camera's video (cam00.mp4 → cam00/images/)
//! DIR/cam01/images/0000.png
//! ...
//! ```
//!
//! - Camera folders are the sorted directories `cam*` that hold an `images/` folder; the i-th
//!   matches row i of `poses_bounds.npy`. When there are none, the sorted subfolders of
//!   `DIR/frames/` are used instead (Deformable-3D-Gaussians' `readCamerasFromNpy` layout,
//!   `frames/<camera>/<image>`). Frames are the `.png`/`.jpg` files, sorted by name, at most
//!   `max_frames` (4DGaussians: 300) per camera.
//! - Pose: the 3×4 part is camera-to-world in LLFF axes (columns: down, right, back, centre).
//!   OpenCV axes are right = column 1, down = column 0, forward = −column 2 (the same camera
//!   4DGaussians builds by going through OpenGL axes).
//! - Intrinsics: `hwf` is (height, width, focal) at the video's resolution; fx = fy = focal,
//!   principal point at the image centre, all scaled to the size of the camera's first frame
//!   (so frames extracted at a lower resolution get matching cameras).
//! - Split: the cameras listed in `test_cameras` (default camera 0, `cam00`) are the test
//!   split, the others training.
//! - Time: `frame / count` by default, where count is the number of frames per camera (the
//!   largest over cameras, after the cap): 4DGaussians uses `idx / 300` on 300-frame videos,
//!   i.e. count, not count − 1, so the last frame's time is below 1, and the paper follows
//!   4DGaussians' protocol for Neu3D. Deformable-3D-Gaussians' `readCamerasFromNpy` uses
//!   `idx / (count − 1)` instead; [`TimeDenominator::CountMinusOne`] selects that.
//! - No point cloud (4DGaussians initialises Neu3D from a separate COLMAP run).

use std::path::{Path, PathBuf};

use glam::{Mat3, Vec3};
use splat_core::Camera;

use crate::IoError;
use crate::camera_info::CameraInfo;
pub use crate::dataset_types::TimeDenominator;
use crate::dataset_types::{Dataset, Format, Frame};
use crate::json_fields::{ROTATION_TOLERANCE, rotation_error};
use crate::npy::read_npy;

/// One row of `poses_bounds.npy`, decoded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Neu3dPose {
    /// The camera, OpenCV axes, at the `hwf` resolution.
    pub camera: Camera,
    /// Near and far bounds of the scene depth.
    pub near_far: [f64; 2],
}

/// Decodes one 17-number row of `poses_bounds.npy`; `row_index` names it in errors.
pub fn decode_pose_row(path: &Path, row_index: usize, row: &[f64]) -> Result<Neu3dPose, IoError> {
    let field = |what: &str| format!("row[{row_index}].{what}");
    if row.len() != 17 {
        return Err(IoError::field(
            path,
            field("length"),
            format!("expected 17 numbers, found {}", row.len()),
        ));
    }
    if row.iter().any(|v| !v.is_finite()) {
        return Err(IoError::field(
            path,
            field("values"),
            "a value is not finite",
        ));
    }
    let m = |r: usize, c: usize| row[r * 5 + c];
    // Rows of the world-to-camera rotation: OpenCV x = LLFF column 1, y = column 0, z = −column 2.
    let rows = [
        [m(0, 1), m(1, 1), m(2, 1)],
        [m(0, 0), m(1, 0), m(2, 0)],
        [-m(0, 2), -m(1, 2), -m(2, 2)],
    ];
    let err = rotation_error(&rows);
    if err > ROTATION_TOLERANCE {
        return Err(IoError::field(
            path,
            field("rotation"),
            format!("not a rotation (R·Rᵀ − I reaches {err:.3e}, or det <= 0)"),
        ));
    }
    let (h, w, focal) = (m(0, 4), m(1, 4), m(2, 4));
    for (name, v) in [("height", h), ("width", w)] {
        if v.fract() != 0.0 || !(1.0..=65536.0).contains(&v) {
            return Err(IoError::field(
                path,
                field(&format!("hwf.{name}")),
                format!("{v} is not a whole number of pixels in 1..=65536"),
            ));
        }
    }
    if focal <= 0.0 {
        return Err(IoError::field(
            path,
            field("hwf.focal"),
            format!("{focal} is not positive"),
        ));
    }
    let centre = [m(0, 3), m(1, 3), m(2, 3)];
    let t = rows.map(|r| -(r[0] * centre[0] + r[1] * centre[1] + r[2] * centre[2]) as f32);
    let rotation = Mat3::from_cols_array_2d(&rows.map(|r| r.map(|v| v as f32))).transpose();
    let (near, far) = (row[15], row[16]);
    Ok(Neu3dPose {
        camera: Camera {
            width: w as u32,
            height: h as u32,
            fx: focal as f32,
            fy: focal as f32,
            cx: 0.5 * w as f32,
            cy: 0.5 * h as f32,
            rotation,
            translation: Vec3::from_array(t),
        },
        near_far: [near, far],
    })
}

fn list_dir(dir: &Path) -> Result<Vec<PathBuf>, IoError> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| IoError::io(dir, e))? {
        out.push(entry.map_err(|e| IoError::io(dir, e))?.path());
    }
    out.sort();
    Ok(out)
}

fn is_image(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| matches!(e.to_ascii_lowercase().as_str(), "png" | "jpg" | "jpeg"))
}

/// Scales a camera to an image of `width × height`; the aspect ratio must agree to a pixel.
fn fit_to_image(camera: Camera, width: u32, height: u32) -> Option<Camera> {
    let s = width as f32 / camera.width as f32;
    if (camera.height as f32 * s - height as f32).abs() > 1.0 {
        return None;
    }
    let sy = height as f32 / camera.height as f32;
    Some(Camera {
        width,
        height,
        fx: camera.fx * s,
        fy: camera.fy * s,
        cx: camera.cx * s,
        cy: camera.cy * sy,
        ..camera
    })
}

/// Reads a Neu3D dataset directory (see the module docs).
pub fn read_neu3d_dataset(
    dir: &Path,
    test_cameras: &[usize],
    max_frames: usize,
    time_denominator: TimeDenominator,
) -> Result<Dataset, IoError> {
    let poses_path = dir.join("poses_bounds.npy");
    let array = read_npy(&poses_path)?;
    let rows = array.expect_2d(&poses_path, 17)?;
    let poses = rows
        .iter()
        .enumerate()
        .map(|(i, r)| decode_pose_row(&poses_path, i, r))
        .collect::<Result<Vec<_>, _>>()?;
    let mut image_dirs: Vec<PathBuf> = list_dir(dir)?
        .into_iter()
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("cam"))
                && p.join("images").is_dir()
        })
        .map(|p| p.join("images"))
        .collect();
    let frames_dir = dir.join("frames");
    if image_dirs.is_empty() && frames_dir.is_dir() {
        image_dirs = list_dir(&frames_dir)?
            .into_iter()
            .filter(|p| p.is_dir())
            .collect();
    }
    if image_dirs.len() != poses.len() {
        return Err(IoError::field(
            &poses_path,
            "shape",
            format!(
                "{} camera poses but {} camera folders (cam*/images/ or frames/*/) in {}",
                poses.len(),
                image_dirs.len(),
                dir.display()
            ),
        ));
    }
    if let Some(&bad) = test_cameras.iter().find(|&&i| i >= poses.len()) {
        return Err(IoError::field(
            &poses_path,
            "shape",
            format!("test camera {bad} does not exist ({} cameras)", poses.len()),
        ));
    }
    let mut per_camera = Vec::with_capacity(poses.len());
    for images_dir in &image_dirs {
        let mut images: Vec<PathBuf> = list_dir(images_dir)?
            .into_iter()
            .filter(|p| is_image(p))
            .collect();
        images.truncate(max_frames);
        if images.is_empty() {
            return Err(IoError::field(
                images_dir,
                "(frames)",
                "no .png or .jpg frames",
            ));
        }
        per_camera.push(images);
    }
    let count = per_camera.iter().map(Vec::len).max().unwrap_or(1);
    let denominator = match time_denominator {
        TimeDenominator::Count => count,
        TimeDenominator::CountMinusOne => count.saturating_sub(1).max(1),
    } as f32;
    let mut dataset = Dataset {
        format: Format::Neu3d,
        train: Vec::new(),
        test: Vec::new(),
        val: Vec::new(),
        points: None,
        normalisation: None,
    };
    for (index, (pose, images)) in poses.iter().zip(per_camera).enumerate() {
        let (w, h) = image::image_dimensions(&images[0]).map_err(|cause| IoError::Image {
            path: images[0].clone(),
            cause,
        })?;
        let camera = fit_to_image(pose.camera, w, h).ok_or_else(|| {
            IoError::field(
                &poses_path,
                format!("row[{index}].hwf"),
                format!(
                    "{}×{} does not have the aspect ratio of frame {} ({w}×{h})",
                    pose.camera.width,
                    pose.camera.height,
                    images[0].display()
                ),
            )
        })?;
        let split = if test_cameras.contains(&index) {
            &mut dataset.test
        } else {
            &mut dataset.train
        };
        split.extend(images.into_iter().enumerate().map(|(k, image_path)| Frame {
            image_path,
            time: k as f32 / denominator,
            camera: CameraInfo::pinhole(camera),
        }));
    }
    Ok(dataset)
}
