//! `times.json`: the frame times a COLMAP dataset stores itself, as `evogs prepare` writes them
//! (each frame's time in its clip, so that a frame COLMAP did not register does not shift the
//! times of the others).
//!
//! ```json
//! { "source": "clip.mp4", "frames": { "frame_00000.png": 0.0, "frame_00001.png": 0.0204 } }
//! ```
//!
//! Names are the images' names relative to the images folder; times are numbers in [0, 1]. A
//! dataset with this file stores its times, so `--time-from` (for datasets that store none) does
//! not apply to it. What it is not: a general per-frame metadata file.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::IoError;
use crate::atomic::write_atomically;
use crate::json_fields::load_json;

/// The file's name in a dataset's root folder.
pub const TIMES_FILE: &str = "times.json";

/// The contents of `times.json`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameTimes {
    /// Where the times come from (the clip or image folder), for a reader; not interpreted.
    #[serde(default)]
    pub source: String,
    /// Each image's time in [0, 1], by name relative to the images folder.
    pub frames: BTreeMap<String, f64>,
}

/// Writes `times` to `path` (a temporary file renamed into place).
pub fn write_frame_times(path: &Path, times: &FrameTimes) -> Result<(), IoError> {
    let text = serde_json::to_string_pretty(times).map_err(|cause| IoError::Json {
        path: path.to_path_buf(),
        cause,
    })?;
    write_atomically(path, |w| {
        w.write_all(text.as_bytes())
            .map_err(|e| IoError::io(path, e))
    })
}

/// The times of the images `names` from the `times.json` at `path`, in the order of `names`.
/// An image the file does not list, a time outside [0, 1] or a file that is not of this shape
/// is an error naming the file and the field.
pub fn read_frame_times(path: &Path, names: &[&str]) -> Result<Vec<f32>, IoError> {
    let value = load_json(path)?;
    let times: FrameTimes = serde_json::from_value(value).map_err(|cause| IoError::Json {
        path: path.to_path_buf(),
        cause,
    })?;
    names
        .iter()
        .map(|&name| {
            let field = || format!("frames.{name}");
            let t = *times.frames.get(name).ok_or_else(|| {
                IoError::field(
                    path,
                    field(),
                    "missing: the dataset has this image but no time for it",
                )
            })?;
            if !(0.0..=1.0).contains(&t) {
                return Err(IoError::field(
                    path,
                    field(),
                    format!("{t}: a time must be a number in [0, 1]"),
                ));
            }
            Ok(t as f32)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, text: &str) -> std::path::PathBuf {
        let path = dir.join(TIMES_FILE);
        std::fs::write(&path, text).unwrap();
        path
    }

    #[test]
    fn times_round_trip_in_the_order_asked() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(TIMES_FILE);
        let times = FrameTimes {
            source: "clip.mp4".into(),
            frames: [("b.png", 0.75), ("a.png", 0.25)]
                .into_iter()
                .map(|(n, t)| (n.to_string(), t))
                .collect(),
        };
        write_frame_times(&path, &times).unwrap();
        assert_eq!(
            read_frame_times(&path, &["a.png", "b.png"]).unwrap(),
            vec![0.25, 0.75]
        );
        assert_eq!(read_frame_times(&path, &["b.png"]).unwrap(), vec![0.75]);
    }

    #[test]
    fn a_missing_frame_a_bad_time_or_a_bad_shape_names_the_field() {
        let dir = tempfile::tempdir().unwrap();
        let path = write(dir.path(), r#"{"frames": {"a.png": 0.5}}"#);
        let err = read_frame_times(&path, &["a.png", "c.png"]).unwrap_err();
        assert!(
            err.to_string()
                .ends_with("times.json: field `frames.c.png`: missing: the dataset has this image but no time for it"),
            "{err}"
        );
        for bad in ["1.5", "-0.25"] {
            let path = write(dir.path(), &format!(r#"{{"frames": {{"a.png": {bad}}}}}"#));
            let err = read_frame_times(&path, &["a.png"]).unwrap_err();
            assert!(
                err.to_string().contains("field `frames.a.png`: ")
                    && err.to_string().contains("a number in [0, 1]"),
                "{err}"
            );
        }
        let path = write(dir.path(), r#"{"frames": {"a.png": "soon"}}"#);
        let err = read_frame_times(&path, &["a.png"]).unwrap_err();
        assert!(
            err.to_string().contains("times.json: invalid JSON"),
            "{err}"
        );
    }
}
