//! PlayCanvas/SuperSplat's compressed PLY (as written by `splat-transform` and SuperSplat, read by
//! the PlayCanvas engine): Gaussians quantised in chunks of [`CHUNK_SIZE`], about 16 bytes each at
//! SH degree 0 against 68 for the 3DGS PLY.
//!
//! The file is binary little-endian PLY with three elements, in this order:
//!
//! | element | rows | properties |
//! | --- | --- | --- |
//! | `chunk` | `ceil(n / 256)` | 18 `float`: [`CHUNK_PROPERTIES`], the chunk's least and greatest mean, log-scale (clamped to ±20) and DC colour `0.5 + SH_C0 · f_dc` per axis or channel |
//! | `vertex` | `n` | 4 `uint`: [`VERTEX_PROPERTIES`] |
//! | `sh` (SH degree > 0 only) | `n` | `uchar f_rest_0 …` (9, 24 or 45, channel-major as in the 3DGS PLY) |
//!
//! Vertex `i` belongs to chunk `i / 256`; its words are `packed_position` (mean, normalised to the
//! chunk's bounds, 11-10-11 bits), `packed_rotation` (`rot_0..3` = `w x y z` normalised, the largest
//! component dropped: its index in 2 bits and the other three in 10 bits each), `packed_scale` (log
//! scale normalised to the chunk's bounds, 11-10-11 bits) and `packed_color` (DC colour normalised
//! to the chunk's bounds and `sigmoid(opacity)`, 8 bits each). Each higher SH coefficient is one
//! byte over [−4, 4] ([`pack`]).
//!
//! What it loses, per chunk of 256: positions to 1/2047 of the chunk's extent in x and z and
//! 1/1023 in y; log scales to 1/2047 (x, z) and 1/1023 (y) of their range, scales below `e^−20`
//! raised to it; colour to 1/255 of the chunk's colour range and opacity to 1/255; rotation
//! components to about 1.4e-3; higher SH coefficients to 1/32 and clamped to [−4, 4].
//!
//! The writer stores Gaussians in Morton order ([`morton::sort_morton`] over all means), as
//! PlayCanvas's writers do, so that each chunk is spatially compact; SuperSplat recognises the
//! format by the file name ending `.compressed.ply`. The reader accepts what the PlayCanvas engine
//! accepts: 12 chunk properties (no colour bounds, colour then absolute) or 18.

pub mod morton;
pub mod pack;

use std::path::Path;

use splat_core::sh::{dc_from_rgb, rgb_from_dc};
use splat_core::{Gaussians, GaussiansView, logit, sh_coeff_count, sigmoid};

use crate::IoError;
use crate::atomic::write_atomically;
use crate::ply::{Element, Encoding, PlyProblem, PropertyKind, ScalarType, parse_header_lines};
use pack::{
    lerp, normalise, pack_11_10_11, pack_8888, pack_rotation, pack_sh, unpack_11_10_11,
    unpack_8888, unpack_rotation, unpack_sh,
};

/// Gaussians per chunk.
pub const CHUNK_SIZE: usize = 256;

/// The `chunk` element's `float` properties, in the order PlayCanvas writes them (the last six,
/// the colour bounds, are optional for the reader).
pub const CHUNK_PROPERTIES: [&str; 18] = [
    "min_x",
    "min_y",
    "min_z",
    "max_x",
    "max_y",
    "max_z",
    "min_scale_x",
    "min_scale_y",
    "min_scale_z",
    "max_scale_x",
    "max_scale_y",
    "max_scale_z",
    "min_r",
    "min_g",
    "min_b",
    "max_r",
    "max_g",
    "max_b",
];

/// The `vertex` element's `uint` properties.
pub const VERTEX_PROPERTIES: [&str; 4] = [
    "packed_position",
    "packed_rotation",
    "packed_scale",
    "packed_color",
];

/// Log scales are clamped to ±this in the chunk bounds (PlayCanvas's writer's limit).
pub const LOG_SCALE_LIMIT: f32 = 20.0;

