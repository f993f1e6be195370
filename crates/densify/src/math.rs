//! Small numeric helpers: the rotation of a raw quaternion and the largest activated scale (the
//! opacity activations are `splat_core`'s [`sigmoid`](splat_core::sigmoid) and
//! [`logit`](splat_core::logit)).

use glam::{Mat3, Quat};

/// Rotation matrix of a raw quaternion `w, x, y, z` after normalisation; the identity when the
/// quaternion is (nearly) zero or not finite.
pub fn rotation(q: [f32; 4]) -> Mat3 {
    let quat = Quat::from_xyzw(q[1], q[2], q[3], q[0]);
    let norm2 = quat.length_squared();
    if !(norm2.is_finite() && norm2 > 1e-20) {
        return Mat3::IDENTITY;
    }
    Mat3::from_quat(quat / norm2.sqrt())
}

/// Largest activated scale, `max(exp(log_scale))`.
pub fn max_scale(log_scale: [f32; 3]) -> f32 {
    log_scale[0].max(log_scale[1]).max(log_scale[2]).exp()
}
