//! Nerfies camera JSON (`camera/<id>.json`): `read_nerfies_camera`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(init: evogs_fuzz::seeds_from_env(), |data: &[u8]| {
    let path = evogs_fuzz::put("camera.json", data);
    let _ = evogs_io::read_nerfies_camera(&path);
});
