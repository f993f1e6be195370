//! Snapshot of a small render's statistics: mean colour per channel, mean alpha, mean depth and
//! the culling line.

use crate::common;

use glam::Vec3;
use splat_raster::{CpuRasterizer, Rasterizer, RenderOptions};

#[test]
fn small_render_statistics() {
    let mut rng = common::rng(2024);
    let cam = common::random_camera(&mut rng, 64, 48);
    let mut g = common::random_gaussians(&mut rng, 200, 2, 2.5);
    // A few Gaussians behind the camera and with a zero quaternion.
    let behind = (cam.center() - cam.rotation.transpose() * Vec3::Z).to_array();
    g.means[0] = behind;
    g.means[1] = behind;
    g.rotations[2] = [0.0; 4];
    g.opacity_logits[3] = f32::NAN;
    let opts = RenderOptions {
        background: [0.0, 0.0, 1.0],
        sh_degree: None,
    };
    let out = CpuRasterizer::new().forward(g.view(), &cam, &opts).unwrap();
    let n = out.color.len() as f64;
    let mean =
        |f: &dyn Fn(usize) -> f32| (0..out.color.len()).map(|p| f64::from(f(p))).sum::<f64>() / n;
    let report = format!(
        "size: {}x{}\nmean colour: r {:.4} g {:.4} b {:.4}\nmean alpha: {:.4}\nmean depth: {:.4}\n{}\n",
        out.width,
        out.height,
        mean(&|p| out.color[p][0]),
        mean(&|p| out.color[p][1]),
        mean(&|p| out.color[p][2]),
        mean(&|p| out.alpha[p]),
        mean(&|p| out.depth[p]),
        out.stats,
    );
    insta::assert_snapshot!(report);
}
