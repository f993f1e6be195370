//! EvoGS state files (safetensors): `EvoState::load`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(init: evogs_fuzz::seeds_from_env(), |data: &[u8]| {
    let path = evogs_fuzz::put("evo_state.safetensors", data);
    if let Ok(state) = evo_state::EvoState::load(&path) {
        assert_eq!(state.valid().len(), state.frames().len());
    }
});
