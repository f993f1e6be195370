//! Malformed datasets: every error names the file and the field; mutated or truncated binary
//! files (COLMAP `.bin`, `.npy`) give errors, never panics.

use std::path::Path;

use evogs_io::colmap::{
    CameraModel, ColmapCamera, ColmapImage, ColmapPoint, encode_cameras_bin, encode_images_bin,
    encode_points3d_bin, parse_cameras_bin, parse_cameras_txt, parse_images_bin, parse_images_txt,
    parse_points3d_bin,
};
use evogs_io::npy::{encode_npy, parse_npy};
use evogs_io::{IoError, LoadOptions, TimeFrom, detect_format, load_dataset};
use proptest::prelude::*;

fn write(path: &Path, bytes: impl AsRef<[u8]>) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, bytes).unwrap();
}

fn message(result: Result<impl std::fmt::Debug, IoError>) -> String {
    result.unwrap_err().to_string()
}

fn assert_names(message: &str, file: &str, field: &str) {
    assert!(
        message.contains(file),
        "expected file `{file}` in: {message}"
    );
    assert!(message.contains(field), "expected `{field}` in: {message}");
    assert!(!message.contains('\n'), "one line: {message}");
}

fn sample_cameras() -> Vec<ColmapCamera> {
    vec![
        ColmapCamera {
            id: 1,
            model: CameraModel::Opencv,
            width: 640,
            height: 480,
            params: vec![500.0, 510.0, 320.0, 240.0, 0.1, -0.02, 0.001, 0.002],
        },
        ColmapCamera {
            id: 2,
            model: CameraModel::SimpleRadial,
            width: 320,
            height: 240,
            params: vec![250.0, 160.0, 120.0, 0.05],
        },
        ColmapCamera {
            id: 3,
            model: CameraModel::SimplePinhole,
            width: 100,
            height: 80,
            params: vec![90.0, 50.0, 40.0],
        },
    ]
}

fn sample_images() -> Vec<ColmapImage> {
    (0..3)
        .map(|i| ColmapImage {
            id: i + 1,
            qvec: [1.0, 0.0, 0.1 * i as f64, 0.0],
            tvec: [0.5, -0.25, 3.0],
            camera_id: i + 1,
            name: format!("im{i}.jpg"),
        })
        .collect()
}

fn sample_points() -> Vec<ColmapPoint> {
    (0..4)
        .map(|i| ColmapPoint {
            xyz: [i as f64, 1.0, -2.0],
            rgb: [i as u8, 2, 3],
        })
        .collect()
}

#[test]
fn binary_models_round_trip_and_keep_distortion() {
    let p = Path::new("cameras.bin");
    assert_eq!(
        parse_cameras_bin(p, &encode_cameras_bin(&sample_cameras())).unwrap(),
        sample_cameras()
    );
    let p = Path::new("images.bin");
    assert_eq!(
        parse_images_bin(p, &encode_images_bin(&sample_images(), 3)).unwrap(),
        sample_images()
    );
    let p = Path::new("points3D.bin");
    assert_eq!(
        parse_points3d_bin(p, &encode_points3d_bin(&sample_points())).unwrap(),
        sample_points()
    );
    let ([fx, fy, cx, cy], d) = sample_cameras()[0].intrinsics();
    assert_eq!([fx, fy, cx, cy], [500.0, 510.0, 320.0, 240.0]);
    assert_eq!(d.radial, [0.1, -0.02, 0.0]);
    assert_eq!(d.tangential, [0.001, 0.002]);
    let (_, d) = sample_cameras()[1].intrinsics();
    assert_eq!((d.radial, d.tangential), ([0.05, 0.0, 0.0], [0.0; 2]));
}

#[test]
fn text_models_round_trip_exactly() {
    use evogs_io::colmap::{
        encode_cameras_txt, encode_images_txt, encode_points3d_txt, parse_points3d_txt,
    };
    let p = Path::new("x.txt");
    let cameras = parse_cameras_txt(p, &encode_cameras_txt(&sample_cameras())).unwrap();
    assert_eq!(cameras, sample_cameras());
    let images = parse_images_txt(p, &encode_images_txt(&sample_images())).unwrap();
    assert_eq!(images, sample_images());
    let points = parse_points3d_txt(p, &encode_points3d_txt(&sample_points())).unwrap();
    assert_eq!(points, sample_points());
}

