//! D-NeRF datasets: real lego frames (the fixture `tests/data/dnerf-lego`: counts, sizes, camera
//! geometry), errors naming the file and field for broken datasets, and the writer read back by
//! the reader.

use std::path::{Path, PathBuf};

use evogs_io::dnerf::camera_from_opengl_c2w;
use evogs_io::{
    DnerfImage, IoError, Split, dnerf_camera_angle_x, load_image, opengl_c2w, read_dnerf_split,
    read_transforms, write_dnerf_split,
};
use glam::Vec3;
use splat_core::Camera;

/// Seven real lego frames at 100×100 (see `tests/data/README.md`).
fn lego() -> PathBuf {
    Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/dnerf-lego"
    ))
    .to_path_buf()
}

#[test]
fn lego_splits_have_the_expected_frames() {
    let root = lego();
    let counts: Vec<usize> = Split::ALL
        .iter()
        .map(|&split| read_dnerf_split(&root, split).unwrap().len())
        .collect();
    assert_eq!(counts, vec![3, 2, 2]);
    let train = read_dnerf_split(&root, Split::Train).unwrap();
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(root.join("transforms_train.json")).unwrap())
            .unwrap();
    let angle = json["camera_angle_x"].as_f64().unwrap();
    let focal = (0.5 * 100.0 / (0.5 * angle).tan()) as f32;
    for (frame, raw) in train.iter().zip(json["frames"].as_array().unwrap()) {
        let c = &frame.camera;
        assert_eq!((c.width, c.height), (100, 100));
        assert_eq!((c.fx, c.fy, c.cx, c.cy), (focal, focal, 50.0, 50.0));
        assert!(frame.image_path.is_file(), "{}", frame.image_path.display());
        assert_eq!(frame.time, raw["time"].as_f64().unwrap() as f32);
        assert!((0.0..=1.0).contains(&frame.time));
        // The camera centre is the matrix's translation column.
        let m = &raw["transform_matrix"];
        let t = Vec3::new(
            m[0][3].as_f64().unwrap() as f32,
            m[1][3].as_f64().unwrap() as f32,
            m[2][3].as_f64().unwrap() as f32,
        );
        assert!(
            (c.center() - t).length() < 1e-5,
            "{:?} vs {t:?}",
            c.center()
        );
        // It looks at the origin, roughly: the forward axis points at it and the origin projects
        // near the image centre.
        let forward = c.rotation.row(2);
        assert!(forward.dot(-t.normalize()) > 0.95, "forward {forward:?}");
        let p = c.world_to_camera(Vec3::ZERO);
        let (u, v) = (c.fx * p.x / p.z + c.cx, c.fy * p.y / p.z + c.cy);
        assert!(
            (u - 50.0).abs() < 10.0 && (v - 50.0).abs() < 10.0,
            "origin at ({u}, {v})"
        );
        // OpenCV axes: world up (+z in Blender) appears towards the top of the image.
        assert!(c.world_to_camera(Vec3::Z).y < p.y);
        assert!((c.rotation.determinant() - 1.0).abs() < 1e-5);
    }
    assert_eq!(train[0].image_path.file_name().unwrap(), "r_0.png");
    // The images are RGBA: at half size over a white background, the corner is background and
    // the centre holds the (non-white) model.
    let (img, cam) =
        evogs_io::load_view(&train[0].image_path, &train[0].camera, [1.0; 3], 0.5).unwrap();
    assert_eq!(
        (img.width, img.height, cam.width, cam.height),
        (50, 50, 50, 50)
    );
    assert_eq!((cam.fx, cam.cx), (focal * 0.5, 25.0));
    assert_eq!(img.get(0, 0), [1.0; 3]);
    let non_white = img
        .pixels
        .iter()
        .filter(|p| p.iter().any(|&c| c < 0.9))
        .count();
    assert!(non_white > 50 * 50 / 20, "{non_white}");
}

#[test]
fn opengl_axes_flip_y_and_z() {
    // Camera at (0, 0, 5) looking down −z with +y up (OpenGL identity orientation).
    let c2w = [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 5.0],
    ];
    let c = camera_from_opengl_c2w(&c2w, 20, 10, 30.0, 30.0);
    assert_eq!(c.world_to_camera(Vec3::ZERO), Vec3::new(0.0, 0.0, 5.0));
    // World +y (up) is camera −y (image up); world +x stays camera +x.
    assert_eq!(c.world_to_camera(Vec3::Y), Vec3::new(0.0, -1.0, 5.0));
    assert_eq!(c.world_to_camera(Vec3::X), Vec3::new(1.0, 0.0, 5.0));
    assert_eq!((c.cx, c.cy), (10.0, 5.0));
}

