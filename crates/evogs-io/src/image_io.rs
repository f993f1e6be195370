//! Images as f32 RGB in file space (no sRGB conversion: 3DGS compares colours as stored), loaded
//! from PNG or JPEG, alpha composited over a background, resized with the camera, saved as PNG.

use std::path::Path;

use image::{DynamicImage, ImageFormat, ImageReader, Rgb32FImage};
use splat_core::Camera;

use crate::IoError;
use crate::atomic::write_atomically;

/// An RGB image with f32 channels, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageRgb {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height` pixels, row-major.
    pub pixels: Vec<[f32; 3]>,
}

impl ImageRgb {
    /// A `width × height` image filled with one colour.
    pub fn filled(width: u32, height: u32, colour: [f32; 3]) -> Self {
        Self {
            width,
            height,
            pixels: vec![colour; width as usize * height as usize],
        }
    }

    /// The pixel at column `x`, row `y`.
    pub fn get(&self, x: u32, y: u32) -> [f32; 3] {
        self.pixels[y as usize * self.width as usize + x as usize]
    }
}

/// Loads a PNG or JPEG (format guessed from the content) as f32 RGB in [0, 1], channel values
/// divided by the format's maximum (255 or 65535). An alpha channel is composited over
/// `background`: `c·α + background·(1 − α)`.
pub fn load_image(path: &Path, background: [f32; 3]) -> Result<ImageRgb, IoError> {
    Ok(to_rgb(&decode(path)?, background))
}

/// Loads an image's transmittance `1 − α` per pixel (0 everywhere without an alpha channel),
/// row-major, resized by `factor` as [`load_view`] resizes the image. The image composited over a
/// colour `b` is the one over black plus `b` times this, up to rounding (compositing and the
/// resize filters are linear): a trainer draws a new background from these two.
pub fn load_transmittance(path: &Path, factor: f32) -> Result<Vec<f32>, IoError> {
    let decoded = decode(path)?;
    let (width, height) = (decoded.width(), decoded.height());
    let pixels = if decoded.color().has_alpha() {
        decoded
            .to_rgba32f()
            .pixels()
            .map(|p| [1.0 - p.0[3]; 3])
            .collect()
    } else {
        vec![[0.0; 3]; width as usize * height as usize]
    };
    let image = ImageRgb {
        width,
        height,
        pixels,
    };
    let resized = resize_image(&image, factor).ok_or_else(|| IoError::InvalidData {
        path: path.to_path_buf(),
        problem: format!("resize factor {factor} is not a positive number"),
    })?;
    Ok(resized.pixels.iter().map(|p| p[0]).collect())
}

/// Decodes a PNG or JPEG, the format guessed from the content.
fn decode(path: &Path) -> Result<DynamicImage, IoError> {
    ImageReader::open(path)
        .map_err(|e| IoError::io(path, e))?
        .with_guessed_format()
        .map_err(|e| IoError::io(path, e))?
        .decode()
        .map_err(|cause| IoError::Image {
            path: path.to_path_buf(),
            cause,
        })
}

fn to_rgb(decoded: &DynamicImage, background: [f32; 3]) -> ImageRgb {
    let (width, height) = (decoded.width(), decoded.height());
    let pixels = if decoded.color().has_alpha() {
        decoded
            .to_rgba32f()
            .pixels()
            .map(|p| {
                let a = p.0[3];
                [0, 1, 2].map(|c| p.0[c] * a + background[c] * (1.0 - a))
            })
            .collect()
    } else {
        decoded.to_rgb32f().pixels().map(|p| p.0).collect()
    };
    ImageRgb {
        width,
        height,
        pixels,
    }
}

/// The integer `n` when `factor` is `1/n` for a whole `n >= 2` dividing both sides.
fn box_divisor(image: &ImageRgb, factor: f32) -> Option<u32> {
    let n = (1.0 / factor as f64).round();
    let exact = (n * factor as f64 - 1.0).abs() < 1e-6;
    let n = n as u32;
    (exact && n >= 2 && image.width.is_multiple_of(n) && image.height.is_multiple_of(n))
        .then_some(n)
}

