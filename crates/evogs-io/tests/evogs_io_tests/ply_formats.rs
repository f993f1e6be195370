//! PLY reading and writing: bit-exact round trips, the 3DGS layout, every accepted encoding and
//! type, and clear errors for malformed files.

use crate::common;

use std::path::Path;

use common::{assert_bits_equal, encode_ply, names_3dgs, random_gaussians, rows_3dgs};
use evogs_io::ply::{Encoding, PlyProblem, ply_header};
use evogs_io::{IoError, read_ply, read_ply_bytes, write_ply, write_ply_to};
use proptest::prelude::*;
use splat_core::Gaussians;

fn to_bytes(g: &Gaussians) -> Vec<u8> {
    let mut out = Vec::new();
    write_ply_to(&mut out, g.view(), Path::new("mem.ply")).unwrap();
    out
}

fn read(bytes: &[u8]) -> Result<evogs_io::LoadedPly, IoError> {
    read_ply_bytes(bytes, Path::new("bad.ply"))
}

fn problem(bytes: &[u8]) -> PlyProblem {
    match read(bytes) {
        Err(IoError::Ply { problem, .. }) => problem,
        other => panic!("expected a PLY problem, got {other:?}"),
    }
}

fn float_props(degree: u32) -> Vec<(String, String)> {
    names_3dgs(degree)
        .into_iter()
        .map(|n| (n, "float".to_string()))
        .collect()
}

/// Gaussians whose values are arbitrary f32 bit patterns (NaN payloads and infinities included).
fn arbitrary_bits() -> impl Strategy<Value = Gaussians> {
    (0u32..=3, 0usize..12).prop_flat_map(|(degree, n)| {
        let stride = 3 * ((degree + 1) * (degree + 1)) as usize;
        prop::collection::vec(any::<u32>(), n * (11 + stride)).prop_map(move |bits| {
            let f: Vec<f32> = bits.into_iter().map(f32::from_bits).collect();
            let mut g = Gaussians::with_degree(degree);
            for row in f.chunks_exact(11 + stride) {
                g.means.push([row[0], row[1], row[2]]);
                g.log_scales.push([row[3], row[4], row[5]]);
                g.rotations.push([row[6], row[7], row[8], row[9]]);
                g.opacity_logits.push(row[10]);
                g.sh.extend_from_slice(&row[11..]);
            }
            g
        })
    })
}

