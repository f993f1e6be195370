//! One synthetic scene (three cameras, two times, tiny images, a few points) written in each
//! dataset layout by independent writers here, read back through `load_dataset`: the same
//! cameras, images and points come out, with each format's documented times and splits.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use evogs_io::colmap::{
    CameraModel, ColmapCamera, ColmapImage, ColmapPoint, encode_cameras_bin, encode_cameras_txt,
    encode_images_bin, encode_images_txt, encode_points3d_bin, encode_points3d_txt,
};
use evogs_io::npy::encode_npy;
use evogs_io::{
    CameraInfo, Dataset, Format, Frame, ImageRgb, LoadOptions, NerfiesSplit, TimeDenominator,
    TimeFrom, detect_format, load_dataset, load_image, opengl_c2w, save_png, write_nerfies_camera,
};
use glam::{DMat3, DQuat, Vec3};
use splat_core::Camera;

const W: u32 = 8;
const H: u32 = 6;
const TIMES: usize = 2;

/// The scene's cameras: square pixels, principal point at the centre (what every format can
/// express), looking at the origin from three sides.
fn cameras() -> Vec<Camera> {
    let eyes = [
        Vec3::new(0.0, -4.0, 1.0),
        Vec3::new(3.0, -2.5, 0.5),
        Vec3::new(-2.0, -3.0, 2.0),
    ];
    eyes.iter()
        .map(|&eye| Camera::look_at(W, H, 1.1, eye, Vec3::ZERO, Vec3::Z))
        .collect()
}

fn points() -> Vec<(Vec3, [u8; 3])> {
    (0..5)
        .map(|i| {
            let f = i as f32;
            (
                Vec3::new(0.1 * f, -0.2 * f, 0.3 - 0.05 * f),
                [10 * i as u8, 200, 255 - 40 * i as u8],
            )
        })
        .collect()
}

/// A flat image whose colour encodes (camera, time index).
fn image_for(cam: usize, k: usize, width: u32, height: u32) -> ImageRgb {
    let colour = [
        (cam as f32 + 1.0) * 60.0 / 255.0,
        (k as f32 + 1.0) * 80.0 / 255.0,
        0.5,
    ];
    ImageRgb::filled(width, height, colour)
}

/// Which (camera, time index) an image shows.
fn identify(image: &ImageRgb) -> (usize, usize) {
    let [r, g, _] = image.get(0, 0);
    (
        (r * 255.0 / 60.0).round() as usize - 1,
        (g * 255.0 / 80.0).round() as usize - 1,
    )
}

fn save(path: &Path, image: &ImageRgb) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    save_png(path, image).unwrap();
}

fn write(path: &Path, bytes: impl AsRef<[u8]>) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, bytes).unwrap();
}

// ---------------------------------------------------------------- writers, one per format

/// D-NeRF: camera 0 is the test split; times are k / (TIMES − 1).
fn write_dnerf(dir: &Path) {
    let cams = cameras();
    let angle = 2.0 * (0.5 * W as f64 / cams[0].fx as f64).atan();
    for (split, ids) in [("train", vec![1, 2]), ("test", vec![0]), ("val", vec![])] {
        let mut frames = Vec::new();
        for &c in &ids {
            let m = opengl_c2w(&cams[c]);
            for k in 0..TIMES {
                let name = format!("{split}/c{c}_t{k}");
                save(&dir.join(format!("{name}.png")), &image_for(c, k, W, H));
                frames.push(serde_json::json!({
                    "file_path": format!("./{name}"),
                    "time": k as f64 / (TIMES - 1) as f64,
                    "transform_matrix": m,
                }));
            }
        }
        let json = serde_json::json!({"camera_angle_x": angle, "frames": frames});
        write(
            &dir.join(format!("transforms_{split}.json")),
            json.to_string(),
        );
    }
}

