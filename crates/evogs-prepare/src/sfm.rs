//! Stages 2–5: COLMAP on the CPU. SIFT features (one shared camera, `SIMPLE_RADIAL`),
//! sequential or exhaustive matching, incremental mapping, the choice of the largest model, and
//! COLMAP's `image_undistorter` when that model's camera has distortion.

use std::path::{Path, PathBuf};

use evogs_io::colmap::{CameraModel, ColmapModel, read_colmap_model};

use crate::tools::{COLMAP, arg, run_logged};
use crate::{Matcher, PrepareError};

/// The camera model COLMAP fits: focal length, principal point and one radial coefficient
/// (COLMAP's default; enough for phone lenses, and undistorted before training).
pub const CAMERA_MODEL: &str = "SIMPLE_RADIAL";

/// `colmap feature_extractor` on the CPU, one camera shared by every frame.
pub fn features(
    database: &Path,
    images: &Path,
    log: &Path,
    subject: &Path,
) -> Result<(), PrepareError> {
    let args = vec![
        "feature_extractor".into(),
        "--database_path".into(),
        arg(database),
        "--image_path".into(),
        arg(images),
        "--ImageReader.single_camera".into(),
        "1".into(),
        "--ImageReader.camera_model".into(),
        CAMERA_MODEL.into(),
        "--SiftExtraction.use_gpu".into(),
        "0".into(),
    ];
    run_logged(&COLMAP, &args, log, subject, "colmap feature_extractor")
}

/// `colmap sequential_matcher` (each frame against the next 10; a video) or
/// `exhaustive_matcher` (every pair), on the CPU.
pub fn matching(
    database: &Path,
    matcher: Matcher,
    log: &Path,
    subject: &Path,
) -> Result<(), PrepareError> {
    let mut args: Vec<String> = vec![
        matcher.colmap_command().into(),
        "--database_path".into(),
        arg(database),
        "--SiftMatching.use_gpu".into(),
        "0".into(),
    ];
    if matcher == Matcher::Sequential {
        args.extend(["--SequentialMatching.overlap".into(), "10".into()]);
    }
    run_logged(
        &COLMAP,
        &args,
        log,
        subject,
        &format!("colmap {}", matcher.colmap_command()),
    )
}

/// `colmap mapper` into `sparse/` (models `sparse/0`, `sparse/1`, …); returns the model with
/// the most registered images and its folder, or `None` when COLMAP made none (a mapper that
/// fails without a model is such a case: the caller reports the registration).
pub fn map(
    database: &Path,
    images: &Path,
    sparse: &Path,
    log: &Path,
    subject: &Path,
) -> Result<Option<(ColmapModel, PathBuf)>, PrepareError> {
    std::fs::create_dir_all(sparse).map_err(|e| PrepareError::io(sparse, e))?;
    let args = vec![
        "mapper".into(),
        "--database_path".into(),
        arg(database),
        "--image_path".into(),
        arg(images),
        "--output_path".into(),
        arg(sparse),
    ];
    let ran = run_logged(&COLMAP, &args, log, subject, "colmap mapper");
    let mut best: Option<(ColmapModel, PathBuf)> = None;
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(sparse)
        .map_err(|e| PrepareError::io(sparse, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_dir())
        .collect();
    dirs.sort();
    for dir in dirs {
        let model = read_colmap_model(&dir)?;
        if best
            .as_ref()
            .is_none_or(|(b, _)| model.images.len() > b.images.len())
        {
            best = Some((model, dir));
        }
    }
    match (ran, best) {
        (Err(e), Some(_)) => Err(e),
        (_, best) => Ok(best),
    }
}

/// True when a camera of the model has a non-zero distortion coefficient.
pub fn has_distortion(model: &ColmapModel) -> bool {
    model.cameras.iter().any(|c| {
        let focal_and_centre = match c.model {
            CameraModel::SimplePinhole | CameraModel::SimpleRadial => 3,
            CameraModel::Pinhole | CameraModel::Opencv => 4,
        };
        c.params[focal_and_centre..].iter().any(|&k| k != 0.0)
    })
}

/// `colmap image_undistorter` into `out/` (`out/images`, `out/sparse/*.bin`, pinhole cameras).
pub fn undistort(
    images: &Path,
    model_dir: &Path,
    out: &Path,
    log: &Path,
    subject: &Path,
) -> Result<(), PrepareError> {
    let args = vec![
        "image_undistorter".into(),
        "--image_path".into(),
        arg(images),
        "--input_path".into(),
        arg(model_dir),
        "--output_path".into(),
        arg(out),
        "--output_type".into(),
        "COLMAP".into(),
    ];
    run_logged(&COLMAP, &args, log, subject, "colmap image_undistorter")
}
