//! `evogs-io`: the file formats of evogs.
//!
//! What it is: readers and writers for 3DGS PLY files ([`ply`]), the web viewers' `.splat`
//! ([`splat`]) and PlayCanvas/SuperSplat's compressed PLY ([`compressed_ply`]), any of the three
//! told apart on reading ([`gaussians_file`]), nerfies camera
//! JSON and D-NeRF `transforms_*.json` cameras ([`camera_json`], [`dnerf`]; D-NeRF splits are
//! written too, [`write_dnerf_split`]), PNG/JPEG images as
//! f32 RGB ([`image_io`]), and datasets: D-NeRF, nerfies (HyperNeRF, NeRF-DS, [`nerfies`]), Neu3D
//! ([`neu3d`]), COLMAP ([`colmap`]) and nerfstudio ([`nerfstudio`]) read into one [`Dataset`]
//! type by [`load_dataset`], which detects the layout ([`detect_format`]), with `.npy` arrays
//! read by [`npy`] and times for frames that store none by [`frame_time`]; conventions as
//! pinned in DESIGN §1–2 and, where it is silent, Deformable-3D-Gaussians'. Every error
//! names the file and the field or problem; every write is atomic (temporary file, then rename).
//!
//! What it is not: a renderer, a trainer or a data augmenter. Cameras come out as
//! [`splat_core::Camera`] (pinhole); skew and lens distortion are kept beside them in
//! [`CameraInfo`] and reported, never applied.

pub mod atomic;
pub mod camera_info;
pub mod camera_json;
pub mod colmap;
pub mod compressed_ply;
pub mod dataset;
mod dataset_types;
pub mod dnerf;
pub mod error;
pub mod frame_time;
pub mod gaussians_file;
pub mod image_io;
mod json_fields;
pub mod nerfies;
pub mod nerfstudio;
pub mod neu3d;
pub mod npy;
pub mod ply;
pub mod splat;
pub mod times_file;
pub mod video;

pub use camera_info::{CameraInfo, Distortion, warning_for_all};
pub use camera_json::{
    TimedCamera, nerfies_camera_json, read_camera_path, read_nerfies_camera, write_nerfies_camera,
};
pub use compressed_ply::{read_compressed_ply, write_compressed_ply};
pub use dataset::{
    Dataset, Format, Frame, LoadOptions, NerfiesSplit, Normalisation, PointCloud, TimeDenominator,
    detect_format, load_dataset,
};
pub use dnerf::{
    DnerfFrame, DnerfImage, Split, dnerf_camera_angle_x, opengl_c2w, read_dnerf_split,
    read_transforms, write_dnerf_split,
};
pub use error::IoError;
pub use frame_time::TimeFrom;
pub use gaussians_file::{GaussiansFormat, LoadedGaussians, read_gaussians};
pub use image_io::{ImageRgb, load_image, load_transmittance, load_view, resize_image, save_png};
pub use json_fields::{ROTATION_TOLERANCE, rotation_error};
pub use ply::{LoadedPly, read_ply, read_ply_bytes, write_ply, write_ply_to};
pub use splat::{read_splat, write_splat};
pub use times_file::{FrameTimes, TIMES_FILE, read_frame_times, write_frame_times};
pub use video::{VideoFormat, VideoWriter};