/// nerfstudio: shared `w`, `h`, `cx`; per-frame `fl_x`, `fl_y`, `cy`; `time` = k / (TIMES − 1)
/// when `with_time`; camera 0 listed in `test_filenames` when `with_lists`; the points as an
/// ASCII `sparse_pc.ply`.
fn write_nerfstudio(dir: &Path, with_time: bool, with_lists: bool) {
    let cams = cameras();
    let mut frames = Vec::new();
    let (mut train, mut test) = (Vec::new(), Vec::new());
    for (c, cam) in cams.iter().enumerate() {
        for k in 0..TIMES {
            let name = format!("images/frame_{k:03}_c{c}.png");
            save(&dir.join(&name), &image_for(c, k, W, H));
            let mut frame = serde_json::json!({
                "file_path": name,
                "transform_matrix": opengl_c2w(cam),
                "fl_x": cam.fx, "fl_y": cam.fy, "cy": cam.cy,
            });
            if with_time {
                frame["time"] = serde_json::json!(k as f64 / (TIMES - 1) as f64);
            }
            frames.push(frame);
            if c == 0 { &mut test } else { &mut train }.push(name);
        }
    }
    let mut ply = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n\
         end_header\n",
        points().len()
    );
    for (p, rgb) in points() {
        ply += &format!("{} {} {} {} {} {}\n", p.x, p.y, p.z, rgb[0], rgb[1], rgb[2]);
    }
    write(&dir.join("sparse_pc.ply"), ply);
    let mut json = serde_json::json!({
        "camera_model": "OPENCV", "w": W, "h": H, "cx": cams[0].cx,
        "frames": frames, "ply_file_path": "sparse_pc.ply",
        "applied_transform": [[0, 1, 0, 0], [1, 0, 0, 0], [0, 0, -1, 0]],
    });
    if with_lists {
        json["train_filenames"] = serde_json::json!(train);
        json["test_filenames"] = serde_json::json!(test);
    }
    write(&dir.join("transforms.json"), json.to_string());
}

/// Nerfies: `NeRF*` name (train_ids/val_ids at 1x), camera 0 in val_ids, time_id = k.
fn write_nerfies(dir: &Path, center: Vec3, scale: f32, downscale: u32) {
    let cams = cameras();
    let mut ids = Vec::new();
    let mut metadata = serde_json::Map::new();
    for (c, cam) in cams.iter().enumerate() {
        // Stored coordinates: the scene's world mapped back through the normalisation.
        let stored_centre = cam.center() / scale + center;
        let stored = Camera::from_center(
            cam.width,
            cam.height,
            cam.fx,
            cam.fy,
            cam.cx,
            cam.cy,
            cam.rotation,
            stored_centre,
        );
        for k in 0..TIMES {
            let id = format!("c{c}_t{k}");
            std::fs::create_dir_all(dir.join("camera")).unwrap();
            write_nerfies_camera(
                &dir.join("camera").join(format!("{id}.json")),
                &CameraInfo::pinhole(stored.scaled(downscale as f32)),
            )
            .unwrap();
            save(
                &dir.join(format!("rgb/{downscale}x/{id}.png")),
                &image_for(c, k, W, H),
            );
            metadata.insert(
                id.clone(),
                serde_json::json!({"time_id": k, "warp_id": k, "appearance_id": k, "camera_id": c}),
            );
            ids.push(id);
        }
    }
    let train: Vec<&String> = ids.iter().filter(|i| !i.starts_with("c0")).collect();
    let val: Vec<&String> = ids.iter().filter(|i| i.starts_with("c0")).collect();
    write(
        &dir.join("dataset.json"),
        serde_json::json!({"count": ids.len(), "num_exemplars": train.len(), "ids": ids,
            "train_ids": train, "val_ids": val})
        .to_string(),
    );
    write(
        &dir.join("metadata.json"),
        serde_json::Value::Object(metadata).to_string(),
    );
    write(
        &dir.join("scene.json"),
        serde_json::json!({"scale": scale, "center": center.to_array(), "near": 0.1, "far": 10.0})
            .to_string(),
    );
    let stored: Vec<f64> = points()
        .iter()
        .flat_map(|(p, _)| (*p / scale + center).to_array().map(f64::from))
        .collect();
    write(
        &dir.join("points.npy"),
        encode_npy(&[points().len(), 3], &stored, true),
    );
}

/// Neu3D: `poses_bounds.npy` in LLFF axes, `camNN/images/NNNN.png` (or D-3DGS's
/// `frames/camNN/NNNN.png`); `frame_scale` is the extracted frames' size relative to hwf.
fn write_neu3d(dir: &Path, frame_scale: u32) {
    write_neu3d_in(dir, frame_scale, false);
}

fn write_neu3d_in(dir: &Path, frame_scale: u32, d3dgs_layout: bool) {
    let cams = cameras();
    let mut rows = Vec::new();
    for (c, cam) in cams.iter().enumerate() {
        let r = cam.rotation;
        let centre = cam.center();
        let (right, down, forward) = (r.row(0), r.row(1), r.row(2));
        // LLFF columns: down, right, back, centre, hwf.
        for i in 0..3 {
            rows.extend(
                [
                    down[i],
                    right[i],
                    -forward[i],
                    centre[i],
                    [H as f32, W as f32, cam.fx][i],
                ]
                .map(f64::from),
            );
        }
        rows.extend([0.5, 20.0]);
        for k in 0..TIMES {
            let rel = if d3dgs_layout {
                format!("frames/cam{c:02}/{k:04}.png")
            } else {
                format!("cam{c:02}/images/{k:04}.png")
            };
            save(
                &dir.join(rel),
                &image_for(c, k, W * frame_scale, H * frame_scale),
            );
        }
    }
    write(
        &dir.join("poses_bounds.npy"),
        encode_npy(&[cams.len(), 17], &rows, false),
    );
}

