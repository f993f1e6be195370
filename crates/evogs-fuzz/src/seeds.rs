//! The seed corpora: valid files written by the project's own writers (they reach deep into each
//! reader) and the repository's D-NeRF `transforms_*.json` fixtures, one folder per target.

use std::path::Path;
use std::sync::OnceLock;

use evo_state::{EvoConfig, EvoState, Frames, Storage};
use evogs_io::colmap::{
    CameraModel, ColmapCamera, ColmapImage, ColmapPoint, encode_cameras_bin, encode_cameras_txt,
    encode_images_bin, encode_images_txt, encode_points3d_bin, encode_points3d_txt,
};
use evogs_io::{CameraInfo, nerfies_camera_json};

use crate::scratch::{DNERF_FIXTURE, POINT_CLOUD_PLY, small_camera};

/// The configuration of the checkpoint target and its seed: the `tiny` preset with a network
/// of two layers of width 8 (a seed of a few KiB: libFuzzer mutates small inputs faster).
#[cfg(feature = "checkpoint")]
pub fn tiny_config() -> evogs_train::TrainConfig {
    let mut config = evogs_train::TrainConfig::preset(evogs_train::Preset::Tiny);
    config.net.width = 8;
    config.net.depth = 2;
    config.net.skip_after = None;
    config
}

/// The files of a run besides its `config.json` and `train_metrics.json`, in the order of the
/// `run` target's selector bits.
#[cfg(feature = "checkpoint")]
pub const RUN_FILES: [&str; 4] = [
    "canonical.ply",
    "deform.safetensors",
    "evo_state.safetensors",
    "checkpoint.safetensors",
];

/// A run of [`tiny_config`] trained for two iterations on the repository's lego fixture, EvoGS
/// or the baseline, written once per process into a temporary folder: the files the `run`
/// target puts beside the fuzzed `config.json`, and the source of its seeds.
#[cfg(feature = "checkpoint")]
pub fn template_run(evogs: bool) -> &'static Path {
    /// The folder (removed never: a static is not dropped) and the two runs in it.
    static RUNS: OnceLock<(tempfile::TempDir, [std::path::PathBuf; 2])> = OnceLock::new();
    let (_, runs) = RUNS.get_or_init(|| {
        let root = tempfile::Builder::new()
            .prefix("evogs-fuzz-runs-")
            .tempdir()
            .expect("template runs' folder");
        let runs = [
            ("evogs", evogs_backbones::Method::Evogs),
            ("baseline", evogs_backbones::Method::Baseline),
        ]
        .map(|(name, method)| {
            let mut config = tiny_config();
            config.method = method;
            config.iterations = 2;
            config.warm_up = 1;
            let request = evogs_train::run::TrainRequest {
                data: Path::new(DNERF_FIXTURE).to_path_buf(),
                out: root.path().join(name),
                config,
                resume: false,
                stop_after: None,
                resume_backend: None,
                resume_net_backend: None,
            };
            evogs_train::run::train(&request, &mut |_, _| {}).expect("the template run trains");
            request.out
        });
        (root, runs)
    });
    &runs[usize::from(!evogs)]
}

/// A fresh state and backbone of [`tiny_config`] (one Gaussian), to load a checkpoint into.
#[cfg(feature = "checkpoint")]
pub fn tiny_state() -> (
    evogs_train::state::SceneState,
    Box<dyn evogs_backbones::Backbone>,
) {
    let config = tiny_config();
    let backbone = evogs_train::trainer::make_backbone(&config).expect("tiny backbone");
    let init = evogs_train::init::random_gaussians(1, 1.0, config.sh_degree, 0);
    let state = evogs_train::state::SceneState::new(init, backbone.as_ref(), &config.lr)
        .expect("tiny state");
    (state, backbone)
}

/// The network of the `weights` target and its seeds: an MLP 3 → 8 → 8 → 2 with a skip
/// connection (five buffers of a few hundred values) stored in `precision`.
pub fn weights_net(precision: tiny_nn::Precision) -> tiny_nn::Mlp {
    tiny_nn::MlpConfig::new(3, 8, 2, 2)
        .skip_after(1)
        .precision(precision)
        .seed(3)
        .build()
        .expect("the weights target's network")
}

