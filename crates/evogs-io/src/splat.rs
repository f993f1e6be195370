//! The `.splat` format of web viewers (antimatter15/splat and its descendants): 32 bytes per
//! Gaussian, little-endian, no header.
//!
//! | bytes | content |
//! | --- | --- |
//! | 0..12 | mean `x, y, z`, f32 |
//! | 12..24 | scale `exp(log_scale)` per axis, f32 |
//! | 24..28 | colour `r, g, b` = `clamp(0.5 + SH_C0 · dc, 0, 1) · 255` rounded, opacity `sigmoid(logit) · 255` rounded, u8 |
//! | 28..32 | unit quaternion `w, x, y, z` as `clamp(round(q · 128 + 128), 0, 255)`, u8 |
//!
//! What it loses: every SH band above the DC (view-dependent colour), colour and opacity below
//! 1/255 (colours outside [0, 1] are clamped), and rotation precision (1/128 per component).
//! Written in the order the format's reference converter uses, largest `volume · opacity`
//! first (`exp(Σ log_scale) · sigmoid(logit)`, descending; ties keep their order).

use std::io::Write;
use std::path::Path;

use splat_core::sh::{SH_C0, dc_from_rgb};
use splat_core::{Gaussians, GaussiansView, logit, sigmoid};

use crate::IoError;
use crate::atomic::write_atomically;
use crate::image_io::to_u8;

/// Bytes per Gaussian.
pub const SPLAT_BYTES: usize = 32;

/// Writes `g` as a `.splat` file atomically (see the module docs); returns the number written.
/// Gaussians with a non-finite value are left out.
pub fn write_splat(path: &Path, g: GaussiansView<'_>) -> Result<usize, IoError> {
    let stride = g.sh_stride();
    let finite = |i: usize| {
        g.means[i]
            .iter()
            .chain(&g.log_scales[i])
            .chain(&g.rotations[i])
            .all(|v| v.is_finite())
            && g.opacity_logits[i].is_finite()
            && g.sh[i * stride..i * stride + 3]
                .iter()
                .all(|v| v.is_finite())
    };
    let key = |i: usize| (g.log_scales[i].iter().sum::<f32>()).exp() * sigmoid(g.opacity_logits[i]);
    let mut order: Vec<usize> = (0..g.len()).filter(|&i| finite(i)).collect();
    order.sort_by(|&a, &b| key(b).total_cmp(&key(a)));
    write_atomically(path, |w| {
        for &i in &order {
            let mut rec = [0u8; SPLAT_BYTES];
            for k in 0..3 {
                rec[4 * k..4 * k + 4].copy_from_slice(&g.means[i][k].to_le_bytes());
                rec[12 + 4 * k..16 + 4 * k]
                    .copy_from_slice(&g.log_scales[i][k].exp().to_le_bytes());
                rec[24 + k] = to_u8(0.5 + SH_C0 * g.sh[i * stride + k]);
            }
            rec[27] = to_u8(sigmoid(g.opacity_logits[i]));
            let q = g.rotations[i];
            let n = q.iter().map(|v| v * v).sum::<f32>().sqrt();
            for k in 0..4 {
                let v = if n > 0.0 {
                    q[k] / n
                } else if k == 0 {
                    1.0
                } else {
                    0.0
                };
                rec[28 + k] = (v * 128.0 + 128.0).round().clamp(0.0, 255.0) as u8;
            }
            w.write_all(&rec).map_err(|e| IoError::io(path, e))?;
        }
        Ok(())
    })?;
    Ok(order.len())
}

/// Reads a `.splat` file into Gaussians of SH degree 0 (the inverse of each field's encoding:
/// log of the scales, `dc_from_rgb` of the colours, logit of the opacity clamped to
/// [0.5/255, 1 − 0.5/255], the quaternion `(byte − 128) / 128`).
pub fn read_splat(path: &Path) -> Result<Gaussians, IoError> {
    let bytes = std::fs::read(path).map_err(|e| IoError::io(path, e))?;
    if bytes.len() % SPLAT_BYTES != 0 {
        return Err(IoError::InvalidData {
            path: path.to_path_buf(),
            problem: format!(
                "{} bytes is not a whole number of {SPLAT_BYTES}-byte Gaussians",
                bytes.len()
            ),
        });
    }
    let mut g = Gaussians::with_degree(0);
    for rec in bytes.chunks_exact(SPLAT_BYTES) {
        let f = |at: usize| f32::from_le_bytes([rec[at], rec[at + 1], rec[at + 2], rec[at + 3]]);
        g.means.push([f(0), f(4), f(8)]);
        g.log_scales.push([f(12).ln(), f(16).ln(), f(20).ln()]);
        g.sh.extend((0..3).map(|k| dc_from_rgb(rec[24 + k] as f32 / 255.0)));
        let a = (rec[27] as f32 / 255.0).clamp(0.5 / 255.0, 1.0 - 0.5 / 255.0);
        g.opacity_logits.push(logit(a));
        g.rotations
            .push([0, 1, 2, 3].map(|k| (rec[28 + k] as f32 - 128.0) / 128.0));
    }
    Ok(g)
}
