//! Reading 3DGS PLY files: header, then a row decoder driven by a per-property plan.

use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use splat_core::Gaussians;

use super::header::{Element, Encoding, Header, PropertyKind, ScalarType, parse_header_lines};
use super::layout::{RecordLayout, degree_from_rest_count, is_rest_name};
use super::problem::PlyProblem;
use crate::IoError;

/// Headers longer than this are rejected (3DGS headers are about 1.5 KiB).
const HEADER_LIMIT: usize = 1 << 20;

/// Gaussians read from a PLY file, with what the reader noticed on the way.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadedPly {
    /// The Gaussians, SH degree inferred from the `f_rest_*` count.
    pub gaussians: Gaussians,
    /// Rows with at least one non-finite value among the properties read. They are kept (the
    /// rasterizer culls them and counts them); this count lets callers warn about them.
    pub nonfinite_rows: usize,
    /// Vertex properties present in the file but not part of the 3DGS layout (ignored). The
    /// normals `nx ny nz` are part of the layout and not listed.
    pub ignored_properties: Vec<String>,
    /// The file's encoding.
    pub encoding: Encoding,
}

/// Why reading stopped, before the file's path is attached.
pub(super) enum Fail {
    Io(std::io::Error),
    Ply(PlyProblem),
}

impl From<std::io::Error> for Fail {
    fn from(e: std::io::Error) -> Self {
        Self::Io(e)
    }
}

impl From<PlyProblem> for Fail {
    fn from(p: PlyProblem) -> Self {
        Self::Ply(p)
    }
}

impl Fail {
    pub(super) fn at(self, path: &Path) -> IoError {
        match self {
            Self::Io(cause) => IoError::io(path, cause),
            Self::Ply(problem) => IoError::Ply {
                path: path.to_path_buf(),
                problem,
            },
        }
    }
}

/// Reads a 3DGS PLY file (DESIGN §2.3): ASCII or binary of either endianness, any numeric property
/// types, properties in any order, unknown properties ignored.
pub fn read_ply(path: &Path) -> Result<LoadedPly, IoError> {
    let file = File::open(path).map_err(|e| IoError::io(path, e))?;
    let len = file.metadata().map_err(|e| IoError::io(path, e))?.len();
    let mut reader = BufReader::with_capacity(1 << 20, file);
    read_from(&mut reader, len).map_err(|f| f.at(path))
}

/// Reads a 3DGS PLY file held in memory; `name` is used in error messages.
pub fn read_ply_bytes(bytes: &[u8], name: &Path) -> Result<LoadedPly, IoError> {
    let mut reader = bytes;
    read_from(&mut reader, bytes.len() as u64).map_err(|f| f.at(name))
}

/// Reads header lines up to `end_header`; returns them and the header's size in bytes.
fn read_header_lines<R: BufRead>(reader: &mut R) -> Result<(Vec<String>, usize), Fail> {
    let mut lines = Vec::new();
    let mut consumed = 0usize;
    let mut buf = Vec::new();
    loop {
        buf.clear();
        let budget = (HEADER_LIMIT - consumed) as u64;
        let n = reader.by_ref().take(budget).read_until(b'\n', &mut buf)?;
        consumed += n;
        if consumed == 0 {
            return Err(PlyProblem::Empty.into());
        }
        if n == 0 || !buf.ends_with(b"\n") {
            if lines.is_empty() && !buf.is_empty() && !b"ply".starts_with(&buf[..]) {
                return Err(PlyProblem::NotPly.into());
            }
            return Err(PlyProblem::UnterminatedHeader {
                limit: HEADER_LIMIT,
            }
            .into());
        }
        let text = String::from_utf8_lossy(&buf);
        let line = text.trim_end_matches(['\n', '\r']).to_string();
        if lines.is_empty() && line.trim() != "ply" {
            return Err(PlyProblem::NotPly.into());
        }
        if line.trim() == "end_header" {
            return Ok((lines, consumed));
        }
        lines.push(line);
    }
}

/// One vertex property to decode: where it is in a row, its type, and its record slot.
struct Column {
    /// Byte offset (binary) or token index (ASCII) within the row.
    position: usize,
    ty: ScalarType,
    slot: usize,
    name: String,
}

/// The decoding plan for the vertex element: which properties go to which record slot.
pub(super) struct Plan {
    record_len: usize,
    columns: Vec<Column>,
    ignored: Vec<String>,
}

