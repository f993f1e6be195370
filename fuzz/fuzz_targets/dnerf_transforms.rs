//! D-NeRF `transforms_*.json`: `read_transforms` in a folder whose `train`/`val`/`test` images
//! are the repository's lego fixture.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(init: evogs_fuzz::seeds_from_env(), |data: &[u8]| {
    let dir = evogs_fuzz::dnerf_scene("dnerf");
    let path = dir.join("transforms_train.json");
    std::fs::write(&path, data).unwrap();
    if let Ok(frames) = evogs_io::read_transforms(&path) {
        for f in &frames {
            assert!((0.0..=1.0).contains(&f.time));
        }
    }
});
