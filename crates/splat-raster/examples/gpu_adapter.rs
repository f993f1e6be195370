//! Prints the wgpu adapter the GPU backend and its tests will use, in one line; exits with an
//! error when there is none. `scripts/test` runs it before the tests.

fn main() -> std::process::ExitCode {
    match splat_raster::GpuContext::new() {
        Ok(ctx) => {
            println!("wgpu adapter: {}", ctx.adapter());
            std::process::ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("wgpu adapter: none: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}
