//! COLMAP text model files: the first byte picks `cameras.txt`, `images.txt` or
//! `points3D.txt`, the rest is the file (UTF-8; other bytes are rejected before parsing, as
//! when reading the file).
#![no_main]

use std::path::Path;

use evogs_io::colmap::{parse_cameras_txt, parse_images_txt, parse_points3d_txt};
use libfuzzer_sys::fuzz_target;

fuzz_target!(init: evogs_fuzz::seeds_from_env(), |data: &[u8]| {
    let Some((&which, file)) = data.split_first() else {
        return;
    };
    let Ok(text) = std::str::from_utf8(file) else {
        return;
    };
    match which % 3 {
        0 => drop(parse_cameras_txt(Path::new("cameras.txt"), text)),
        1 => drop(parse_images_txt(Path::new("images.txt"), text)),
        _ => drop(parse_points3d_txt(Path::new("points3D.txt"), text)),
    }
});
