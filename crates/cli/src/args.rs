//! Command-line arguments (clap derive).

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};

/// Dynamic 3D Gaussian Splatting with EvoGS. So far: render a 3DGS PLY or the demo scene.
#[derive(Debug, Parser)]
#[command(name = "evogs", version)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Render Gaussians (a 3DGS PLY, or the built-in demo scene) to a PNG image.
    Render(RenderArgs),
}

/// Arguments of `evogs render`.
#[derive(Debug, Args)]
#[command(
    after_help = "Without --ply and --camera, renders the built-in procedural demo scene \
                        (a torus, spheres and a ground disc) from a default camera."
)]
pub struct RenderArgs {
    /// Gaussians to render: a PLY file in the 3DGS layout. Needs --camera.
    #[arg(long, value_name = "FILE", requires = "camera")]
    pub ply: Option<PathBuf>,

    /// Camera to render from: a nerfies camera JSON file. Needs --ply.
    #[arg(long, value_name = "CAMERA.json", requires = "ply")]
    pub camera: Option<PathBuf>,

    /// Output PNG image, written atomically (temporary file, then rename).
    #[arg(long, value_name = "IMAGE.png")]
    pub out: PathBuf,

    /// Background colour behind the Gaussians, three numbers in [0, 1].
    #[arg(long, value_name = "R,G,B", default_value = "0,0,0", value_parser = parse_background)]
    pub background: [f32; 3],

    /// Image width in pixels [demo scene default: 800]. With --camera, the camera is resized to
    /// this width (intrinsics scaled to match).
    #[arg(long, value_name = "PIXELS", value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub width: Option<u32>,

    /// Image height in pixels [demo scene default: 600]. With --camera, the camera is resized to
    /// this height (intrinsics scaled to match).
    #[arg(long, value_name = "PIXELS", value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub height: Option<u32>,
}

/// Parses `R,G,B` with each channel a number in [0, 1].
pub fn parse_background(text: &str) -> Result<[f32; 3], String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!(
            "expected three comma-separated numbers R,G,B, found {} part(s)",
            parts.len()
        ));
    }
    let mut colour = [0f32; 3];
    for (channel, (slot, part)) in colour.iter_mut().zip(&parts).enumerate() {
        let value: f32 = part
            .parse()
            .map_err(|_| format!("channel {channel} `{part}` is not a number"))?;
        if !(0.0..=1.0).contains(&value) {
            return Err(format!("channel {channel} is {value}, outside [0, 1]"));
        }
        *slot = value;
    }
    Ok(colour)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn background_parsing() {
        assert_eq!(parse_background("0,0.5, 1").unwrap(), [0.0, 0.5, 1.0]);
        assert!(parse_background("1,1").unwrap_err().contains("three"));
        assert!(parse_background("1,x,1").unwrap_err().contains("channel 1"));
        assert!(parse_background("1,1,1.5").unwrap_err().contains("outside"));
        assert!(parse_background("NaN,0,0").unwrap_err().contains("outside"));
    }

    #[test]
    fn clap_definition_is_consistent() {
        use clap::CommandFactory;
        Cli::command().debug_assert();
    }
}