impl Plan {
    /// The type of the property decoded into `slot`, if any.
    pub(super) fn type_of_slot(&self, slot: usize) -> Option<ScalarType> {
        self.columns.iter().find(|c| c.slot == slot).map(|c| c.ty)
    }
}

/// Where decoded vertex records go.
pub(super) trait Rows {
    /// Room for `count` records (called once the count has been checked against the file size).
    fn reserve(&mut self, count: usize);
    /// One record, `Plan::record_len` values.
    fn push(&mut self, record: &[f32]);
}

/// The 3DGS plan for a vertex element, and the SH degree its `f_rest_*` count gives.
fn plan_vertex(vertex: &Element, encoding: Encoding) -> Result<(Plan, u32), PlyProblem> {
    let rest = vertex
        .properties
        .iter()
        .filter(|p| is_rest_name(&p.name))
        .count();
    let degree = degree_from_rest_count(rest).ok_or(PlyProblem::BadShCount { count: rest })?;
    let layout = RecordLayout { degree };
    let plan = plan_columns(
        vertex,
        encoding,
        layout.len(),
        |name| layout.slot_of(name),
        |name| matches!(name, "nx" | "ny" | "nz"),
        &layout.required_names(),
    )?;
    Ok((plan, degree))
}

/// The plan for a vertex element: `slot_of` maps a property name to its record slot (`None`:
/// ignored and listed, unless `unlisted` says it is expected); every `required` name must exist.
pub(super) fn plan_columns(
    vertex: &Element,
    encoding: Encoding,
    record_len: usize,
    slot_of: impl Fn(&str) -> Option<usize>,
    unlisted: impl Fn(&str) -> bool,
    required: &[String],
) -> Result<Plan, PlyProblem> {
    let mut columns = Vec::new();
    let mut ignored = Vec::new();
    let mut offset = 0usize;
    for (index, property) in vertex.properties.iter().enumerate() {
        let PropertyKind::Scalar(ty) = property.kind else {
            // A list anywhere in the vertex element makes rows variable in size.
            return Err(PlyProblem::ListProperty(property.name.clone()));
        };
        let position = match encoding {
            Encoding::Ascii => index,
            _ => offset,
        };
        offset += ty.size();
        match slot_of(&property.name) {
            Some(slot) => columns.push(Column {
                position,
                ty,
                slot,
                name: property.name.clone(),
            }),
            None if unlisted(&property.name) => {}
            None => ignored.push(property.name.clone()),
        }
    }
    for name in required {
        if !columns.iter().any(|c| &c.name == name) {
            return Err(PlyProblem::MissingProperty(name.clone()));
        }
    }
    Ok(Plan {
        record_len,
        columns,
        ignored,
    })
}

/// A file's header, read up to `end_header`, with the index of its vertex element and the
/// bytes that follow the header.
pub(super) struct Prelude {
    header: Header,
    vertex_index: usize,
    available: u64,
}

impl Prelude {
    /// Reads the header of a file of `total_len` bytes.
    pub(super) fn read<R: BufRead>(reader: &mut R, total_len: u64) -> Result<Self, Fail> {
        let (lines, header_len) = read_header_lines(reader)?;
        let header = parse_header_lines(&lines)?;
        let vertex_index = header
            .elements
            .iter()
            .position(|e| e.name == "vertex")
            .ok_or(PlyProblem::NoVertexElement)?;
        Ok(Self {
            header,
            vertex_index,
            available: total_len.saturating_sub(header_len as u64),
        })
    }

    /// The vertex element.
    pub(super) fn vertex(&self) -> &Element {
        &self.header.elements[self.vertex_index]
    }

    /// The file's encoding.
    pub(super) fn encoding(&self) -> Encoding {
        self.header.encoding
    }

    /// Decodes every vertex row by `plan` into `sink`.
    pub(super) fn read_rows<R: BufRead, S: Rows>(
        &self,
        reader: &mut R,
        plan: &Plan,
        sink: &mut S,
    ) -> Result<(), Fail> {
        let (header, index, available) = (&self.header, self.vertex_index, self.available);
        match header.encoding {
            Encoding::Ascii => read_ascii(reader, header, index, plan, available, sink),
            _ => read_binary(reader, header, index, plan, available, sink),
        }
    }
}