/// Headers longer than this are rejected (ours is about 1 KiB).
const HEADER_LIMIT: usize = 1 << 16;

/// Higher SH coefficients (`f_rest_*`) per Gaussian at an SH degree.
fn rest_count(degree: u32) -> usize {
    3 * (sh_coeff_count(degree) - 1)
}

/// The header written for `count` Gaussians at an SH degree, `end_header` line included.
pub fn compressed_ply_header(count: usize, degree: u32) -> String {
    let mut h = String::from("ply\nformat binary_little_endian 1.0\n");
    h.push_str("comment evogs: PlayCanvas compressed PLY, 256 Gaussians a chunk, Morton order\n");
    h.push_str(&format!("element chunk {}\n", count.div_ceil(CHUNK_SIZE)));
    for name in CHUNK_PROPERTIES {
        h.push_str(&format!("property float {name}\n"));
    }
    h.push_str(&format!("element vertex {count}\n"));
    for name in VERTEX_PROPERTIES {
        h.push_str(&format!("property uint {name}\n"));
    }
    if degree > 0 {
        h.push_str(&format!("element sh {count}\n"));
        for k in 0..rest_count(degree) {
            h.push_str(&format!("property uchar f_rest_{k}\n"));
        }
    }
    h.push_str("end_header\n");
    h
}

/// The size in bytes of the file [`write_compressed_ply`] writes for `count` Gaussians at an SH
/// degree: the header, 72 bytes a chunk, 16 bytes a Gaussian and one byte per higher SH
/// coefficient.
pub fn compressed_ply_len(count: usize, degree: u32) -> u64 {
    let header = compressed_ply_header(count, degree).len();
    (header + 72 * count.div_ceil(CHUNK_SIZE) + (16 + rest_count(degree)) * count) as u64
}

/// The least and greatest of each component.
fn bounds(values: impl Iterator<Item = [f32; 3]>) -> ([f32; 3], [f32; 3]) {
    values.fold(
        ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]),
        |(lo, hi), v| {
            (
                [0, 1, 2].map(|k| lo[k].min(v[k])),
                [0, 1, 2].map(|k| hi[k].max(v[k])),
            )
        },
    )
}

