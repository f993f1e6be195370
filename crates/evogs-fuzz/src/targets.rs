//! One function per fuzz target: it feeds the input to its reader and returns whether the reader
//! accepted it, after checking that what it returned is self-consistent (a panic otherwise).
//! The libFuzzer targets in `fuzz/fuzz_targets/<name>.rs` call these, and so does the replay
//! test; [`TARGETS`] lists them by those names.

use std::path::Path;

use evogs_io::TimeFrom;
use evogs_io::colmap::{
    parse_cameras_bin, parse_cameras_txt, parse_images_bin, parse_images_txt, parse_points3d_bin,
    parse_points3d_txt,
};
use evogs_io::nerfstudio::read_nerfstudio_dataset;

use crate::scratch::{dnerf_scene, nerfies_scene, nerfstudio_scene, parts, put};

/// A fuzz target: its name (the libFuzzer binary's, the seed and regression folders') and its
/// body.
#[derive(Clone, Copy, Debug)]
pub struct Target {
    /// The name of the target (`fuzz/fuzz_targets/<name>.rs`).
    pub name: &'static str,
    /// Feeds one input to the reader; true when the reader accepted it.
    pub run: fn(&[u8]) -> bool,
}

impl Target {
    const fn new(name: &'static str, run: fn(&[u8]) -> bool) -> Self {
        Self { name, run }
    }
}

/// Every fuzz target (the checkpoint target only with the feature `checkpoint`).
pub const TARGETS: &[Target] = &[
    Target::new("ply", ply),
    Target::new("nerfies_camera", nerfies_camera),
    Target::new("nerfies_dataset", nerfies_dataset),
    Target::new("dnerf_transforms", dnerf_transforms),
    Target::new("colmap_bin", colmap_bin),
    Target::new("colmap_txt", colmap_txt),
    Target::new("npy", npy),
    Target::new("nerfstudio", nerfstudio),
    Target::new("evo_state", evo_state),
    Target::new("camera_path", camera_path),
    Target::new("point_cloud", point_cloud),
    Target::new("splat", splat),
    Target::new("compressed_ply", compressed_ply),
    Target::new("weights", weights),
    #[cfg(feature = "checkpoint")]
    Target::new("checkpoint", checkpoint),
    #[cfg(feature = "checkpoint")]
    Target::new("config", config),
    #[cfg(feature = "checkpoint")]
    Target::new("run", run),
];

/// PLY (ASCII and binary of either endianness): `read_ply_bytes`.
pub fn ply(data: &[u8]) -> bool {
    let Ok(loaded) = evogs_io::read_ply_bytes(data, Path::new("fuzz.ply")) else {
        return false;
    };
    consistent(&loaded.gaussians);
    // Every Gaussian takes at least one byte of the file.
    assert!(loaded.gaussians.means.len() <= data.len());
    true
}

/// Nerfies camera JSON (`camera/<id>.json`): `read_nerfies_camera`.
pub fn nerfies_camera(data: &[u8]) -> bool {
    let path = put("camera.json", data);
    evogs_io::read_nerfies_camera(&path).is_ok()
}

/// Nerfies dataset JSON: the input is `dataset.json`, `metadata.json` and `scene.json` separated
/// by NUL bytes, read by `load_dataset` in a scene with two valid cameras (`a`, `b`) and images.
pub fn nerfies_dataset(data: &[u8]) -> bool {
    let dir = nerfies_scene("nerfies");
    let files = parts(data, 3);
    for (name, bytes) in ["dataset.json", "metadata.json", "scene.json"]
        .iter()
        .zip(files)
    {
        std::fs::write(dir.join(name), bytes).unwrap();
    }
    let Ok(dataset) = evogs_io::load_dataset(&dir, &evogs_io::LoadOptions::default()) else {
        return false;
    };
    assert!(dataset.all_frames().count() > 0);
    true
}

