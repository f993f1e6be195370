//! Cameras on a sphere around the object (their D-NeRF form is `evogs_io::opengl_c2w`).

use glam::Vec3;
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use splat_raster::Camera;

/// A camera at `distance` from the origin, looking at it, in a random direction with elevation
/// `asin(z)` for `z` uniform in [−0.15, 0.85] and uniform azimuth; world up is +z.
pub(crate) fn sample_camera(rng: &mut ChaCha8Rng, size: u32, fov_x: f32, distance: f32) -> Camera {
    let z: f32 = rng.random_range(-0.15..0.85);
    let azimuth: f32 = rng.random_range(0.0..std::f32::consts::TAU);
    let r = (1.0 - z * z).sqrt();
    let eye = Vec3::new(r * azimuth.cos(), r * azimuth.sin(), z) * distance;
    Camera::look_at(size, size, fov_x, eye, Vec3::ZERO, Vec3::Z)
}
