//! Small numeric helpers: activations and the rotation of a raw quaternion.

use glam::{Mat3, Quat};

/// `1 / (1 + e^-x)`.
pub fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

/// Inverse of [`sigmoid`], `ln(p / (1 - p))`.
pub fn logit(p: f32) -> f32 {
    (p / (1.0 - p)).ln()
}

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