fn read_from<R: BufRead>(reader: &mut R, total_len: u64) -> Result<LoadedPly, Fail> {
    let prelude = Prelude::read(reader, total_len)?;
    let (plan, degree) = plan_vertex(prelude.vertex(), prelude.encoding())?;
    let mut sink = RowSink::new(degree);
    prelude.read_rows(reader, &plan, &mut sink)?;
    let header = &prelude.header;
    Ok(LoadedPly {
        gaussians: sink.gaussians,
        nonfinite_rows: sink.nonfinite_rows,
        ignored_properties: plan.ignored,
        encoding: header.encoding,
    })
}

/// Accumulates decoded records into [`Gaussians`].
struct RowSink {
    gaussians: Gaussians,
    nonfinite_rows: usize,
}

impl RowSink {
    /// Empty; capacity is reserved later, once the count has been checked against the file size.
    fn new(degree: u32) -> Self {
        Self {
            gaussians: Gaussians::with_degree(degree),
            nonfinite_rows: 0,
        }
    }
}

impl Rows for RowSink {
    fn reserve(&mut self, count: usize) {
        let g = &mut self.gaussians;
        let stride = g.sh_stride();
        g.means.reserve_exact(count);
        g.log_scales.reserve_exact(count);
        g.rotations.reserve_exact(count);
        g.opacity_logits.reserve_exact(count);
        g.sh.reserve_exact(count * stride);
    }

    fn push(&mut self, rec: &[f32]) {
        if rec.iter().any(|v| !v.is_finite()) {
            self.nonfinite_rows += 1;
        }
        let g = &mut self.gaussians;
        let m = RecordLayout::MEAN;
        let s = RecordLayout::SCALE;
        let r = RecordLayout::ROT;
        g.means.push([rec[m], rec[m + 1], rec[m + 2]]);
        g.opacity_logits.push(rec[RecordLayout::OPACITY]);
        g.log_scales.push([rec[s], rec[s + 1], rec[s + 2]]);
        g.rotations
            .push([rec[r], rec[r + 1], rec[r + 2], rec[r + 3]]);
        g.sh.extend_from_slice(&rec[RecordLayout::SH..]);
    }
}

/// Decodes one binary scalar at the start of `bytes` (which holds at least `ty.size()` bytes).
#[inline(always)]
fn decode(bytes: &[u8], ty: ScalarType, big_endian: bool) -> f32 {
    macro_rules! get {
        ($t:ty, $n:expr) => {{
            let mut b = [0u8; $n];
            b.copy_from_slice(&bytes[..$n]);
            if big_endian {
                <$t>::from_be_bytes(b)
            } else {
                <$t>::from_le_bytes(b)
            }
        }};
    }
    match ty {
        ScalarType::F32 => get!(f32, 4),
        ScalarType::F64 => get!(f64, 8) as f32,
        ScalarType::I8 => get!(i8, 1) as f32,
        ScalarType::U8 => get!(u8, 1) as f32,
        ScalarType::I16 => get!(i16, 2) as f32,
        ScalarType::U16 => get!(u16, 2) as f32,
        ScalarType::I32 => get!(i32, 4) as f32,
        ScalarType::U32 => get!(u32, 4) as f32,
    }
}

fn truncated(element: &Element, needed: u128, available: u64) -> PlyProblem {
    PlyProblem::Truncated {
        element: element.name.clone(),
        count: element.count,
        needed,
        available,
    }
}

