//! nerfies camera JSON: field meanings (DESIGN §1.3), write/read round trips, warnings for skew and
//! distortion, and errors naming the file and the field.

use std::path::{Path, PathBuf};

use evogs_io::{CameraInfo, Distortion, IoError, read_nerfies_camera, write_nerfies_camera};
use glam::{Mat3, Quat, Vec3};
use proptest::prelude::*;
use splat_core::Camera;

const HYPERNERF_SAMPLE: &str = r#"{
  "orientation": [
    [0.0, 0.0, 1.0],
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0]
  ],
  "position": [-2.0, 0.5, 0.25],
  "focal_length": 1000.0,
  "principal_point": [480.5, 270.25],
  "skew": 0.0,
  "pixel_aspect_ratio": 1.0009,
  "radial_distortion": [-0.03, 0.02, 0.0],
  "tangential_distortion": [0.001, -0.0005],
  "image_size": [960, 540]
}"#;

fn write_temp(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn sample_fields_map_to_the_camera() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_temp(dir.path(), "cam.json", HYPERNERF_SAMPLE);
    let info = read_nerfies_camera(&path).unwrap();
    let c = info.camera;
    assert_eq!((c.width, c.height), (960, 540));
    assert_eq!(c.fx, 1000.0);
    assert_eq!(c.fy, (1000.0f64 * 1.0009) as f32);
    assert_eq!((c.cx, c.cy), (480.5, 270.25));
    // Rows of R are the orientation rows: camera x is world z, camera y is world x, camera z
    // (forward) is world y.
    assert_eq!(c.rotation.row(0), Vec3::Z);
    assert_eq!(c.rotation.row(1), Vec3::X);
    assert_eq!(c.rotation.row(2), Vec3::Y);
    assert!((c.center() - Vec3::new(-2.0, 0.5, 0.25)).length() < 1e-6);
    // A point one unit ahead along the forward axis projects to the principal point.
    let ahead = c.world_to_camera(c.center() + Vec3::Y);
    assert!((ahead - Vec3::Z).length() < 1e-6);
    assert_eq!(info.distortion.radial, [-0.03, 0.02, 0.0]);
    assert_eq!(info.distortion.tangential, [0.001, -0.0005]);
    let warning = info.warning().expect("distortion must be reported");
    assert!(
        warning.contains("radial distortion") && warning.contains("pinhole"),
        "{warning}"
    );
    assert!(!warning.contains("skew"));
}

#[test]
fn optional_fields_default_and_pinhole_gives_no_warning() {
    let dir = tempfile::tempdir().unwrap();
    let text = r#"{"orientation": [[1,0,0],[0,1,0],[0,0,1]], "position": [0,0,-3],
        "focal_length": 50, "principal_point": [16, 8], "image_size": [32, 16]}"#;
    let info = read_nerfies_camera(&write_temp(dir.path(), "c.json", text)).unwrap();
    assert_eq!(info.skew, 0.0);
    assert_eq!(info.distortion, Distortion::default());
    assert_eq!(info.camera.fy, 50.0);
    assert_eq!(info.camera.translation, Vec3::new(0.0, 0.0, 3.0));
    assert!(info.warning().is_none());
    let skewed = CameraInfo { skew: 0.5, ..info };
    assert!(skewed.warning().unwrap().contains("skew 0.5"));
}

#[test]
fn written_json_is_stable() {
    let camera = Camera::look_at(64, 48, 0.9, Vec3::new(0.0, -4.0, 1.0), Vec3::ZERO, Vec3::Z);
    let info = CameraInfo {
        camera: Camera {
            fy: camera.fx * 1.25,
            cx: 30.5,
            ..camera
        },
        skew: 0.0,
        distortion: Distortion {
            radial: [0.1, 0.0, 0.0],
            tangential: [0.0, 0.0],
            ..Distortion::default()
        },
    };
    insta::assert_snapshot!("nerfies_written", evogs_io::nerfies_camera_json(&info));
}

fn camera_strategy() -> impl Strategy<Value = CameraInfo> {
    (
        (
            prop::array::uniform4(-1.0f32..1.0),
            prop::array::uniform3(-50.0f32..50.0),
        ),
        (1u32..5000, 1u32..5000, 1.0f32..5000.0, 0.25f32..4.0),
        (prop::array::uniform2(-100.0f32..5000.0), -1.0f32..1.0),
        (
            prop::array::uniform3(-0.5f32..0.5),
            prop::array::uniform2(-0.1f32..0.1),
        ),
    )
        .prop_filter("non-degenerate quaternion", |((q, _), ..)| {
            q.iter().map(|v| v * v).sum::<f32>() > 0.01
        })
        .prop_map(
            |((q, c), (w, h, fx, aspect), (pp, skew), (radial, tangential))| {
                let rotation = Mat3::from_quat(Quat::from_array(q).normalize());
                CameraInfo {
                    camera: Camera::from_center(
                        w,
                        h,
                        fx,
                        fx * aspect,
                        pp[0],
                        pp[1],
                        rotation,
                        Vec3::from_array(c),
                    ),
                    skew,
                    distortion: Distortion {
                        radial,
                        tangential,
                        ..Distortion::default()
                    },
                }
            },
        )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn write_then_read_round_trips(info in camera_strategy()) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("camera.json");
        write_nerfies_camera(&path, &info).unwrap();
        let back = read_nerfies_camera(&path).unwrap();
        let (a, b) = (&info.camera, &back.camera);
        prop_assert_eq!((a.width, a.height, a.fx, a.fy, a.cx, a.cy), (b.width, b.height, b.fx, b.fy, b.cx, b.cy));
        prop_assert_eq!(a.rotation, b.rotation);
        let scale = a.translation.abs().max_element().max(1.0);
        prop_assert!((a.translation - b.translation).abs().max_element() <= 1e-6 * scale,
            "{:?} vs {:?}", a.translation, b.translation);
        prop_assert_eq!(info.skew, back.skew);
        prop_assert_eq!(info.distortion, back.distortion);
    }
}

