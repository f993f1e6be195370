//! Nerfies dataset JSON: the input is `dataset.json`, `metadata.json` and `scene.json` separated
//! by NUL bytes, read by `load_dataset` in a scene with two valid cameras (`a`, `b`) and images.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(init: evogs_fuzz::seeds_from_env(), |data: &[u8]| {
    let dir = evogs_fuzz::nerfies_scene("nerfies");
    let files = evogs_fuzz::parts(data, 3);
    for (name, bytes) in ["dataset.json", "metadata.json", "scene.json"].iter().zip(files) {
        std::fs::write(dir.join(name), bytes).unwrap();
    }
    if let Ok(dataset) = evogs_io::load_dataset(&dir, &evogs_io::LoadOptions::default()) {
        assert!(dataset.all_frames().count() > 0);
    }
});
