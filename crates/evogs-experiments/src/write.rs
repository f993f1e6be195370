//! Atomic writes of the experiments' outputs (tables, JSON, plots), shared by the ablation ladder
//! and the benchmark.

use std::path::Path;

use crate::error::ExperimentError;

/// Writes `bytes` to `path` atomically (temporary file + rename).
pub(crate) fn write_bytes(path: &Path, bytes: &[u8]) -> Result<(), ExperimentError> {
    use std::io::Write;
    evogs_io::atomic::write_atomically(path, |w| {
        w.write_all(bytes).map_err(|cause| evogs_io::IoError::Io {
            path: path.to_path_buf(),
            cause,
        })
    })?;
    Ok(())
}

/// Writes `image` to `path` as a PNG, atomically.
pub(crate) fn write_png(path: &Path, image: &image::RgbImage) -> Result<(), ExperimentError> {
    evogs_io::image_io::save_rgb8_png(path, image)?;
    Ok(())
}

/// `value` as pretty JSON, written to `path` atomically.
pub(crate) fn write_json(path: &Path, value: &serde_json::Value) -> Result<(), ExperimentError> {
    let json = serde_json::to_string_pretty(value)
        .map_err(|e| ExperimentError::output(path, e.to_string()))?;
    write_bytes(path, json.as_bytes())
}
