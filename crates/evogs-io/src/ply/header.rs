//! The PLY header: format, elements and their properties.

use super::PlyProblem;

/// How the body of a PLY file is encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    /// Whitespace-separated text, one row per line.
    Ascii,
    /// Binary, little-endian.
    BinaryLittleEndian,
    /// Binary, big-endian.
    BinaryBigEndian,
}

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ScalarType {
    /// `char` / `int8`.
    I8,
    /// `uchar` / `uint8`.
    U8,
    /// `short` / `int16`.
    I16,
    /// `ushort` / `uint16`.
    U16,
    /// `int` / `int32`.
    I32,
    /// `uint` / `uint32`.
    U32,
    /// `float` / `float32`.
    F32,
    /// `double` / `float64`.
    F64,
}

impl ScalarType {
    /// Parses a PLY type name (both the old and the sized spellings).
    pub fn from_name(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    /// Size in bytes in a binary file.
    pub fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    /// The canonical PLY name.
    pub fn name(self) -> &'static str {
        match self {
            Self::I8 => "char",
            Self::U8 => "uchar",
            Self::I16 => "short",
            Self::U16 => "ushort",
            Self::I32 => "int",
            Self::U32 => "uint",
            Self::F32 => "float",
            Self::F64 => "double",
        }
    }
}

/// A property's type: a scalar or a list.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum PropertyKind {
    Scalar(ScalarType),
    List,
}

/// A declared property.
#[derive(Clone, Debug)]
pub(crate) struct Property {
    pub name: String,
    pub kind: PropertyKind,
}

/// A declared element.
#[derive(Clone, Debug)]
pub(crate) struct Element {
    pub name: String,
    pub count: u64,
    pub properties: Vec<Property>,
}

impl Element {
    /// Row size in bytes in a binary file, `None` when a property is a list.
    pub fn binary_row_size(&self) -> Option<usize> {
        self.properties
            .iter()
            .map(|p| match p.kind {
                PropertyKind::Scalar(t) => Some(t.size()),
                PropertyKind::List => None,
            })
            .sum()
    }
}

/// A parsed header.
#[derive(Clone, Debug)]
pub(crate) struct Header {
    pub encoding: Encoding,
    pub elements: Vec<Element>,
}

fn bad_line(line: usize, text: &str, reason: impl Into<String>) -> PlyProblem {
    let mut text = text.to_string();
    if text.len() > 80 {
        let mut cut = 80;
        while !text.is_char_boundary(cut) {
            cut -= 1;
        }
        text.truncate(cut);
        text.push('…');
    }
    PlyProblem::BadHeaderLine {
        line,
        text,
        reason: reason.into(),
    }
}

/// Parses the header lines (everything up to but excluding `end_header`).
pub(crate) fn parse_header_lines(lines: &[String]) -> Result<Header, PlyProblem> {
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    for (index, raw) in lines.iter().enumerate() {
        let line_no = index + 1;
        let mut tokens = raw.split_ascii_whitespace();
        let keyword = tokens.next().unwrap_or("");
        let rest: Vec<&str> = tokens.collect();
        match keyword {
            "ply" if index == 0 => {}
            _ if index == 0 => return Err(PlyProblem::NotPly),
            "" | "comment" | "obj_info" => {}
            "format" => {
                if encoding.is_some() {
                    return Err(bad_line(line_no, raw, "second `format` line"));
                }
                if rest.len() != 2 || rest[1] != "1.0" {
                    return Err(bad_line(line_no, raw, "expected `format <encoding> 1.0`"));
                }
                encoding = Some(match rest[0] {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::BinaryLittleEndian,
                    "binary_big_endian" => Encoding::BinaryBigEndian,
                    _ => return Err(bad_line(line_no, raw, "unknown encoding")),
                });
            }
            "element" => {
                let [name, count] = rest[..] else {
                    return Err(bad_line(line_no, raw, "expected `element <name> <count>`"));
                };
                let count: u64 = count
                    .parse()
                    .map_err(|_| bad_line(line_no, raw, "element count is not a whole number"))?;
                if elements.iter().any(|e| e.name == name) {
                    return Err(bad_line(line_no, raw, "element declared twice"));
                }
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    properties: Vec::new(),
                });
            }
            "property" => {
                let Some(element) = elements.last_mut() else {
                    return Err(bad_line(line_no, raw, "property before any element"));
                };
                let (name, kind) = match rest[..] {
                    ["list", count_ty, item_ty, name] => {
                        for ty in [count_ty, item_ty] {
                            if ScalarType::from_name(ty).is_none() {
                                return Err(bad_line(line_no, raw, "unknown property type"));
                            }
                        }
                        (name, PropertyKind::List)
                    }
                    [ty, name] => match ScalarType::from_name(ty) {
                        Some(t) => (name, PropertyKind::Scalar(t)),
                        None => return Err(bad_line(line_no, raw, "unknown property type")),
                    },
                    _ => {
                        return Err(bad_line(
                            line_no,
                            raw,
                            "expected `property <type> <name>` or `property list <type> <type> <name>`",
                        ));
                    }
                };
                if element.properties.iter().any(|p| p.name == name) {
                    return Err(PlyProblem::DuplicateProperty(name.to_string()));
                }
                element.properties.push(Property {
                    name: name.to_string(),
                    kind,
                });
            }
            _ => return Err(bad_line(line_no, raw, "unknown keyword")),
        }
    }
    if lines.is_empty() {
        return Err(PlyProblem::NotPly);
    }
    let encoding = encoding.ok_or(PlyProblem::MissingFormat)?;
    Ok(Header { encoding, elements })
}
