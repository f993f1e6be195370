//! A small, complete reader (and writer) for NumPy `.npy` arrays of floating-point numbers: format
//! versions 1.0, 2.0 and 3.0 (the header length is a `u16` in 1.0, a `u32` after), dtypes `<f4`
//! and `<f8` (and `>f4`/`>f8`), C and Fortran order. Values are returned as f64 in C (row-major)
//! order with the shape, so callers check the shape they expect ([`NpyArray::expect_2d`]).
//!
//! It is what `poses_bounds.npy` (Neu3D / LLFF) and `points.npy` (nerfies) need; integer,
//! complex, object and structured dtypes are rejected with an error naming the file and the
//! header field.

use std::io::Write;
use std::path::Path;

use crate::IoError;
use crate::atomic::write_atomically;

const MAGIC: &[u8] = b"\x93NUMPY";

/// Arrays with more elements than this are rejected as a sign of a corrupt header.
pub const MAX_ELEMENTS: usize = 1 << 31;

/// A floating-point array read from a `.npy` file.
#[derive(Clone, Debug, PartialEq)]
pub struct NpyArray {
    /// The shape (empty for a scalar).
    pub shape: Vec<usize>,
    /// The values in C (row-major) order, whatever the file's order.
    pub data: Vec<f64>,
}

impl NpyArray {
    /// The array as rows of a 2-D array with `cols` columns; an error naming `path` and the
    /// shape otherwise.
    pub fn expect_2d(&self, path: &Path, cols: usize) -> Result<Vec<&[f64]>, IoError> {
        match self.shape.as_slice() {
            [_, c] if *c == cols && cols > 0 => Ok(self.data.chunks_exact(cols).collect()),
            _ => Err(IoError::field(
                path,
                "shape",
                format!("expected (N, {cols}), found {:?}", self.shape),
            )),
        }
    }
}

/// Reads a `.npy` file.
pub fn read_npy(path: &Path) -> Result<NpyArray, IoError> {
    let bytes = std::fs::read(path).map_err(|e| IoError::io(path, e))?;
    parse_npy(path, &bytes)
}

fn header_error(path: &Path, field: &str, problem: impl Into<String>) -> IoError {
    IoError::field(path, format!("header.{field}"), problem)
}

/// Parses the bytes of a `.npy` file; `path` is only used in error messages.
pub fn parse_npy(path: &Path, bytes: &[u8]) -> Result<NpyArray, IoError> {
    if bytes.len() < MAGIC.len() + 2 || &bytes[..MAGIC.len()] != MAGIC {
        return Err(header_error(
            path,
            "magic",
            "not a .npy file (missing the \\x93NUMPY prefix)",
        ));
    }
    let major = bytes[6];
    let (len_size, header_len): (usize, Option<usize>) = match major {
        1 => (
            2,
            bytes
                .get(8..10)
                .map(|b| u16::from_le_bytes([b[0], b[1]]) as usize),
        ),
        2 | 3 => (
            4,
            bytes
                .get(8..12)
                .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize),
        ),
        other => {
            return Err(header_error(
                path,
                "version",
                format!("format version {other}.{} is not 1, 2 or 3", bytes[7]),
            ));
        }
    };
    let header_len =
        header_len.ok_or_else(|| header_error(path, "length", "file ends inside the header"))?;
    let start = 8 + len_size;
    let header_bytes = bytes
        .get(start..start.saturating_add(header_len))
        .ok_or_else(|| {
            header_error(
                path,
                "length",
                format!(
                    "header of {header_len} bytes does not fit in a file of {} bytes",
                    bytes.len()
                ),
            )
        })?;
    let header = std::str::from_utf8(header_bytes)
        .map_err(|_| header_error(path, "dict", "header is not UTF-8 text"))?;
    let dtype = dict_value(header, "descr")
        .ok_or_else(|| header_error(path, "descr", "missing"))?
        .trim_matches(|c| c == '\'' || c == '"');
    let (little, size) = match dtype {
        "<f4" => (true, 4),
        "<f8" => (true, 8),
        ">f4" => (false, 4),
        ">f8" => (false, 8),
        other => {
            return Err(header_error(
                path,
                "descr",
                format!("dtype `{other}` is not supported (expected <f4 or <f8)"),
            ));
        }
    };
    let fortran = match dict_value(header, "fortran_order") {
        Some("True") => true,
        Some("False") => false,
        Some(other) => {
            return Err(header_error(
                path,
                "fortran_order",
                format!("expected True or False, found `{other}`"),
            ));
        }
        None => return Err(header_error(path, "fortran_order", "missing")),
    };
    let shape_text =
        dict_value(header, "shape").ok_or_else(|| header_error(path, "shape", "missing"))?;
    let shape = parse_shape(shape_text)
        .ok_or_else(|| header_error(path, "shape", format!("`{shape_text}` is not a tuple")))?;
    let count = shape
        .iter()
        .try_fold(1usize, |acc, &d| acc.checked_mul(d))
        .filter(|&n| n <= MAX_ELEMENTS)
        .ok_or_else(|| {
            header_error(
                path,
                "shape",
                format!("{shape:?} has more than {MAX_ELEMENTS} elements"),
            )
        })?;
    let body = &bytes[start + header_len..];
    if body.len() != count * size {
        return Err(IoError::field(
            path,
            "data",
            format!(
                "shape {shape:?} of {dtype} needs {} bytes, the file has {}",
                count * size,
                body.len()
            ),
        ));
    }
    let values: Vec<f64> = body
        .chunks_exact(size)
        .map(|b| match (size, little) {
            (4, true) => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            (4, false) => f64::from(f32::from_be_bytes([b[0], b[1], b[2], b[3]])),
            (_, true) => f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]),
            (_, false) => f64::from_be_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]),
        })
        .collect();
    let data = if fortran && shape.len() > 1 {
        fortran_to_c(&shape, &values)
    } else {
        values
    };
    Ok(NpyArray { shape, data })
}