/// Writes `g` as a compressed PLY atomically (see the module docs); returns the number written.
/// Gaussians with a NaN, or an infinite mean, rotation or SH coefficient, are left out; infinite
/// log scales and opacity logits are kept (clamped to ±20, opacity 0 or 1).
pub fn write_compressed_ply(path: &Path, g: GaussiansView<'_>) -> Result<usize, IoError> {
    g.check_lengths().map_err(|e| IoError::InvalidData {
        path: path.to_path_buf(),
        problem: e.to_string(),
    })?;
    let stride = g.sh_stride();
    let coeffs = sh_coeff_count(g.sh_degree);
    let rest = rest_count(g.sh_degree);
    let kept = |i: usize| {
        g.means[i].iter().all(|v| v.is_finite())
            && g.rotations[i].iter().all(|v| v.is_finite())
            && g.sh[i * stride..(i + 1) * stride]
                .iter()
                .all(|v| v.is_finite())
            && !g.log_scales[i].iter().any(|v| v.is_nan())
            && !g.opacity_logits[i].is_nan()
    };
    let mut order: Vec<usize> = (0..g.len()).filter(|&i| kept(i)).collect();
    morton::sort_morton(g.means, &mut order);
    let colour = |i: usize| [0, 1, 2].map(|k| rgb_from_dc(g.sh[i * stride + k]));

    let header = compressed_ply_header(order.len(), g.sh_degree);
    let mut chunks = Vec::with_capacity(72 * order.len().div_ceil(CHUNK_SIZE));
    let mut vertices = Vec::with_capacity(16 * order.len());
    let mut sh = Vec::with_capacity(rest * order.len());
    for members in order.chunks(CHUNK_SIZE) {
        let (p_lo, p_hi) = bounds(members.iter().map(|&i| g.means[i]));
        let (s_lo, s_hi) = bounds(members.iter().map(|&i| g.log_scales[i]));
        let clamp = |v: [f32; 3]| v.map(|s| s.clamp(-LOG_SCALE_LIMIT, LOG_SCALE_LIMIT));
        let (s_lo, s_hi) = (clamp(s_lo), clamp(s_hi));
        let (c_lo, c_hi) = bounds(members.iter().map(|&i| colour(i)));
        for v in [p_lo, p_hi, s_lo, s_hi, c_lo, c_hi].iter().flatten() {
            chunks.extend_from_slice(&v.to_le_bytes());
        }
        let fraction = |v: [f32; 3], lo: [f32; 3], hi: [f32; 3]| {
            [0, 1, 2].map(|k| normalise(v[k], lo[k], hi[k]))
        };
        for &i in members {
            let c = fraction(colour(i), c_lo, c_hi);
            let words = [
                pack_11_10_11(fraction(g.means[i], p_lo, p_hi)),
                pack_rotation(g.rotations[i]),
                pack_11_10_11(fraction(g.log_scales[i], s_lo, s_hi)),
                pack_8888([c[0], c[1], c[2], sigmoid(g.opacity_logits[i])]),
            ];
            for w in words {
                vertices.extend_from_slice(&w.to_le_bytes());
            }
            let coefficients = &g.sh[i * stride..(i + 1) * stride];
            for channel in 0..3 {
                for coeff in 1..coeffs {
                    sh.push(pack_sh(coefficients[coeff * 3 + channel]));
                }
            }
        }
    }
    write_atomically(path, |w| {
        use std::io::Write;
        for part in [header.as_bytes(), &chunks, &vertices, &sh] {
            w.write_all(part).map_err(|e| IoError::io(path, e))?;
        }
        Ok(())
    })?;
    Ok(order.len())
}

/// Reads a compressed PLY file (see the module docs) into Gaussians in file order, SH degree from
/// the `sh` element (0 without one). Opacity bytes 0 and 255 read as 0.5/255 and 1 − 0.5/255 so
/// that every logit is finite.
pub fn read_compressed_ply(path: &Path) -> Result<Gaussians, IoError> {
    let bytes = std::fs::read(path).map_err(|e| IoError::io(path, e))?;
    read_compressed_ply_bytes(&bytes, path)
}

