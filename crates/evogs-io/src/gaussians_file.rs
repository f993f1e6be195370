//! Reading Gaussians from any of the files evogs writes (`evogs render --ply` reads what
//! `evogs export` writes): a 3DGS PLY, a compressed PLY, or a `.splat`. The two PLY layouts
//! are told apart by the header (the compressed one starts with an `element chunk`), the
//! `.splat` by its name (it has no header).
//!
//! What it is not: a fourth reader; each format's own reader ([`crate::read_ply`],
//! [`crate::read_compressed_ply`], [`crate::read_splat`]) does the work and names the file.

use std::io::Read;
use std::path::Path;

use splat_core::Gaussians;

use crate::error::IoError;

/// The file layouts [`read_gaussians`] reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GaussiansFormat {
    /// The INRIA 3DGS PLY.
    Ply,
    /// PlayCanvas/SuperSplat's compressed PLY.
    CompressedPly,
    /// The 32-byte `.splat` of web viewers.
    Splat,
}

/// Gaussians read by [`read_gaussians`].
#[derive(Clone, Debug)]
pub struct LoadedGaussians {
    /// The Gaussians.
    pub gaussians: Gaussians,
    /// Rows with at least one non-finite value (kept: the rasterizer culls and counts them).
    pub nonfinite_rows: usize,
    /// The layout the file had.
    pub format: GaussiansFormat,
}

/// The header bytes read to tell the two PLY layouts apart (a PLY header is a few hundred).
const HEADER_PEEK: u64 = 64 * 1024;

/// The layout of `path`: a PLY's header says which PLY; a file without one is a `.splat` when
/// its name says so, else a PLY (whose reader then names what is wrong).
pub fn format_of(path: &Path) -> Result<GaussiansFormat, IoError> {
    let mut head = Vec::new();
    std::fs::File::open(path)
        .and_then(|f| f.take(HEADER_PEEK).read_to_end(&mut head))
        .map_err(|e| IoError::io(path, e))?;
    if head.starts_with(b"ply") {
        let text = String::from_utf8_lossy(&head);
        let header = text.split("end_header").next().unwrap_or_default();
        let chunked = header
            .lines()
            .any(|l| l.split_whitespace().take(2).eq(["element", "chunk"]));
        return Ok(if chunked {
            GaussiansFormat::CompressedPly
        } else {
            GaussiansFormat::Ply
        });
    }
    let named_splat = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("splat"));
    Ok(if named_splat {
        GaussiansFormat::Splat
    } else {
        GaussiansFormat::Ply
    })
}

/// Reads the Gaussians of `path` in whichever layout it has ([`format_of`]).
pub fn read_gaussians(path: &Path) -> Result<LoadedGaussians, IoError> {
    let format = format_of(path)?;
    let (gaussians, nonfinite_rows) = match format {
        GaussiansFormat::Ply => {
            let loaded = crate::read_ply(path)?;
            (loaded.gaussians, loaded.nonfinite_rows)
        }
        GaussiansFormat::CompressedPly => counted(crate::read_compressed_ply(path)?),
        GaussiansFormat::Splat => counted(crate::read_splat(path)?),
    };
    Ok(LoadedGaussians {
        gaussians,
        nonfinite_rows,
        format,
    })
}

/// `g` with its count of rows holding a non-finite value.
fn counted(g: Gaussians) -> (Gaussians, usize) {
    let stride = g.sh_stride();
    let finite = |v: &[f32]| v.iter().all(|x| x.is_finite());
    let n = (0..g.len())
        .filter(|&i| {
            !(finite(&g.means[i])
                && finite(&g.log_scales[i])
                && finite(&g.rotations[i])
                && g.opacity_logits[i].is_finite()
                && finite(&g.sh[i * stride..(i + 1) * stride]))
        })
        .count();
    (g, n)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two() -> Gaussians {
        let mut g = Gaussians::with_degree(0);
        for i in 0..2 {
            g.means.push([i as f32, 0.5, -0.25]);
            g.log_scales.push([-2.0, -2.5, -3.0]);
            g.rotations.push([1.0, 0.0, 0.0, 0.0]);
            g.opacity_logits.push(0.5);
            g.sh.extend([0.1, 0.2, 0.3]);
        }
        g
    }

    /// Every layout evogs writes reads back through the one function, told apart by its header
    /// (or, for `.splat`, its name), with the count of its non-finite rows.
    #[test]
    fn every_written_layout_reads_back() {
        let dir = tempfile::tempdir().unwrap();
        let g = two();
        let ply = dir.path().join("a.ply");
        crate::write_ply(&ply, g.view()).unwrap();
        let compressed = dir.path().join("named-as-plain.ply");
        crate::write_compressed_ply(&compressed, g.view()).unwrap();
        let splat = dir.path().join("a.SPLAT");
        crate::write_splat(&splat, g.view()).unwrap();
        // The writer leaves non-finite Gaussians out: a NaN position written by hand into the
        // second 32-byte record (its x, the record's first f32).
        let mut bytes = std::fs::read(&splat).unwrap();
        bytes[32..36].copy_from_slice(&f32::NAN.to_le_bytes());
        std::fs::write(&splat, bytes).unwrap();
        for (path, format) in [
            (&ply, GaussiansFormat::Ply),
            (&compressed, GaussiansFormat::CompressedPly),
            (&splat, GaussiansFormat::Splat),
        ] {
            let loaded = read_gaussians(path).unwrap();
            assert_eq!(loaded.format, format, "{}", path.display());
            assert_eq!(loaded.gaussians.len(), 2, "{}", path.display());
            let expected = usize::from(format == GaussiansFormat::Splat);
            assert_eq!(loaded.nonfinite_rows, expected, "{}", path.display());
        }
        // Neither a PLY nor named `.splat`: the PLY reader's message, naming the file.
        let other = dir.path().join("x.bin");
        std::fs::write(&other, [0u8; 64]).unwrap();
        let e = read_gaussians(&other).unwrap_err().to_string();
        assert!(e.contains("x.bin"), "{e}");
    }
}
