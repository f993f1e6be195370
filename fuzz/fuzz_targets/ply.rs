//! PLY (ASCII and binary of either endianness): `read_ply_bytes`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(init: evogs_fuzz::seeds_from_env(), |data: &[u8]| {
    if let Ok(loaded) = evogs_io::read_ply_bytes(data, std::path::Path::new("fuzz.ply")) {
        let g = &loaded.gaussians;
        let n = g.means.len();
        assert_eq!(g.log_scales.len(), n);
        assert_eq!(g.rotations.len(), n);
        assert_eq!(g.opacity_logits.len(), n);
        assert_eq!(g.sh.len(), n * 3 * splat_core::sh_coeff_count(g.sh_degree));
        // Every Gaussian takes at least one byte of the file.
        assert!(n <= data.len());
    }
});