/// Resizes by `factor` (> 0) to the size [`Camera::scaled`] gives. A factor `1/n` whose `n`
/// divides both sides uses an exact box (area) filter; other factors use a triangle filter.
/// Returns `None` when the factor is not a positive finite number.
pub fn resize_image(image: &ImageRgb, factor: f32) -> Option<ImageRgb> {
    if !(factor.is_finite() && factor > 0.0) {
        return None;
    }
    if factor == 1.0 {
        return Some(image.clone());
    }
    if let Some(n) = box_divisor(image, factor) {
        let (w, h) = (image.width / n, image.height / n);
        let norm = 1.0 / (n * n) as f32;
        let mut pixels = Vec::with_capacity(w as usize * h as usize);
        for y in 0..h {
            for x in 0..w {
                let mut sum = [0f32; 3];
                for dy in 0..n {
                    for dx in 0..n {
                        let p = image.get(x * n + dx, y * n + dy);
                        (0..3).for_each(|c| sum[c] += p[c]);
                    }
                }
                pixels.push(sum.map(|s| s * norm));
            }
        }
        return Some(ImageRgb {
            width: w,
            height: h,
            pixels,
        });
    }
    let side = |s: u32| (s as f32 * factor).round().max(1.0) as u32;
    let (w, h) = (side(image.width), side(image.height));
    let flat: Vec<f32> = image.pixels.iter().flatten().copied().collect();
    let source = Rgb32FImage::from_raw(image.width, image.height, flat)?;
    let resized = image::imageops::resize(&source, w, h, image::imageops::FilterType::Triangle);
    Some(ImageRgb {
        width: w,
        height: h,
        pixels: resized.pixels().map(|p| p.0).collect(),
    })
}

/// Loads the image a camera sees, composited over `background`, and resizes both by `factor`
/// (intrinsics scaled by the same factor, DESIGN §1.2). The image must be the camera's size.
pub fn load_view(
    path: &Path,
    camera: &Camera,
    background: [f32; 3],
    factor: f32,
) -> Result<(ImageRgb, Camera), IoError> {
    let image = load_image(path, background)?;
    if (image.width, image.height) != (camera.width, camera.height) {
        return Err(IoError::InvalidData {
            path: path.to_path_buf(),
            problem: format!(
                "image is {}×{} but its camera is {}×{}",
                image.width, image.height, camera.width, camera.height
            ),
        });
    }
    let resized = resize_image(&image, factor).ok_or_else(|| IoError::InvalidData {
        path: path.to_path_buf(),
        problem: format!("resize factor {factor} is not a positive number"),
    })?;
    let mut scaled = camera.scaled(factor);
    // Keep the camera's size equal to the image's whatever rounding the filter chose.
    scaled.width = resized.width;
    scaled.height = resized.height;
    Ok((resized, scaled))
}

/// Converts a channel value to 8 bits: clamped to [0, 1], times 255, rounded; NaN becomes 0.
pub fn to_u8(v: f32) -> u8 {
    if v.is_nan() {
        0
    } else {
        (v.clamp(0.0, 1.0) * 255.0).round() as u8
    }
}

/// Saves an 8-bit RGB image (a plot, a picture) as a PNG, atomically.
pub fn save_rgb8_png(path: &Path, image: &image::RgbImage) -> Result<(), IoError> {
    write_atomically(path, |w| {
        image
            .write_to(w, ImageFormat::Png)
            .map_err(|cause| IoError::Image {
                path: path.to_path_buf(),
                cause,
            })
    })
}

/// Saves f32 RGB pixels as an 8-bit PNG (see [`to_u8`]), atomically.
pub fn save_png(path: &Path, image: &ImageRgb) -> Result<(), IoError> {
    let expected = image.width as usize * image.height as usize;
    if image.pixels.len() != expected || image.width == 0 || image.height == 0 {
        return Err(IoError::InvalidData {
            path: path.to_path_buf(),
            problem: format!(
                "{} pixels for a {}×{} image",
                image.pixels.len(),
                image.width,
                image.height
            ),
        });
    }
    let bytes: Vec<u8> = image.pixels.iter().flatten().map(|&v| to_u8(v)).collect();
    let rgb = image::RgbImage::from_raw(image.width, image.height, bytes).ok_or_else(|| {
        IoError::InvalidData {
            path: path.to_path_buf(),
            problem: "pixel buffer does not match the size".into(),
        }
    })?;
    save_rgb8_png(path, &rgb)
}
