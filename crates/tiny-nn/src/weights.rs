//! Saving and loading parameters as safetensors files, bit-exact.
//!
//! Every parameter buffer is one 1-D tensor named by its module path (for example
//! `mlp.params`, `triplane.params`), stored as `F32` or `F16` according to the module's storage
//! precision, little-endian. Loading requires every tensor of the module to be present with the
//! same dtype and length and copies the bits unchanged. Files are written to a temporary file in
//! the same directory and renamed into place.

use std::collections::HashMap;
use std::io::Write;
use std::path::Path;

use half::f16;
use safetensors::tensor::{Dtype, SafeTensors, TensorView};

use crate::error::NnError;
use crate::precision::{StoreMut, StoreRef};

/// A module with named parameter buffers.
pub trait Parameters {
    /// The named buffers (read-only), in a fixed order.
    fn named_params(&self) -> Vec<(String, StoreRef<'_>)>;
    /// The same buffers, mutable, same names and order.
    fn named_params_mut(&mut self) -> Vec<(String, StoreMut<'_>)>;
}

fn le_bytes(s: StoreRef<'_>) -> (Dtype, Vec<u8>) {
    match s {
        StoreRef::F32(v) => (Dtype::F32, v.iter().flat_map(|x| x.to_le_bytes()).collect()),
        StoreRef::F16(v) => (Dtype::F16, v.iter().flat_map(|x| x.to_le_bytes()).collect()),
    }
}

/// Writes every parameter of `module` to `path` (temporary file, then rename).
pub fn save(path: &Path, module: &impl Parameters) -> Result<(), NnError> {
    let file_err = |field: &str, msg: String| NnError::File {
        path: path.to_path_buf(),
        field: field.to_string(),
        msg,
    };
    let bufs: Vec<(String, Dtype, usize, Vec<u8>)> = module
        .named_params()
        .into_iter()
        .map(|(name, s)| {
            let len = s.len();
            let (dt, bytes) = le_bytes(s);
            (name, dt, len, bytes)
        })
        .collect();
    let mut views = Vec::with_capacity(bufs.len());
    for (name, dt, len, bytes) in &bufs {
        let view = TensorView::new(*dt, vec![*len], bytes)
            .map_err(|e| file_err(name, format!("cannot describe tensor: {e}")))?;
        views.push((name.clone(), view));
    }
    let mut meta = HashMap::new();
    meta.insert("format".to_string(), "tiny-nn".to_string());
    let data = safetensors::serialize(views, Some(meta))
        .map_err(|e| file_err("header", format!("cannot serialise: {e}")))?;
    let io_err = |source| NnError::Io {
        path: path.to_path_buf(),
        source,
    };
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    // The prefix of evogs-io's atomic writes, so that a run directory's clean-up after a kill
    // finds this file too.
    let mut tmp = tempfile::Builder::new()
        .prefix(".evogs-tmp-")
        .tempfile_in(dir)
        .map_err(io_err)?;
    // Through the plain file: the temporary file's own writer adds its random name to errors.
    tmp.as_file_mut().write_all(&data).map_err(io_err)?;
    set_output_mode(tmp.as_file(), path).map_err(io_err)?;
    tmp.as_file().sync_all().map_err(io_err)?;
    tmp.persist(path).map_err(|e| io_err(e.error))?;
    Ok(())
}

/// Temporary files are created private (0600): gives `file`, about to be renamed over `target`,
/// the mode an existing `target` has, or the usual 0644 for a new one (a no-op off Unix). The
/// same rule as evogs-io's atomic writes (`evogs_io::atomic`), for the files written here and by
/// evo-state (which sits below evogs-io).
pub fn set_output_mode(file: &std::fs::File, target: &Path) -> std::io::Result<()> {
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

/// Reads `path` into the parameters of `module` (same names, dtypes and lengths), bit-exact.
pub fn load(path: &Path, module: &mut impl Parameters) -> Result<(), NnError> {
    let bytes = std::fs::read(path).map_err(|source| NnError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let file_err = |field: &str, msg: String| NnError::File {
        path: path.to_path_buf(),
        field: field.to_string(),
        msg,
    };
    let st = SafeTensors::deserialize(&bytes)
        .map_err(|e| file_err("header", format!("not a safetensors file: {e}")))?;
    for (name, dst) in module.named_params_mut() {
        let t = st
            .tensor(&name)
            .map_err(|e| file_err(&name, format!("missing tensor ({e})")))?;
        let want = match dst {
            StoreMut::F32(_) => Dtype::F32,
            StoreMut::F16(_) => Dtype::F16,
        };
        if t.dtype() != want {
            return Err(file_err(
                &name,
                format!("dtype {:?}, but the network stores {want:?}", t.dtype()),
            ));
        }
        if t.shape() != [dst.len()] {
            return Err(file_err(
                &name,
                format!("shape {:?}, but the network has [{}]", t.shape(), dst.len()),
            ));
        }
        let data = t.data();
        match dst {
            StoreMut::F32(v) => {
                for (x, b) in v.iter_mut().zip(data.chunks_exact(4)) {
                    *x = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
                }
            }
            StoreMut::F16(v) => {
                for (x, b) in v.iter_mut().zip(data.chunks_exact(2)) {
                    *x = f16::from_le_bytes([b[0], b[1]]);
                }
            }
        }
    }
    Ok(())
}
