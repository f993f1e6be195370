//! A small scene built in memory, with no files: what `evogs demo` and quick tests train on.

use super::{Preset, SceneSpec, SynthError, SyntheticScene, generate};

/// Seed of the embedded scene.
pub const EMBEDDED_SEED: u64 = 7;

/// The embedded scene: the `wave` preset at 64×64 pixels, 16 training frames (3 test, 3 val)
/// and about 750 Gaussians. Deterministic; takes well under a second to build.
pub fn embedded_scene() -> Result<SyntheticScene, SynthError> {
    let spec = SceneSpec::preset(Preset::Wave)
        .with_size(64)
        .with_frames(16)
        .with_gaussian_scale(0.25);
    generate(&spec, EMBEDDED_SEED)
}
