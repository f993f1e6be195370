//! Training reads any dataset layout `evogs-io` detects, and starts from the dataset's point
//! cloud where it brings one (COLMAP here) rather than from random points.

use crate::common;

use std::path::Path;

use evogs_io::colmap::{
    CameraModel, ColmapCamera, ColmapImage, ColmapPoint, encode_cameras_txt, encode_images_txt,
    encode_points3d_txt,
};
use evogs_io::{Format, LoadOptions, Split};
use evogs_train::{Preset, TrainConfig, TrainRequest, train};
use glam::Quat;

/// Writes the common test scene's training views as a static COLMAP text model (one PINHOLE
/// camera per image, `images/` beside `sparse/`), with the scene's Gaussians at t = 0.5 as its
/// sparse points. Returns the number of points.
fn write_colmap_from(dnerf: &Path, out: &Path) -> usize {
    let dataset = evogs_io::load_dataset(dnerf, &LoadOptions::default()).unwrap();
    assert_eq!(dataset.format, Format::Dnerf);
    std::fs::create_dir_all(out.join("images")).unwrap();
    std::fs::create_dir_all(out.join("sparse")).unwrap();
    let mut cameras = Vec::new();
    let mut images = Vec::new();
    for (i, frame) in dataset.split(Split::Train).iter().enumerate() {
        let cam = frame.camera.camera;
        let name = format!("view{i:03}.png");
        std::fs::copy(&frame.image_path, out.join("images").join(&name)).unwrap();
        let id = i as u32 + 1;
        cameras.push(ColmapCamera {
            id,
            model: CameraModel::Pinhole,
            width: cam.width,
            height: cam.height,
            params: [cam.fx, cam.fy, cam.cx, cam.cy].map(f64::from).to_vec(),
        });
        let q = Quat::from_mat3(&cam.rotation);
        images.push(ColmapImage {
            id,
            qvec: [q.w, q.x, q.y, q.z].map(f64::from),
            tvec: cam.translation.to_array().map(f64::from),
            camera_id: id,
            name,
        });
    }
    let scene = common::scene_at(0.5);
    let points: Vec<ColmapPoint> = scene
        .means
        .iter()
        .enumerate()
        .map(|(i, m)| ColmapPoint {
            xyz: m.map(f64::from),
            rgb: [(i * 40 % 256) as u8, 128, 255 - (i * 40 % 256) as u8],
        })
        .collect();
    let sparse = out.join("sparse");
    std::fs::write(sparse.join("cameras.txt"), encode_cameras_txt(&cameras)).unwrap();
    std::fs::write(sparse.join("images.txt"), encode_images_txt(&images)).unwrap();
    std::fs::write(sparse.join("points3D.txt"), encode_points3d_txt(&points)).unwrap();
    points.len()
}

#[test]
fn colmap_dataset_trains_from_its_point_cloud() {
    let dir = tempfile::tempdir().unwrap();
    let dnerf = dir.path().join("dnerf");
    common::write_scene(&dnerf);
    let colmap = dir.path().join("colmap");
    let n_points = write_colmap_from(&dnerf, &colmap);

    let mut config = TrainConfig::preset(Preset::Tiny).with_iterations(20);
    config.init_points = 300;
    let run = |data: &Path, out: &str| {
        // One iteration: one Adam step, which moves each parameter by about its learning rate
        // (≤ 0.0025 here), so the canonical Gaussians are the initial ones to within 1e-2.
        let request = TrainRequest {
            data: data.to_path_buf(),
            out: dir.path().join(out),
            config: config.clone(),
            resume: false,
            stop_after: Some(1),
            resume_backend: None,
            resume_net_backend: None,
        };
        train(&request, &mut |_, _| {}).unwrap();
        evogs_io::read_ply(&dir.path().join(out).join("canonical.ply"))
            .unwrap()
            .gaussians
    };

    let from_points = run(&colmap, "colmap_run");
    assert_eq!(from_points.len(), n_points);
    let scene = common::scene_at(0.5);
    for (got, want) in from_points.means.iter().zip(&scene.means) {
        for a in 0..3 {
            assert!((got[a] - want[a]).abs() < 1e-2, "{got:?} vs {want:?}");
        }
    }
    // SH DC is RGB2SH of the point colour: (c − 0.5) / C0.
    let stride = from_points.sh_stride();
    let dc = &from_points.sh[stride..stride + 3];
    let want = [40.0 / 255.0, 128.0 / 255.0, 215.0 / 255.0].map(|c: f32| (c - 0.5) / 0.282_094_8);
    for (g, w) in dc.iter().zip(want) {
        assert!((g - w).abs() < 1e-2, "{dc:?} vs {want:?}");
    }

    // A D-NeRF scene brings no point cloud: random points in the box, as many as configured.
    let random = run(&dnerf, "dnerf_run");
    assert_eq!(random.len(), 300);
}
