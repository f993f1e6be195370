//! The `dnerf` capture protocol's files, pinned: a digest of every file a small scene writes
//! (snapshot taken before capture protocols existed, so adding the `monocular` protocol and the
//! noise options provably left the D-NeRF output byte for byte unchanged).

use std::path::{Path, PathBuf};

use evogs_synth::{Preset, SceneSpec, generate, write_dnerf};

/// FNV-1a, 64 bits: a digest that is stable across Rust versions and platforms.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(walk(&p));
        } else {
            out.push(p);
        }
    }
    out
}

#[test]
fn dnerf_scene_files_are_unchanged() {
    let spec = SceneSpec::preset(Preset::Mixed)
        .with_size(16)
        .with_frames(6)
        .with_gaussian_scale(0.1);
    let scene = generate(&spec, 11).unwrap();
    let dir = tempfile::tempdir().unwrap();
    write_dnerf(&scene, dir.path()).unwrap();
    let mut files = walk(dir.path());
    files.sort();
    let listing: String = files
        .iter()
        .map(|f| {
            let bytes = std::fs::read(f).unwrap();
            format!(
                "{} {:6} {:016x}\n",
                f.strip_prefix(dir.path()).unwrap().display(),
                bytes.len(),
                fnv1a(&bytes)
            )
        })
        .collect();
    insta::assert_snapshot!("dnerf_files", listing);
}
