//! The effects a scene can enable, each with its parameters.

use serde::Serialize;

/// Rigid motion of the object (body and satellite): rotation by `angle · t` radians about `axis`
/// through the origin, and translation `velocity · (t − 0.5)`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct RigidMotion {
    /// Rotation axis (normalised when used).
    pub axis: [f32; 3],
    /// Total rotation over t ∈ [0, 1], radians.
    pub angle: f32,
    /// Translation per unit time.
    pub velocity: [f32; 3],
}

/// A non-rigid travelling wave on the body: `Δz = amplitude · sin(2π (x / wavelength − t · cycles))`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Wave {
    /// Displacement amplitude (world units).
    pub amplitude: f32,
    /// Wavelength along x (world units).
    pub wavelength: f32,
    /// Periods travelled over t ∈ [0, 1].
    pub cycles: f32,
}

/// Large motion: translation `(length · (t − 0.5), 0, lift · sin(π t))`, larger than the object.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct LargeMotion {
    /// Distance travelled along x.
    pub length: f32,
    /// Height of the arc.
    pub lift: f32,
}

/// An abrupt jump of the satellite: for `t >= time` it is displaced by `offset + velocity · (t −
/// time)`; before, it is still. `time` lies strictly between two consecutive training times.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Jump {
    /// When the jump happens.
    pub time: f32,
    /// The teleport.
    pub offset: [f32; 3],
    /// Velocity after the jump.
    pub velocity: [f32; 3],
}

/// Appearance change of the body: `rgb(t) = rgb + strength · sin(π t) · (tint − rgb)`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct AppearanceChange {
    /// The colour blended towards.
    pub tint: [f32; 3],
    /// Blend at t = 0.5, in [0, 1].
    pub strength: f32,
}

/// Occlusion: a panel of Gaussians on a circle of `radius` about the z axis, facing the origin,
/// making `turns` revolutions over t ∈ [0, 1] (so it passes in front of cameras at every azimuth).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Occlusion {
    /// Orbit radius.
    pub radius: f32,
    /// Panel width and height.
    pub size: [f32; 2],
    /// Revolutions over t ∈ [0, 1].
    pub turns: f32,
}
