//! Training checkpoints (safetensors with a JSON header): `load_checkpoint` into the state of
//! the `tiny` preset with a small network (`evogs_fuzz::tiny_config`, which its seed was written with).
#![no_main]

use evogs_train::checkpoint::load_checkpoint;
use libfuzzer_sys::fuzz_target;

fuzz_target!(init: evogs_fuzz::seeds_from_env(), |data: &[u8]| {
    let path = evogs_fuzz::put("checkpoint.safetensors", data);
    let (mut state, mut backbone) = evogs_fuzz::tiny_state();
    if let Ok(meta) = load_checkpoint(&path, &mut state, backbone.as_mut()) {
        assert_eq!(state.gaussians.means.len(), meta.gaussians);
        assert_eq!(state.stats.grad_sum.len(), meta.gaussians);
    }
});
