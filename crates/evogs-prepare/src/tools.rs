//! The external programs: finding them, and running one stage with its output in a log file.

use std::fs::File;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use crate::PrepareError;

/// An external program and the Debian package that provides it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tool {
    /// The program's name on `PATH`.
    pub program: &'static str,
    /// The Debian package.
    pub package: &'static str,
    /// Arguments that make it print its version and exit successfully.
    pub version_args: &'static [&'static str],
}

/// ffmpeg (frame extraction, image scaling).
pub const FFMPEG: Tool = Tool {
    program: "ffmpeg",
    package: "ffmpeg",
    version_args: &["-version"],
};

/// ffprobe (the clip's duration and frame rate), shipped with ffmpeg.
pub const FFPROBE: Tool = Tool {
    program: "ffprobe",
    package: "ffmpeg",
    version_args: &["-version"],
};

/// COLMAP (features, matching, mapping, undistortion).
pub const COLMAP: Tool = Tool {
    program: "colmap",
    package: "colmap",
    version_args: &["help"],
};

impl Tool {
    /// The first line the program prints about its version, or [`PrepareError::MissingTool`]
    /// when it cannot be started.
    pub fn version(&self) -> Result<String, PrepareError> {
        let missing = || PrepareError::MissingTool {
            program: self.program,
            package: self.package,
        };
        let out = Command::new(self.program)
            .args(self.version_args)
            .stdin(Stdio::null())
            .output()
            .map_err(|_| missing())?;
        let text = String::from_utf8_lossy(&out.stdout);
        Ok(text
            .lines()
            .find(|l| !l.trim().is_empty())
            .unwrap_or("")
            .trim()
            .to_string())
    }
}

/// The last non-empty line of a log file that reads like a message (COLMAP and ffmpeg end with
/// the reason they stopped), shortened to 200 characters.
pub fn last_message(log: &Path) -> String {
    let text = std::fs::read_to_string(log).unwrap_or_default();
    let line = text
        .lines()
        .rev()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.chars().all(|c| c == '=' || c == '-'))
        .unwrap_or("(no output)");
    line.chars().take(200).collect()
}

/// Runs `tool` with `args`, its standard output and error going to `log`; an error naming
/// `subject` (the input) and `stage` with the program's last message when it fails.
pub fn run_logged(
    tool: &Tool,
    args: &[String],
    log: &Path,
    subject: &Path,
    stage: &str,
) -> Result<(), PrepareError> {
    let file = File::create(log).map_err(|e| PrepareError::io(log, e))?;
    let err = file.try_clone().map_err(|e| PrepareError::io(log, e))?;
    let status = Command::new(tool.program)
        .args(args)
        .stdin(Stdio::null())
        .stdout(file)
        .stderr(err)
        .status()
        .map_err(|_| PrepareError::MissingTool {
            program: tool.program,
            package: tool.package,
        })?;
    if status.success() {
        Ok(())
    } else {
        Err(PrepareError::Stage {
            path: subject.to_path_buf(),
            stage: stage.to_string(),
            problem: format!("{status}: {}", last_message(log)),
        })
    }
}

/// A path as a program argument.
pub fn arg(path: &Path) -> String {
    path.to_string_lossy().into_owned()
}

/// The sorted files of `dir` whose extension is an image's (`png`, `jpg`, `jpeg`, any case).
pub fn image_files(dir: &Path) -> Result<Vec<PathBuf>, PrepareError> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| PrepareError::io(dir, e))? {
        let path = entry.map_err(|e| PrepareError::io(dir, e))?.path();
        let image = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| matches!(e.to_ascii_lowercase().as_str(), "png" | "jpg" | "jpeg"));
        if image && path.is_file() {
            out.push(path);
        }
    }
    out.sort();
    Ok(out)
}
