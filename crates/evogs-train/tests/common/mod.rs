//! A tiny dynamic scene written by the tests themselves in the D-NeRF layout: coloured
//! Gaussians translating along x over time, rendered with `splat-raster` from cameras on a
//! circle, saved with `evogs-io`'s PNG writer beside `transforms_{train,val,test}.json`.

#![allow(dead_code)]

use std::path::Path;

use glam::Vec3;
use serde_json::json;
use splat_raster::{Camera, CpuRasterizer, Gaussians, Rasterizer, RenderOptions};

/// Image side in pixels.
pub const SIDE: u32 = 32;

/// The ground-truth Gaussians at time `t`: a 5×5×2 block moving 0.4 along x over [0, 1].
pub fn scene_at(t: f32) -> Gaussians {
    let mut g = Gaussians::with_degree(0);
    for i in 0..5 {
        for j in 0..5 {
            for k in 0..2 {
                let p = [
                    -0.4 + 0.2 * i as f32 + 0.4 * t - 0.2,
                    -0.4 + 0.2 * j as f32,
                    -0.1 + 0.2 * k as f32,
                ];
                g.means.push(p);
                g.log_scales.push([-2.3; 3]);
                g.rotations.push([1.0, 0.0, 0.0, 0.0]);
                g.opacity_logits.push(2.0);
                g.sh.extend([
                    (i as f32 / 4.0 - 0.5) * 1.5,
                    (j as f32 / 4.0 - 0.5) * 1.5,
                    (k as f32 - 0.5) * 1.5,
                ]);
            }
        }
    }
    g
}

fn camera(angle: f32, elevation: f32) -> Camera {
    let eye = Vec3::new(
        3.0 * angle.cos() * elevation.cos(),
        3.0 * angle.sin() * elevation.cos(),
        3.0 * elevation.sin(),
    );
    Camera::look_at(SIDE, SIDE, 0.7, eye, Vec3::ZERO, Vec3::Z)
}

/// Camera-to-world in OpenGL axes (D-NeRF), rows of a 4×4 matrix.
fn c2w_opengl(cam: &Camera) -> [[f32; 4]; 4] {
    let r_c2w = cam.rotation.transpose();
    let c = cam.center();
    let x = r_c2w.x_axis;
    let y = -r_c2w.y_axis;
    let z = -r_c2w.z_axis;
    [
        [x.x, y.x, z.x, c.x],
        [x.y, y.y, z.y, c.y],
        [x.z, y.z, z.z, c.z],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

/// Writes the scene under `root` (train: 16 views, val: 4, test: 4; black background).
pub fn write_scene(root: &Path) {
    let raster = CpuRasterizer::new();
    let opts = RenderOptions::default();
    for (split, count, offset) in [
        ("train", 16usize, 0.0f32),
        ("val", 4, 0.37),
        ("test", 4, 0.71),
    ] {
        std::fs::create_dir_all(root.join(split)).unwrap();
        let mut frames = Vec::new();
        let mut fov = 0.0;
        for k in 0..count {
            let t = if count > 1 {
                k as f32 / (count - 1) as f32
            } else {
                0.0
            };
            let cam = camera(offset + k as f32 * 2.4, 0.3 + 0.2 * (k % 3) as f32);
            fov = 2.0 * (0.5 * SIDE as f32 / cam.fx).atan();
            let out = raster.forward(scene_at(t).view(), &cam, &opts).unwrap();
            let img = evogs_io::ImageRgb {
                width: SIDE,
                height: SIDE,
                pixels: out.color,
            };
            let name = format!("r_{k:03}");
            evogs_io::save_png(&root.join(split).join(format!("{name}.png")), &img).unwrap();
            frames.push(json!({
                "file_path": format!("./{split}/{name}"),
                "time": t,
                "transform_matrix": c2w_opengl(&cam),
            }));
        }
        let doc = json!({"camera_angle_x": fov, "frames": frames});
        std::fs::write(
            root.join(format!("transforms_{split}.json")),
            serde_json::to_string_pretty(&doc).unwrap(),
        )
        .unwrap();
    }
}
