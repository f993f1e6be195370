//! Writing a scene in the D-NeRF layout (the splits through `evogs_io::write_dnerf_split`), with
//! its ground truth.
//!
//! ```text
//! DIR/transforms_{train,test,val}.json   camera_angle_x; frames: file_path, time, transform_matrix
//! DIR/{train,test,val}/r_NNN.png         RGBA, 8 bit, straight (un-premultiplied) alpha
//! DIR/canonical.ply                      canonical Gaussians, 3DGS PLY layout (DESIGN §2.2)
//! DIR/ground_truth.safetensors           per-frame state, f32 little-endian (see below)
//! DIR/scene.json                         index: summary, spec, seed, tensor names and shapes
//! DIR/fixed/transforms_train.json,      monocular scenes only: every training time from one fixed
//! DIR/fixed/train/r_NNN.png              camera (the flicker ground truth; a D-NeRF dataset itself)
//! ```
//!
//! `ground_truth.safetensors` holds `times` `[T]`, `means` `[T, N, 3]`, and only when the scene
//! has them `rotations` `[T, N, 4]` (raw quaternion w, x, y, z) and `sh_dc` `[T, N, 3]`; `parts`
//! `[N]` (u8: 0 body, 1 satellite, 2 occluder). `T` counts the distinct frame times of all
//! splits, sorted; [`read_ground_truth`](super::read_ground_truth) reads it back. Loading a PNG over a background `b` gives `color + b·(1 − α)`, the render over
//! `b` (to 8-bit precision). Every file is written atomically.

use std::collections::HashMap;
use std::io::Write;
use std::path::Path;

use evogs_io::atomic::write_atomically;
use evogs_io::{DnerfImage, IoError, Split, dnerf_camera_angle_x, write_dnerf_split, write_ply};
use safetensors::{Dtype, tensor::TensorView};
use serde_json::json;

use super::scene::FIXED_SPLIT;
use super::{Part, SceneSummary, SynthError, SynthFrame, SyntheticScene};

/// File name of the canonical Gaussians.
pub const PLY_FILE: &str = "canonical.ply";
/// File name of the per-frame ground truth.
pub const GROUND_TRUTH_FILE: &str = "ground_truth.safetensors";
/// File name of the scene index.
pub const SCENE_FILE: &str = "scene.json";
/// Directory of the fixed-camera sequence (`monocular` scenes only): a D-NeRF dataset whose
/// `train` split holds every training time seen from one fixed camera.
pub const FIXED_DIR: &str = FIXED_SPLIT;

fn io_error(path: &Path, cause: std::io::Error) -> IoError {
    IoError::Io {
        path: path.to_path_buf(),
        cause,
    }
}

fn write_bytes(path: &Path, bytes: &[u8]) -> Result<(), SynthError> {
    write_atomically(path, |w| w.write_all(bytes).map_err(|e| io_error(path, e)))?;
    Ok(())
}

fn f32_bytes(values: impl IntoIterator<Item = f32>) -> Vec<u8> {
    values.into_iter().flat_map(f32::to_le_bytes).collect()
}

/// Writes `frames` as the split `split` of the D-NeRF dataset `dir`.
fn write_frames(
    scene: &SyntheticScene,
    dir: &Path,
    split: Split,
    frames: &[SynthFrame],
) -> Result<(), SynthError> {
    let images: Vec<DnerfImage<'_>> = frames
        .iter()
        .map(|f| DnerfImage {
            time: f.time,
            camera: &f.camera,
            color: &f.color,
            alpha: &f.alpha,
        })
        .collect();
    let angle = frames
        .first()
        .map_or(f64::from(scene.spec.camera_angle_x), |f| {
            dnerf_camera_angle_x(&f.camera)
        });
    write_dnerf_split(dir, split, &images, angle)?;
    Ok(())
}

/// Writes `scene` into `dir` (created if missing) in the D-NeRF layout with its ground truth.
pub fn write_dnerf(scene: &SyntheticScene, dir: &Path) -> Result<(), SynthError> {
    std::fs::create_dir_all(dir).map_err(|e| io_error(dir, e))?;
    for split in Split::ALL {
        write_frames(scene, dir, split, scene.split(split))?;
    }
    if !scene.fixed.is_empty() {
        write_frames(scene, &dir.join(FIXED_DIR), Split::Train, &scene.fixed)?;
    }

    write_ply(&dir.join(PLY_FILE), scene.canonical.view())?;

    let traj = &scene.trajectories;
    let (t, n) = (traj.times.len(), scene.canonical.len());
    let mut tensors: Vec<(String, Dtype, Vec<usize>, Vec<u8>)> = vec![
        (
            "times".into(),
            Dtype::F32,
            vec![t],
            f32_bytes(traj.times.iter().copied()),
        ),
        (
            "means".into(),
            Dtype::F32,
            vec![t, n, 3],
            f32_bytes(traj.means.iter().flatten().flatten().copied()),
        ),
        (
            "parts".into(),
            Dtype::U8,
            vec![n],
            scene
                .parts
                .iter()
                .map(|p| match p {
                    Part::Body => 0u8,
                    Part::Satellite => 1,
                    Part::Occluder => 2,
                })
                .collect(),
        ),
    ];
    if let Some(r) = &traj.rotations {
        tensors.push((
            "rotations".into(),
            Dtype::F32,
            vec![t, n, 4],
            f32_bytes(r.iter().flatten().flatten().copied()),
        ));
    }
    if let Some(c) = &traj.sh_dc {
        tensors.push((
            "sh_dc".into(),
            Dtype::F32,
            vec![t, n, 3],
            f32_bytes(c.iter().flatten().flatten().copied()),
        ));
    }
    let gt_path = dir.join(GROUND_TRUTH_FILE);
    let encode_error = |problem: String| SynthError::Encode {
        path: gt_path.clone(),
        problem,
    };
    let views = tensors
        .iter()
        .map(|(name, dtype, shape, bytes)| {
            TensorView::new(*dtype, shape.clone(), bytes)
                .map(|v| (name.clone(), v))
                .map_err(|e| encode_error(e.to_string()))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let metadata = HashMap::from([(
        "format".to_string(),
        "evogs-synth-ground-truth/1".to_string(),
    )]);
    let bytes = safetensors::tensor::serialize(views, Some(metadata))
        .map_err(|e| encode_error(e.to_string()))?;
    write_bytes(&gt_path, &bytes)?;

    let index = json!({
        "summary": SceneSummary::of(scene),
        "seed": scene.seed,
        "spec": scene.spec,
        "files": {
            "canonical": PLY_FILE,
            "ground_truth": GROUND_TRUTH_FILE,
            "tensors": tensors
                .iter()
                .map(|(name, dtype, shape, _)| json!({"name": name, "dtype": dtype.to_string(), "shape": shape}))
                .collect::<Vec<_>>(),
        },
    });
    let scene_path = dir.join(SCENE_FILE);
    let text = serde_json::to_string_pretty(&index).map_err(|e| SynthError::Encode {
        path: scene_path.clone(),
        problem: e.to_string(),
    })?;
    write_bytes(&scene_path, text.as_bytes())
}