proptest! {
    #[test]
    fn write_then_read_is_bit_exact(g in arbitrary_bits()) {
        let loaded = read(&to_bytes(&g)).unwrap();
        assert_bits_equal(&g, &loaded.gaussians);
        let stride = g.sh_stride();
        let nonfinite = (0..g.len())
            .filter(|&i| {
                g.means[i].iter().chain(&g.log_scales[i]).chain(&g.rotations[i])
                    .chain(std::iter::once(&g.opacity_logits[i]))
                    .chain(&g.sh[i * stride..(i + 1) * stride])
                    .any(|v| !v.is_finite())
            })
            .count();
        prop_assert_eq!(loaded.nonfinite_rows, nonfinite);
        prop_assert_eq!(loaded.encoding, Encoding::BinaryLittleEndian);
        prop_assert!(loaded.ignored_properties.is_empty());
    }

    /// Any property order, float or double per property, small integers in any integer type
    /// for x/y/z, unknown extra properties, and every encoding read to the same Gaussians.
    #[test]
    fn any_order_types_and_encoding_read_the_same(
        degree in 0u32..=3,
        n in 0usize..6,
        seed in any::<u64>(),
        encoding in prop::sample::select(vec!["ascii", "binary_little_endian", "binary_big_endian"]),
        order_seed in any::<u64>(),
        type_choices in prop::collection::vec(0usize..4, 64),
        int_means in any::<bool>(),
        extras in 0usize..3,
    ) {
        let mut g = random_gaussians(n, degree, seed);
        if int_means {
            for m in &mut g.means {
                *m = m.map(|v| (v * 20.0).round() + 0.0); // no -0: integers have no sign of zero
            }
        }
        let names = names_3dgs(degree);
        let mut rows = rows_3dgs(&g);
        let mut props: Vec<(String, String)> = names
            .iter()
            .zip(&type_choices)
            .map(|(name, &choice)| {
                let is_mean = matches!(name.as_str(), "x" | "y" | "z");
                let ty = match (is_mean && int_means, choice) {
                    (true, 0) => "short",
                    (true, 1) => "int",
                    (true, 2) => "char",
                    (false, 0 | 2) => "double",
                    _ => "float",
                };
                (name.clone(), ty.to_string())
            })
            .collect();
        for e in 0..extras {
            props.push((format!("extra_{e}"), "uchar".into()));
            for r in &mut rows {
                r.push(7.0);
            }
        }
        // Permute columns deterministically from the seed.
        let mut order: Vec<usize> = (0..props.len()).collect();
        let mut state = order_seed | 1;
        for i in (1..order.len()).rev() {
            state ^= state << 13; state ^= state >> 7; state ^= state << 17;
            order.swap(i, (state % (i as u64 + 1)) as usize);
        }
        let props: Vec<_> = order.iter().map(|&i| props[i].clone()).collect();
        let rows: Vec<Vec<f64>> = rows.iter().map(|r| order.iter().map(|&i| r[i]).collect()).collect();
        let loaded = read(&encode_ply(encoding, &props, &rows)).unwrap();
        assert_bits_equal(&g, &loaded.gaussians);
        prop_assert_eq!(loaded.ignored_properties.len(), extras);
        prop_assert_eq!(loaded.nonfinite_rows, 0);
    }
}

#[test]
fn written_file_is_the_3dgs_layout() {
    let g = random_gaussians(3, 3, 11);
    let bytes = to_bytes(&g);
    let header = ply_header(3, 3);
    insta::assert_snapshot!("header_degree_3", header);
    // The body equals an independent encoding of the 3DGS rows.
    let expected = encode_ply("binary_little_endian", &float_props(3), &rows_3dgs(&g));
    let expected_body = &expected[expected
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11..];
    assert_eq!(&bytes[header.len()..], expected_body);
    assert_eq!(bytes.len(), header.len() + 3 * 62 * 4);
    assert!(bytes.starts_with(header.as_bytes()));
}

#[test]
fn file_round_trip_and_atomic_write() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("points.ply");
    let g = random_gaussians(100, 2, 5);
    write_ply(&path, g.view()).unwrap();
    let loaded = read_ply(&path).unwrap();
    assert_bits_equal(&g, &loaded.gaussians);
    // Inconsistent Gaussians are refused and leave the existing file as it was.
    let before = std::fs::read(&path).unwrap();
    let mut bad = g.clone();
    bad.sh.pop();
    let err = write_ply(&path, bad.view()).unwrap_err();
    assert!(matches!(err, IoError::InvalidData { .. }), "{err}");
    assert!(
        err.to_string().contains("points.ply") && err.to_string().contains("sh"),
        "{err}"
    );
    assert_eq!(std::fs::read(&path).unwrap(), before);
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    // A missing file names itself.
    let err = read_ply(&dir.path().join("absent.ply")).unwrap_err();
    assert!(err.to_string().contains("absent.ply"), "{err}");
}

