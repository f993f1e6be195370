//! The uniforms of the sort and the scan (declared through `wgsl_mirror!`) against their WGSL
//! declarations, the block sizes the Rust side dispatches with against the kernels' constants,
//! and a check that a drifted declaration is caught. Compiled for tests only; not in `layout`
//! itself, since the modules checked here import `layout`'s macro.

use crate::scan::{BLOCK as SCAN_BLOCK, ScanParams};
use crate::sort::{BINS, BLOCK as SORT_BLOCK, Params};
use crate::wgsl_text::{check_mirror, const_value};

const SORT_COMMON: &str = include_str!("shaders/sort_common.wgsl");
const SCAN: &str = include_str!("shaders/scan.wgsl");

#[test]
fn uniforms_match_their_wgsl_structs() {
    check_mirror(Params::FIELDS, size_of::<Params>(), SORT_COMMON, "Params");
    check_mirror(
        ScanParams::FIELDS,
        size_of::<ScanParams>(),
        SCAN,
        "ScanParams",
    );
}

#[test]
fn block_sizes_match_the_kernels() {
    assert_eq!(const_value(SCAN, "BLOCK"), f64::from(SCAN_BLOCK));
    assert_eq!(const_value(SORT_COMMON, "BLOCK"), f64::from(SORT_BLOCK));
    assert_eq!(const_value(SORT_COMMON, "BINS"), f64::from(BINS));
}

#[test]
fn a_drifted_declaration_is_caught() {
    // Two fields swapped, a type changed, a field dropped: each must fail the check.
    let swapped = SCAN.replace(
        "    pad0: u32,\n    pad1: u32,",
        "    pad1: u32,\n    pad0: u32,",
    );
    let retyped = SORT_COMMON.replace("    shift: u32,", "    shift: f32,");
    let dropped = SCAN.replace("    pad2: u32,\n", "");
    assert_ne!(swapped, SCAN);
    assert_ne!(retyped, SORT_COMMON);
    assert_ne!(dropped, SCAN);
    let scan = |src: String| {
        std::panic::catch_unwind(move || {
            check_mirror(
                ScanParams::FIELDS,
                size_of::<ScanParams>(),
                &src,
                "ScanParams",
            );
        })
    };
    assert!(scan(swapped).is_err());
    assert!(scan(dropped).is_err());
    let sort = std::panic::catch_unwind(move || {
        check_mirror(Params::FIELDS, size_of::<Params>(), &retyped, "Params");
    });
    assert!(sort.is_err());
}