/// Called by every target's `init`: when `EVOGS_FUZZ_SEEDS` names a folder, writes the seed
/// corpora of every target into `<folder>/<target>/` (libFuzzer reads its corpus after `init`).
pub fn seeds_from_env() {
    static DONE: OnceLock<()> = OnceLock::new();
    DONE.get_or_init(|| {
        if let Some(dir) = std::env::var_os("EVOGS_FUZZ_SEEDS") {
            write_all_seeds(Path::new(&dir));
        }
    });
}

/// Writes `bytes` as seed `name` of `target` under `dir`.
fn seed(dir: &Path, target: &str, name: &str, bytes: impl AsRef<[u8]>) {
    let folder = dir.join(target);
    std::fs::create_dir_all(&folder).unwrap();
    std::fs::write(folder.join(name), bytes).unwrap();
}

fn joined(parts: &[&str]) -> Vec<u8> {
    parts.join("\0").into_bytes()
}

/// Writes the seed corpora of every target into `dir/<target>/`: valid files written by the
/// project's own writers (they reach deep into each reader) and, for `dnerf_transforms`, the
/// repository's `transforms_*.json` fixtures.
pub fn write_all_seeds(dir: &Path) {
    for split in ["train", "val", "test"] {
        let name = format!("transforms_{split}.json");
        let bytes = std::fs::read(Path::new(DNERF_FIXTURE).join(&name)).unwrap();
        seed(dir, "dnerf_transforms", &name, bytes);
    }
    // PLY: binary (SH degrees 0 and 1) and ASCII.
    for degree in [0, 1] {
        let g = small_gaussians(3, degree);
        let mut bytes = Vec::new();
        evogs_io::write_ply_to(&mut bytes, g.view(), Path::new("seed.ply")).unwrap();
        seed(dir, "ply", &format!("binary_sh{degree}.ply"), &bytes);
    }
    let names = evogs_io::ply::property_names(0);
    let mut ascii = String::from("ply\nformat ascii 1.0\nelement vertex 2\n");
    for n in &names {
        ascii += &format!("property float {n}\n");
    }
    ascii += "end_header\n";
    for row in 0..2 {
        let values: Vec<String> = (0..names.len())
            .map(|k| format!("{}", (row * 7 + k) as f32 * 0.1))
            .collect();
        ascii += &values.join(" ");
        ascii += "\n";
    }
    seed(dir, "ply", "ascii_sh0.ply", ascii);

    // Point clouds: ASCII with 8-bit colours, and a binary 3DGS PLY (no colours: grey).
    seed(dir, "point_cloud", "ascii_rgb.ply", POINT_CLOUD_PLY);
    let mut binary = Vec::new();
    evogs_io::write_ply_to(
        &mut binary,
        small_gaussians(3, 0).view(),
        Path::new("seed.ply"),
    )
    .unwrap();
    seed(dir, "point_cloud", "binary_3dgs.ply", binary);

    // .splat and .compressed.ply, written by the exporters.
    std::fs::create_dir_all(dir.join("splat")).unwrap();
    evogs_io::write_splat(&dir.join("splat/three.splat"), small_gaussians(3, 0).view()).unwrap();
    std::fs::create_dir_all(dir.join("compressed_ply")).unwrap();
    for degree in [0, 1] {
        let path = dir.join(format!("compressed_ply/sh{degree}.compressed.ply"));
        evogs_io::write_compressed_ply(&path, small_gaussians(3, degree).view()).unwrap();
    }

    // Nerfies camera and dataset JSON.
    let camera = CameraInfo::pinhole(small_camera());
    seed(
        dir,
        "nerfies_camera",
        "camera.json",
        nerfies_camera_json(&camera),
    );
    // A camera path: the camera at two times.
    let object = nerfies_camera_json(&camera);
    let object = object.trim_end().strip_suffix('}').expect("a JSON object");
    seed(
        dir,
        "camera_path",
        "two_times.json",
        format!("[{object}, \"time\": 0.0}}, {object}, \"time\": 0.75}}]"),
    );
    seed(
        dir,
        "nerfies_dataset",
        "scene",
        joined(&[
            r#"{"count": 2, "num_exemplars": 2, "ids": ["a", "b"], "train_ids": ["a"], "val_ids": ["b"]}"#,
            r#"{"a": {"time_id": 0, "camera_id": 0, "warp_id": 0}, "b": {"time_id": 1, "camera_id": 0, "warp_id": 1}}"#,
            r#"{"scale": 0.5, "center": [0.1, 0.2, 0.3], "near": 0.1, "far": 9.0}"#,
        ]),
    );

    // COLMAP binary and text (first byte: 0 cameras, 1 images, 2 points).
    let cameras = vec![
        ColmapCamera {
            id: 1,
            model: CameraModel::Pinhole,
            width: 8,
            height: 6,
            params: vec![7.0, 7.5, 4.0, 3.0],
        },
        ColmapCamera {
            id: 2,
            model: CameraModel::Opencv,
            width: 8,
            height: 6,
            params: vec![7.0, 7.5, 4.0, 3.0, 0.01, -0.01, 0.001, 0.002],
        },
    ];
    let images = vec![ColmapImage {
        id: 1,
        qvec: [1.0, 0.0, 0.0, 0.0],
        tvec: [0.1, 0.2, 3.0],
        camera_id: 1,
        name: "a.png".into(),
    }];
    let points = vec![ColmapPoint {
        xyz: [0.1, -0.2, 0.3],
        rgb: [10, 200, 30],
    }];
    let with = |k: u8, bytes: Vec<u8>| [vec![k], bytes].concat();
    seed(
        dir,
        "colmap_bin",
        "cameras",
        with(0, encode_cameras_bin(&cameras)),
    );
    seed(
        dir,
        "colmap_bin",
        "images",
        with(1, encode_images_bin(&images, 2)),
    );
    seed(
        dir,
        "colmap_bin",
        "points",
        with(2, encode_points3d_bin(&points)),
    );
    seed(
        dir,
        "colmap_txt",
        "cameras",
        with(0, encode_cameras_txt(&cameras).into_bytes()),
    );
    seed(
        dir,
        "colmap_txt",
        "images",
        with(1, encode_images_txt(&images).into_bytes()),
    );
    seed(
        dir,
        "colmap_txt",
        "points",
        with(2, encode_points3d_txt(&points).into_bytes()),
    );

    // nerfstudio transforms.json (first byte: 0 times from order, 1 from the names' numbers).
    let c2w = |x: f64| format!("[[1, 0, 0, {x}], [0, 1, 0, 0], [0, 0, 1, 3], [0, 0, 0, 1]]");
    let with_time = format!(
        r#"{{"camera_model": "OPENCV", "w": 8, "h": 6, "fl_x": 7.0, "fl_y": 7.5, "cx": 4.0, "cy": 3.0, "k1": 0.01, "ply_file_path": "sparse_pc.ply", "applied_transform": [[0, 1, 0, 0], [1, 0, 0, 0], [0, 0, -1, 0]], "train_filenames": ["images/a.png"], "test_filenames": ["images/b.png"], "frames": [{{"file_path": "images/a.png", "time": 0.0, "transform_matrix": {}}}, {{"file_path": "images/b.png", "time": 1.0, "transform_matrix": {}}}]}}"#,
        c2w(0.0),
        c2w(0.5)
    );
    seed(
        dir,
        "nerfstudio",
        "with_time",
        [b"\0".as_slice(), with_time.as_bytes()].concat(),
    );
    let per_frame = format!(
        r#"{{"w": 8, "h": 6, "cx": 4.0, "frames": [{{"file_path": "images/frame_0002.png", "fl_x": 7.0, "fl_y": 7.0, "cy": 3.0, "distortion_params": [0.1, 0, 0, 0, 0.01, 0], "transform_matrix": {}}}, {{"file_path": "images/frame_0001.png", "fl_x": 6.0, "fl_y": 6.5, "cy": 3.0, "transform_matrix": {}}}]}}"#,
        c2w(0.0),
        c2w(-0.5)
    );
    seed(
        dir,
        "nerfstudio",
        "per_frame",
        [b"\x01".as_slice(), per_frame.as_bytes()].concat(),
    );

    // npy: f64 and f32 (the writer's two dtypes).
    let data = [0.5, -1.0, 2.0, 3.5, 4.0, -5.25];
    seed(
        dir,
        "npy",
        "f64.npy",
        evogs_io::npy::encode_npy(&[2, 3], &data, false),
    );
    seed(
        dir,
        "npy",
        "f32.npy",
        evogs_io::npy::encode_npy(&[3, 2], &data, true),
    );

    // Evo state: f32 and f16 buffers, with frames filled.
    for storage in [Storage::F32, Storage::F16] {
        let config = EvoConfig {
            storage,
            ..EvoConfig::default()
        };
        let frames = Frames::new(vec![0.0, 0.5, 1.0]).unwrap();
        let mut state = EvoState::new(config, frames, 2, 7).unwrap();
        let z = vec![0.25; 2 * state.dim()];
        for t in [0.0, 0.5] {
            let step = state.forward(t, &z).unwrap();
            state.commit(&step).unwrap();
        }
        let path = dir
            .join("evo_state")
            .join(format!("{storage:?}.safetensors"));
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        state.save(&path).unwrap();
    }

    // Network weights, f32 and f16 (the target's first byte picks the storage).
    for (byte, precision) in [(0u8, tiny_nn::Precision::F32), (1, tiny_nn::Precision::F16)] {
        let path = dir
            .join("weights")
            .join(format!("{precision:?}.safetensors"));
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        tiny_nn::weights::save(&path, &weights_net(precision)).unwrap();
        let file = std::fs::read(&path).unwrap();
        std::fs::write(&path, [[byte].as_slice(), &file].concat()).unwrap();
    }

    #[cfg(feature = "checkpoint")]
    {
        // Checkpoint of the tiny preset with three Gaussians.
        let config = tiny_config();
        let backbone = evogs_train::trainer::make_backbone(&config).unwrap();
        let init = evogs_train::init::random_gaussians(3, 1.0, config.sh_degree, 0);
        let state =
            evogs_train::state::SceneState::new(init, backbone.as_ref(), &config.lr).unwrap();
        let path = dir.join("checkpoint").join("tiny.safetensors");
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        evogs_train::checkpoint::save_checkpoint(
            &path,
            &state,
            backbone.as_ref(),
            5,
            0,
            None,
            None,
        )
        .unwrap();

        // config.json: the template runs' and the repository's fixtures of real runs' (every
        // method, backbone and switch `evogs train` records, crates/evogs-cli/tests/data).
        let fixtures = Path::new(CONFIG_FIXTURES);
        let mut names: Vec<_> = std::fs::read_dir(fixtures)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .filter(|n| n.ends_with(".json"))
            .collect();
        names.sort();
        for name in names {
            seed(
                dir,
                "config",
                &name,
                std::fs::read(fixtures.join(&name)).unwrap(),
            );
        }
        // A run's folder: each template run opened whole, from its end-of-run files and from its
        // checkpoint (the selector byte of the `run` target).
        for (evogs, name) in [(true, "evogs"), (false, "baseline")] {
            let run = template_run(evogs);
            let config = std::fs::read(run.join("config.json")).unwrap();
            seed(dir, "config", &format!("template-{name}.json"), &config);
            let metrics = std::fs::read(run.join("train_metrics.json")).unwrap();
            for (selector, how) in [(0u8, "end"), (0x10, "checkpoint")] {
                let selector = selector | if evogs { 0 } else { 0x20 };
                let input = [&[selector][..], &config, &[0], &metrics].concat();
                seed(dir, "run", &format!("{name}-{how}"), input);
            }
        }
    }
}

/// The repository's `config.json` files of real runs, in the current format (the fixtures of
/// `evogs-cli`'s config test).
#[cfg(feature = "checkpoint")]
const CONFIG_FIXTURES: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../evogs-cli/tests/data/config-current"
);

/// `n` Gaussians of SH degree `degree` with distinct, unremarkable values.
pub fn small_gaussians(n: usize, degree: u32) -> splat_core::Gaussians {
    let mut g = splat_core::Gaussians::with_degree(degree);
    for i in 0..n {
        let x = i as f32 * 0.25;
        g.means.push([x, -x, 0.5 * x]);
        g.log_scales.push([-2.0 - x; 3]);
        g.rotations.push([1.0, 0.1 * x, 0.0, 0.0]);
        g.opacity_logits.push(x - 0.5);
    }
    g.sh = (0..n * g.sh_stride())
        .map(|e| (e % 7) as f32 * 0.1 - 0.3)
        .collect();
    g
}