#[test]
fn non_finite_rows_are_kept_and_counted() {
    let mut g = random_gaussians(5, 1, 3);
    g.means[1][0] = f32::NAN;
    let stride = g.sh_stride();
    g.sh[4 * stride + 7] = f32::INFINITY;
    g.opacity_logits[4] = f32::NEG_INFINITY;
    let loaded = read(&to_bytes(&g)).unwrap();
    assert_eq!(loaded.nonfinite_rows, 2);
    assert_bits_equal(&g, &loaded.gaussians);
    // ASCII spellings of non-finite values parse too.
    let props = float_props(0);
    let mut rows = rows_3dgs(&random_gaussians(2, 0, 1));
    rows[0][0] = f64::NAN;
    let loaded = read(&encode_ply("ascii", &props, &rows)).unwrap();
    assert_eq!(loaded.nonfinite_rows, 1);
    assert!(loaded.gaussians.means[0][0].is_nan());
}

#[test]
fn other_elements_before_and_after_vertex_are_skipped() {
    let g = random_gaussians(4, 0, 9);
    let body = to_bytes(&g);
    let header_end = body.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    // A fixed-size element before the vertices, and a list element after them.
    let mut header = String::from_utf8(body[..header_end].to_vec()).unwrap();
    header = header.replace(
        "element vertex 4\n",
        "element camera 2\nproperty double a\nproperty uchar b\nelement vertex 4\n",
    );
    header = header.replace(
        "end_header\n",
        "element face 1\nproperty list uchar int vertex_indices\nend_header\n",
    );
    let mut bytes = header.into_bytes();
    bytes.extend_from_slice(&[0xAB; 18]);
    bytes.extend_from_slice(&body[header_end..]);
    bytes.extend_from_slice(&[3, 0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0]);
    assert_bits_equal(&g, &read(&bytes).unwrap().gaussians);
    // The same in ASCII, with CRLF line ends.
    let text = "ply\r\nformat ascii 1.0\r\nelement camera 1\r\nproperty float a\r\nelement vertex 1\r\n\
        property float x\r\nproperty float y\r\nproperty float z\r\nproperty float f_dc_0\r\n\
        property float f_dc_1\r\nproperty float f_dc_2\r\nproperty float opacity\r\n\
        property float scale_0\r\nproperty float scale_1\r\nproperty float scale_2\r\n\
        property float rot_0\r\nproperty float rot_1\r\nproperty float rot_2\r\nproperty float rot_3\r\n\
        end_header\r\n5\r\n1 2 3 0.1 0.2 0.3 -1 -2 -3 -4 1 0 0 0\r\n";
    let g = read(text.as_bytes()).unwrap().gaussians;
    assert_eq!(g.means, vec![[1.0, 2.0, 3.0]]);
    assert_eq!(g.sh, vec![0.1, 0.2, 0.3]);
    assert_eq!(g.opacity_logits, vec![-1.0]);
    assert_eq!(g.log_scales, vec![[-2.0, -3.0, -4.0]]);
    assert_eq!(g.rotations, vec![[1.0, 0.0, 0.0, 0.0]]);
}