#[test]
fn bad_camera_files_name_the_file_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let base: serde_json::Value = serde_json::from_str(HYPERNERF_SAMPLE).unwrap();
    let with = |key: &str, value: serde_json::Value| -> String {
        let mut v = base.clone();
        v[key] = value;
        v.to_string()
    };
    let without = |key: &str| -> String {
        let mut v = base.clone();
        v.as_object_mut().unwrap().remove(key);
        v.to_string()
    };
    use serde_json::json;
    let cases: Vec<(&str, String)> = vec![
        ("not json", "{\"orientation\": [[1,0,0],".to_string()),
        ("not an object", "[1, 2, 3]".to_string()),
        ("missing position", without("position")),
        ("focal is a string", with("focal_length", json!("1000"))),
        ("negative focal", with("focal_length", json!(-3.0))),
        (
            "short principal point",
            with("principal_point", json!([1.0])),
        ),
        (
            "not a rotation",
            with("orientation", json!([[1, 0, 0], [0, 2, 0], [0, 0, 1]])),
        ),
        (
            "reflection",
            with("orientation", json!([[1, 0, 0], [0, 1, 0], [0, 0, -1]])),
        ),
        (
            "orientation row too short",
            with("orientation", json!([[1, 0, 0], [0, 1], [0, 0, 1]])),
        ),
        (
            "orientation entry null",
            with("orientation", json!([[1, 0, 0], [0, null, 0], [0, 0, 1]])),
        ),
        ("fractional size", with("image_size", json!([960.5, 540]))),
        ("zero size", with("image_size", json!([960, 0]))),
        (
            "too many radial",
            with("radial_distortion", json!([0.1, 0.2, 0.3, 0.4])),
        ),
        ("aspect zero", with("pixel_aspect_ratio", json!(0.0))),
    ];
    let mut report = String::new();
    for (name, text) in &cases {
        let path = write_temp(dir.path(), "bad.json", text);
        let err = read_nerfies_camera(&path).expect_err(name);
        let message = err.to_string();
        assert!(message.contains("bad.json"), "{name}: {message}");
        assert!(!message.contains('\n'), "{name}: {message}");
        let shown = message.replace(&dir.path().display().to_string(), "<dir>");
        report.push_str(&format!("{name}: {shown}\n"));
    }
    insta::assert_snapshot!("nerfies_errors", report);
    let err = read_nerfies_camera(&dir.path().join("missing.json")).unwrap_err();
    assert!(matches!(err, IoError::Io { .. }) && err.to_string().contains("missing.json"));
}

#[test]
fn writing_refuses_invalid_cameras_and_keeps_the_old_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_temp(dir.path(), "cam.json", "old");
    let mut info = CameraInfo::pinhole(Camera::look_at(8, 8, 1.0, Vec3::ONE, Vec3::ZERO, Vec3::Z));
    info.camera.fx = f32::NAN;
    let err = write_nerfies_camera(&path, &info).unwrap_err();
    assert!(err.to_string().contains("cam.json"), "{err}");
    assert_eq!(std::fs::read_to_string(&path).unwrap(), "old");
}

#[test]
fn camera_path_reads_each_camera_with_its_time() {
    let dir = tempfile::tempdir().unwrap();
    let with_time = |t: &str| HYPERNERF_SAMPLE.replacen('{', &format!("{{\n  \"time\": {t},"), 1);
    let text = format!("[{}, {}]", with_time("0.75"), with_time("0.25"));
    let path = write_temp(dir.path(), "path.json", &text);
    let cams = evogs_io::read_camera_path(&path).unwrap();
    let single = read_nerfies_camera(&write_temp(dir.path(), "c.json", HYPERNERF_SAMPLE)).unwrap();
    assert_eq!(cams.len(), 2);
    // File order is kept (the path sorts by time itself).
    assert_eq!(cams[0].time, 0.75);
    assert_eq!(cams[1].time, 0.25);
    assert_eq!(cams[1].info, single);
}

#[test]
fn camera_path_errors_name_the_element_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        ("{}", "(root)"),
        ("[]", "empty"),
        (
            &format!("[{HYPERNERF_SAMPLE}]") as &str,
            "`[0].time`: missing",
        ),
        ("[3]", "`[0]`: expected an object"),
    ];
    for (text, expected) in cases {
        let path = write_temp(dir.path(), "bad.json", text);
        let err = evogs_io::read_camera_path(&path).unwrap_err().to_string();
        assert!(err.contains("bad.json") && err.contains(expected), "{err}");
        assert!(!err.contains('\n'), "{err}");
    }
}
