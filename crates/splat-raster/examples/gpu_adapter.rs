//! Prints the wgpu adapter the GPU backend and its tests will use, in one line; exits with an
//! error when there is none. `scripts/test` runs it before the tests.

fn main() -> std::process::ExitCode {
    match splat_raster::request_device() {
        Ok((adapter, _, _)) => {
            let info = adapter.get_info();
            println!(
                "wgpu adapter: {} ({:?}, {:?}, driver {} {})",
                info.name, info.backend, info.device_type, info.driver, info.driver_info
            );
            std::process::ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("wgpu adapter: none: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}