fn read_binary<R: BufRead, S: Rows>(
    reader: &mut R,
    header: &Header,
    vertex_index: usize,
    plan: &Plan,
    mut available: u64,
    sink: &mut S,
) -> Result<(), Fail> {
    let big_endian = header.encoding == Encoding::BinaryBigEndian;
    for element in &header.elements[..vertex_index] {
        let row = element
            .binary_row_size()
            .ok_or_else(|| PlyProblem::ListBeforeVertex(element.name.clone()))?;
        let needed = element.count as u128 * row as u128;
        if needed > available as u128 {
            return Err(truncated(element, needed, available).into());
        }
        let skipped = std::io::copy(
            &mut reader.by_ref().take(needed as u64),
            &mut std::io::sink(),
        )?;
        if skipped as u128 != needed {
            return Err(truncated(element, needed, skipped).into());
        }
        available -= skipped;
    }
    let vertex = &header.elements[vertex_index];
    // Lists were rejected by the plan, so every vertex property has a fixed size.
    let row_size = vertex.binary_row_size().unwrap_or(0).max(1);
    let needed = vertex.count as u128 * row_size as u128;
    if needed > available as u128 {
        return Err(truncated(vertex, needed, available).into());
    }
    let count = vertex.count as usize;
    sink.reserve(count);
    let mut rec = vec![0f32; plan.record_len];
    let rows_per_chunk = ((1usize << 20) / row_size).max(1);
    let mut buf = vec![0u8; rows_per_chunk.min(count.max(1)) * row_size];
    let mut done = 0usize;
    let all_le_f32 = !big_endian && plan.columns.iter().all(|c| c.ty == ScalarType::F32);
    while done < count {
        let rows = rows_per_chunk.min(count - done);
        let chunk = &mut buf[..rows * row_size];
        reader.read_exact(chunk).map_err(|e| {
            if e.kind() == std::io::ErrorKind::UnexpectedEof {
                Fail::Ply(truncated(vertex, needed, available))
            } else {
                Fail::Io(e)
            }
        })?;
        for row in chunk.chunks_exact(row_size) {
            if all_le_f32 {
                for c in &plan.columns {
                    let mut b = [0u8; 4];
                    b.copy_from_slice(&row[c.position..c.position + 4]);
                    rec[c.slot] = f32::from_le_bytes(b);
                }
            } else {
                for c in &plan.columns {
                    rec[c.slot] = decode(&row[c.position..], c.ty, big_endian);
                }
            }
            sink.push(&rec);
        }
        done += rows;
    }
    Ok(())
}

/// Parses one ASCII token as its declared type, converted to f32.
fn parse_token(token: &str, ty: ScalarType) -> Option<f32> {
    let int_range = |lo: i64, hi: i64| -> Option<f32> {
        let v: i64 = token.parse().ok()?;
        (lo..=hi).contains(&v).then_some(v as f32)
    };
    match ty {
        ScalarType::F32 => token.parse::<f32>().ok(),
        ScalarType::F64 => token.parse::<f64>().ok().map(|v| v as f32),
        ScalarType::I8 => int_range(i8::MIN.into(), i8::MAX.into()),
        ScalarType::U8 => int_range(0, u8::MAX.into()),
        ScalarType::I16 => int_range(i16::MIN.into(), i16::MAX.into()),
        ScalarType::U16 => int_range(0, u16::MAX.into()),
        ScalarType::I32 => int_range(i32::MIN.into(), i32::MAX.into()),
        ScalarType::U32 => int_range(0, u32::MAX.into()),
    }
}

fn read_ascii<R: BufRead, S: Rows>(
    reader: &mut R,
    header: &Header,
    vertex_index: usize,
    plan: &Plan,
    available: u64,
    sink: &mut S,
) -> Result<(), Fail> {
    let vertex = &header.elements[vertex_index];
    let props = vertex.properties.len().max(1);
    // Each row needs at least one character and one separator per value.
    let needed = (vertex.count as u128 * 2 * props as u128).saturating_sub(1);
    if needed > available as u128 {
        return Err(truncated(vertex, needed, available).into());
    }
    let mut body = Vec::new();
    reader.take(available).read_to_end(&mut body)?;
    let text = std::str::from_utf8(&body).map_err(|_| PlyProblem::NotText)?;
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    for element in &header.elements[..vertex_index] {
        for got in 0..element.count {
            if lines.next().is_none() {
                return Err(PlyProblem::MissingRows {
                    element: element.name.clone(),
                    count: element.count,
                    got,
                }
                .into());
            }
        }
    }
    sink.reserve(vertex.count as usize);
    let mut rec = vec![0f32; plan.record_len];
    let mut tokens: Vec<&str> = Vec::with_capacity(props);
    for row in 0..vertex.count {
        let Some(line) = lines.next() else {
            return Err(PlyProblem::MissingRows {
                element: vertex.name.clone(),
                count: vertex.count,
                got: row,
            }
            .into());
        };
        tokens.clear();
        tokens.extend(line.split_ascii_whitespace());
        if tokens.len() != vertex.properties.len() {
            return Err(PlyProblem::RowLength {
                row,
                got: tokens.len(),
                expected: vertex.properties.len(),
            }
            .into());
        }
        for c in &plan.columns {
            let token = tokens[c.position];
            rec[c.slot] = parse_token(token, c.ty).ok_or_else(|| PlyProblem::BadValue {
                row,
                property: c.name.clone(),
                text: token.chars().take(40).collect(),
                ty: c.ty.name().to_string(),
            })?;
        }
        sink.push(&rec);
    }
    Ok(())
}
