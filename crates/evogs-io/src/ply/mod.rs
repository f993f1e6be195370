//! 3DGS PLY files (DESIGN §2): the original 3DGS vertex layout, written as binary little-endian
//! float32 and read from ASCII or binary of either endianness with any numeric property types;
//! and plain point clouds (`x y z red green blue`, [`read_point_cloud`]) with the same decoder.
//!
//! The parser is hand-written: the format is small, the `ply-rs` family of crates neither checks
//! counts against the file size before allocating nor reports errors by field, and a direct
//! row decoder is several times faster than a generic property map for 1M-row files.

mod header;
mod layout;
mod points;
mod problem;
mod read;
mod write;

pub(crate) use header::{Element, PropertyKind, parse_header_lines};
pub use header::{Encoding, ScalarType};
pub use layout::property_names;
pub use points::read_point_cloud;
pub use problem::PlyProblem;
pub use read::{LoadedPly, read_ply, read_ply_bytes};
pub use write::{ply_header, write_ply, write_ply_to};