/// D-NeRF `transforms_*.json`: `read_transforms` in a folder whose `train`/`val`/`test` images
/// are the repository's lego fixture.
pub fn dnerf_transforms(data: &[u8]) -> bool {
    let dir = dnerf_scene("dnerf");
    let path = dir.join("transforms_train.json");
    std::fs::write(&path, data).unwrap();
    let Ok(frames) = evogs_io::read_transforms(&path) else {
        return false;
    };
    for f in &frames {
        assert!((0.0..=1.0).contains(&f.time));
    }
    true
}

/// COLMAP binary model files: the first byte picks `cameras.bin`, `images.bin` or
/// `points3D.bin`, the rest is the file.
pub fn colmap_bin(data: &[u8]) -> bool {
    let Some((&which, file)) = data.split_first() else {
        return false;
    };
    match which % 3 {
        0 => parse_cameras_bin(Path::new("cameras.bin"), file).is_ok(),
        1 => parse_images_bin(Path::new("images.bin"), file).is_ok(),
        _ => parse_points3d_bin(Path::new("points3D.bin"), file).is_ok(),
    }
}

/// COLMAP text model files: the first byte picks `cameras.txt`, `images.txt` or
/// `points3D.txt`, the rest is the file (UTF-8; other bytes are rejected before parsing, as
/// when reading the file).
pub fn colmap_txt(data: &[u8]) -> bool {
    let Some((&which, file)) = data.split_first() else {
        return false;
    };
    let Ok(text) = std::str::from_utf8(file) else {
        return false;
    };
    match which % 3 {
        0 => parse_cameras_txt(Path::new("cameras.txt"), text).is_ok(),
        1 => parse_images_txt(Path::new("images.txt"), text).is_ok(),
        _ => parse_points3d_txt(Path::new("points3D.txt"), text).is_ok(),
    }
}

/// NumPy `.npy` arrays: `parse_npy`.
pub fn npy(data: &[u8]) -> bool {
    let Ok(array) = evogs_io::npy::parse_npy(Path::new("fuzz.npy"), data) else {
        return false;
    };
    assert_eq!(array.data.len(), array.shape.iter().product::<usize>());
    true
}

/// nerfstudio `transforms.json`: `read_nerfstudio_dataset` in a folder holding four 8×6 images
/// and an ASCII point cloud ([`crate::scratch::nerfstudio_scene`]); the first byte picks how
/// times are given when the frames have none, the rest is the file.
pub fn nerfstudio(data: &[u8]) -> bool {
    let Some((&which, file)) = data.split_first() else {
        return false;
    };
    let dir = nerfstudio_scene("nerfstudio");
    std::fs::write(dir.join("transforms.json"), file).unwrap();
    let time_from = [TimeFrom::Order, TimeFrom::Name, TimeFrom::None][usize::from(which % 3)];
    let Ok(dataset) = read_nerfstudio_dataset(&dir, time_from) else {
        return false;
    };
    assert!(dataset.all_frames().count() > 0);
    for frame in dataset.all_frames() {
        assert!((0.0..=1.0).contains(&frame.time));
    }
    true
}

/// EvoGS state files (safetensors): `EvoState::load`.
pub fn evo_state(data: &[u8]) -> bool {
    let path = put("evo_state.safetensors", data);
    let Ok(state) = evo_state::EvoState::load(&path) else {
        return false;
    };
    assert_eq!(state.valid().len(), state.frames().len());
    true
}

/// Camera paths (`evogs video --path`, a JSON array of nerfies cameras with times):
/// `read_camera_path`.
pub fn camera_path(data: &[u8]) -> bool {
    let path = put("camera_path.json", data);
    let Ok(cameras) = evogs_io::read_camera_path(&path) else {
        return false;
    };
    assert!(!cameras.is_empty());
    for c in &cameras {
        assert!(c.time.is_finite());
    }
    true
}

/// PLY point clouds (a dataset's initial points: `x y z`, optional colours):
/// `read_point_cloud`.
pub fn point_cloud(data: &[u8]) -> bool {
    let path = put("points.ply", data);
    let Ok(cloud) = evogs_io::ply::read_point_cloud(&path) else {
        return false;
    };
    assert_eq!(cloud.colours.len(), cloud.positions.len());
    assert!(cloud.positions.len() <= data.len());
    true
}

