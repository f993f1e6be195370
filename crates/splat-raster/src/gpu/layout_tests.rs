//! The checks of the Rust mirrors of [`super::layout`] against the shaders (compiled for tests
//! only): every uniform declared through `wgsl_mirror!` ([`FrameUniform`] as `Frame`, the
//! sort's `Params`, the scan's `ScanParams`) against the WGSL declaration read from the shader
//! source, field by field (name, type, byte offset, size) and in the struct's size; the record
//! layouts that exist only on the device by size (`Splat`) and stride (the backward's output)
//! against the constants the Rust side sizes buffers with; and the dispatch sizes and cull codes
//! against the kernels' constants.
//!
//! Not in `layout` itself: the modules checked here import `layout` for its macro, so the checks
//! sit above them, in a module that nothing imports.

use super::backward::OUT_STRIDE;
use super::forward::SPLAT_BYTES;
use super::frame::FrameUniform;
use super::scan::ScanParams;
use super::sort::Params;
use crate::wgsl_text::{const_value, struct_layout};

const COMMON: &str = include_str!("shaders/common.wgsl");
const SORT_COMMON: &str = include_str!("shaders/sort_common.wgsl");
const SCAN: &str = include_str!("shaders/scan.wgsl");
const PROJECT_BWD: &str = include_str!("shaders/project_bwd.wgsl");

type Fields = &'static [(&'static str, &'static str, usize, usize)];

/// Panics, naming the struct and the first difference, unless the Rust fields and size equal
/// the WGSL declaration's.
fn check(fields: Fields, rust_size: usize, src: &str, wgsl_name: &str) {
    let (members, wgsl_size) = struct_layout(src, wgsl_name);
    let wgsl: Vec<(&str, &str, usize, usize)> = members
        .iter()
        .map(|m| (m.name.as_str(), m.ty.as_str(), m.offset, m.size))
        .collect();
    for (k, (r, w)) in fields.iter().zip(&wgsl).enumerate() {
        assert_eq!(
            r, w,
            "{wgsl_name} field {k}: Rust (name, type, offset, size) vs WGSL"
        );
    }
    assert_eq!(fields.len(), wgsl.len(), "{wgsl_name}: number of fields");
    assert_eq!(rust_size, wgsl_size, "{wgsl_name}: size in bytes");
}

#[test]
fn uniforms_match_their_wgsl_structs() {
    check(
        FrameUniform::FIELDS,
        size_of::<FrameUniform>(),
        COMMON,
        "Frame",
    );
    check(Params::FIELDS, size_of::<Params>(), SORT_COMMON, "Params");
    check(
        ScanParams::FIELDS,
        size_of::<ScanParams>(),
        SCAN,
        "ScanParams",
    );
}

#[test]
fn device_records_match_the_sizes_the_buffers_are_made_for() {
    assert_eq!(struct_layout(COMMON, "Splat").1 as u64, SPLAT_BYTES);
    assert_eq!(const_value(PROJECT_BWD, "OUT_STRIDE"), OUT_STRIDE as f64);
}

#[test]
fn dispatch_sizes_and_cull_codes_match_the_kernels() {
    use super::forward::cull;
    // The Rust side sizes the dispatches and buffers with these; the kernels index with theirs.
    assert_eq!(const_value(SCAN, "BLOCK"), f64::from(super::scan::BLOCK));
    assert_eq!(
        const_value(SORT_COMMON, "BLOCK"),
        f64::from(super::sort::BLOCK)
    );
    assert_eq!(
        const_value(SORT_COMMON, "BINS"),
        f64::from(super::sort::BINS)
    );
    // The projection counts each Gaussian at the index of its `CULL_*` code.
    for (name, index) in [
        ("CULL_NON_FINITE", cull::NON_FINITE),
        ("CULL_ZERO_QUATERNION", cull::ZERO_QUATERNION),
        ("CULL_LOW_OPACITY", cull::LOW_OPACITY),
        ("CULL_BEHIND_NEAR_PLANE", cull::BEHIND_NEAR_PLANE),
        ("CULL_DEGENERATE", cull::DEGENERATE),
        ("CULL_OFF_SCREEN", cull::OFF_SCREEN),
    ] {
        assert_eq!(const_value(COMMON, name), index as f64, "{name}");
    }
    assert_eq!(cull::DRAWN, 0, "a Gaussian with reason 0 is drawn");
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
            check(
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
        check(Params::FIELDS, size_of::<Params>(), &retyped, "Params");
    });
    assert!(sort.is_err());
}
