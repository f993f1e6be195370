//! The `run` target: `evogs_fuzz::targets::run` (its reader and checks are documented there).
#![no_main]

libfuzzer_sys::fuzz_target!(init: evogs_fuzz::seeds_from_env(), |data: &[u8]| {
    evogs_fuzz::targets::run(data);
});