/// The text of `'key': value` in a Python dict literal (value up to the next top-level comma).
fn dict_value<'h>(header: &'h str, key: &str) -> Option<&'h str> {
    let at = header
        .find(&format!("'{key}'"))
        .or_else(|| header.find(&format!("\"{key}\"")))?;
    let rest = &header[at + key.len() + 2..];
    let rest = rest.trim_start().strip_prefix(':')?.trim_start();
    let mut depth = 0i32;
    let end = rest
        .char_indices()
        .find(|&(_, c)| {
            match c {
                '(' => depth += 1,
                ')' => depth -= 1,
                _ => {}
            }
            depth < 0 || (depth == 0 && (c == ',' || c == '}'))
        })
        .map_or(rest.len(), |(i, c)| if c == ')' { i + 1 } else { i });
    Some(rest[..end].trim())
}

/// Parses `(a, b, ...)` (a trailing comma allowed, `()` for a scalar).
fn parse_shape(text: &str) -> Option<Vec<usize>> {
    let inner = text.strip_prefix('(')?.strip_suffix(')')?;
    inner
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().ok())
        .collect()
}

/// Reorders column-major values into row-major order.
fn fortran_to_c(shape: &[usize], values: &[f64]) -> Vec<f64> {
    let n = values.len();
    let mut out = vec![0.0; n];
    let mut index = vec![0usize; shape.len()];
    for (c_offset, slot) in out.iter_mut().enumerate() {
        // Decompose the C offset into a multi-index, then form the Fortran offset.
        let mut rem = c_offset;
        for (axis, &dim) in shape.iter().enumerate().rev() {
            index[axis] = rem % dim;
            rem /= dim;
        }
        let mut f_offset = 0;
        for (axis, &dim) in shape.iter().enumerate().rev() {
            f_offset = f_offset * dim + index[axis];
        }
        *slot = values[f_offset];
    }
    out
}