#[test]
fn unknown_camera_models_are_named() {
    let mut bytes = encode_cameras_bin(&sample_cameras()[2..]);
    // model_id sits after num_cameras (8 bytes) and camera_id (4 bytes).
    bytes[12..16].copy_from_slice(&3i32.to_le_bytes());
    let m = message(parse_cameras_bin(Path::new("cameras.bin"), &bytes));
    assert_names(&m, "cameras.bin", "cameras[0].model_id");
    assert!(m.contains("RADIAL (id 3) is not supported"), "{m}");
    bytes[12..16].copy_from_slice(&99i32.to_le_bytes());
    let m = message(parse_cameras_bin(Path::new("cameras.bin"), &bytes));
    assert!(m.contains("id 99 is unknown"), "{m}");
    let text = "# comment\n1 FULL_OPENCV 10 10 1 1 5 5 0 0 0 0 0 0 0 0\n";
    let m = message(parse_cameras_txt(Path::new("cameras.txt"), text));
    assert_names(&m, "cameras.txt", "line 2: MODEL");
    assert!(m.contains("FULL_OPENCV"), "{m}");
    let m = message(parse_cameras_txt(
        Path::new("cameras.txt"),
        "1 PINHOLE 10 10 1 1 5\n",
    ));
    assert_names(&m, "cameras.txt", "PINHOLE has 4 parameters, found 3");
}

#[test]
fn truncated_binary_files_name_the_field() {
    let bytes = encode_images_bin(&sample_images(), 2);
    let m = message(parse_images_bin(
        Path::new("images.bin"),
        &bytes[..bytes.len() - 5],
    ));
    assert_names(&m, "images.bin", "images[2].num_points2D");
    assert!(m.contains("truncated"), "{m}");
    let m = message(parse_images_bin(Path::new("images.bin"), &bytes[..20]));
    assert_names(&m, "images.bin", "num_reg_images");
    let bytes = encode_points3d_bin(&sample_points());
    let m = message(parse_points3d_bin(Path::new("points3D.bin"), &bytes[..60]));
    assert_names(&m, "points3D.bin", "num_points");
    let mut long = bytes.clone();
    long.push(0);
    let m = message(parse_points3d_bin(Path::new("points3D.bin"), &long));
    assert_names(&m, "points3D.bin", "unexpected bytes");
}

#[test]
fn text_images_file_errors_name_the_line() {
    let text = "# header\n1 1 0 0 0 0 0 nan 1 a.png\n\n";
    let m = message(parse_images_txt(Path::new("images.txt"), text));
    assert_names(&m, "images.txt", "line 2: TVEC");
    let text = "1 1 0 0 0 0 0 0 1\n";
    let m = message(parse_images_txt(Path::new("images.txt"), text));
    assert_names(&m, "images.txt", "line 1: image");
    // An empty points line is the image's second line, not a missing image.
    let text = "1 1 0 0 0 0 0 0 1 a.png\n\n2 1 0 0 0 0 0 1 1 b c.png\n1.0 2.0 -1\n";
    let images = parse_images_txt(Path::new("images.txt"), text).unwrap();
    assert_eq!(images.len(), 2);
    assert_eq!(images[1].name, "b c.png");
}

#[test]
fn colmap_dataset_errors_name_file_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let sparse = dir.path().join("sparse/0");
    write(
        &sparse.join("cameras.bin"),
        encode_cameras_bin(&sample_cameras()),
    );
    write(
        &sparse.join("points3D.bin"),
        encode_points3d_bin(&sample_points()),
    );
    let m = message(load_dataset(dir.path(), &LoadOptions::default()));
    assert_names(&m, "sparse/0", "neither images.bin nor images.txt");
    let mut images = sample_images();
    images[1].camera_id = 7;
    write(&sparse.join("images.bin"), encode_images_bin(&images, 0));
    let m = message(load_dataset(dir.path(), &LoadOptions::default()));
    assert_names(&m, "images.bin", "image 2.camera_id");
    write(
        &sparse.join("images.bin"),
        encode_images_bin(&sample_images(), 0),
    );
    let m = message(load_dataset(dir.path(), &LoadOptions::default()));
    assert_names(&m, "images.bin", "image 1.name");
    assert!(m.contains("im0.jpg") && m.contains("does not exist"), "{m}");
    // Times from names need a number in every name: the first without one is named.
    let mut images = sample_images();
    images[2].name = "sunset.jpg".into();
    write(&sparse.join("images.bin"), encode_images_bin(&images, 0));
    let by_name = LoadOptions {
        time_from: TimeFrom::Name,
        ..LoadOptions::default()
    };
    let m = message(load_dataset(dir.path(), &by_name));
    assert_names(&m, "images.bin", "image 3.name");
    assert!(m.contains("`sunset.jpg` has no frame number"), "{m}");
}