/// Reads a compressed PLY file held in memory; `name` is used in error messages.
pub fn read_compressed_ply_bytes(bytes: &[u8], name: &Path) -> Result<Gaussians, IoError> {
    let ply = |problem| IoError::Ply {
        path: name.to_path_buf(),
        problem,
    };
    let field = |field: String, problem: String| IoError::field(name, field, problem);
    if bytes.is_empty() {
        return Err(ply(PlyProblem::Empty));
    }
    if !bytes.starts_with(b"ply\n") && !bytes.starts_with(b"ply\r\n") {
        return Err(ply(PlyProblem::NotPly));
    }
    const END: &[u8] = b"end_header\n";
    let head = &bytes[..bytes.len().min(HEADER_LIMIT)];
    let end = head
        .windows(END.len())
        .position(|w| w == END)
        .filter(|&at| at == 0 || head[at - 1] == b'\n')
        .ok_or(ply(PlyProblem::UnterminatedHeader {
            limit: HEADER_LIMIT,
        }))?;
    let lines: Vec<String> = String::from_utf8_lossy(&bytes[..end])
        .lines()
        .map(str::to_string)
        .collect();
    let header = parse_header_lines(&lines).map_err(ply)?;
    if header.encoding != Encoding::BinaryLittleEndian {
        return Err(field(
            "format".into(),
            format!(
                "{}; a compressed PLY is binary_little_endian",
                match header.encoding {
                    Encoding::Ascii => "ascii",
                    _ => "binary_big_endian",
                }
            ),
        ));
    }
    let element_names: Vec<&str> = header.elements.iter().map(|e| e.name.as_str()).collect();
    let (chunk, vertex, sh) = match &header.elements[..] {
        [c, v] if element_names == ["chunk", "vertex"] => (c, v, None),
        [c, v, s] if element_names == ["chunk", "vertex", "sh"] => (c, v, Some(s)),
        _ => {
            return Err(field(
                "element".into(),
                format!(
                    "found `{}`; a compressed PLY has `chunk`, `vertex` and an optional `sh`, in this order",
                    element_names.join("`, `")
                ),
            ));
        }
    };

    let chunk_at = offsets(name, chunk, ScalarType::F32, &CHUNK_PROPERTIES)?;
    let has_colour = match chunk_at[12..].iter().filter(|o| o.is_some()).count() {
        0 => false,
        6 => true,
        _ => {
            return Err(field(
                "chunk".into(),
                "has some of the colour bounds min_r … max_b; expected all six or none".into(),
            ));
        }
    };
    let vertex_at = offsets(name, vertex, ScalarType::U32, &VERTEX_PROPERTIES)?;
    for (at, property) in chunk_at[..12]
        .iter()
        .zip(CHUNK_PROPERTIES)
        .chain(vertex_at.iter().zip(VERTEX_PROPERTIES))
    {
        if at.is_none() {
            let element = if VERTEX_PROPERTIES.contains(&property) {
                "vertex"
            } else {
                "chunk"
            };
            return Err(field(format!("{element}.{property}"), "missing".into()));
        }
    }
    let (degree, sh_at) = match sh {
        None => (0, Vec::new()),
        Some(sh) => {
            let Some(degree) = (1..=3).find(|&d| rest_count(d) == sh.properties.len()) else {
                return Err(field(
                    "sh".into(),
                    format!(
                        "{} properties; expected 9, 24 or 45 (SH degree 1 to 3)",
                        sh.properties.len()
                    ),
                ));
            };
            let names: Vec<String> = (0..rest_count(degree))
                .map(|k| format!("f_rest_{k}"))
                .collect();
            let names: Vec<&str> = names.iter().map(String::as_str).collect();
            let at = offsets(name, sh, ScalarType::U8, &names)?;
            if sh.count != vertex.count {
                return Err(field(
                    "element sh".into(),
                    format!(
                        "{} rows; expected one per vertex, {}",
                        sh.count, vertex.count
                    ),
                ));
            }
            (degree, at.into_iter().map(|o| o.unwrap_or(0)).collect())
        }
    };
    if chunk.count != vertex.count.div_ceil(CHUNK_SIZE as u64) {
        return Err(field(
            "element chunk".into(),
            format!(
                "{} rows; {} vertices need {}",
                chunk.count,
                vertex.count,
                vertex.count.div_ceil(CHUNK_SIZE as u64)
            ),
        ));
    }

    // Check every element fits in the file before allocating anything.
    let mut body = &bytes[end + END.len()..];
    let mut rows = Vec::with_capacity(3);
    for element in &header.elements {
        let row = element.binary_row_size().unwrap_or(0);
        let needed = element.count as u128 * row as u128;
        if needed > body.len() as u128 {
            return Err(ply(PlyProblem::Truncated {
                element: element.name.clone(),
                count: element.count,
                needed,
                available: body.len() as u64,
            }));
        }
        let (data, rest) = body.split_at(needed as usize);
        rows.push((data, row));
        body = rest;
    }
    let f32_at = |b: &[u8], at: usize| f32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]);
    let u32_at = |b: &[u8], at: usize| u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]);

    let (chunk_data, chunk_row) = rows[0];
    let mut bounds = Vec::with_capacity(chunk.count as usize);
    for (c, row) in chunk_data.chunks_exact(chunk_row.max(1)).enumerate() {
        let mut b = [0.0f32; 18];
        for (k, at) in chunk_at.iter().enumerate() {
            let Some(at) = at else { continue };
            b[k] = f32_at(row, *at);
            if !b[k].is_finite() {
                return Err(field(
                    format!("chunk[{c}].{}", CHUNK_PROPERTIES[k]),
                    format!("{} is not finite", b[k]),
                ));
            }
        }
        bounds.push(b);
    }

    let (vertex_data, vertex_row) = rows[1];
    let n = vertex.count as usize;
    let mut g = Gaussians::with_degree(degree);
    g.means.reserve(n);
    g.log_scales.reserve(n);
    g.rotations.reserve(n);
    g.opacity_logits.reserve(n);
    g.sh.reserve(n * 3 * sh_coeff_count(degree));
    let coeffs = sh_coeff_count(degree);
    let mut coefficients = vec![0.0f32; 3 * coeffs];
    for (i, row) in vertex_data.chunks_exact(vertex_row.max(1)).enumerate() {
        let b = &bounds[i / CHUNK_SIZE];
        let [position, rotation, scale, colour] =
            [0, 1, 2, 3].map(|k| u32_at(row, vertex_at[k].unwrap_or(0)));
        let p = unpack_11_10_11(position);
        g.means.push([0, 1, 2].map(|k| lerp(b[k], b[3 + k], p[k])));
        let s = unpack_11_10_11(scale);
        g.log_scales
            .push([0, 1, 2].map(|k| lerp(b[6 + k], b[9 + k], s[k])));
        g.rotations.push(unpack_rotation(rotation));
        let c = unpack_8888(colour);
        let rgb = [0, 1, 2].map(|k| {
            if has_colour {
                lerp(b[12 + k], b[15 + k], c[k])
            } else {
                c[k]
            }
        });
        g.opacity_logits
            .push(logit(c[3].clamp(0.5 / 255.0, 1.0 - 0.5 / 255.0)));
        for k in 0..3 {
            coefficients[k] = dc_from_rgb(rgb[k]);
        }
        if let Some(&(sh_data, sh_row)) = rows.get(2) {
            let row = &sh_data[i * sh_row..(i + 1) * sh_row];
            for (j, &at) in sh_at.iter().enumerate() {
                let (channel, coeff) = (j / (coeffs - 1), 1 + j % (coeffs - 1));
                coefficients[coeff * 3 + channel] = unpack_sh(row[at]);
            }
        }
        g.sh.extend_from_slice(&coefficients);
    }
    Ok(g)
}

