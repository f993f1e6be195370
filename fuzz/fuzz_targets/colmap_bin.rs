//! COLMAP binary model files: the first byte picks `cameras.bin`, `images.bin` or
//! `points3D.bin`, the rest is the file.
#![no_main]

use std::path::Path;

use evogs_io::colmap::{parse_cameras_bin, parse_images_bin, parse_points3d_bin};
use libfuzzer_sys::fuzz_target;

fuzz_target!(init: evogs_fuzz::seeds_from_env(), |data: &[u8]| {
    let Some((&which, file)) = data.split_first() else {
        return;
    };
    match which % 3 {
        0 => drop(parse_cameras_bin(Path::new("cameras.bin"), file)),
        1 => drop(parse_images_bin(Path::new("images.bin"), file)),
        _ => drop(parse_points3d_bin(Path::new("points3D.bin"), file)),
    }
});
