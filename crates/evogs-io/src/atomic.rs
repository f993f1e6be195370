//! Atomic file output: write to a temporary file in the target's directory, then rename it into
//! place, so a reader never sees a half-written file and a failed write leaves the old one intact;
//! and [`StagedFiles`], a set of files that appears in a folder all together or not at all.

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use crate::IoError;

/// File-name prefix of the temporary files: a kill during a write leaves one behind, which
/// [`remove_interrupted`] clears.
pub const TEMP_PREFIX: &str = ".evogs-tmp-";

/// Removes the temporary files that killed writes left in `dir` (its files named
/// [`TEMP_PREFIX`]`*`, not its subfolders'); returns how many. Call it only while no other
/// process writes into `dir`.
pub fn remove_interrupted(dir: &Path) -> Result<usize, IoError> {
    let mut removed = 0;
    for entry in std::fs::read_dir(dir).map_err(|e| IoError::io(dir, e))? {
        let path = entry.map_err(|e| IoError::io(dir, e))?.path();
        let temp = path
            .file_name()
            .and_then(|n| n.to_str())
            .is_some_and(|n| n.starts_with(TEMP_PREFIX));
        if temp && path.is_file() {
            std::fs::remove_file(&path).map_err(|e| IoError::io(&path, e))?;
            removed += 1;
        }
    }
    Ok(removed)
}

/// Writes `path` atomically: `fill` writes the whole content into a buffered temporary file in the
/// same directory, which is flushed, synced and renamed over `path` only if `fill` succeeded.
pub fn write_atomically<F>(path: &Path, fill: F) -> Result<(), IoError>
where
    F: FnOnce(&mut BufWriter<File>) -> Result<(), IoError>,
{
    let mut file = AtomicFile::create(path)?;
    fill(file.writer())?;
    file.commit()
}

/// A file being written atomically: a buffered temporary file beside `path`, renamed over it by
/// [`AtomicFile::commit`]; dropped without a commit, the temporary file is removed and `path` is
/// untouched. For content that arrives piece by piece (video frames).
pub struct AtomicFile {
    path: PathBuf,
    writer: BufWriter<File>,
    temp_path: tempfile::TempPath,
}

impl std::io::Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.writer.write(buf)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.writer.flush()
    }
}

/// Temporary files are created private (0600): gives `file`, about to be renamed over
/// `target`, the mode an existing `target` has, or the usual 0644 for a new one (a no-op off
/// Unix).
pub(crate) fn set_output_mode(file: &File, target: &Path) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(target).map_or(0o644, |m| m.permissions().mode() & 0o7777);
        file.set_permissions(std::fs::Permissions::from_mode(mode))?;
    }
    #[cfg(not(unix))]
    let _ = (file, target);
    Ok(())
}

/// The error of creating the temporary file or folder for `target` in `dir`, naming `target`
/// and never the temporary name (which `tempfile` appends to its errors): a missing folder is
/// said as such, anything else by its kind.
pub(crate) fn temp_error(target: &Path, dir: &Path, e: &std::io::Error) -> IoError {
    let problem = if dir.is_dir() {
        format!("cannot create a file beside it: {}", e.kind())
    } else {
        format!("no such folder {}", dir.display())
    };
    IoError::io(target, std::io::Error::new(e.kind(), problem))
}

/// The directory a path is in (`.` for a bare file name).
pub(crate) fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

impl AtomicFile {
    /// Creates the temporary file in `path`'s directory (an error naming `path` when it cannot).
    pub fn create(path: &Path) -> Result<Self, IoError> {
        let temp = tempfile::Builder::new()
            .prefix(TEMP_PREFIX)
            .tempfile_in(parent_dir(path))
            .map_err(|e| temp_error(path, parent_dir(path), &e))?;
        let (file, temp_path) = temp.into_parts();
        Ok(Self {
            path: path.to_path_buf(),
            writer: BufWriter::with_capacity(1 << 20, file),
            temp_path,
        })
    }

