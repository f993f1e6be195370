//! `evogs-video`: where the cameras of a trained run's pictures come from, and the frames of its
//! videos.
//!
//! - [`camera_path`]: camera paths fitted to the training cameras (orbit, spiral), keyframed
//!   paths through dataset or JSON cameras, a camera named by a file or `dataset:SPLIT:INDEX`
//!   ([`camera_path::CameraSpec`], which `evogs render` and the viewer use), a run's dataset
//!   cameras at its resolution;
//! - [`video`]: the camera and time of every frame of a video (path and time modes), and two
//!   runs side by side with labels.
//!
//! What it is not: a renderer or an encoder. Each frame is rendered by
//! `evogs_eval::render::render_at` and encoded by `evogs_io::VideoWriter`; this crate only says
//! what to render. It sits beside the training core, not in it: nothing in training depends on it.

pub mod camera_path;
pub mod video;
