//! Datasets: the views of a split (image, camera, time) of any layout `evogs-io` reads (D-NeRF,
//! nerfies, Neu3D, COLMAP; detected from the directory), resized by the run's factor, and checked
//! (no empty split, every image the size of the first).

use std::path::{Path, PathBuf};

use evogs_io::{Dataset, Format, ImageRgb, LoadOptions, Split, TimeFrom, load_view};
use rayon::prelude::*;
use splat_raster::Camera;

use crate::error::TrainError;

/// One training or evaluation view.
#[derive(Clone, Debug)]
pub struct View {
    /// The image file it came from.
    pub path: PathBuf,
    /// The image, composited over the background and resized.
    pub image: ImageRgb,
    /// Its camera at the resized size.
    pub camera: Camera,
    /// Time in [0, 1].
    pub time: f32,
}

/// A split's views.
#[derive(Clone, Debug)]
pub struct SplitViews {
    /// Which split.
    pub split: Split,
    /// The views in file order.
    pub views: Vec<View>,
}

impl SplitViews {
    /// The cameras.
    pub fn cameras(&self) -> Vec<Camera> {
        self.views.iter().map(|v| v.camera).collect()
    }

    /// The distinct times, sorted.
    pub fn times(&self) -> Vec<f32> {
        let mut t: Vec<f32> = self.views.iter().map(|v| v.time).collect();
        t.sort_by(f32::total_cmp);
        t.dedup();
        t
    }
}

/// Reads a dataset directory's cameras, times and point cloud (not its images), detecting the
/// layout (`evogs_io::detect_format`); `Dataset::summary` says which layout was chosen.
/// `time_from` gives times to frames whose layout stores none (COLMAP without `times.json`,
/// nerfstudio frames without `time`).
pub fn open_dataset(root: &Path, time_from: TimeFrom) -> Result<Dataset, TrainError> {
    let options = LoadOptions {
        time_from,
        ..LoadOptions::default()
    };
    Ok(evogs_io::load_dataset(root, &options)?)
}

/// Loads a split of the dataset directory `root` (any layout, see [`open_dataset`]).
pub fn load_split(
    root: &Path,
    split: Split,
    time_from: TimeFrom,
    background: [f32; 3],
    factor: f32,
) -> Result<SplitViews, TrainError> {
    load_dataset_split(
        &open_dataset(root, time_from)?,
        root,
        split,
        background,
        factor,
    )
}

/// Loads a split of an opened dataset: images composited over `background` and resized by
/// `factor`. Errors name the file: an empty split (D-NeRF: its `transforms_*.json`), a missing
/// image, an image whose size differs from the split's first image.
pub fn load_dataset_split(
    dataset: &Dataset,
    root: &Path,
    split: Split,
    background: [f32; 3],
    factor: f32,
) -> Result<SplitViews, TrainError> {
    let frames = dataset.split(split);
    if frames.is_empty() {
        let (file, field) = match dataset.format {
            Format::Dnerf => (split.transforms_path(root), "frames"),
            _ => (root.to_path_buf(), split.name()),
        };
        return Err(TrainError::field(
            file,
            field,
            "the split is empty: no frames to use",
        ));
    }
    let loaded: Vec<Result<View, TrainError>> = {
        frames
            .par_iter()
            .map(|f| {
                let (image, camera) =
                    load_view(&f.image_path, &f.camera.camera, background, factor)?;
                Ok(View {
                    path: f.image_path.clone(),
                    image,
                    camera,
                    time: f.time,
                })
            })
            .collect()
    };
    let views = loaded.into_iter().collect::<Result<Vec<_>, _>>()?;
    let (w, h) = (views[0].image.width, views[0].image.height);
    if let Some(v) = views
        .iter()
        .find(|v| (v.image.width, v.image.height) != (w, h))
    {
        return Err(TrainError::file(
            &v.path,
            format!(
                "image is {}×{} after resizing, but the split's first image ({}) is {w}×{h}",
                v.image.width,
                v.image.height,
                views[0].path.display()
            ),
        ));
    }
    Ok(SplitViews { split, views })
}

/// Per view, its image's transmittance 1 − α per pixel, read again from its file and resized by
/// `factor` as the view was ([`evogs_io::load_transmittance`]): the view's image over black plus
/// a colour times this is the image over that colour (a random background,
/// [`crate::Background::Random`]). Errors name the file; a view whose image is not the size of
/// its file's resized is refused.
pub fn load_transmittance(views: &SplitViews, factor: f32) -> Result<Vec<Vec<f32>>, TrainError> {
    // Collected whole, then the first error in view order: the message does not depend on which
    // thread failed first.
    let loaded: Vec<Result<Vec<f32>, TrainError>> = views
        .views
        .par_iter()
        .map(|v| {
            let t = evogs_io::load_transmittance(&v.path, factor)?;
            if t.len() != v.image.pixels.len() {
                return Err(TrainError::file(
                    &v.path,
                    format!(
                        "its alpha has {} pixels after resizing, the view's image {}",
                        t.len(),
                        v.image.pixels.len()
                    ),
                ));
            }
            Ok(t)
        })
        .collect();
    loaded.into_iter().collect()
}
