//! Test helpers: an independent PLY encoder and random Gaussians.
#![allow(dead_code)]

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use splat_core::Gaussians;

/// The 3DGS property names for a degree, written out independently of the crate.
pub fn names_3dgs(degree: u32) -> Vec<String> {
    let rest = 3 * ((degree + 1) * (degree + 1) - 1) as usize;
    let mut v: Vec<String> = vec![
        "x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2",
    ]
    .into_iter()
    .map(String::from)
    .collect();
    v.extend((0..rest).map(|i| format!("f_rest_{i}")));
    v.push("opacity".into());
    v.extend((0..3).map(|i| format!("scale_{i}")));
    v.extend((0..4).map(|i| format!("rot_{i}")));
    v
}

/// Rows in the 3DGS order, as f64.
pub fn rows_3dgs(g: &Gaussians) -> Vec<Vec<f64>> {
    let coeffs = ((g.sh_degree + 1) * (g.sh_degree + 1)) as usize;
    let stride = coeffs * 3;
    (0..g.len())
        .map(|i| {
            let mut row: Vec<f64> = g.means[i].iter().map(|&v| v as f64).collect();
            row.extend([0.0; 3]);
            let sh = &g.sh[i * stride..(i + 1) * stride];
            row.extend(sh[..3].iter().map(|&v| v as f64));
            for c in 0..3 {
                for k in 1..coeffs {
                    row.push(sh[k * 3 + c] as f64);
                }
            }
            row.push(g.opacity_logits[i] as f64);
            row.extend(g.log_scales[i].iter().map(|&v| v as f64));
            row.extend(g.rotations[i].iter().map(|&v| v as f64));
            row
        })
        .collect()
}

/// Encodes a PLY file with one `vertex` element: `format` is `ascii`, `binary_little_endian`
/// or `binary_big_endian`; each property has a PLY type name.
pub fn encode_ply(format: &str, props: &[(String, String)], rows: &[Vec<f64>]) -> Vec<u8> {
    let mut out = format!(
        "ply\nformat {format} 1.0\ncomment test file\nelement vertex {}\n",
        rows.len()
    );
    for (name, ty) in props {
        out.push_str(&format!("property {ty} {name}\n"));
    }
    out.push_str("end_header\n");
    let mut bytes = out.into_bytes();
    let big = format == "binary_big_endian";
    for row in rows {
        assert_eq!(row.len(), props.len());
        if format == "ascii" {
            let text: Vec<String> = row
                .iter()
                .zip(props)
                .map(|(&v, (_, ty))| match ty.as_str() {
                    "float" | "float32" => format!("{}", v as f32),
                    "double" | "float64" => format!("{v}"),
                    _ => format!("{}", v as i64),
                })
                .collect();
            bytes.extend_from_slice(text.join(" ").as_bytes());
            bytes.push(b'\n');
            continue;
        }
        for (&v, (_, ty)) in row.iter().zip(props) {
            macro_rules! put {
                ($x:expr) => {
                    if big {
                        bytes.extend_from_slice(&$x.to_be_bytes())
                    } else {
                        bytes.extend_from_slice(&$x.to_le_bytes())
                    }
                };
            }
            match ty.as_str() {
                "float" | "float32" => put!(v as f32),
                "double" | "float64" => put!(v),
                "char" | "int8" => put!(v as i8),
                "uchar" | "uint8" => put!(v as u8),
                "short" | "int16" => put!(v as i16),
                "ushort" | "uint16" => put!(v as u16),
                "int" | "int32" => put!(v as i32),
                "uint" | "uint32" => put!(v as u32),
                other => panic!("unknown type {other}"),
            }
        }
    }
    bytes
}

/// Random Gaussians with finite values of moderate size.
pub fn random_gaussians(n: usize, degree: u32, seed: u64) -> Gaussians {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut g = Gaussians::with_degree(degree);
    let stride = g.sh_stride();
    for _ in 0..n {
        g.means.push([0; 3].map(|_| rng.random_range(-5.0..5.0)));
        g.log_scales
            .push([0; 3].map(|_| rng.random_range(-6.0..0.0)));
        g.rotations
            .push([0; 4].map(|_| rng.random_range(-1.0..1.0)));
        g.opacity_logits.push(rng.random_range(-4.0..4.0));
        g.sh.extend((0..stride).map(|_| rng.random_range(-1.0f32..1.0)));
    }
    g
}

/// Bitwise equality of every value (NaN payloads included).
pub fn assert_bits_equal(a: &Gaussians, b: &Gaussians) {
    assert_eq!(a.sh_degree, b.sh_degree);
    assert_eq!(a.len(), b.len());
    let bits = |g: &Gaussians| -> Vec<u32> {
        g.means
            .iter()
            .flatten()
            .chain(g.log_scales.iter().flatten())
            .chain(g.rotations.iter().flatten())
            .chain(g.opacity_logits.iter())
            .chain(g.sh.iter())
            .map(|v| v.to_bits())
            .collect()
    };
    assert_eq!(bits(a), bits(b));
}