fn colmap_model() -> (Vec<ColmapCamera>, Vec<ColmapImage>, Vec<ColmapPoint>) {
    let cams = cameras();
    let mut cameras_out = Vec::new();
    let mut images = Vec::new();
    for (c, cam) in cams.iter().enumerate() {
        cameras_out.push(ColmapCamera {
            id: c as u32 + 1,
            model: CameraModel::Pinhole,
            width: W,
            height: H,
            params: [cam.fx, cam.fy, cam.cx, cam.cy].map(f64::from).to_vec(),
        });
        let q = DQuat::from_mat3(&DMat3::from_cols_array(
            &cam.rotation.to_cols_array().map(f64::from),
        ));
        images.push(ColmapImage {
            id: 10 + c as u32,
            qvec: [q.w, q.x, q.y, q.z],
            tvec: cam.translation.to_array().map(f64::from),
            camera_id: c as u32 + 1,
            name: format!("c{c}.png"),
        });
    }
    let pts = points()
        .iter()
        .map(|(p, rgb)| ColmapPoint {
            xyz: p.to_array().map(f64::from),
            rgb: *rgb,
        })
        .collect();
    (cameras_out, images, pts)
}

/// COLMAP (static): the images of time 0, the model in `sparse/0/` (binary) or `sparse/` (text).
fn write_colmap(dir: &Path, binary: bool) {
    let (cams, images, pts) = colmap_model();
    for c in 0..cams.len() {
        save(
            &dir.join(format!("images/c{c}.png")),
            &image_for(c, 0, W, H),
        );
    }
    if binary {
        let sparse = dir.join("sparse/0");
        write(&sparse.join("cameras.bin"), encode_cameras_bin(&cams));
        write(&sparse.join("images.bin"), encode_images_bin(&images, 2));
        write(&sparse.join("points3D.bin"), encode_points3d_bin(&pts));
    } else {
        let sparse = dir.join("sparse");
        write(&sparse.join("cameras.txt"), encode_cameras_txt(&cams));
        write(&sparse.join("images.txt"), encode_images_txt(&images));
        write(&sparse.join("points3D.txt"), encode_points3d_txt(&pts));
    }
}

// ---------------------------------------------------------------- checks

fn assert_same_camera(got: &Camera, want: &Camera, what: &str) {
    assert_eq!((got.width, got.height), (want.width, want.height), "{what}");
    for (g, w, name) in [
        (got.fx, want.fx, "fx"),
        (got.fy, want.fy, "fy"),
        (got.cx, want.cx, "cx"),
        (got.cy, want.cy, "cy"),
    ] {
        assert!(
            (g - w).abs() <= 1e-4 * w.abs().max(1.0),
            "{what} {name}: {g} vs {w}"
        );
    }
    let dr = (got.rotation - want.rotation).to_cols_array();
    assert!(
        dr.iter().all(|d| d.abs() < 1e-5),
        "{what} rotation: {got:?} vs {want:?}"
    );
    let dt = got.translation - want.translation;
    assert!(
        dt.abs().max_element() < 1e-4,
        "{what} translation: {got:?} vs {want:?}"
    );
}

/// Every frame's image identifies its (camera, time index); its camera must be that camera and
/// its time the format's time for that index. Returns the (camera, index) pairs per split.
fn check_frames(
    frames: &[Frame],
    want_cameras: &[Camera],
    time_of: impl Fn(usize) -> f32,
) -> Vec<(usize, usize)> {
    let mut seen = Vec::new();
    for frame in frames {
        let image = load_image(&frame.image_path, [0.0; 3]).unwrap();
        assert_eq!(
            (image.width, image.height),
            (frame.camera.camera.width, frame.camera.camera.height)
        );
        let (c, k) = identify(&image);
        assert_same_camera(
            &frame.camera.camera,
            &want_cameras[c],
            &format!("{}", frame.image_path.display()),
        );
        assert!(frame.camera.is_pinhole());
        assert!(
            (frame.time - time_of(k)).abs() < 1e-6,
            "time {} for index {k}",
            frame.time
        );
        seen.push((c, k));
    }
    seen.sort_unstable();
    seen
}

fn all_pairs(cams: &[usize], times: usize) -> Vec<(usize, usize)> {
    cams.iter()
        .flat_map(|&c| (0..times).map(move |k| (c, k)))
        .collect()
}

