//! Cameras on a sphere around the object, and their D-NeRF (OpenGL camera-to-world) form.

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

/// The camera's `transform_matrix` for D-NeRF: camera-to-world in OpenGL axes (columns: camera
/// +x, +y (up), +z (backwards) in world, and the centre), rows of a 4×4 matrix.
pub fn opengl_c2w(camera: &Camera) -> [[f64; 4]; 4] {
    let r = camera.rotation;
    // Rows of R are the OpenCV axes in world; OpenGL's y and z are their negatives.
    let x = r.row(0).as_dvec3();
    let y = -r.row(1).as_dvec3();
    let z = -r.row(2).as_dvec3();
    let c = camera.center().as_dvec3();
    [
        [x.x, y.x, z.x, c.x],
        [x.y, y.y, z.y, c.y],
        [x.z, y.z, z.z, c.z],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

/// D-NeRF's `camera_angle_x` of a camera: `2·atan(0.5·W / fx)`.
pub fn dnerf_camera_angle_x(camera: &Camera) -> f64 {
    2.0 * (0.5 * f64::from(camera.width) / f64::from(camera.fx)).atan()
}
