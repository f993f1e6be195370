//! The compressed PLY: written and read back within the format's stated precision (each value
//! against the bounds of its chunk, recomputed here from the input), file sizes as documented,
//! hard cases (one Gaussian, zero scale, counts not a multiple of 256, NaN), and one-line errors
//! for malformed files.

use crate::common;

use std::path::Path;

use common::random_gaussians;
use evogs_io::compressed_ply::morton::sort_morton;
use evogs_io::compressed_ply::{
    CHUNK_SIZE, LOG_SCALE_LIMIT, compressed_ply_header, compressed_ply_len,
    read_compressed_ply_bytes,
};
use evogs_io::{IoError, read_compressed_ply, write_compressed_ply};
use proptest::prelude::*;
use splat_core::sh::rgb_from_dc;
use splat_core::{Gaussians, sh_coeff_count, sigmoid};

/// Writes `g` into a temporary folder and reads it back; returns the file's size too.
fn round_trip(g: &Gaussians) -> (Gaussians, usize, u64) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("g.compressed.ply");
    let written = write_compressed_ply(&path, g.view()).unwrap();
    let size = std::fs::metadata(&path).unwrap().len();
    (read_compressed_ply(&path).unwrap(), written, size)
}

/// A quaternion and its negation are one rotation: the largest component difference of the
/// nearer sign.
fn rotation_distance(a: [f32; 4], b: [f32; 4]) -> f32 {
    let n = b.iter().map(|v| v * v).sum::<f32>().sqrt();
    let d = |s: f32| {
        (0..4)
            .map(|i| (a[i] - s * b[i] / n).abs())
            .fold(0.0, f32::max)
    };
    d(1.0).min(d(-1.0))
}

/// The largest error of each kind, each divided by what the module docs state for it (so every
/// entry is at most 1 when the stated precision holds).
#[derive(Debug, Default)]
struct Errors {
    position: f32,
    log_scale: f32,
    colour: f32,
    opacity: f32,
    rotation: f32,
    sh: f32,
}

/// Compares `back` (file order) with `g` (Gaussians `kept`, in their original order) against the
/// stated precision, chunk by chunk.
fn errors(g: &Gaussians, kept: &[usize], back: &Gaussians) -> Errors {
    let mut order = kept.to_vec();
    sort_morton(&g.means, &mut order);
    assert_eq!(back.len(), order.len());
    assert_eq!(back.sh_degree, g.sh_degree);
    let stride = g.sh_stride();
    let coeffs = sh_coeff_count(g.sh_degree);
    let mut e = Errors::default();
    for (c, members) in order.chunks(CHUNK_SIZE).enumerate() {
        // A chunk's range per axis; log scales clamped to ±20 as the writer does.
        let range = |f: &dyn Fn(usize) -> [f32; 3], limit: f32| -> [f32; 3] {
            [0, 1, 2].map(|k| {
                let v = members.iter().map(|&i| f(i)[k].clamp(-limit, limit));
                let lo = v.clone().fold(f32::INFINITY, f32::min);
                v.fold(f32::NEG_INFINITY, f32::max) - lo
            })
        };
        let colour = |i: usize| [0, 1, 2].map(|k| rgb_from_dc(g.sh[i * stride + k]));
        let p_range = range(&|i| g.means[i], f32::MAX);
        let s_range = range(&|i| g.log_scales[i], LOG_SCALE_LIMIT);
        let c_range = range(&colour, f32::MAX);
        // Half a step of the range; a range narrower than 1e-5 is stored as its least value.
        let step = |range: f32, bits: u32| {
            if range < 1e-5 {
                1e-5
            } else {
                range / (2.0 * ((1 << bits) - 1) as f32)
            }
        };
        for (j, &i) in members.iter().enumerate() {
            let b = c * CHUNK_SIZE + j;
            for (k, bits) in [11, 10, 11].into_iter().enumerate() {
                let tol = |range: f32, bits: u32, v: f32| {
                    step(range, bits) + 4.0 * f32::EPSILON * (v.abs() + range)
                };
                let dp = (back.means[b][k] - g.means[i][k]).abs();
                e.position = e.position.max(dp / tol(p_range[k], bits, g.means[i][k]));
                let want = g.log_scales[i][k].max(-LOG_SCALE_LIMIT);
                let ds = (back.log_scales[b][k] - want).abs();
                e.log_scale = e.log_scale.max(ds / tol(s_range[k], bits, want));
                let dc = (rgb_from_dc(back.sh[b * stride + k]) - colour(i)[k]).abs();
                e.colour = e.colour.max(dc / tol(c_range[k], 8, 1.0));
            }
            let da = (sigmoid(back.opacity_logits[b]) - sigmoid(g.opacity_logits[i])).abs();
            e.opacity = e.opacity.max(da / (0.5 / 255.0 + 1e-6));
            let dq = rotation_distance(back.rotations[b], g.rotations[i]);
            e.rotation = e.rotation.max(dq / 2.5e-3);
            for k in 3..3 * coeffs {
                let d = (back.sh[b * stride + k] - g.sh[i * stride + k]).abs();
                e.sh = e.sh.max(d / (1.0 / 32.0 + 1e-6));
            }
        }
    }
    e
}