fn check_points(dataset: &Dataset, tolerance: f32) {
    let cloud = dataset.points.as_ref().expect("a point cloud");
    let want = points();
    assert_eq!(cloud.positions.len(), want.len());
    assert_eq!(cloud.colours.len(), want.len());
    for (got, (p, _)) in cloud.positions.iter().zip(&want) {
        assert!((*got - *p).abs().max_element() < tolerance, "{got} vs {p}");
    }
}

fn load(dir: &Path, options: &LoadOptions) -> Dataset {
    load_dataset(dir, options).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn dnerf_layout_reads_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    write_dnerf(dir.path());
    assert_eq!(detect_format(dir.path()).unwrap(), Format::Dnerf);
    let d = load(dir.path(), &LoadOptions::default());
    assert_eq!(d.format, Format::Dnerf);
    let time = |k: usize| k as f32 / (TIMES - 1) as f32;
    assert_eq!(
        check_frames(&d.train, &cameras(), time),
        all_pairs(&[1, 2], TIMES)
    );
    assert_eq!(
        check_frames(&d.test, &cameras(), time),
        all_pairs(&[0], TIMES)
    );
    assert!(d.val.is_empty() && d.points.is_none() && d.normalisation.is_none());
}

#[test]
fn nerfstudio_layout_reads_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    write_nerfstudio(dir.path(), true, true);
    assert_eq!(detect_format(dir.path()).unwrap(), Format::Nerfstudio);
    let d = load(dir.path(), &LoadOptions::default());
    assert_eq!(d.format, Format::Nerfstudio);
    let time = |k: usize| k as f32 / (TIMES - 1) as f32;
    assert_eq!(
        check_frames(&d.train, &cameras(), time),
        all_pairs(&[1, 2], TIMES)
    );
    assert_eq!(
        check_frames(&d.test, &cameras(), time),
        all_pairs(&[0], TIMES)
    );
    assert!(d.val.is_empty() && d.normalisation.is_none());
    check_points(&d, 1e-6);
    // No time key: times from the names' frame numbers (`frame_<k>_c<c>`); no split lists:
    // nerfstudio's 90% rule over the six sorted frames (ceil(5.4) = 6: all train).
    let dir = tempfile::tempdir().unwrap();
    write_nerfstudio(dir.path(), false, false);
    let by_name = LoadOptions {
        time_from: TimeFrom::Name,
        ..LoadOptions::default()
    };
    let d = load(dir.path(), &by_name);
    assert_eq!(
        check_frames(&d.train, &cameras(), time),
        all_pairs(&[0, 1, 2], TIMES)
    );
    assert!(d.test.is_empty());
    // By order: the sorted paths frame_000_c0, frame_000_c1, … get 0, 0.2, … 1.
    let d = load(dir.path(), &LoadOptions::default());
    let times: Vec<f32> = d.train.iter().map(|f| f.time).collect();
    assert_eq!(times, vec![0.0, 0.2, 0.4, 0.6, 0.8, 1.0]);
}

#[test]
fn nerfstudio_points_from_colmap_follow_applied_transform() {
    let dir = tempfile::tempdir().unwrap();
    write_nerfstudio(dir.path(), true, true);
    // No ply_file_path: the points of colmap/sparse/0, mapped COLMAP → stored by
    // applied_transform (here x ↔ y, z → −z), as ns-process-data would have written them.
    let path = dir.path().join("transforms.json");
    let mut json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    json.as_object_mut().unwrap().remove("ply_file_path");
    write(&path, json.to_string());
    let (cams, images, _) = colmap_model();
    let stored_to_colmap = |p: Vec3| Vec3::new(p.y, p.x, -p.z);
    let pts: Vec<ColmapPoint> = points()
        .iter()
        .map(|(p, rgb)| ColmapPoint {
            xyz: stored_to_colmap(*p).to_array().map(f64::from),
            rgb: *rgb,
        })
        .collect();
    let sparse = dir.path().join("colmap/sparse/0");
    write(&sparse.join("cameras.bin"), encode_cameras_bin(&cams));
    write(&sparse.join("images.bin"), encode_images_bin(&images, 0));
    write(&sparse.join("points3D.bin"), encode_points3d_bin(&pts));
    let d = load(dir.path(), &LoadOptions::default());
    check_points(&d, 1e-6);
    // Without applied_transform nerfstudio assumes the same legacy matrix.
    json.as_object_mut().unwrap().remove("applied_transform");
    write(&path, json.to_string());
    check_points(&load(dir.path(), &LoadOptions::default()), 1e-6);
}

