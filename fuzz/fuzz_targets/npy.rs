//! NumPy `.npy` arrays: `parse_npy`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(init: evogs_fuzz::seeds_from_env(), |data: &[u8]| {
    if let Ok(array) = evogs_io::npy::parse_npy(std::path::Path::new("fuzz.npy"), data) {
        assert_eq!(array.data.len(), array.shape.iter().product::<usize>());
    }
});
