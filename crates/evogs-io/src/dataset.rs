//! One dataset type for every format: frames (image, time, camera) per split, an optional
//! initial point cloud, and the scene normalisation that was applied. [`detect_format`] tells
//! the layout of a directory and [`load_dataset`] reads it.

use std::path::{Path, PathBuf};

use glam::Vec3;

use crate::camera_info::{CameraInfo, warning_for_all};
use crate::dnerf::{Split, read_dnerf_split};
use crate::frame_time::TimeFrom;
pub use crate::neu3d::TimeDenominator;
use crate::{IoError, colmap, nerfies, nerfstudio, neu3d};

/// The dataset layouts this crate reads ([`Display`](std::fmt::Display): the lower-case name).
#[derive(strum::Display, strum::IntoStaticStr)]
#[strum(serialize_all = "lowercase")]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Format {
    /// COLMAP sparse reconstruction (`sparse/0/` or `sparse/`, `.bin` or `.txt`) with `images/`.
    Colmap,
    /// D-NeRF / Blender (`transforms_{train,test,val}.json`).
    Dnerf,
    /// Nerfies / HyperNeRF / NeRF-DS (`dataset.json`, `metadata.json`, `scene.json`, …).
    Nerfies,
    /// Neu3D / DyNeRF (`poses_bounds.npy`, `camNN/images/NNNN.png`).
    Neu3d,
    /// nerfstudio (`transforms.json`, as `ns-process-data` and brush write it).
    Nerfstudio,
}

impl Format {
    /// A short lower-case name.
    pub fn name(self) -> &'static str {
        self.into()
    }
}

/// One training or test view.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// The image file.
    pub image_path: PathBuf,
    /// Time in [0, 1] (0 for static scenes).
    pub time: f32,
    /// The camera (OpenCV axes, DESIGN §1.2) at the image file's size, with skew and distortion.
    pub camera: CameraInfo,
}

/// An initial point cloud for the Gaussians.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PointCloud {
    /// Positions, in the dataset's (normalised) world frame.
    pub positions: Vec<Vec3>,
    /// Colours in [0, 1], one per position.
    pub colours: Vec<Vec3>,
}

/// The map applied to the stored world coordinates: `x' = (x − center) · scale`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Normalisation {
    /// The scene centre, in stored coordinates.
    pub center: Vec3,
    /// The scale factor.
    pub scale: f32,
}

/// A dataset read from a directory.
#[derive(Clone, Debug, PartialEq)]
pub struct Dataset {
    /// The layout it was read from.
    pub format: Format,
    /// Training frames.
    pub train: Vec<Frame>,
    /// Test frames (may be empty).
    pub test: Vec<Frame>,
    /// Validation frames (D-NeRF, and nerfstudio's `val_filenames`; empty otherwise).
    pub val: Vec<Frame>,
    /// The initial point cloud, when the format has one.
    pub points: Option<PointCloud>,
    /// The normalisation applied to cameras and points, when the format has one.
    pub normalisation: Option<Normalisation>,
}

impl Dataset {
    /// The frames of a split.
    pub fn split(&self, split: Split) -> &[Frame] {
        match split {
            Split::Train => &self.train,
            Split::Test => &self.test,
            Split::Val => &self.val,
        }
    }

    /// Every frame: train, then test, then val.
    pub fn all_frames(&self) -> impl Iterator<Item = &Frame> {
        self.train.iter().chain(&self.test).chain(&self.val)
    }

    /// One warning line when any camera has skew or distortion that pinhole rendering ignores.
    pub fn camera_warning(&self) -> Option<String> {
        let cameras: Vec<CameraInfo> = self.all_frames().map(|f| f.camera).collect();
        warning_for_all(&cameras)
    }

    /// A one-line summary, e.g. `nerfies: 120 train, 30 test, 0 val frames, 5000 points`.
    pub fn summary(&self) -> String {
        let points = self
            .points
            .as_ref()
            .map_or("no point cloud".to_string(), |p| {
                format!("{} points", p.positions.len())
            });
        format!(
            "{}: {} train, {} test, {} val frames, {points}",
            self.format,
            self.train.len(),
            self.test.len(),
            self.val.len()
        )
    }
}

/// How the nerfies train/test split is chosen (D-3DGS `readNerfiesCameras`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NerfiesSplit {
    /// `train_ids` / `val_ids` of `dataset.json` (D-3DGS for `vrig*` and `NeRF*` scenes).
    TrainVal,
    /// Every 4th id from 0 for training, every 4th from 2 for testing (`interp*` scenes).
    Interp,
    /// Every 4th id for training, no test frames (other HyperNeRF scenes).
    EveryFourth,
}

/// Options for [`load_dataset`]; the defaults follow Deformable-3D-Gaussians.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadOptions {
    /// Nerfies split rule; `None` picks it from the directory name as D-3DGS does.
    pub nerfies_split: Option<NerfiesSplit>,
    /// Nerfies image downscale (the `rgb/<N>x/` folder); `None` picks it from the directory
    /// name as D-3DGS does (vrig 4, NeRF-DS 1, others 2).
    pub nerfies_downscale: Option<u32>,
    /// COLMAP: every `llff_hold`-th image (by name, from the first) is a test image; 0 puts
    /// every image in training. D-3DGS uses 8 with `--eval`.
    pub colmap_llff_hold: usize,
    /// Neu3D: indices (into the sorted `cam*` folders) of the test cameras; D-3DGS/4DGaussians
    /// use camera 0.
    pub neu3d_test_cameras: Vec<usize>,
    /// Neu3D: at most this many frames per camera (4DGaussians: 300).
    pub neu3d_max_frames: usize,
    /// Neu3D: `frame / count` (4DGaussians, the default) or `frame / (count − 1)` (D-3DGS).
    pub neu3d_time: TimeDenominator,
    /// COLMAP, and nerfstudio frames without a `time`: where times come from (default: the
    /// order of the image names, as 4DGaussians; see [`TimeFrom`]).
    pub time_from: TimeFrom,
}

impl Default for LoadOptions {
    fn default() -> Self {
        Self {
            nerfies_split: None,
            nerfies_downscale: None,
            colmap_llff_hold: 8,
            neu3d_test_cameras: vec![0],
            neu3d_max_frames: 300,
            neu3d_time: TimeDenominator::Count,
            time_from: TimeFrom::Order,
        }
    }
}

/// Tells a dataset directory's layout, checking in order: `sparse/` → COLMAP,
/// `transforms_train.json` → D-NeRF, `transforms.json` → nerfstudio, `dataset.json` → nerfies,
/// `poses_bounds.npy` → Neu3D.
pub fn detect_format(dir: &Path) -> Result<Format, IoError> {
    if !dir.is_dir() {
        return Err(IoError::field(dir, "(directory)", "is not a directory"));
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
