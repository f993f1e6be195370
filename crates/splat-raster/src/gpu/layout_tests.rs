//! The rasterizer's Rust mirrors against its shaders (compiled for tests only): the uniform
//! declared through `gpu_core::wgsl_mirror!` ([`FrameUniform`] as `Frame`) against the WGSL
//! declaration, field by field (name, type, byte offset, size) and in the struct's size; the
//! record layouts that exist only on the device by size (`Splat`) and stride (the backward's
//! output) against the constants the Rust side sizes buffers with; and the cull codes against the
//! kernels' constants. The sort's and scan's uniforms are checked in `gpu-core`.

use super::backward::OUT_STRIDE;
use super::forward::SPLAT_BYTES;
use super::frame::FrameUniform;
use gpu_core::wgsl_text::{check_mirror, const_value, struct_layout};

const COMMON: &str = include_str!("shaders/common.wgsl");
const PROJECT_BWD: &str = include_str!("shaders/project_bwd.wgsl");

#[test]
fn uniforms_match_their_wgsl_structs() {
    check_mirror(
        FrameUniform::FIELDS,
        size_of::<FrameUniform>(),
        COMMON,
        "Frame",
    );
}

#[test]
fn device_records_match_the_sizes_the_buffers_are_made_for() {
    assert_eq!(struct_layout(COMMON, "Splat").1 as u64, SPLAT_BYTES);
    assert_eq!(const_value(PROJECT_BWD, "OUT_STRIDE"), OUT_STRIDE as f64);
}

#[test]
fn cull_codes_match_the_kernels() {
    use super::forward::cull;
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