#[test]
fn nerfstudio_errors_name_file_and_field() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["a.png", "b.png"] {
        write(
            &dir.path().join(name),
            b"not read: only its existence is checked",
        );
    }
    let frame = |name: &str| {
        serde_json::json!({"file_path": name, "fl_x": 50.0, "transform_matrix":
            [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 3], [0, 0, 0, 1]]})
    };
    let good = serde_json::json!({"w": 8, "h": 6, "fl_y": 50.0, "cx": 4.0, "cy": 3.0,
        "frames": [frame("a.png"), frame("b.png")]});
    let path = dir.path().join("transforms.json");
    let check = |edit: &dyn Fn(&mut serde_json::Value),
                 options: &LoadOptions,
                 field: &str,
                 problem: &str| {
        let mut json = good.clone();
        edit(&mut json);
        write(&path, json.to_string());
        let m = message(load_dataset(dir.path(), options));
        assert_names(&m, "transforms.json", field);
        assert!(m.contains(problem), "expected `{problem}` in: {m}");
    };
    let plain = LoadOptions::default();
    write(&path, good.to_string());
    load_dataset(dir.path(), &plain).unwrap();
    check(
        &|j| {
            j["frames"][1].as_object_mut().unwrap().remove("fl_x");
        },
        &plain,
        "frames[1].fl_x",
        "missing",
    );
    check(
        &|j| {
            j.as_object_mut().unwrap().remove("cy");
        },
        &plain,
        "frames[0].cy",
        "missing",
    );
    check(
        &|j| j["frames"][0]["file_path"] = "c.png".into(),
        &plain,
        "frames[0].file_path",
        "does not exist",
    );
    check(
        &|j| j["camera_model"] = "EQUIRECTANGULAR".into(),
        &plain,
        "camera_model",
        "not supported",
    );
    // k4 alone does not make distortion shared (nerfstudio's rule): per frame it is read.
    check(
        &|j| j["frames"][0]["k4"] = 0.1.into(),
        &plain,
        "frames[0].k4",
        "OPENCV_FISHEYE",
    );
    check(
        &|j| {
            j["k1"] = 0.1.into();
            j["k4"] = 0.1.into();
        },
        &plain,
        "k4",
        "OPENCV_FISHEYE",
    );
    check(
        &|j| j["frames"][0]["time"] = 0.5.into(),
        &plain,
        "frames",
        "1 of 2 frames",
    );
    check(
        &|j| j["frames"][0]["time"] = 2.0.into(),
        &plain,
        "frames[0].time",
        "outside",
    );
    check(
        &|j| j["test_filenames"] = serde_json::json!(["b.png"]),
        &plain,
        "train_filenames",
        "missing",
    );
    // Found by the fuzz replay's mutation pass: an empty list was accepted as a dataset with no
    // frame in any split.
    check(
        &|j| j["train_filenames"] = serde_json::json!([]),
        &plain,
        "train_filenames",
        "names no frame",
    );
    check(
        &|j| j["train_filenames"] = serde_json::json!(["a.png", "d.png"]),
        &plain,
        "train_filenames[1]",
        "`d.png` is not a frame",
    );
    check(
        &|j| j["ply_file_path"] = "pc.ply".into(),
        &plain,
        "ply_file_path",
        "does not exist",
    );
    check(
        &|j| j["frames"][1]["transform_matrix"][0][0] = 2.into(),
        &plain,
        "frames[1].transform_matrix",
        "not a rotation",
    );
    let by_name = LoadOptions {
        time_from: TimeFrom::Name,
        ..LoadOptions::default()
    };
    check(
        &|_| {},
        &by_name,
        "frames[0].file_path",
        "`a.png` has no frame number",
    );
}

