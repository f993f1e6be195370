//! Reading back `ground_truth.safetensors` (the layout is documented in [`write_dnerf`](super::write_dnerf)).

use std::path::Path;

use safetensors::{Dtype, SafeTensors};

use super::{Part, SynthError, Trajectories};

fn decode_error(path: &Path, field: &str, problem: impl Into<String>) -> SynthError {
    SynthError::Decode {
        path: path.to_path_buf(),
        field: field.to_string(),
        problem: problem.into(),
    }
}

/// Reads a tensor's f32 values, checking dtype, shape and finiteness.
fn f32_tensor(
    st: &SafeTensors<'_>,
    path: &Path,
    name: &str,
    shape: &[usize],
) -> Result<Vec<f32>, SynthError> {
    let view = st
        .tensor(name)
        .map_err(|e| decode_error(path, name, e.to_string()))?;
    if view.dtype() != Dtype::F32 {
        return Err(decode_error(
            path,
            name,
            format!("dtype {} is not F32", view.dtype()),
        ));
    }
    if view.shape() != shape {
        return Err(decode_error(
            path,
            name,
            format!("shape {:?}, expected {shape:?}", view.shape()),
        ));
    }
    let values: Vec<f32> = view
        .data()
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(decode_error(
            path,
            name,
            format!("non-finite value at element {i}"),
        ));
    }
    Ok(values)
}

fn rows<const K: usize>(values: &[f32], n: usize) -> Vec<Vec<[f32; K]>> {
    values
        .chunks_exact((n * K).max(1))
        .map(|frame| {
            frame
                .chunks_exact(K)
                .map(|c| std::array::from_fn(|k| c[k]))
                .collect()
        })
        .collect()
}

/// Reads the trajectories and the per-Gaussian parts written by `write_dnerf`. Errors name the
/// file and the tensor.
pub fn read_ground_truth(path: &Path) -> Result<(Trajectories, Vec<Part>), SynthError> {
    let bytes = std::fs::read(path).map_err(|cause| evogs_io::IoError::Io {
        path: path.to_path_buf(),
        cause,
    })?;
    let st = SafeTensors::deserialize(&bytes)
        .map_err(|e| decode_error(path, "header", e.to_string()))?;
    let parts_view = st
        .tensor("parts")
        .map_err(|e| decode_error(path, "parts", e.to_string()))?;
    if parts_view.dtype() != Dtype::U8 || parts_view.shape().len() != 1 {
        return Err(decode_error(path, "parts", "expected a U8 vector"));
    }
    let parts = parts_view
        .data()
        .iter()
        .enumerate()
        .map(|(i, &p)| match p {
            0 => Ok(Part::Body),
            1 => Ok(Part::Satellite),
            2 => Ok(Part::Occluder),
            other => Err(decode_error(
                path,
                "parts",
                format!("value {other} at {i} is not 0, 1 or 2"),
            )),
        })
        .collect::<Result<Vec<_>, _>>()?;
    let n = parts.len();
    let t = st
        .tensor("times")
        .map_err(|e| decode_error(path, "times", e.to_string()))?
        .shape()
        .first()
        .copied()
        .unwrap_or(0);
    let times = f32_tensor(&st, path, "times", &[t])?;
    if times.windows(2).any(|w| w[0] >= w[1]) {
        return Err(decode_error(path, "times", "not strictly increasing"));
    }
    let means = rows::<3>(&f32_tensor(&st, path, "means", &[t, n, 3])?, n);
    let has = |name: &str| st.names().contains(&name);
    let rotations = if has("rotations") {
        Some(rows::<4>(
            &f32_tensor(&st, path, "rotations", &[t, n, 4])?,
            n,
        ))
    } else {
        None
    };
    let sh_dc = if has("sh_dc") {
        Some(rows::<3>(&f32_tensor(&st, path, "sh_dc", &[t, n, 3])?, n))
    } else {
        None
    };
    Ok((
        Trajectories {
            times,
            means,
            rotations,
            sh_dc,
        },
        parts,
    ))
}
