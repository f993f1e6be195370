//! Builders shared by the integration tests.
#![allow(dead_code)]

use densify::{DensifyConfig, DensifyStats};
use splat_core::Gaussians;

/// `n` Gaussians at x = i, isotropic scale `scale`, identity rotation, opacity 0.5, SH degree 1
/// with coefficients tagged by row (row + k/100).
pub fn gaussians(n: usize, scale: f32) -> Gaussians {
    let mut g = Gaussians::with_degree(1);
    for i in 0..n {
        g.means.push([i as f32, 0.0, 0.0]);
        g.log_scales.push([scale.ln(); 3]);
        g.rotations.push([1.0, 0.0, 0.0, 0.0]);
        g.opacity_logits.push(0.0);
    }
    let stride = g.sh_stride();
    g.sh = (0..n * stride)
        .map(|e| (e / stride) as f32 + (e % stride) as f32 / 100.0)
        .collect();
    g
}

/// Statistics where Gaussian i has mean NDC gradient `grads[i]` over one visible view.
pub fn stats_with_grads(grads: &[f32]) -> DensifyStats {
    let mut s = DensifyStats::new(grads.len());
    for (i, &gr) in grads.iter().enumerate() {
        s.grad_sum[i] = gr;
        s.visible[i] = 1;
    }
    s
}

/// Default 3DGS configuration.
pub fn standard() -> DensifyConfig {
    DensifyConfig::default()
}