#[test]
fn nerfies_layout_reads_the_scene() {
    let root = tempfile::tempdir().unwrap();
    let dir = root.path().join("NeRF-synthetic");
    write_nerfies(&dir, Vec3::ZERO, 1.0, 1);
    assert_eq!(detect_format(&dir).unwrap(), Format::Nerfies);
    let d = load(&dir, &LoadOptions::default());
    assert_eq!(d.format, Format::Nerfies);
    // time = time_id / max time_id.
    let time = |k: usize| k as f32 / (TIMES - 1) as f32;
    assert_eq!(
        check_frames(&d.train, &cameras(), time),
        all_pairs(&[1, 2], TIMES)
    );
    assert_eq!(
        check_frames(&d.test, &cameras(), time),
        all_pairs(&[0], TIMES)
    );
    check_points(&d, 1e-6);
    assert!(
        d.points
            .as_ref()
            .unwrap()
            .colours
            .iter()
            .all(|c| *c == Vec3::splat(0.5))
    );
}

#[test]
fn nerfies_normalisation_and_downscale_follow_d3dgs() {
    let root = tempfile::tempdir().unwrap();
    // A `vrig` name: train_ids/val_ids at 4x.
    let dir = root.path().join("vrig-synthetic");
    let center = Vec3::new(1.5, -2.0, 0.25);
    let scale = 0.125;
    write_nerfies(&dir, center, scale, 4);
    let d = load(&dir, &LoadOptions::default());
    let n = d.normalisation.unwrap();
    assert_eq!((n.center, n.scale), (center, scale));
    let time = |k: usize| k as f32 / (TIMES - 1) as f32;
    assert_eq!(
        check_frames(&d.train, &cameras(), time),
        all_pairs(&[1, 2], TIMES)
    );
    assert!(
        d.train
            .iter()
            .all(|f| f.image_path.to_string_lossy().contains("rgb/4x"))
    );
    // The name is the folder's own, however the path is spelled.
    let dotted = dir.join("camera").join("..");
    assert_eq!(
        evogs_io::nerfies::nerfies_defaults(&dotted),
        (NerfiesSplit::TrainVal, 4)
    );
    // Points: (p − center) · scale recovers the scene's points (f32 npy storage).
    check_points(&d, 1e-5);
    // An explicit split rule: `interp` takes ids 0, 4, … for training and 2, 6, … for test
    // (ids are c0_t0 c0_t1 c1_t0 c1_t1 c2_t0 c2_t1).
    let options = LoadOptions {
        nerfies_split: Some(NerfiesSplit::Interp),
        ..LoadOptions::default()
    };
    let d = load(&dir, &options);
    let time = |k: usize| k as f32; // max time_id over the selected frames is 1
    assert_eq!(
        check_frames(&d.train, &cameras(), time),
        vec![(0, 0), (2, 0)]
    );
    assert_eq!(check_frames(&d.test, &cameras(), time), vec![(1, 0)]);
    let options = LoadOptions {
        nerfies_split: Some(NerfiesSplit::EveryFourth),
        ..LoadOptions::default()
    };
    let d = load(&dir, &options);
    // Every selected frame has time_id 0, so every time is 0 (no division by zero).
    assert_eq!(
        check_frames(&d.train, &cameras(), |_| 0.0),
        vec![(0, 0), (2, 0)]
    );
    assert!(d.test.is_empty());
}

#[test]
fn neu3d_layout_reads_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    write_neu3d(dir.path(), 1);
    assert_eq!(detect_format(dir.path()).unwrap(), Format::Neu3d);
    let d = load(dir.path(), &LoadOptions::default());
    assert_eq!(d.format, Format::Neu3d);
    // time = frame / count (count, not count − 1, as 4DGaussians).
    let time = |k: usize| k as f32 / TIMES as f32;
    assert_eq!(
        check_frames(&d.train, &cameras(), time),
        all_pairs(&[1, 2], TIMES)
    );
    assert_eq!(
        check_frames(&d.test, &cameras(), time),
        all_pairs(&[0], TIMES)
    );
    assert!(d.points.is_none());
}

#[test]
fn neu3d_frames_extracted_at_another_size_get_scaled_cameras() {
    let dir = tempfile::tempdir().unwrap();
    write_neu3d(dir.path(), 2);
    let options = LoadOptions {
        neu3d_test_cameras: vec![2],
        neu3d_max_frames: 1,
        ..LoadOptions::default()
    };
    let d = load(dir.path(), &options);
    let scaled: Vec<Camera> = cameras().iter().map(|c| c.scaled(2.0)).collect();
    // One frame per camera: time 0 only.
    assert_eq!(
        check_frames(&d.train, &scaled, |_| 0.0),
        vec![(0, 0), (1, 0)]
    );
    assert_eq!(check_frames(&d.test, &scaled, |_| 0.0), vec![(2, 0)]);
}