fn assert_within(e: &Errors, what: &str) {
    for (name, v) in [
        ("position", e.position),
        ("log scale", e.log_scale),
        ("colour", e.colour),
        ("opacity", e.opacity),
        ("rotation", e.rotation),
        ("sh", e.sh),
    ] {
        assert!(v <= 1.0, "{what}: {name} error {v} times the stated bound");
    }
}

#[test]
fn read_back_within_the_stated_precision_with_documented_sizes() {
    for degree in 0..=3 {
        for n in [1, 255, 256, 700] {
            let g = random_gaussians(n, degree, 7 + n as u64);
            let (back, written, size) = round_trip(&g);
            assert_eq!(written, n);
            assert_eq!(size, compressed_ply_len(n, degree), "degree {degree}, {n}");
            let rest = 3 * (sh_coeff_count(degree) - 1);
            let header = compressed_ply_header(n, degree).len();
            assert_eq!(
                size as usize,
                header + 72 * n.div_ceil(256) + (16 + rest) * n
            );
            let e = errors(&g, &(0..n).collect::<Vec<_>>(), &back);
            assert_within(&e, &format!("degree {degree}, {n} Gaussians"));
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Counts around a chunk's size and spreads of position and scale over orders of magnitude.
    #[test]
    fn any_count_and_spread_reads_back_within_precision(
        n in 1usize..600, degree in 0u32..=3, seed in any::<u64>(), spread in -3i32..4
    ) {
        let mut g = random_gaussians(n, degree, seed);
        let s = 10f32.powi(spread);
        g.means.iter_mut().flatten().for_each(|v| *v *= s);
        g.log_scales.iter_mut().flatten().for_each(|v| *v *= s.min(3.0));
        let (back, _, size) = round_trip(&g);
        prop_assert_eq!(size, compressed_ply_len(n, degree));
        let e = errors(&g, &(0..n).collect::<Vec<_>>(), &back);
        assert_within(&e, &format!("{n} Gaussians, spread {s}"));
    }
}

#[test]
fn hard_cases_one_gaussian_zero_scale_nan_and_infinite_opacity() {
    // One Gaussian: every chunk range is empty, so it comes back exactly (rotation aside).
    let g = random_gaussians(1, 1, 3);
    let (back, _, _) = round_trip(&g);
    assert_eq!(back.means, g.means);
    assert_eq!(back.log_scales, g.log_scales);
    assert!(rotation_distance(back.rotations[0], g.rotations[0]) < 2.5e-3);

    // 300 Gaussians: a zero scale (log −inf), a zero and an infinite-opacity Gaussian, a zero
    // quaternion, and two with NaN (left out), spread over both chunks.
    let mut g = random_gaussians(300, 0, 4);
    g.log_scales[5] = [f32::NEG_INFINITY, -3.0, f32::NEG_INFINITY];
    g.log_scales[290][1] = f32::NEG_INFINITY;
    g.opacity_logits[6] = f32::INFINITY;
    g.opacity_logits[7] = f32::NEG_INFINITY;
    g.rotations[8] = [0.0; 4];
    g.means[9][1] = f32::NAN;
    g.sh[3 * 299] = f32::NAN;
    let (back, written, size) = round_trip(&g);
    assert_eq!((written, back.len()), (298, 298));
    assert_eq!(size, compressed_ply_len(298, 0));
    g.rotations[8] = [1.0, 0.0, 0.0, 0.0];
    let kept: Vec<usize> = (0..300).filter(|&i| i != 9 && i != 299).collect();
    assert_within(&errors(&g, &kept, &back), "hard cases");
    // The zero scales read as e^−20; opacities stay finite logits.
    let mut order = kept.clone();
    sort_morton(&g.means, &mut order);
    let at = |i: usize| order.iter().position(|&k| k == i).unwrap();
    assert_eq!(back.log_scales[at(5)][0], -LOG_SCALE_LIMIT);
    assert!(back.opacity_logits.iter().all(|v| v.is_finite()));
    assert!(sigmoid(back.opacity_logits[at(6)]) > 0.99);
    assert!(sigmoid(back.opacity_logits[at(7)]) < 0.01);

    // No Gaussians: a header and nothing else.
    let (back, written, size) = round_trip(&Gaussians::with_degree(2));
    assert_eq!((written, back.len(), back.sh_degree), (0, 0, 2));
    assert_eq!(size as usize, compressed_ply_header(0, 2).len());
}

#[test]
fn writes_are_atomic_and_errors_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let g = random_gaussians(10, 0, 1);
    let missing = dir.path().join("no/such/dir/f.compressed.ply");
    let e = write_compressed_ply(&missing, g.view()).unwrap_err();
    assert!(
        e.to_string().contains("no/such/dir/f.compressed.ply"),
        "{e}"
    );
    let mut bad = g.clone();
    bad.opacity_logits.pop();
    let target = dir.path().join("f.compressed.ply");
    std::fs::write(&target, b"old").unwrap();
    let e = write_compressed_ply(&target, bad.view()).unwrap_err();
    assert!(matches!(e, IoError::InvalidData { .. }), "{e}");
    assert_eq!(std::fs::read(&target).unwrap(), b"old");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn header_snapshot() {
    insta::assert_snapshot!("compressed_header_degree_1", compressed_ply_header(700, 1));
}

/// A valid two-Gaussian file at SH degree 1, as bytes, and the offset of its body.
fn valid_file() -> (Vec<u8>, usize) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("g.compressed.ply");
    write_compressed_ply(&path, random_gaussians(2, 1, 9).view()).unwrap();
    (
        std::fs::read(&path).unwrap(),
        compressed_ply_header(2, 1).len(),
    )
}

#[test]
fn malformed_files_give_one_line_errors_naming_file_and_field() {
    let (good, body) = valid_file();
    read_compressed_ply_bytes(&good, Path::new("bad.ply")).unwrap();
    let header = String::from_utf8(good[..body].to_vec()).unwrap();
    let with_header = |h: &str| [h.as_bytes(), &good[body..]].concat();
    let nan_bound = {
        let mut b = good.clone();
        b[body + 4..body + 8].copy_from_slice(&f32::NAN.to_le_bytes());
        b
    };
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("empty", Vec::new()),
        ("not ply", b"solid cube\n".to_vec()),
        ("no end_header", header.replace("end_header\n", "").into_bytes()),
        (
            "ascii",
            with_header(&header.replace("binary_little_endian", "ascii")),
        ),
        (
            "big endian",
            with_header(&header.replace("binary_little_endian", "binary_big_endian")),
        ),
        (
            "3DGS PLY",
            b"ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\nend_header\n"
                .to_vec(),
        ),
        (
            "wrong type",
            with_header(&header.replace("uint packed_scale", "float packed_scale")),
        ),
        (
            "unknown property",
            with_header(&header.replace("uint packed_color", "uint packed_colour")),
        ),
        (
            "missing property",
            with_header(&header.replace("property float min_scale_z\n", "")),
        ),
        (
            "some colour bounds",
            with_header(&header.replace("property float max_b\n", "")),
        ),
        (
            "chunk count",
            with_header(&header.replace("element chunk 1", "element chunk 2")),
        ),
        (
            "sh count",
            with_header(&header.replace("property uchar f_rest_8\n", "")),
        ),
        (
            "sh rows",
            with_header(&header.replace("element sh 2", "element sh 1")),
        ),
        ("truncated", good[..good.len() - 1].to_vec()),
        ("NaN bound", nan_bound),
    ];
    let mut report = String::new();
    for (name, bytes) in &cases {
        let err = read_compressed_ply_bytes(bytes, Path::new("bad.ply")).expect_err(name);
        let message = err.to_string();
        assert!(message.starts_with("bad.ply: "), "{name}: {message}");
        assert_eq!(message.lines().count(), 1, "{name}: {message}");
        report.push_str(&format!("{name}: {message}\n"));
    }
    insta::assert_snapshot!("compressed_malformed_messages", report);
    assert!(report.contains("field `chunk[0].min_y`: NaN is not finite"));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Any bytes of a valid file replaced, or the file cut short: the reader returns Gaussians
    /// with consistent lengths or an error, never panics.
    #[test]
    fn damaged_files_read_or_fail_without_panicking(
        edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8),
        cut in any::<prop::sample::Index>(),
        truncate in any::<bool>(),
    ) {
        let (mut bytes, _) = valid_file();
        for (at, byte) in edits {
            let at = at.index(bytes.len());
            bytes[at] = byte;
        }
        if truncate {
            bytes.truncate(cut.index(bytes.len()));
        }
        if let Ok(g) = read_compressed_ply_bytes(&bytes, Path::new("fuzz.ply")) {
            let n = g.means.len();
            prop_assert_eq!(g.log_scales.len(), n);
            prop_assert_eq!(g.rotations.len(), n);
            prop_assert_eq!(g.opacity_logits.len(), n);
            prop_assert_eq!(g.sh.len(), n * 3 * sh_coeff_count(g.sh_degree));
            prop_assert!(g.means.iter().flatten().all(|v| v.is_finite()));
        }
    }
}
