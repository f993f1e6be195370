//! What can be wrong with a PLY file.

use thiserror::Error;

/// A malformed or unsupported PLY file, naming the line, element, property or row.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum PlyProblem {
    /// The file is empty.
    #[error("file is empty")]
    Empty,
    /// The file does not start with the `ply` magic line.
    #[error("not a PLY file (first line is not `ply`)")]
    NotPly,
    /// No `end_header` line within the header size limit or before the end of the file.
    #[error("header has no `end_header` line within its first {limit} bytes")]
    UnterminatedHeader {
        /// The limit in bytes.
        limit: usize,
    },
    /// A header line that cannot be understood.
    #[error("header line {line}: {reason}: `{text}`")]
    BadHeaderLine {
        /// 1-based line number.
        line: usize,
        /// The line (shortened).
        text: String,
        /// Why it is rejected.
        reason: String,
    },
    /// The header has no `format` line.
    #[error("header has no `format` line")]
    MissingFormat,
    /// There is no `vertex` element.
    #[error("header declares no `vertex` element")]
    NoVertexElement,
    /// A property appears twice in one element.
    #[error("property `{0}` is declared twice in one element")]
    DuplicateProperty(String),
    /// A required vertex property is absent.
    #[error("vertex property `{0}` is missing")]
    MissingProperty(String),
    /// A property the reader needs is a list.
    #[error("vertex property `{0}` is a list; expected a scalar")]
    ListProperty(String),
    /// An element before the vertex data has list properties in a binary file (cannot be skipped
    /// without parsing it, which this reader does not do).
    #[error("element `{0}` before `vertex` has list properties; not supported in binary files")]
    ListBeforeVertex(String),
    /// The number of `f_rest_*` properties does not match an SH degree 0..=3.
    #[error("{count} `f_rest_*` properties; expected 0, 9, 24 or 45 (SH degree 0 to 3)")]
    BadShCount {
        /// How many there are.
        count: usize,
    },
    /// The declared row count needs more data than the file holds.
    #[error(
        "element `{element}` declares {count} rows needing {needed} bytes, but only {available} \
         bytes follow (truncated file or wrong count)"
    )]
    Truncated {
        /// Element name.
        element: String,
        /// Declared row count.
        count: u64,
        /// Bytes (binary) or a lower bound on bytes (ASCII) the rows need.
        needed: u128,
        /// Bytes that follow in the file.
        available: u64,
    },
    /// An ASCII file ends before all rows were read.
    #[error("element `{element}`: file ends after {got} of {count} rows")]
    MissingRows {
        /// Element name.
        element: String,
        /// Declared row count.
        count: u64,
        /// Rows found.
        got: u64,
    },
    /// An ASCII row has the wrong number of values.
    #[error("vertex row {row}: {got} values, expected {expected}")]
    RowLength {
        /// 0-based row.
        row: u64,
        /// Values found.
        got: usize,
        /// Values declared.
        expected: usize,
    },
    /// An ASCII value does not parse as its declared type.
    #[error("vertex row {row}, property `{property}`: cannot parse `{text}` as {ty}")]
    BadValue {
        /// 0-based row.
        row: u64,
        /// Property name.
        property: String,
        /// The text (shortened).
        text: String,
        /// The declared type.
        ty: String,
    },
    /// An ASCII file body is not valid UTF-8 text.
    #[error("ASCII body is not valid text")]
    NotText,
}