#[test]
fn neu3d_d3dgs_layout_and_time_convention() {
    let dir = tempfile::tempdir().unwrap();
    write_neu3d_in(dir.path(), 1, true);
    let options = LoadOptions {
        neu3d_time: TimeDenominator::CountMinusOne,
        ..LoadOptions::default()
    };
    let d = load(dir.path(), &options);
    // time = frame / (count − 1), as D-3DGS `readCamerasFromNpy`.
    let time = |k: usize| k as f32 / (TIMES - 1) as f32;
    assert_eq!(
        check_frames(&d.train, &cameras(), time),
        all_pairs(&[1, 2], TIMES)
    );
    assert_eq!(
        check_frames(&d.test, &cameras(), time),
        all_pairs(&[0], TIMES)
    );
    assert!(
        d.train
            .iter()
            .all(|f| f.image_path.to_string_lossy().contains("frames/cam"))
    );
}

#[test]
fn colmap_binary_and_text_read_the_scene() {
    for binary in [true, false] {
        let dir = tempfile::tempdir().unwrap();
        write_colmap(dir.path(), binary);
        assert_eq!(detect_format(dir.path()).unwrap(), Format::Colmap);
        // llff_hold 2: sorted names c0, c1, c2 → c0 and c2 are test frames. A static scene.
        let options = LoadOptions {
            colmap_llff_hold: 2,
            time_from: TimeFrom::None,
            ..LoadOptions::default()
        };
        let d = load(dir.path(), &options);
        assert_eq!(d.format, Format::Colmap);
        assert_eq!(check_frames(&d.train, &cameras(), |_| 0.0), vec![(1, 0)]);
        assert_eq!(
            check_frames(&d.test, &cameras(), |_| 0.0),
            vec![(0, 0), (2, 0)]
        );
        check_points(&d, 1e-6);
        let colours = &d.points.as_ref().unwrap().colours;
        for (got, (_, rgb)) in colours.iter().zip(points()) {
            assert_eq!(*got, Vec3::from_array(rgb.map(|v| v as f32 / 255.0)));
        }
        // Default hold 8: only the first image is a test frame; default times by name order.
        let d = load(dir.path(), &LoadOptions::default());
        assert_eq!((d.train.len(), d.test.len()), (2, 1));
        let times: Vec<f32> = d.all_frames().map(|f| f.time).collect();
        assert_eq!(times, vec![0.5, 1.0, 0.0]);
    }
}

/// A multi-camera COLMAP capture: every camera at every time, images named
/// `cam<c>/frame_<k>.png` (times from the frame number) or `<k>_<c>.png`-free `c<c>_t<k>.png`.
fn write_colmap_sequence(dir: &Path, name_of: impl Fn(usize, usize) -> String) {
    let (cams, views, pts) = colmap_model();
    let mut images = Vec::new();
    for (c, view) in views.iter().enumerate() {
        for k in 0..TIMES {
            let name = name_of(c, k);
            save(&dir.join("images").join(&name), &image_for(c, k, W, H));
            images.push(ColmapImage {
                id: (100 * c + k) as u32 + 1,
                name,
                ..view.clone()
            });
        }
    }
    let sparse = dir.join("sparse/0");
    write(&sparse.join("cameras.bin"), encode_cameras_bin(&cams));
    write(&sparse.join("images.bin"), encode_images_bin(&images, 2));
    write(&sparse.join("points3D.bin"), encode_points3d_bin(&pts));
}

#[test]
fn colmap_times_from_frame_numbers_and_from_order() {
    let dir = tempfile::tempdir().unwrap();
    // Frame numbers 10 and 11: times 0 and 1 for every camera.
    write_colmap_sequence(dir.path(), |c, k| format!("cam{c}/frame_{:04}.png", 10 + k));
    let by_name = LoadOptions {
        colmap_llff_hold: 0,
        time_from: TimeFrom::Name,
        ..LoadOptions::default()
    };
    let d = load(dir.path(), &by_name);
    let time = |k: usize| k as f32 / (TIMES - 1) as f32;
    assert_eq!(
        check_frames(&d.train, &cameras(), time),
        all_pairs(&[0, 1, 2], TIMES)
    );
    // By order the six sorted names get six different times: camera-major, not what a
    // multi-camera capture means.
    let by_order = LoadOptions {
        time_from: TimeFrom::Order,
        ..by_name.clone()
    };
    let d = load(dir.path(), &by_order);
    let times: Vec<f32> = d.train.iter().map(|f| f.time).collect();
    assert_eq!(times, vec![0.0, 0.2, 0.4, 0.6, 0.8, 1.0]);
    // A single-camera sequence: order and name agree.
    let dir = tempfile::tempdir().unwrap();
    write_colmap_sequence(dir.path(), |c, k| format!("{:03}.png", c * TIMES + k));
    let times = |options: &LoadOptions| -> Vec<f32> {
        load(dir.path(), options)
            .train
            .iter()
            .map(|f| f.time)
            .collect()
    };
    assert_eq!(times(&by_name), times(&by_order));
    assert_eq!(times(&by_name), vec![0.0, 0.2, 0.4, 0.6, 0.8, 1.0]);
}