    /// The target path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The buffered temporary file.
    pub fn writer(&mut self) -> &mut BufWriter<File> {
        &mut self.writer
    }

    /// Flushes, syncs and renames the temporary file over the target.
    pub fn commit(self) -> Result<(), IoError> {
        let Self {
            path,
            writer,
            temp_path,
        } = self;
        let file = writer
            .into_inner()
            .map_err(|e| IoError::io(&path, e.into_error()))?;
        set_output_mode(&file, &path).map_err(|e| IoError::io(&path, e))?;
        file.sync_all().map_err(|e| IoError::io(&path, e))?;
        drop(file);
        temp_path
            .persist(&path)
            .map_err(|e| IoError::io(&path, e.error))?;
        Ok(())
    }
}

/// Files that appear in a folder together or not at all (an exported sequence): each is written
/// into a hidden temporary folder inside `dir` ([`StagedFiles::stage`]) and [`StagedFiles::commit`]
/// renames them into `dir` in the order staged (so a file staged last, such as an index, appears
/// last). Dropped without a commit, the temporary folder and all in it are removed, and `dir` too
/// when this created it and it is still empty.
pub struct StagedFiles {
    dir: PathBuf,
    temp: Option<tempfile::TempDir>,
    names: Vec<String>,
    created_dir: bool,
}

impl StagedFiles {
    /// Creates `dir` (and its parents) when missing and the temporary folder in it.
    pub fn create(dir: &Path) -> Result<Self, IoError> {
        let created_dir = !dir.exists();
        std::fs::create_dir_all(dir).map_err(|e| IoError::io(dir, e))?;
        let mut staged = Self {
            dir: dir.to_path_buf(),
            temp: None,
            names: Vec::new(),
            created_dir,
        };
        staged.temp = Some(
            tempfile::Builder::new()
                .prefix(TEMP_PREFIX)
                .tempdir_in(dir)
                .map_err(|e| temp_error(dir, dir, &e))?,
        );
        Ok(staged)
    }

    /// Where to write the file that is to become `dir/name` (a plain file name).
    pub fn stage(&mut self, name: &str) -> PathBuf {
        self.names.push(name.to_string());
        self.temp_dir().join(name)
    }

    /// `e`, an error about a staged file, as an error about the file it is to become: a message
    /// names what was asked for, not the hidden temporary folder. Other errors are unchanged.
    pub fn named_as_target(&self, e: IoError) -> IoError {
        match self.target_of(e.path()) {
            Some(target) => e.with_path(target),
            None => e,
        }
    }

    /// The file a staged `path` is to become (`None` for a path that is not staged here).
    pub fn target_of(&self, path: &Path) -> Option<PathBuf> {
        let temp = self.temp.as_ref()?;
        let name = path.strip_prefix(temp.path()).ok()?;
        Some(self.dir.join(name))
    }

    fn temp_dir(&self) -> &Path {
        self.temp.as_ref().map_or(&self.dir, |t| t.path())
    }

    /// Renames every staged file into `dir`, in the order staged, and removes the temporary
    /// folder.
    pub fn commit(mut self) -> Result<(), IoError> {
        for name in &self.names {
            let target = self.dir.join(name);
            std::fs::rename(self.temp_dir().join(name), &target)
                .map_err(|e| IoError::io(&target, e))?;
        }
        if let Some(temp) = self.temp.take() {
            let path = temp.path().to_path_buf();
            temp.close().map_err(|e| IoError::io(path, e))?;
        }
        self.created_dir = false;
        Ok(())
    }
}

impl Drop for StagedFiles {
    fn drop(&mut self) {
        drop(self.temp.take());
        if self.created_dir {
            // Only succeeds when empty: what was there before, or was renamed in, stays.
            let _ = std::fs::remove_dir(&self.dir);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    /// Writing into a missing folder names the file asked for and the folder, never the
    /// temporary file's name.
    #[test]
    fn a_missing_folder_is_named_not_the_temporary_file() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("nodir/x.png");
        let e = write_atomically(&target, |_| Ok(()))
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with(&target.display().to_string()) && e.contains("no such folder"),
            "{e}"
        );
        assert!(!e.contains(TEMP_PREFIX), "{e}");
    }