#[test]
fn nerfies_errors_name_file_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("NeRF-bad");
    write(
        &root.join("dataset.json"),
        r#"{"ids": ["a", "b"], "train_ids": ["a"], "val_ids": ["b"]}"#,
    );
    write(
        &root.join("scene.json"),
        r#"{"scale": 1.0, "center": [0, 0, 0]}"#,
    );
    write(
        &root.join("metadata.json"),
        r#"{"a": {"time_id": 0, "camera_id": 0}}"#,
    );
    let m = message(load_dataset(&root, &LoadOptions::default()));
    assert_names(&m, "metadata.json", "field `b`: missing");
    write(
        &root.join("metadata.json"),
        r#"{"a": {"time_id": 0}, "b": {"camera_id": 0}}"#,
    );
    let m = message(load_dataset(&root, &LoadOptions::default()));
    assert_names(&m, "metadata.json", "b.warp_id");
    write(
        &root.join("metadata.json"),
        r#"{"a": {"time_id": 0}, "b": {"time_id": 1}}"#,
    );
    let m = message(load_dataset(&root, &LoadOptions::default()));
    assert_names(&m, "dataset.json", "`ids`");
    assert!(m.contains("camera/a.json"), "{m}");
    // A camera whose image_size does not match its image.
    let camera = splat_core::Camera::look_at(
        8,
        6,
        1.0,
        glam::Vec3::new(0.0, -3.0, 0.0),
        glam::Vec3::ZERO,
        glam::Vec3::Z,
    );
    for id in ["a", "b"] {
        std::fs::create_dir_all(root.join("camera")).unwrap();
        evogs_io::write_nerfies_camera(
            &root.join(format!("camera/{id}.json")),
            &evogs_io::CameraInfo::pinhole(camera),
        )
        .unwrap();
        std::fs::create_dir_all(root.join("rgb/1x")).unwrap();
        evogs_io::save_png(
            &root.join(format!("rgb/1x/{id}.png")),
            &evogs_io::ImageRgb::filled(8, 9, [0.5; 3]),
        )
        .unwrap();
    }
    let m = message(load_dataset(&root, &LoadOptions::default()));
    assert_names(&m, "camera/a.json", "image_size");
    assert!(m.contains("8×6") && m.contains("8×9"), "{m}");
    write(
        &root.join("scene.json"),
        r#"{"scale": -1.0, "center": [0, 0, 0]}"#,
    );
    let m = message(load_dataset(&root, &LoadOptions::default()));
    assert_names(&m, "scene.json", "scale");
    write(
        &root.join("dataset.json"),
        r#"{"ids": ["a"], "train_ids": "a"}"#,
    );
    let m = message(load_dataset(&root, &LoadOptions::default()));
    assert_names(&m, "dataset.json", "train_ids");
}

#[test]
fn neu3d_errors_name_file_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let poses = dir.path().join("poses_bounds.npy");
    write(&poses, encode_npy(&[2, 15], &[0.0; 30], false));
    let m = message(load_dataset(dir.path(), &LoadOptions::default()));
    assert_names(&m, "poses_bounds.npy", "shape");
    assert!(m.contains("(N, 17)"), "{m}");
    // A row whose rotation is not a rotation.
    let mut row = [0.0f64; 17];
    row[4] = 6.0;
    row[9] = 8.0;
    row[14] = 5.0;
    write(&poses, encode_npy(&[1, 17], &row, false));
    let m = message(load_dataset(dir.path(), &LoadOptions::default()));
    assert_names(&m, "poses_bounds.npy", "row[0].rotation");
    // Identity axes but no camera folders.
    // LLFF columns: down = world y, right = world x, back = −(world z) (forward = +z).
    row[1] = 1.0;
    row[5] = 1.0;
    row[12] = -1.0;
    write(&poses, encode_npy(&[1, 17], &row, false));
    let m = message(load_dataset(dir.path(), &LoadOptions::default()));
    assert_names(
        &m,
        "poses_bounds.npy",
        "1 camera poses but 0 camera folders",
    );
    write(&poses, b"\x93NUMPY\x01\x00\x10\x00{'descr': '<f8'}");
    let m = message(load_dataset(dir.path(), &LoadOptions::default()));
    assert_names(&m, "poses_bounds.npy", "header.");
}

