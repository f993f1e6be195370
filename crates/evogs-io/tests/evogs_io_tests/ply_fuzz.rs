//! Fuzz-style robustness: mutated PLY files (byte flips, truncations, insertions, header edits)
//! never panic or allocate beyond the file's size; whatever parses is self-consistent.

use crate::common;

use std::path::Path;

use common::{encode_ply, names_3dgs, random_gaussians, rows_3dgs};
use evogs_io::read_ply_bytes;
use proptest::prelude::*;

fn base_files() -> Vec<Vec<u8>> {
    let typed = |degree: u32, ty: &str| -> Vec<(String, String)> {
        names_3dgs(degree)
            .into_iter()
            .map(|n| (n, ty.to_string()))
            .collect()
    };
    let g1 = random_gaussians(3, 1, 1);
    let g0 = random_gaussians(3, 0, 2);
    let g2 = random_gaussians(2, 2, 3);
    let mut with_elements = encode_ply("binary_big_endian", &typed(2, "double"), &rows_3dgs(&g2));
    // Put a small element before the vertices.
    let at = with_elements
        .windows(7)
        .position(|w| w == b"element")
        .unwrap();
    with_elements.splice(
        at..at,
        b"element extra 1\nproperty short s\n".iter().copied(),
    );
    let header_end = with_elements
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    with_elements.splice(header_end..header_end, [0u8, 7]);
    vec![
        encode_ply("binary_little_endian", &typed(1, "float"), &rows_3dgs(&g1)),
        encode_ply("ascii", &typed(0, "float"), &rows_3dgs(&g0)),
        with_elements,
    ]
}

#[derive(Clone, Debug)]
enum Mutation {
    Flip {
        at: usize,
        xor: u8,
    },
    Truncate {
        keep: usize,
    },
    Insert {
        at: usize,
        bytes: Vec<u8>,
    },
    HeaderToken {
        line: usize,
        token: usize,
        text: String,
    },
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let token_text = prop_oneof![
        Just("18446744073709551615".to_string()),
        Just("4294967296".to_string()),
        Just("-1".to_string()),
        Just("0".to_string()),
        Just("list".to_string()),
        Just("double".to_string()),
        Just("uchar".to_string()),
        Just("ascii".to_string()),
        Just("binary_big_endian".to_string()),
        Just("f_rest_3".to_string()),
        Just(String::new()),
        "[a-z_0-9 ]{0,12}",
    ];
    prop_oneof![
        (any::<usize>(), 1u8..=255).prop_map(|(at, xor)| Mutation::Flip { at, xor }),
        any::<usize>().prop_map(|keep| Mutation::Truncate { keep }),
        (any::<usize>(), prop::collection::vec(any::<u8>(), 1..8))
            .prop_map(|(at, bytes)| Mutation::Insert { at, bytes }),
        (0usize..70, 0usize..4, token_text).prop_map(|(line, token, text)| Mutation::HeaderToken {
            line,
            token,
            text
        }),
    ]
}

fn apply(bytes: &mut Vec<u8>, m: &Mutation) {
    match m {
        Mutation::Flip { at, xor } => {
            if !bytes.is_empty() {
                let i = at % bytes.len();
                bytes[i] ^= xor;
            }
        }
        Mutation::Truncate { keep } => bytes.truncate(keep % (bytes.len() + 1)),
        Mutation::Insert { at, bytes: new } => {
            let i = at % (bytes.len() + 1);
            bytes.splice(i..i, new.iter().copied());
        }
        Mutation::HeaderToken { line, token, text } => {
            let Some(end) = bytes.windows(11).position(|w| w == b"end_header\n") else {
                return;
            };
            let header = String::from_utf8_lossy(&bytes[..end]).to_string();
            let mut lines: Vec<String> = header.lines().map(String::from).collect();
            if lines.is_empty() {
                return;
            }
            let l = line % lines.len();
            let mut tokens: Vec<String> = lines[l].split(' ').map(String::from).collect();
            let t = token % tokens.len();
            tokens[t] = text.clone();
            lines[l] = tokens.join(" ");
            let mut rebuilt = lines.join("\n").into_bytes();
            rebuilt.push(b'\n');
            rebuilt.extend_from_slice(&bytes[end..]);
            *bytes = rebuilt;
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 600, ..ProptestConfig::default() })]

    #[test]
    fn mutated_files_never_panic(
        base in 0usize..3,
        mutations in prop::collection::vec(mutation(), 1..4),
    ) {
        let mut bytes = base_files().swap_remove(base);
        for m in &mutations {
            apply(&mut bytes, m);
        }
        match read_ply_bytes(&bytes, Path::new("fuzz.ply")) {
            Ok(loaded) => {
                let g = &loaded.gaussians;
                prop_assert!(g.view().check_lengths().is_ok());
                // Rows cannot outnumber the bytes that hold them.
                prop_assert!(g.len() <= bytes.len());
            }
            Err(err) => prop_assert!(err.to_string().starts_with("fuzz.ply: ")),
        }
    }
}

#[test]
fn unmutated_bases_parse() {
    for (i, bytes) in base_files().iter().enumerate() {
        let loaded = read_ply_bytes(bytes, Path::new("base.ply")).unwrap();
        assert!(loaded.gaussians.len() >= 2, "base {i}");
    }
}