/// Malformed files: each gives a specific problem, and the messages (snapshot) name the file
/// and the field.
#[test]
fn malformed_files_give_errors_naming_the_problem() {
    let g = random_gaussians(2, 3, 4);
    let good = to_bytes(&g);
    let header_len = ply_header(2, 3).len();
    let edit = |from: &str, to: &str| -> Vec<u8> {
        let header = String::from_utf8(good[..header_len].to_vec()).unwrap();
        assert!(header.contains(from), "{from}");
        let mut bytes = header.replacen(from, to, 1).into_bytes();
        bytes.extend_from_slice(&good[header_len..]);
        bytes
    };
    let ascii = |body: &str| -> Vec<u8> {
        format!(
            "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
             property float z\nproperty float f_dc_0\nproperty float f_dc_1\nproperty float f_dc_2\n\
             property float opacity\nproperty float scale_0\nproperty float scale_1\n\
             property float scale_2\nproperty uchar rot_0\nproperty float rot_1\nproperty float rot_2\n\
             property float rot_3\nend_header\n{body}"
        )
        .into_bytes()
    };
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("empty file", Vec::new()),
        ("garbage", b"\x00\x01garbage\xff\xfe".to_vec()),
        (
            "no end_header",
            b"ply\nformat ascii 1.0\nelement vertex 1\n".to_vec(),
        ),
        (
            "unknown format",
            edit("binary_little_endian", "binary_middle_endian"),
        ),
        (
            "bad version",
            edit("binary_little_endian 1.0", "binary_little_endian 2.0"),
        ),
        ("no format", edit("format binary_little_endian 1.0\n", "")),
        (
            "unknown keyword",
            edit("element vertex 2\n", "element vertex 2\nbogus line\n"),
        ),
        ("bad count", edit("element vertex 2", "element vertex two")),
        (
            "negative count",
            edit("element vertex 2", "element vertex -2"),
        ),
        (
            "unknown type",
            edit("property float opacity", "property quad opacity"),
        ),
        (
            "duplicate property",
            edit("property float scale_1", "property float scale_0"),
        ),
        (
            "missing opacity",
            edit("property float opacity", "property float opacityx"),
        ),
        (
            "missing rot_3",
            edit("property float rot_3", "property float rot_9"),
        ),
        (
            "44 f_rest",
            edit("property float f_rest_44", "property float g_rest_44"),
        ),
        (
            "f_rest gap",
            edit("property float f_rest_44", "property float f_rest_45"),
        ),
        (
            "list in vertex",
            edit(
                "property float opacity",
                "property list uchar float opacity",
            ),
        ),
        (
            "no vertex element",
            edit("element vertex 2", "element point 2"),
        ),
        ("truncated", good[..good.len() - 5].to_vec()),
        (
            "count too large",
            edit("element vertex 2", "element vertex 3"),
        ),
        (
            "absurd count",
            edit("element vertex 2", "element vertex 18446744073709551615"),
        ),
        (
            "ascii bad value",
            ascii("1 2 3 4 5 6 7 8 9 10 1 0 0 0\n1 2 3 4 5 6 7 8 9 10 x 0 0 0\n"),
        ),
        (
            "ascii uchar out of range",
            ascii("1 2 3 4 5 6 7 8 9 10 300 0 0 0\n1 2 3 4 5 6 7 8 9 10 1 0 0 0\n"),
        ),
        (
            "ascii short row",
            ascii("1 2 3 4 5 6 7 8 9 10 1 0 0 0\n1 2 3 4 5 6 7 8 9 10 1 0 0\n"),
        ),
        // Blank lines pad the file past the size check, so the row count itself is tested.
        (
            "ascii missing row",
            ascii(&format!(
                "1 2 3 4 5 6 7 8 9 10 1 0 0 0\n{}",
                "\n".repeat(40)
            )),
        ),
        (
            "ascii not text",
            ascii("1 2 3 4 5 6 7 8 9 10 1 0 0 0\n1 2 3 4 5 6 7 8 9 10 1 0 0 \u{0}\u{0}\n")
                .into_iter()
                .map(|b| if b == 0 { 0xff } else { b })
                .collect(),
        ),
    ];
    let mut report = String::new();
    for (name, bytes) in &cases {
        let err = read(bytes).expect_err(name);
        let message = err.to_string();
        assert!(message.starts_with("bad.ply: "), "{name}: {message}");
        assert!(matches!(err, IoError::Ply { .. }), "{name}: {message}");
        report.push_str(&format!("{name}: {message}\n"));
    }
    insta::assert_snapshot!("malformed_messages", report);
    // A few checked structurally as well.
    assert_eq!(
        problem(&cases[11].1),
        PlyProblem::MissingProperty("opacity".into())
    );
    assert_eq!(problem(&cases[13].1), PlyProblem::BadShCount { count: 44 });
    assert_eq!(
        problem(&cases[14].1),
        PlyProblem::MissingProperty("f_rest_44".into())
    );
    assert!(matches!(
        problem(&cases[19].1),
        PlyProblem::Truncated {
            count: u64::MAX,
            ..
        }
    ));
}