    /// An error about a staged file names the file it was to become, never the hidden folder;
    /// an error about any other file is left as it was.
    #[test]
    fn staged_errors_name_their_target() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("seq");
        let mut staged = StagedFiles::create(&out).unwrap();
        let path = staged.stage("frame_0000.splat");
        let cause = || std::io::Error::other("disk full");
        let e = staged.named_as_target(IoError::io(&path, cause()));
        assert_eq!(e.path(), out.join("frame_0000.splat"));
        assert_eq!(
            e.to_string(),
            format!("{}: disk full", out.join("frame_0000.splat").display())
        );
        let elsewhere = dir.path().join("other.ply");
        let e = staged.named_as_target(IoError::io(&elsewhere, cause()));
        assert_eq!(e.path(), elsewhere);
        assert_eq!(staged.target_of(&elsewhere), None);
    }

    #[test]
    fn failed_fill_leaves_existing_file_and_no_temp_files() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out.txt");
        std::fs::write(&target, b"old").unwrap();
        let result = write_atomically(&target, |w| {
            w.write_all(b"half").unwrap();
            Err(IoError::InvalidData {
                path: target.clone(),
                problem: "stop".into(),
            })
        });
        assert!(result.is_err());
        assert_eq!(std::fs::read(&target).unwrap(), b"old");
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(names.len(), 1, "temporary file left behind");
    }

    #[test]
    fn successful_write_replaces_file_and_relative_paths_work() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out.txt");
        std::fs::write(&target, b"old").unwrap();
        write_atomically(&target, |w| {
            w.write_all(b"new").map_err(|e| IoError::io(&target, e))
        })
        .unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"new");
    }

    #[test]
    fn staged_files_appear_together_or_not_at_all() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("seq/inner");
        let names = |p: &Path| -> Vec<String> {
            let mut n: Vec<String> = std::fs::read_dir(p)
                .unwrap()
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect();
            n.sort();
            n
        };
        // Abandoned half way: nothing left, not even the folder it created.
        {
            let mut staged = StagedFiles::create(&out).unwrap();
            let a = staged.stage("a.bin");
            write_atomically(&a, |w| w.write_all(b"a").map_err(|e| IoError::io(&a, e))).unwrap();
            assert!(!out.join("a.bin").exists());
        }
        assert!(!out.exists());
        // Committed: both files, no temporary folder.
        let mut staged = StagedFiles::create(&out).unwrap();
        for name in ["a.bin", "index.json"] {
            let p = staged.stage(name);
            std::fs::write(&p, name).unwrap();
        }
        staged.commit().unwrap();
        assert_eq!(names(&out), ["a.bin", "index.json"]);
        // Abandoned in an existing folder: the folder and its files stay as they were.
        let mut staged = StagedFiles::create(&out).unwrap();
        std::fs::write(staged.stage("a.bin"), b"new").unwrap();
        drop(staged);
        assert_eq!(names(&out), ["a.bin", "index.json"]);
        assert_eq!(std::fs::read(out.join("a.bin")).unwrap(), b"a.bin");
    }

    #[cfg(unix)]
    #[test]
    fn new_files_get_0644_and_replaced_files_keep_their_mode() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o7777;
        let fresh = dir.path().join("fresh.bin");
        write_atomically(&fresh, |w| {
            w.write_all(b"x").map_err(|e| IoError::io(&fresh, e))
        })
        .unwrap();
        assert_eq!(mode(&fresh), 0o644);
        let kept = dir.path().join("kept.bin");
        std::fs::write(&kept, b"old").unwrap();
        std::fs::set_permissions(&kept, std::fs::Permissions::from_mode(0o600)).unwrap();
        write_atomically(&kept, |w| {
            w.write_all(b"y").map_err(|e| IoError::io(&kept, e))
        })
        .unwrap();
        assert_eq!(mode(&kept), 0o600);
    }
}