/// Encodes an array as a version 1.0 `.npy` file in C order, `<f8` or (`f32 = true`) `<f4`.
pub fn encode_npy(shape: &[usize], data: &[f64], f32: bool) -> Vec<u8> {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let shape_text = match dims.len() {
        1 => format!("({},)", dims[0]),
        _ => format!("({})", dims.join(", ")),
    };
    let descr = if f32 { "<f4" } else { "<f8" };
    let mut header =
        format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape_text}, }}");
    // Pad with spaces so that the data starts on a multiple of 64 bytes; end with a newline.
    let unpadded = MAGIC.len() + 4 + header.len() + 1;
    header.push_str(&" ".repeat((64 - unpadded % 64) % 64));
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + data.len() * 8);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&[1, 0]);
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for &v in data {
        if f32 {
            out.extend_from_slice(&(v as f32).to_le_bytes());
        } else {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    out
}

/// Writes an f64 array as a `.npy` file (version 1.0, `<f8`, C order), atomically.
pub fn write_npy(path: &Path, shape: &[usize], data: &[f64]) -> Result<(), IoError> {
    if shape.iter().product::<usize>() != data.len() {
        return Err(IoError::InvalidData {
            path: path.to_path_buf(),
            problem: format!("shape {shape:?} does not hold {} values", data.len()),
        });
    }
    let bytes = encode_npy(shape, data, false);
    write_atomically(path, |w| {
        w.write_all(&bytes).map_err(|e| IoError::io(path, e))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p() -> &'static Path {
        Path::new("a.npy")
    }

    /// A file with a hand-written header, for versions and orders the writer does not produce.
    fn raw(major: u8, header: &str, body: &[u8]) -> Vec<u8> {
        let mut out = MAGIC.to_vec();
        out.extend_from_slice(&[major, 0]);
        if major == 1 {
            out.extend_from_slice(&(header.len() as u16).to_le_bytes());
        } else {
            out.extend_from_slice(&(header.len() as u32).to_le_bytes());
        }
        out.extend_from_slice(header.as_bytes());
        out.extend_from_slice(body);
        out
    }

    #[test]
    fn round_trips_f8_and_f4() {
        let data: Vec<f64> = (0..6).map(|i| i as f64 * 0.25 - 0.5).collect();
        for f32 in [false, true] {
            let bytes = encode_npy(&[2, 3], &data, f32);
            assert_eq!((bytes.len() - data.len() * if f32 { 4 } else { 8 }) % 64, 0);
            let a = parse_npy(p(), &bytes).unwrap();
            assert_eq!(a.shape, vec![2, 3]);
            assert_eq!(a.data, data);
        }
    }

    #[test]
    fn version_2_header_and_fortran_order() {
        // Column-major storage of [[1, 2, 3], [4, 5, 6]].
        let body: Vec<u8> = [1.0f64, 4.0, 2.0, 5.0, 3.0, 6.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let header = "{'descr': '<f8', 'fortran_order': True, 'shape': (2, 3), }\n";
        let a = parse_npy(p(), &raw(2, header, &body)).unwrap();
        assert_eq!(a.shape, vec![2, 3]);
        assert_eq!(a.data, vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        // Big-endian f4, 1-D shape with a trailing comma.
        let body: Vec<u8> = [1.5f32, -2.0]
            .iter()
            .flat_map(|v| v.to_be_bytes())
            .collect();
        let header = "{'fortran_order': False, 'shape': (2,), 'descr': '>f4'}\n";
        let a = parse_npy(p(), &raw(1, header, &body)).unwrap();
        assert_eq!((a.shape, a.data), (vec![2], vec![1.5, -2.0]));
    }

    #[test]
    fn three_dimensional_fortran_order_matches_c_indexing() {
        let shape = [2usize, 3, 4];
        // Element (i, j, k) has value 100i + 10j + k; Fortran offset i + 2j + 6k.
        let mut body = [0.0f64; 24];
        for i in 0..2 {
            for j in 0..3 {
                for k in 0..4 {
                    body[i + 2 * j + 6 * k] = (100 * i + 10 * j + k) as f64;
                }
            }
        }
        let bytes: Vec<u8> = body.iter().flat_map(|v| v.to_le_bytes()).collect();
        let header = "{'descr': '<f8', 'fortran_order': True, 'shape': (2, 3, 4), }\n";
        let a = parse_npy(p(), &raw(1, header, &bytes)).unwrap();
        assert_eq!(a.shape, shape.to_vec());
        for (c, v) in a.data.iter().enumerate() {
            let (i, j, k) = (c / 12, (c / 4) % 3, c % 4);
            assert_eq!(*v, (100 * i + 10 * j + k) as f64);
        }
    }

    #[test]
    fn bad_headers_name_the_field() {
        let cases: [(Vec<u8>, &str); 6] = [
            (b"PK\x03\x04 not npy".to_vec(), "header.magic"),
            (raw(9, "{}", &[]), "header.version"),
            (
                raw(
                    1,
                    "{'descr': '<i8', 'fortran_order': False, 'shape': (1,)}",
                    &[0; 8],
                ),
                "header.descr",
            ),
            (
                raw(
                    1,
                    "{'descr': '<f8', 'fortran_order': 1, 'shape': (1,)}",
                    &[0; 8],
                ),
                "header.fortran_order",
            ),
            (
                raw(
                    1,
                    "{'descr': '<f8', 'fortran_order': False, 'shape': [1]}",
                    &[0; 8],
                ),
                "header.shape",
            ),
            (
                raw(
                    1,
                    "{'descr': '<f8', 'fortran_order': False, 'shape': (2,)}",
                    &[0; 8],
                ),
                "`data`",
            ),
        ];
        for (bytes, field) in cases {
            let message = parse_npy(p(), &bytes).unwrap_err().to_string();
            assert!(message.starts_with("a.npy"), "{message}");
            assert!(message.contains(field), "{field}: {message}");
        }
    }

    #[test]
    fn expect_2d_checks_the_shape() {
        let a = NpyArray {
            shape: vec![2, 17],
            data: vec![0.0; 34],
        };
        assert_eq!(a.expect_2d(p(), 17).unwrap().len(), 2);
        let message = a.expect_2d(p(), 3).unwrap_err().to_string();
        assert!(
            message.contains("shape") && message.contains("(N, 3)"),
            "{message}"
        );
    }
}
