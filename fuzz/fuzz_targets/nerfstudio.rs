//! nerfstudio `transforms.json`: `read_nerfstudio_dataset` in a folder holding two 8×6 images
//! (`images/a.png`, `images/b.png`) and an ASCII point cloud (`sparse_pc.ply`); the first byte
//! picks how times are given when the frames have none, the rest is the file.
#![no_main]

use evogs_io::TimeFrom;
use evogs_io::nerfstudio::read_nerfstudio_dataset;
use libfuzzer_sys::fuzz_target;

fuzz_target!(init: evogs_fuzz::seeds_from_env(), |data: &[u8]| {
    let Some((&which, file)) = data.split_first() else {
        return;
    };
    let dir = evogs_fuzz::nerfstudio_scene("nerfstudio");
    std::fs::write(dir.join("transforms.json"), file).unwrap();
    let time_from = [TimeFrom::Order, TimeFrom::Name, TimeFrom::None][usize::from(which % 3)];
    if let Ok(dataset) = read_nerfstudio_dataset(&dir, time_from) {
        assert!(dataset.all_frames().count() > 0);
        for frame in dataset.all_frames() {
            assert!((0.0..=1.0).contains(&frame.time));
        }
    }
});
