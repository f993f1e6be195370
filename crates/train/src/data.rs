//! Datasets: the views of a D-NeRF split (image, camera, time) loaded through `evogs-io`, resized
//! by the run's factor, and checked (no empty split, every image the size of the first).

use std::path::{Path, PathBuf};

use evogs_io::{ImageRgb, Split, load_view, read_dnerf_split};
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

/// Loads a split of a D-NeRF dataset directory: images composited over `background` and resized
/// by `factor`. Errors name the file: a missing or malformed `transforms_*.json`, a missing
/// image, an empty frame list, an image whose size differs from the split's first image.
pub fn load_split(
    root: &Path,
    split: Split,
    background: [f32; 3],
    factor: f32,
) -> Result<SplitViews, TrainError> {
    let transforms = split.transforms_path(root);
    let frames = read_dnerf_split(root, split)?;
    if frames.is_empty() {
        return Err(TrainError::field(
            transforms,
            "frames",
            "the split is empty: no frames to use",
        ));
    }
    let loaded: Vec<Result<View, TrainError>> = {
        use rayon::prelude::*;
        frames
            .par_iter()
            .map(|f| {
                let (image, camera) = load_view(&f.image_path, &f.camera, background, factor)?;
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