#[test]
fn colmap_times_json_is_the_datasets_own_time_and_the_rule_does_not_apply() {
    // Six frames, as a clip of ten frames whose frames 0, 3 and 8 were not registered: the
    // stored times are the clip's, not the ranks of the survivors.
    let dir = tempfile::tempdir().unwrap();
    write_colmap_sequence(dir.path(), |c, k| format!("{:03}.png", c * TIMES + k));
    let clip = [1, 2, 4, 5, 6, 7];
    let stored: Vec<f64> = clip.iter().map(|&i| f64::from(i) / 9.0).collect();
    let times = evogs_io::FrameTimes {
        source: "clip.mp4".into(),
        frames: (0..6)
            .map(|i| (format!("{i:03}.png"), stored[i]))
            .chain([("999.png".to_string(), 1.0)])
            .collect(),
    };
    evogs_io::write_frame_times(&dir.path().join(evogs_io::TIMES_FILE), &times).unwrap();
    for rule in TimeFrom::ALL {
        let options = LoadOptions {
            colmap_llff_hold: 0,
            time_from: rule,
            ..LoadOptions::default()
        };
        let got: Vec<f32> = load(dir.path(), &options)
            .train
            .iter()
            .map(|f| f.time)
            .collect();
        let want: Vec<f32> = stored.iter().map(|&t| t as f32).collect();
        assert_eq!(got, want, "{rule}");
    }
    // A frame the file leaves out is an error naming the file and the field.
    let mut partial = times.clone();
    partial.frames.remove("004.png");
    evogs_io::write_frame_times(&dir.path().join(evogs_io::TIMES_FILE), &partial).unwrap();
    let err = load_dataset(dir.path(), &LoadOptions::default()).unwrap_err();
    assert!(
        err.to_string()
            .contains("times.json: field `frames.004.png`: missing"),
        "{err}"
    );
}

#[test]
fn every_format_gives_the_same_cameras_for_the_same_image() {
    let root = tempfile::tempdir().unwrap();
    let dirs: Vec<PathBuf> = ["dnerf", "NeRF-scene", "neu3d", "colmap", "nerfstudio"]
        .iter()
        .map(|n| root.path().join(n))
        .collect();
    write_dnerf(&dirs[0]);
    write_nerfies(&dirs[1], Vec3::new(0.5, 0.5, 0.5), 2.0, 1);
    write_neu3d(&dirs[2], 1);
    write_colmap(&dirs[3], true);
    write_nerfstudio(&dirs[4], true, false);
    let mut by_image: BTreeMap<(usize, usize), Vec<(Format, Camera)>> = BTreeMap::new();
    for dir in &dirs {
        let d = load(dir, &LoadOptions::default());
        for f in d.all_frames() {
            let key = identify(&load_image(&f.image_path, [0.0; 3]).unwrap());
            by_image
                .entry(key)
                .or_default()
                .push((d.format, f.camera.camera));
        }
    }
    assert_eq!(by_image.len(), 3 * TIMES);
    for (key, list) in &by_image {
        let formats = if key.1 == 0 { 5 } else { 4 };
        assert_eq!(list.len(), formats, "{key:?}");
        for (format, cam) in &list[1..] {
            assert_same_camera(cam, &list[0].1, &format!("{key:?} {format}"));
        }
    }
}

