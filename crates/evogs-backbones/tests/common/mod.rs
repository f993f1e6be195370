//! What the backbone tests share: a small deterministic generator and random Gaussians.

#![allow(dead_code)] // Each test binary uses a part.

use splat_core::Gaussians;

/// A small deterministic generator in [-1, 1).
pub struct Lcg(pub u64);

impl Lcg {
    /// The next value in [-1, 1).
    pub fn next(&mut self) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    }
}

/// `n` small Gaussians (SH degree 0) at random means in [-1, 1)³ with random opacity logits in
/// [-2, 2).
pub fn gaussians(n: usize, rng: &mut Lcg) -> Gaussians {
    let mut g = Gaussians::with_degree(0);
    for _ in 0..n {
        g.means.push([rng.next(), rng.next(), rng.next()]);
        g.log_scales.push([-2.0; 3]);
        g.rotations.push([1.0, 0.0, 0.0, 0.0]);
        g.opacity_logits.push(2.0 * rng.next());
        g.sh.extend([0.1, 0.2, 0.3]);
    }
    g
}
