//! The types of a dataset read from a directory, whatever its format: [`Dataset`] (frames of
//! image, time and camera per split, an optional initial [`PointCloud`], the [`Normalisation`]
//! applied), its [`Format`], and the [`LoadOptions`] the readers take ([`NerfiesSplit`],
//! [`TimeDenominator`]).
//!
//! What it is not: a reader. The readers ([`colmap`](crate::colmap), [`nerfies`](crate::nerfies),
//! [`neu3d`](crate::neu3d), [`nerfstudio`](crate::nerfstudio), the D-NeRF one in
//! [`dataset`](crate::dataset)) build these types, and [`dataset`](crate::dataset) picks the
//! reader for a directory; both import this module, which imports neither (every type here is
//! re-exported from [`dataset`](crate::dataset) and the crate root).

use std::path::PathBuf;

use glam::Vec3;

use crate::camera_info::{CameraInfo, warning_for_all};
use crate::dnerf::Split;
use crate::frame_time::TimeFrom;

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

/// Options for [`load_dataset`](crate::load_dataset); the defaults follow Deformable-3D-Gaussians.
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
    /// COLMAP without `times.json`, and nerfstudio frames without a `time`: where times come from (default: the
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

/// Neu3D: how frame indices become times ([`LoadOptions::neu3d_time`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TimeDenominator {
    /// `frame / count` (4DGaussians; last frame below 1).
    #[default]
    Count,
    /// `frame / (count − 1)` (Deformable-3D-Gaussians; last frame at 1; a single frame is 0).
    CountMinusOne,
}