fn tiny_dataset(dir: &Path, transforms: &str) -> PathBuf {
    std::fs::create_dir_all(dir.join("train")).unwrap();
    image::RgbImage::from_pixel(4, 2, image::Rgb([10, 20, 30]))
        .save(dir.join("train/r_0.png"))
        .unwrap();
    let path = dir.join("transforms_train.json");
    std::fs::write(&path, transforms).unwrap();
    path
}

const FRAME: &str = r#""transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]"#;

#[test]
fn image_size_from_file_or_w_h_keys() {
    let dir = tempfile::tempdir().unwrap();
    let path = tiny_dataset(
        dir.path(),
        &format!(
            r#"{{"camera_angle_x": 1.0, "frames": [{{"file_path": "./train/r_0", "time": 0.5, {FRAME}}}]}}"#
        ),
    );
    let frames = read_transforms(&path).unwrap();
    assert_eq!((frames[0].camera.width, frames[0].camera.height), (4, 2));
    assert_eq!(frames[0].camera.fx, (2.0 / 0.5f64.tan()) as f32);
    let path = tiny_dataset(
        dir.path(),
        &format!(
            r#"{{"camera_angle_x": 1.0, "w": 8, "h": 6, "frames": [{{"file_path": "train/r_0.png", "time": 0, {FRAME}}}]}}"#
        ),
    );
    let frames = read_transforms(&path).unwrap();
    assert_eq!((frames[0].camera.width, frames[0].camera.height), (8, 6));
    // The image then does not match its camera, which loading reports.
    let err =
        evogs_io::load_view(&frames[0].image_path, &frames[0].camera, [0.0; 3], 1.0).unwrap_err();
    assert!(
        err.to_string().contains("r_0.png") && err.to_string().contains("4×2"),
        "{err}"
    );
}

