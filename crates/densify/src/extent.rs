//! The scene extent of 3DGS (`getNerfppNorm` in `scene/dataset_readers.py`): 1.1 × the largest
//! distance of a camera centre from the mean of the camera centres.

use crate::error::DensifyError;
use glam::Vec3;
use splat_core::Camera;

/// 1.1 × the largest distance of a camera centre from their mean.
///
/// Errors on no cameras or a non-finite centre. A single camera (or coincident centres) gives
/// 0, which 3DGS would also compute; callers that need a positive extent must check.
pub fn scene_extent(cameras: &[Camera]) -> Result<f32, DensifyError> {
    if cameras.is_empty() {
        return Err(DensifyError::Input {
            field: "cameras",
            problem: "no cameras: the scene extent is undefined".into(),
        });
    }
    let centres: Vec<Vec3> = cameras.iter().map(Camera::center).collect();
    if let Some(i) = centres.iter().position(|c| !c.is_finite()) {
        return Err(DensifyError::Input {
            field: "cameras",
            problem: format!("camera {i} has a non-finite centre"),
        });
    }
    let mean = centres.iter().copied().sum::<Vec3>() / centres.len() as f32;
    let radius = centres
        .iter()
        .map(|c| c.distance(mean))
        .fold(0.0f32, f32::max);
    Ok(1.1 * radius)
}