#[test]
fn undetectable_directories_are_reported() {
    let dir = tempfile::tempdir().unwrap();
    let m = message(detect_format(dir.path()));
    assert!(
        m.contains("sparse/") && m.contains("poses_bounds.npy"),
        "{m}"
    );
    let m = message(detect_format(&dir.path().join("missing")));
    assert_names(&m, "missing", "no such dataset directory");
    let file = dir.path().join("a.txt");
    std::fs::write(&file, b"").unwrap();
    let m = message(detect_format(&file));
    assert_names(&m, "a.txt", "is a file, not a dataset directory");
}

/// Applies mutations (byte overwrites) and a truncation to valid bytes.
fn mutate(mut bytes: Vec<u8>, edits: &[(usize, u8)], cut: usize) -> Vec<u8> {
    for &(at, value) in edits {
        if !bytes.is_empty() {
            let i = at % bytes.len();
            bytes[i] = value;
        }
    }
    let keep = bytes.len() - cut % (bytes.len() + 1);
    bytes.truncate(keep);
    bytes
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn mutated_colmap_bin_never_panics(
        which in 0usize..3,
        edits in proptest::collection::vec((any::<usize>(), any::<u8>()), 0..6),
        cut in 0usize..40,
    ) {
        let path = Path::new("model.bin");
        let valid = match which {
            0 => encode_cameras_bin(&sample_cameras()),
            1 => encode_images_bin(&sample_images(), 2),
            _ => encode_points3d_bin(&sample_points()),
        };
        let bytes = mutate(valid, &edits, cut);
        let result = match which {
            0 => parse_cameras_bin(path, &bytes).map(|v| v.len()),
            1 => parse_images_bin(path, &bytes).map(|v| v.len()),
            _ => parse_points3d_bin(path, &bytes).map(|v| v.len()),
        };
        if let Err(e) = result {
            let m = e.to_string();
            prop_assert!(m.starts_with("model.bin: field `"), "{}", m);
        }
    }

    #[test]
    fn mutated_colmap_text_never_panics(
        which in 0usize..3,
        edits in proptest::collection::vec((any::<usize>(), 32u8..127), 0..6),
        cut in 0usize..60,
    ) {
        use evogs_io::colmap::{encode_cameras_txt, encode_images_txt, encode_points3d_txt, parse_points3d_txt};
        let path = Path::new("model.txt");
        let valid = match which {
            0 => encode_cameras_txt(&sample_cameras()),
            1 => encode_images_txt(&sample_images()),
            _ => encode_points3d_txt(&sample_points()),
        };
        let bytes = mutate(valid.into_bytes(), &edits, cut);
        let text = String::from_utf8_lossy(&bytes);
        let result = match which {
            0 => parse_cameras_txt(path, &text).map(|v| v.len()),
            1 => parse_images_txt(path, &text).map(|v| v.len()),
            _ => parse_points3d_txt(path, &text).map(|v| v.len()),
        };
        if let Err(e) = result {
            let m = e.to_string();
            prop_assert!(m.starts_with("model.txt: field `line "), "{}", m);
        }
    }

    #[test]
    fn mutated_npy_never_panics(
        rows in 1usize..5,
        f32 in any::<bool>(),
        edits in proptest::collection::vec((0usize..140, any::<u8>()), 0..6),
        cut in 0usize..30,
    ) {
        let data: Vec<f64> = (0..rows * 3).map(|i| i as f64 * 0.5).collect();
        let bytes = mutate(encode_npy(&[rows, 3], &data, f32), &edits, cut);
        match parse_npy(Path::new("p.npy"), &bytes) {
            Ok(array) => prop_assert_eq!(array.data.len(), array.shape.iter().product::<usize>()),
            Err(e) => {
                let m = e.to_string();
                prop_assert!(m.starts_with("p.npy: field `"), "{}", m);
            }
        }
    }
}