/// The byte offset within a row of each of `names` in `element` (`None` when absent), every
/// property being a `ty` scalar named in `names`.
fn offsets(
    path: &Path,
    element: &Element,
    ty: ScalarType,
    names: &[&str],
) -> Result<Vec<Option<usize>>, IoError> {
    let mut at = vec![None; names.len()];
    let mut offset = 0;
    for p in &element.properties {
        let field = format!("{}.{}", element.name, p.name);
        let Some(k) = names.iter().position(|n| *n == p.name) else {
            return Err(IoError::field(
                path,
                field,
                "not a property of the compressed PLY layout",
            ));
        };
        match p.kind {
            PropertyKind::Scalar(t) if t == ty => {}
            _ => {
                return Err(IoError::field(
                    path,
                    field,
                    format!("expected type {}", ty.name()),
                ));
            }
        }
        at[k] = Some(offset);
        offset += ty.size();
    }
    Ok(at)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_lists_chunk_vertex_and_sh_elements() {
        let h = compressed_ply_header(700, 1);
        assert!(h.contains("element chunk 3\n"));
        assert!(h.contains("element vertex 700\n"));
        assert!(h.contains("element sh 700\n"));
        assert!(h.contains("property uchar f_rest_8\n"));
        assert!(!h.contains("f_rest_9"));
        assert!(!compressed_ply_header(10, 0).contains("element sh"));
        assert_eq!(
            compressed_ply_len(700, 1) as usize,
            compressed_ply_header(700, 1).len() + 3 * 72 + 700 * (16 + 9)
        );
    }
}
