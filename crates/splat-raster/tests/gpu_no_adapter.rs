//! Without an adapter the wgpu backend is a clear error, never a panic. Its own test binary
//! (one test, one thread), because it narrows wgpu's backends through the environment.

use splat_raster::{GpuContext, RasterError, WgpuRasterizer};

#[test]
fn no_adapter_is_an_error_naming_the_stage_and_the_remedy() {
    // SAFETY: this binary runs this single test on one thread, and no other thread of the
    // process reads or writes the environment while it is changed.
    unsafe {
        // A backend this build does not compile in: wgpu finds no adapter at all.
        std::env::set_var("WGPU_BACKEND", "gl");
    }
    let err = GpuContext::new().unwrap_err();
    assert_eq!(err.stage, "adapter");
    assert!(err.message.contains("no GPU adapter"), "{err}");
    assert!(err.message.contains("CPU backend"), "{err}");
    assert!(
        err.to_string().starts_with("wgpu backend (adapter): "),
        "{err}"
    );
    // The rasterizer reports the same, as its own error type.
    let raster = WgpuRasterizer::new().unwrap_err();
    assert_eq!(raster, RasterError::from(err.clone()));
    assert_eq!(raster.to_string(), err.to_string());
}
