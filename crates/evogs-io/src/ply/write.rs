//! Writing 3DGS PLY files: binary little-endian float32 in the original property order.

use std::io::Write;
use std::path::Path;

use splat_core::GaussiansView;

use super::layout::{property_names, rest_count};
use crate::IoError;
use crate::atomic::write_atomically;

/// The header 3DGS writes for `count` Gaussians at an SH degree, `end_header` line included.
pub fn ply_header(count: usize, degree: u32) -> String {
    let mut header = format!("ply\nformat binary_little_endian 1.0\nelement vertex {count}\n");
    for name in property_names(degree) {
        header.push_str("property float ");
        header.push_str(&name);
        header.push('\n');
    }
    header.push_str("end_header\n");
    header
}

/// Writes Gaussians to `writer` in the 3DGS layout (DESIGN §2.2): normals zero, `f_rest` channel-major,
/// raw values bit for bit. `path` only names the destination in errors.
pub fn write_ply_to<W: Write>(
    writer: &mut W,
    gaussians: GaussiansView<'_>,
    path: &Path,
) -> Result<(), IoError> {
    gaussians
        .check_lengths()
        .map_err(|e| IoError::InvalidData {
            path: path.to_path_buf(),
            problem: e.to_string(),
        })?;
    let degree = gaussians.sh_degree;
    let coeffs = splat_core::sh_coeff_count(degree);
    let stride = gaussians.sh_stride();
    let floats_per_row = 14 + rest_count(degree);
    let io = |e| IoError::io(path, e);
    writer
        .write_all(ply_header(gaussians.len(), degree).as_bytes())
        .map_err(io)?;
    const ROWS_PER_CHUNK: usize = 4096;
    let mut buf: Vec<u8> = Vec::with_capacity(ROWS_PER_CHUNK * floats_per_row * 4);
    for start in (0..gaussians.len()).step_by(ROWS_PER_CHUNK) {
        buf.clear();
        let end = (start + ROWS_PER_CHUNK).min(gaussians.len());
        for i in start..end {
            let mut put = |v: f32| buf.extend_from_slice(&v.to_le_bytes());
            gaussians.means[i].iter().copied().for_each(&mut put);
            (0..3).for_each(|_| put(0.0));
            let sh = &gaussians.sh[i * stride..(i + 1) * stride];
            sh[..3].iter().copied().for_each(&mut put);
            for channel in 0..3 {
                for coeff in 1..coeffs {
                    put(sh[coeff * 3 + channel]);
                }
            }
            put(gaussians.opacity_logits[i]);
            gaussians.log_scales[i].iter().copied().for_each(&mut put);
            gaussians.rotations[i].iter().copied().for_each(&mut put);
        }
        writer.write_all(&buf).map_err(io)?;
    }
    Ok(())
}

/// Writes Gaussians to a PLY file atomically (a temporary file in the same directory, renamed
/// into place).
pub fn write_ply(path: &Path, gaussians: GaussiansView<'_>) -> Result<(), IoError> {
    // Check before creating the temporary file, so bad data leaves no trace at all.
    gaussians
        .check_lengths()
        .map_err(|e| IoError::InvalidData {
            path: path.to_path_buf(),
            problem: e.to_string(),
        })?;
    write_atomically(path, |w| write_ply_to(w, gaussians, path))
}