/// antimatter15's `.splat` (32 bytes a Gaussian): `read_splat`.
pub fn splat(data: &[u8]) -> bool {
    let path = put("fuzz.splat", data);
    let Ok(g) = evogs_io::read_splat(&path) else {
        return false;
    };
    consistent(&g);
    assert_eq!(g.means.len() * 32, data.len());
    true
}

/// PlayCanvas/SuperSplat's `.compressed.ply`: `read_compressed_ply_bytes`.
pub fn compressed_ply(data: &[u8]) -> bool {
    let Ok(g) =
        evogs_io::compressed_ply::read_compressed_ply_bytes(data, Path::new("fuzz.compressed.ply"))
    else {
        return false;
    };
    consistent(&g);
    assert!(g.means.len() <= data.len());
    true
}

/// Network weights (safetensors, one 1-D tensor per parameter buffer): `tiny_nn::weights::load`
/// into a small network ([`crate::seeds::weights_net`], which its seeds were written with); the
/// first byte picks its storage (f32 or f16), the rest is the file.
pub fn weights(data: &[u8]) -> bool {
    let Some((&which, file)) = data.split_first() else {
        return false;
    };
    let precision = [tiny_nn::Precision::F32, tiny_nn::Precision::F16][usize::from(which % 2)];
    let path = put("weights.safetensors", file);
    let mut net = crate::seeds::weights_net(precision);
    if tiny_nn::weights::load(&path, &mut net).is_err() {
        return false;
    }
    // Saved and loaded again, the network is the same, bit for bit (every value came from the
    // file, and the writer and reader agree on every buffer).
    let first = put("weights-saved.safetensors", &[]);
    tiny_nn::weights::save(&first, &net).unwrap();
    let mut other = crate::seeds::weights_net(precision);
    tiny_nn::weights::load(&first, &mut other).unwrap();
    let second = put("weights-resaved.safetensors", &[]);
    tiny_nn::weights::save(&second, &other).unwrap();
    assert!(std::fs::read(&first).unwrap() == std::fs::read(&second).unwrap());
    true
}

/// Every per-Gaussian array of `g` has one row per Gaussian.
fn consistent(g: &splat_core::Gaussians) {
    let n = g.means.len();
    assert_eq!(g.log_scales.len(), n);
    assert_eq!(g.rotations.len(), n);
    assert_eq!(g.opacity_logits.len(), n);
    assert_eq!(g.sh.len(), n * 3 * splat_core::sh_coeff_count(g.sh_degree));
}

/// Training checkpoints (safetensors with a JSON header): `load_checkpoint` into the state of
/// the `tiny` preset with a small network ([`crate::seeds::tiny_config`], which its seed was
/// written with).
#[cfg(feature = "checkpoint")]
pub fn checkpoint(data: &[u8]) -> bool {
    let path = put("checkpoint.safetensors", data);
    let (mut state, mut backbone) = crate::seeds::tiny_state();
    let Ok(meta) = evogs_train::checkpoint::load_checkpoint(&path, &mut state, backbone.as_mut())
    else {
        return false;
    };
    assert_eq!(state.gaussians().means.len(), meta.gaussians);
    assert_eq!(state.stats().grad_sum.len(), meta.gaussians);
    true
}

/// The most parameters a network built by the `config` and `run` targets may have (16 Mi
/// floats, 64 MiB): a valid `config.json` may ask for networks of gigabytes, which the memory
/// checks refuse or allow by the machine's memory (F2), not by the fuzzer's; larger ones are
/// counted but not built.
#[cfg(feature = "checkpoint")]
pub const MAX_BUILT_PARAMS: usize = 1 << 24;

