//! Reading a dataset directory in any format: [`detect_format`] tells the layout of a directory
//! and [`load_dataset`] reads it with that format's reader ([`read_dnerf_dataset`] is D-NeRF's),
//! into the one dataset type for every format, [`Dataset`]: frames (image, time, camera) per
//! split, an optional initial point cloud, and the scene normalisation that was applied. The
//! dataset types are defined below the readers (module `dataset_types`, which the readers import
//! and this module re-exports), so that this module imports the readers and no reader imports it.

use std::path::Path;

use crate::camera_info::CameraInfo;
pub use crate::dataset_types::{
    Dataset, Format, Frame, LoadOptions, NerfiesSplit, Normalisation, PointCloud, TimeDenominator,
};
use crate::dnerf::{Split, read_dnerf_split};
use crate::{IoError, colmap, nerfies, nerfstudio, neu3d};

/// Tells a dataset directory's layout, checking in order: `sparse/` → COLMAP,
/// `transforms_train.json` → D-NeRF, `transforms.json` → nerfstudio, `dataset.json` → nerfies,
/// `poses_bounds.npy` → Neu3D.
pub fn detect_format(dir: &Path) -> Result<Format, IoError> {
    if !dir.is_dir() {
        let problem = if dir.exists() {
            "is a file, not a dataset directory"
        } else {
            "no such dataset directory"
        };
        return Err(IoError::io(
            dir,
            std::io::Error::new(std::io::ErrorKind::NotFound, problem),
        ));
    }
    let rules = [
        ("sparse", Format::Colmap),
        ("transforms_train.json", Format::Dnerf),
        ("transforms.json", Format::Nerfstudio),
        ("dataset.json", Format::Nerfies),
        ("poses_bounds.npy", Format::Neu3d),
    ];
    rules
        .into_iter()
        .find(|(name, _)| dir.join(name).exists())
        .map(|(_, format)| format)
        .ok_or_else(|| {
            IoError::field(
                dir,
                "(layout)",
                "no dataset found: expected sparse/ (COLMAP), transforms_train.json (D-NeRF), \
                 transforms.json (nerfstudio), dataset.json (nerfies) or poses_bounds.npy (Neu3D)",
            )
        })
}

/// Reads a dataset directory in the layout [`detect_format`] finds; the returned
/// [`Dataset::format`] says which it chose.
pub fn load_dataset(dir: &Path, options: &LoadOptions) -> Result<Dataset, IoError> {
    match detect_format(dir)? {
        Format::Colmap => {
            colmap::read_colmap_dataset(dir, options.colmap_llff_hold, options.time_from)
        }
        Format::Dnerf => read_dnerf_dataset(dir),
        Format::Nerfies => nerfies::read_nerfies_dataset(dir, options),
        Format::Neu3d => neu3d::read_neu3d_dataset(
            dir,
            &options.neu3d_test_cameras,
            options.neu3d_max_frames,
            options.neu3d_time,
        ),
        Format::Nerfstudio => nerfstudio::read_nerfstudio_dataset(dir, options.time_from),
    }
}

/// Reads a D-NeRF directory: train and test splits (and val when `transforms_val.json`
/// exists); no point cloud (D-3DGS initialises D-NeRF scenes with random points).
pub fn read_dnerf_dataset(dir: &Path) -> Result<Dataset, IoError> {
    let frames = |split: Split| -> Result<Vec<Frame>, IoError> {
        Ok(read_dnerf_split(dir, split)?
            .into_iter()
            .map(|f| Frame {
                image_path: f.image_path,
                time: f.time,
                camera: CameraInfo::pinhole(f.camera),
            })
            .collect())
    };
    let val = if Split::Val.transforms_path(dir).exists() {
        frames(Split::Val)?
    } else {
        Vec::new()
    };
    Ok(Dataset {
        format: Format::Dnerf,
        train: frames(Split::Train)?,
        test: frames(Split::Test)?,
        val,
        points: None,
        normalisation: None,
    })
}
