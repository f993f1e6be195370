//! Scratch files: the path-based readers are fed through files in a per-thread scratch
//! directory, beside the fixed scenes some readers need around the fuzzed file.

use std::path::{Path, PathBuf};

use evogs_io::{CameraInfo, write_nerfies_camera};
use splat_core::Camera;

/// The repository's D-NeRF lego fixture (seven frames at 100×100).
pub const DNERF_FIXTURE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../evogs-io/tests/data/dnerf-lego"
);

thread_local! {
    /// This thread's scratch directory: in `/dev/shm` when it exists (writes there cost no
    /// disk); per thread, so that tests replaying different targets at once share no file.
    static SCRATCH: tempfile::TempDir = tempfile::Builder::new()
        .prefix("evogs-fuzz-")
        .tempdir_in("/dev/shm")
        .or_else(|_| tempfile::tempdir())
        .expect("scratch directory");
}

/// This thread's scratch directory (removed when the thread ends).
pub fn scratch() -> PathBuf {
    SCRATCH.with(|dir| dir.path().to_path_buf())
}

/// Writes `bytes` to `scratch()/relative` and returns the path.
pub fn put(relative: &str, bytes: &[u8]) -> PathBuf {
    let path = scratch().join(relative);
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).expect("scratch folder");
    }
    std::fs::write(&path, bytes).expect("scratch write");
    path
}

/// Splits `data` at NUL bytes into exactly `n` parts (missing parts are empty, the last part
/// keeps any further NULs).
pub fn parts(data: &[u8], n: usize) -> Vec<&[u8]> {
    let mut out: Vec<&[u8]> = data.splitn(n, |&b| b == 0).collect();
    out.resize(n, &[]);
    out
}

/// A small pinhole camera (8×6 pixels).
pub fn small_camera() -> Camera {
    use glam::vec3;
    Camera::look_at(
        8,
        6,
        0.9,
        vec3(0.0, 0.0, 4.0),
        vec3(0.0, 0.0, 0.0),
        vec3(0.0, 1.0, 0.0),
    )
}

/// A nerfies scene directory `scratch()/<name>` holding everything but the three JSON files the
/// fuzzer writes: cameras `a` and `b` (8×6) and their 2x-downscaled 4×3 images.
pub fn nerfies_scene(name: &str) -> PathBuf {
    let dir = scratch().join(name);
    if !dir.join("rgb/2x/b.png").exists() {
        for id in ["a", "b"] {
            let camera = dir.join("camera").join(format!("{id}.json"));
            std::fs::create_dir_all(camera.parent().unwrap()).unwrap();
            write_nerfies_camera(&camera, &CameraInfo::pinhole(small_camera())).unwrap();
            let image = dir.join("rgb/2x").join(format!("{id}.png"));
            std::fs::create_dir_all(image.parent().unwrap()).unwrap();
            evogs_io::save_png(&image, &evogs_io::ImageRgb::filled(4, 3, [0.2, 0.5, 0.7])).unwrap();
        }
    }
    dir
}

/// A D-NeRF scene directory `scratch()/<name>` whose `train`, `val` and `test` folders link to
/// the repository's lego fixture, so that the fuzzed `transforms.json` can name real images.
pub fn dnerf_scene(name: &str) -> PathBuf {
    let dir = scratch().join(name);
    if !dir.join("test").exists() {
        std::fs::create_dir_all(&dir).unwrap();
        for split in ["train", "val", "test"] {
            std::os::unix::fs::symlink(Path::new(DNERF_FIXTURE).join(split), dir.join(split))
                .unwrap();
        }
    }
    dir
}

/// A nerfstudio scene directory `scratch()/<name>` holding everything but `transforms.json`:
/// images `images/a.png`, `images/b.png`, `images/frame_0001.png` and `images/frame_0002.png`
/// (8×6; the last two for times read from the names) and an ASCII point cloud `sparse_pc.ply`.
pub fn nerfstudio_scene(name: &str) -> PathBuf {
    let dir = scratch().join(name);
    if !dir.join("sparse_pc.ply").exists() {
        std::fs::create_dir_all(dir.join("images")).unwrap();
        for id in ["a", "b", "frame_0001", "frame_0002"] {
            let image = dir.join("images").join(format!("{id}.png"));
            evogs_io::save_png(&image, &evogs_io::ImageRgb::filled(8, 6, [0.2, 0.5, 0.7])).unwrap();
        }
        std::fs::write(dir.join("sparse_pc.ply"), POINT_CLOUD_PLY).unwrap();
    }
    dir
}

/// A small ASCII point cloud with 8-bit colours: [`nerfstudio_scene`]'s, and a seed of the
/// `point_cloud` target.
pub const POINT_CLOUD_PLY: &str = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n\
property float y\nproperty float z\nproperty uchar red\nproperty uchar green\n\
property uchar blue\nend_header\n0.1 0.2 0.3 10 20 30\n-0.5 0.25 1 200 100 0\n";