#[test]
fn summaries_snapshot() {
    let root = tempfile::tempdir().unwrap();
    let mut lines = Vec::new();
    for (name, writer) in [
        ("dnerf", &(|d: &Path| write_dnerf(d)) as &dyn Fn(&Path)),
        ("NeRF-x", &|d: &Path| write_nerfies(d, Vec3::ZERO, 1.0, 1)),
        ("neu3d", &|d: &Path| write_neu3d(d, 1)),
        ("colmap", &|d: &Path| write_colmap(d, false)),
        ("nerfstudio", &|d: &Path| write_nerfstudio(d, true, false)),
    ] {
        let dir = root.path().join(name);
        writer(&dir);
        let d = load(&dir, &LoadOptions::default());
        lines.push(d.summary());
        lines.push(format!("  warning: {:?}", d.camera_warning()));
    }
    // A COLMAP OPENCV camera: distortion kept and reported once.
    let dir = root.path().join("colmap-opencv");
    write_colmap(&dir, true);
    let (mut cams, _, _) = colmap_model();
    for cam in &mut cams {
        cam.model = CameraModel::Opencv;
        cam.params.extend([0.125, -0.0625, 0.001953125, 0.0]);
    }
    write(&dir.join("sparse/0/cameras.bin"), encode_cameras_bin(&cams));
    let d = load(&dir, &LoadOptions::default());
    lines.push(d.summary());
    lines.push(format!("  warning: {:?}", d.camera_warning()));
    // A nerfstudio OPENCV_FISHEYE camera: k1..k4 kept as fisheye coefficients and reported.
    let dir = root.path().join("nerfstudio-fisheye");
    write_nerfstudio(&dir, true, false);
    let path = dir.join("transforms.json");
    let mut json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    json["camera_model"] = "OPENCV_FISHEYE".into();
    json["k1"] = 0.25.into();
    json["k4"] = (-0.03125).into();
    write(&path, json.to_string());
    let d = load(&dir, &LoadOptions::default());
    assert!(
        d.all_frames()
            .all(|f| f.camera.distortion.fisheye == [0.25, 0.0, 0.0, -0.03125])
    );
    lines.push(d.summary());
    lines.push(format!("  warning: {:?}", d.camera_warning()));
    insta::assert_snapshot!(lines.join("\n"));
}

#[test]
fn real_lego_scene_is_detected_and_loaded() {
    // Seven real lego frames at 100×100 (see `tests/data/README.md`).
    let lego = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/dnerf-lego"
    ));
    assert_eq!(detect_format(lego).unwrap(), Format::Dnerf);
    let d = load(lego, &LoadOptions::default());
    assert_eq!((d.train.len(), d.test.len(), d.val.len()), (3, 2, 2));
    assert_eq!(
        d.summary(),
        "dnerf: 3 train, 2 test, 2 val frames, no point cloud"
    );
    assert!(
        d.all_frames()
            .all(|f| f.camera.is_pinhole() && f.image_path.is_file())
    );
}

/// The LLFF row of a camera (columns down, right, back, centre, hwf; then near, far).
fn llff_row(cam: &Camera) -> Vec<f64> {
    let r = cam.rotation;
    let centre = cam.center();
    let (right, down, forward) = (r.row(0), r.row(1), r.row(2));
    let mut row = Vec::new();
    for i in 0..3 {
        row.extend(
            [
                down[i],
                right[i],
                -forward[i],
                centre[i],
                [cam.height as f32, cam.width as f32, cam.fx][i],
            ]
            .map(f64::from),
        );
    }
    row.extend([0.5, 20.0]);
    row
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(200))]

    /// Any camera survives the Neu3D row and the COLMAP qvec/tvec conversions.
    #[test]
    fn random_cameras_survive_neu3d_and_colmap_conversions(
        eye in proptest::array::uniform3(-10.0f32..10.0),
        target in proptest::array::uniform3(-1.0f32..1.0),
        fov in 0.3f32..2.5,
        width in 2u32..4000,
        height in 2u32..4000,
    ) {
        let eye = Vec3::from_array(eye);
        let target = Vec3::from_array(target);
        proptest::prop_assume!((eye - target).length() > 0.5);
        proptest::prop_assume!((eye - target).normalize().cross(Vec3::Z).length() > 0.1);
        let cam = Camera::look_at(width, height, fov, eye, target, Vec3::Z);

        let pose = evogs_io::neu3d::decode_pose_row(Path::new("p.npy"), 0, &llff_row(&cam))
            .unwrap();
        assert_same_camera(&pose.camera, &cam, "neu3d");
        proptest::prop_assert_eq!(pose.near_far, [0.5, 20.0]);

        let q = DQuat::from_mat3(&DMat3::from_cols_array(
            &cam.rotation.to_cols_array().map(f64::from),
        ));
        let model = evogs_io::colmap::ColmapModel {
            cameras: vec![ColmapCamera {
                id: 1,
                model: CameraModel::SimplePinhole,
                width,
                height,
                params: vec![cam.fx.into(), cam.cx.into(), cam.cy.into()],
            }],
            images: Vec::new(),
            points: Vec::new(),
            images_path: PathBuf::from("images.bin"),
        };
        // A quaternion that is not unit length (COLMAP writes unit ones) is normalised.
        let image = ColmapImage {
            id: 1,
            qvec: [q.w * 2.0, q.x * 2.0, q.y * 2.0, q.z * 2.0],
            tvec: cam.translation.to_array().map(f64::from),
            camera_id: 1,
            name: "a.png".into(),
        };
        let info = model.camera_info(&image).unwrap();
        assert_same_camera(&info.camera, &cam, "colmap");
    }
}