/// A run's `config.json`: `read_run_file` (parse, then every range checked), then everything a
/// command derives from the settings before it reads anything else: the parameter count, the
/// memory estimate on a dataset of the lego fixture's size (7 views of 100 × 100), the Gaussian
/// cap, densification's settings, and the backbone itself when it is small
/// ([`MAX_BUILT_PARAMS`]). None of it may panic or abort on a configuration the reader
/// accepted (issue F2: ten edited values made `eval`, `render` or `train --resume` abort).
#[cfg(feature = "checkpoint")]
pub fn config(data: &[u8]) -> bool {
    use evogs_train::memory::{MemoryEstimate, MemoryInputs};
    let dir = crate::scratch::scratch().join("config-run");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("config.json"), data).unwrap();
    let Ok((_, run)) = evogs_train::run::read_run_file(&dir) else {
        return false;
    };
    let train = &run.train;
    let cap = train.gaussian_cap(7);
    let _ = evogs_train::trainer::densify_config(train).validate();
    let Ok(params) = evogs_train::trainer::parameter_count(train) else {
        return true;
    };
    let memory = MemoryEstimate::new(
        train,
        &MemoryInputs {
            views: 7,
            pixels: 100 * 100,
            frames: 7,
            network_params: params,
        },
    );
    assert!(memory.at(train.init_points) >= memory.at(0));
    if let Some(cap) = cap {
        assert!(cap >= 1);
    }
    if params <= MAX_BUILT_PARAMS {
        let mut limited = train.clone();
        limited.memory_limit = Some(1 << 30);
        if let Ok(backbone) = evogs_train::trainer::make_backbone(&limited) {
            let built: usize = backbone.params().iter().map(|(_, p)| p.len()).sum();
            assert_eq!(built, params, "the parameter count is the built backbone's");
        }
    }
    true
}

/// A trained run's folder as a whole: the input is a selector byte, then `config.json` and
/// `train_metrics.json` separated by a NUL byte; the run's other files come from a small run
/// trained once per process ([`crate::seeds::template_run`]: EvoGS, or the baseline when bit 5
/// of the selector is set), each left out when its bit (0 `canonical.ply`, 1
/// `deform.safetensors`, 2 `evo_state.safetensors`, 3 `checkpoint.safetensors`) is set. The run
/// is opened as `eval`, `render` and `view` open it (its end-of-run files, or with bit 4 its
/// checkpoint) and, once open, deformed at t = 0.5: a `config.json` that disagrees with the
/// files beside it (another backbone, other sizes) must give an error, not a panic.
#[cfg(feature = "checkpoint")]
pub fn run(data: &[u8]) -> bool {
    let Some((&selector, rest)) = data.split_first() else {
        return false;
    };
    let files = parts(rest, 2);
    let dir = crate::scratch::scratch().join("run");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("config.json"), files[0]).unwrap();
    std::fs::write(dir.join("train_metrics.json"), files[1]).unwrap();
    let template = crate::seeds::template_run(selector & 0x20 == 0);
    for (bit, name) in crate::seeds::RUN_FILES.iter().enumerate() {
        if selector & (1 << bit) == 0 && template.join(name).is_file() {
            // Read and written (std retries both on EINTR), not `fs::copy`: its
            // copy_file_range failed with EINTR under libFuzzer's timer signal.
            let bytes = std::fs::read(template.join(name)).unwrap();
            std::fs::write(dir.join(name), bytes).unwrap();
        }
    }
    // What the run's config asks for is counted before anything is built: a valid config that
    // asks for a large network is the memory checks' to refuse, not this target's to allocate.
    if let Ok((_, run)) = evogs_train::run::read_run_file(&dir)
        && evogs_train::trainer::parameter_count(&run.train).is_ok_and(|n| n > MAX_BUILT_PARAMS)
    {
        return true;
    }
    let opened = if selector & 0x10 == 0 {
        evogs_eval::LoadedRun::open(&dir)
    } else {
        evogs_eval::LoadedRun::open_checkpoint(&dir)
    };
    let Ok(mut run) = opened else {
        return false;
    };
    if let Ok(g) = run.deformed(0.5) {
        assert_eq!(g.len(), run.canonical.len());
    }
    true
}