#[test]
fn broken_datasets_name_the_file_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let frame = |body: &str| format!(r#"{{"camera_angle_x": 0.7, "frames": [{body}]}}"#);
    let cases: Vec<(&str, String)> = vec![
        (
            "malformed json",
            r#"{"camera_angle_x": 0.7, "frames": [ {"#.to_string(),
        ),
        (
            "missing image",
            frame(&format!(
                r#"{{"file_path": "./train/r_9", "time": 0.1, {FRAME}}}"#
            )),
        ),
        (
            "missing time",
            frame(&format!(r#"{{"file_path": "./train/r_0", {FRAME}}}"#)),
        ),
        (
            "time out of range",
            frame(&format!(
                r#"{{"file_path": "./train/r_0", "time": 1.5, {FRAME}}}"#
            )),
        ),
        (
            "bad matrix",
            frame(
                r#"{"file_path": "./train/r_0", "time": 0.1, "transform_matrix": [[1,0,0],[0,1,0],[0,0,1]]}"#,
            ),
        ),
        (
            "scaled matrix",
            frame(
                r#"{"file_path": "./train/r_0", "time": 0.1, "transform_matrix": [[2,0,0,0],[0,1,0,0],[0,0,1,0]]}"#,
            ),
        ),
        (
            "frames not an array",
            r#"{"camera_angle_x": 0.7, "frames": {}}"#.to_string(),
        ),
        ("no angle", r#"{"frames": []}"#.to_string()),
        (
            "w without h",
            r#"{"camera_angle_x": 0.7, "w": 800, "frames": []}"#.to_string(),
        ),
        (
            "file_path a number",
            frame(&format!(r#"{{"file_path": 3, "time": 0.1, {FRAME}}}"#)),
        ),
    ];
    let mut report = String::new();
    for (name, text) in &cases {
        let path = tiny_dataset(dir.path(), text);
        let err = read_dnerf_split(dir.path(), Split::Train).expect_err(name);
        assert_eq!(err.path(), path, "{name}");
        let message = err
            .to_string()
            .replace(&dir.path().display().to_string(), "<dir>");
        assert!(!message.contains('\n'));
        report.push_str(&format!("{name}: {message}\n"));
    }
    insta::assert_snapshot!("dnerf_errors", report);
    // A corrupt image is reported under the image's own name.
    let path = tiny_dataset(
        dir.path(),
        &frame(&format!(
            r#"{{"file_path": "./train/r_0", "time": 0.1, {FRAME}}}"#
        )),
    );
    std::fs::write(dir.path().join("train/r_0.png"), b"not a png").unwrap();
    let err = read_transforms(&path).unwrap_err();
    assert!(matches!(err, IoError::Image { .. }), "{err}");
    assert!(err.path().ends_with("train/r_0.png"));
    // A split whose file is absent names that file.
    let err = read_dnerf_split(dir.path(), Split::Val).unwrap_err();
    assert!(err.to_string().contains("transforms_val.json"), "{err}");
}

/// A `w×h` image whose pixels vary in colour and opacity (fully transparent in one corner), as
/// premultiplied colour and alpha.
fn test_pixels(w: u32, h: u32, seed: u32) -> (Vec<[f32; 3]>, Vec<f32>) {
    let (mut color, mut alpha) = (Vec::new(), Vec::new());
    for y in 0..h {
        for x in 0..w {
            let a = if x + y == 0 {
                0.0
            } else {
                (x + seed) as f32 / (w + seed) as f32
            };
            let straight = [
                x as f32 / w as f32,
                y as f32 / h as f32,
                ((x * y + seed) % 7) as f32 / 6.0,
            ];
            color.push(straight.map(|c| c * a));
            alpha.push(a);
        }
    }
    (color, alpha)
}

#[test]
fn written_split_reads_back_with_the_same_cameras_times_and_pixels() {
    let (w, h) = (12, 8);
    let cameras = [
        Camera::look_at(w, h, 0.9, Vec3::new(3.0, 1.0, 2.0), Vec3::ZERO, Vec3::Z),
        Camera::look_at(w, h, 0.9, Vec3::new(-1.0, -4.0, 0.5), Vec3::ZERO, Vec3::Z),
    ];
    let pixels = [test_pixels(w, h, 1), test_pixels(w, h, 4)];
    let times = [0.0, 0.75];
    let images: Vec<DnerfImage<'_>> = (0..2)
        .map(|i| DnerfImage {
            time: times[i],
            camera: &cameras[i],
            color: &pixels[i].0,
            alpha: &pixels[i].1,
        })
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let angle = dnerf_camera_angle_x(&cameras[0]);
    write_dnerf_split(dir.path(), Split::Val, &images, angle).unwrap();
    assert!(dir.path().join("val/r_001.png").is_file());

    let frames = read_dnerf_split(dir.path(), Split::Val).unwrap();
    assert_eq!(frames.len(), 2);
    let background = [0.2, 0.5, 1.0];
    for (i, (read, mine)) in frames.iter().zip(&cameras).enumerate() {
        assert_eq!(read.time, times[i]);
        assert_eq!((read.camera.width, read.camera.height), (w, h));
        for (a, b) in [(read.camera.fx, mine.fx), (read.camera.fy, mine.fy)] {
            assert!((a - b).abs() < 1e-4 * b, "focal {a} vs {b}");
        }
        assert!(read.camera.rotation.abs_diff_eq(mine.rotation, 1e-6));
        assert!(read.camera.translation.abs_diff_eq(mine.translation, 1e-5));
        // Over a background the PNG gives the premultiplied colour plus b·(1 − α), to 8 bits.
        let image = load_image(&read.image_path, background).unwrap();
        let (color, alpha) = &pixels[i];
        for (p, (c, &a)) in image.pixels.iter().zip(color.iter().zip(alpha)) {
            for k in 0..3 {
                let want = c[k] + background[k] * (1.0 - a);
                assert!((p[k] - want).abs() <= 1.5 / 255.0, "{p:?} vs {c:?}, α {a}");
            }
        }
    }
}

#[test]
fn opengl_c2w_inverts_the_readers_conversion() {
    let camera = Camera::look_at(30, 20, 1.1, Vec3::new(1.0, -2.0, 3.0), Vec3::X, Vec3::Z);
    let m = opengl_c2w(&camera);
    assert_eq!(m[3], [0.0, 0.0, 0.0, 1.0]);
    let back = camera_from_opengl_c2w(
        &[m[0], m[1], m[2]],
        30,
        20,
        f64::from(camera.fx),
        f64::from(camera.fy),
    );
    assert!(back.rotation.abs_diff_eq(camera.rotation, 1e-6));
    assert!(back.translation.abs_diff_eq(camera.translation, 1e-5));
    // The focal length of `camera_angle_x` is the camera's.
    let focal = 0.5 * 30.0 / (0.5 * dnerf_camera_angle_x(&camera)).tan();
    assert!((focal - f64::from(camera.fx)).abs() < 1e-9 * focal);
}

#[test]
fn writing_pixels_of_the_wrong_size_names_the_image() {
    let camera = Camera::look_at(4, 4, 0.9, Vec3::new(0.0, -3.0, 0.0), Vec3::ZERO, Vec3::Z);
    let (color, alpha) = test_pixels(4, 3, 0);
    let image = DnerfImage {
        time: 0.5,
        camera: &camera,
        color: &color,
        alpha: &alpha,
    };
    let dir = tempfile::tempdir().unwrap();
    let err = write_dnerf_split(dir.path(), Split::Train, &[image], 0.9).unwrap_err();
    assert!(matches!(err, IoError::InvalidData { .. }), "{err}");
    assert!(err.to_string().contains("r_000.png"), "{err}");
    assert!(!dir.path().join("transforms_train.json").exists());
}
