//! A run directory's files as text: JSON and text written atomically (a temporary file, then a
//! rename) and JSON read back, the error naming the file. Below [`run`](crate::run), which
//! re-exports these functions (their public path is `evogs_train::run`), and
//! [`train_log`](crate::train_log), which writes `train_log.jsonl` with [`write_text`].

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::TrainError;

/// Writes `value` as pretty JSON to `path`, atomically (a run directory's JSON files).
pub fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<(), TrainError> {
    let text = serde_json::to_string_pretty(value)
        .map_err(|e| TrainError::file(path, format!("cannot encode JSON: {e}")))?;
    write_text(path, &text)
}

/// Writes `text` to `path`, atomically (a run directory's text files).
pub fn write_text(path: &Path, text: &str) -> Result<(), TrainError> {
    evogs_io::atomic::write_atomically(path, |w| {
        use std::io::Write;
        w.write_all(text.as_bytes())
            .map_err(|cause| evogs_io::IoError::Io {
                path: path.to_path_buf(),
                cause,
            })
    })?;
    Ok(())
}

/// Reads the JSON file `path` (a run directory's `config.json`, `train_metrics.json`, …); the
/// error names the file.
pub fn read_json<T: for<'de> Deserialize<'de>>(path: &Path) -> Result<T, TrainError> {
    let text = std::fs::read_to_string(path).map_err(|e| TrainError::io(path, e))?;
    serde_json::from_str(&text).map_err(|e| TrainError::file(path, format!("invalid JSON: {e}")))
}
