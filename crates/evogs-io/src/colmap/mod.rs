//! COLMAP sparse reconstructions (`cameras`, `images`, `points3D`, in `.bin` or `.txt`), read
//! as Deformable-3D-Gaussians does (ingra14m/Deformable-3D-Gaussians, `scene/colmap_loader.py`
//! and `readColmapSceneInfo` in `scene/dataset_readers.py`):
//!
//! ```text
//! DIR/sparse/0/{cameras,images,points3D}.bin   (or .txt; or directly in DIR/sparse/)
//! DIR/images/<name>                            the images named in images.bin/txt
//! DIR/times.json                               optional: each image's time (`evogs prepare`)
//! ```
//!
//! - `.bin` is preferred when both exist. Camera models `PINHOLE`, `SIMPLE_PINHOLE`, `OPENCV` and
//!   `SIMPLE_RADIAL` are read; distortion (k1, k2, p1, p2, or `SIMPLE_RADIAL`'s k) is kept in
//!   [`CameraInfo`](crate::CameraInfo) and reported, never applied. Any other model is an error
//!   naming the file and the model.
//! - COLMAP's `qvec` (w, x, y, z) and `tvec` are world-to-camera in OpenCV axes, and its pixel
//!   centres are at +0.5 like DESIGN §1.2, so they convert directly.
//! - Frames are sorted by image name; with `llff_hold > 0` every `llff_hold`-th (from the first)
//!   is a test frame (D-3DGS `--eval`, hold 8).
//! - Times from `DIR/times.json` when it exists ([`times_file`](crate::times_file): the dataset
//!   stores its times, as `evogs prepare` writes them); otherwise by [`TimeFrom`] over all
//!   registered images before the split: the rank of the name
//!   (default, as 4DGaussians), a number in the name (as D-3DGS; multi-camera captures by a
//!   `frame` number, see [`frame_time`](crate::frame_time)), or 0 (a static scene).
//! - The sparse points (colours /255) are the initial point cloud; no normalisation.

mod binary;
mod model;
mod text;

use std::path::{Path, PathBuf};

use glam::Vec3;

pub use binary::{
    encode_cameras_bin, encode_images_bin, encode_points3d_bin, parse_cameras_bin,
    parse_images_bin, parse_points3d_bin, read_cameras_bin, read_images_bin, read_points3d_bin,
};
pub use model::{
    CameraModel, ColmapCamera, ColmapImage, ColmapModel, ColmapPoint, rotation_from_qvec,
};
pub use text::{
    encode_cameras_txt, encode_images_txt, encode_points3d_txt, parse_cameras_txt,
    parse_images_txt, parse_points3d_txt, read_cameras_txt, read_images_txt, read_points3d_txt,
};

use crate::IoError;
use crate::dataset_types::{Dataset, Format, Frame, PointCloud};
use crate::frame_time::{TimeFrom, times_from_names};

/// The folder of a dataset directory that holds the sparse model: `sparse/0/` when it exists,
/// else `sparse/`.
pub fn sparse_dir(dir: &Path) -> PathBuf {
    let zero = dir.join("sparse").join("0");
    if zero.is_dir() {
        zero
    } else {
        dir.join("sparse")
    }
}

/// Reads a sparse model folder (`cameras`, `images`, `points3D`; `.bin` preferred, else `.txt`).
pub fn read_colmap_model(sparse: &Path) -> Result<ColmapModel, IoError> {
    let bin = |name: &str| sparse.join(format!("{name}.bin"));
    let txt = |name: &str| sparse.join(format!("{name}.txt"));
    let pick = |name: &str| -> Result<(PathBuf, bool), IoError> {
        if bin(name).is_file() {
            Ok((bin(name), true))
        } else if txt(name).is_file() {
            Ok((txt(name), false))
        } else {
            Err(IoError::field(
                sparse,
                name,
                format!("neither {name}.bin nor {name}.txt exists"),
            ))
        }
    };
    let (cameras_path, cameras_bin) = pick("cameras")?;
    let (images_path, images_bin) = pick("images")?;
    let (points_path, points_bin) = pick("points3D")?;
    let cameras = if cameras_bin {
        read_cameras_bin(&cameras_path)?
    } else {
        read_cameras_txt(&cameras_path)?
    };
    let images = if images_bin {
        read_images_bin(&images_path)?
    } else {
        read_images_txt(&images_path)?
    };
    let points = if points_bin {
        read_points3d_bin(&points_path)?
    } else {
        read_points3d_txt(&points_path)?
    };
    Ok(ColmapModel {
        cameras,
        images,
        points,
        images_path,
    })
}

/// Reads a COLMAP dataset directory (see the module docs).
pub fn read_colmap_dataset(
    dir: &Path,
    llff_hold: usize,
    time_from: TimeFrom,
) -> Result<Dataset, IoError> {
    let model = read_colmap_model(&sparse_dir(dir))?;
    let mut images: Vec<&ColmapImage> = model.images.iter().collect();
    images.sort_by(|a, b| a.name.cmp(&b.name));
    let names: Vec<&str> = images.iter().map(|image| image.name.as_str()).collect();
    // A dataset that stores its times (`times.json`, from `evogs prepare`) keeps them; the
    // rule applies to those that store none.
    let times_path = dir.join(crate::times_file::TIMES_FILE);
    let times = if times_path.is_file() {
        crate::times_file::read_frame_times(&times_path, &names)?
    } else {
        times_from_names(&names, time_from).map_err(|(index, problem)| {
            IoError::field(
                &model.images_path,
                format!("image {}.name", images[index].id),
                problem,
            )
        })?
    };
    let mut dataset = Dataset {
        format: Format::Colmap,
        train: Vec::new(),
        test: Vec::new(),
        val: Vec::new(),
        points: Some(PointCloud {
            positions: model
                .points
                .iter()
                .map(|p| Vec3::from_array(p.xyz.map(|v| v as f32)))
                .collect(),
            colours: model
                .points
                .iter()
                .map(|p| Vec3::from_array(p.rgb.map(|v| f32::from(v) / 255.0)))
                .collect(),
        }),
        normalisation: None,
    };
    // Model consistency first (every image's camera), then the image files.
    let cameras = images
        .iter()
        .map(|image| model.camera_info(image))
        .collect::<Result<Vec<_>, _>>()?;
    for (index, ((image, camera), time)) in images.into_iter().zip(cameras).zip(times).enumerate() {
        let image_path = dir.join("images").join(&image.name);
        if !image_path.is_file() {
            return Err(IoError::field(
                &model.images_path,
                format!("image {}.name", image.id),
                format!("image {} does not exist", image_path.display()),
            ));
        }
        let frame = Frame {
            image_path,
            time,
            camera,
        };
        if llff_hold > 0 && index % llff_hold == 0 {
            dataset.test.push(frame);
        } else {
            dataset.train.push(frame);
        }
    }
    Ok(dataset)
}
