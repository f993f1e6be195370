//! Images: file-space f32 RGB, alpha compositing, box and filtered resizing with the camera,
//! atomic clamped PNG output.

use std::path::Path;

use evogs_io::image_io::to_u8;
use evogs_io::{
    ImageRgb, IoError, load_image, load_transmittance, load_view, resize_image, save_png,
};
use glam::Vec3;
use proptest::prelude::*;
use splat_core::Camera;

fn save_rgba(path: &Path, w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 4]) {
    image::RgbaImage::from_fn(w, h, |x, y| image::Rgba(f(x, y)))
        .save(path)
        .unwrap();
}

#[test]
fn rgba_is_composited_over_the_background_in_file_space() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("a.png");
    save_rgba(&path, 3, 2, |x, _| [200, 100, 0, [0, 128, 255][x as usize]]);
    let bg = [0.25, 0.5, 1.0];
    let img = load_image(&path, bg).unwrap();
    assert_eq!((img.width, img.height), (3, 2));
    assert_eq!(img.get(0, 0), bg);
    let opaque = img.get(2, 1);
    assert!((opaque[0] - 200.0 / 255.0).abs() < 1e-6 && (opaque[1] - 100.0 / 255.0).abs() < 1e-6);
    let a = 128.0f32 / 255.0;
    let want: [f32; 3] = [200.0 / 255.0, 100.0 / 255.0, 0.0];
    let got = img.get(1, 0);
    for c in 0..3 {
        let expected = want[c] * a + bg[c] * (1.0 - a);
        assert!((got[c] - expected).abs() < 1e-6, "{got:?}");
    }
}

#[test]
fn sixteen_bit_gray_and_jpeg_load() {
    let dir = tempfile::tempdir().unwrap();
    let p16 = dir.path().join("deep.png");
    image::ImageBuffer::<image::Rgb<u16>, _>::from_pixel(2, 2, image::Rgb([65535, 32768, 0]))
        .save(&p16)
        .unwrap();
    let img = load_image(&p16, [0.0; 3]).unwrap();
    let deep = img.get(1, 1);
    assert!(
        (deep[0] - 1.0).abs() < 1e-6
            && (deep[1] - 32768.0 / 65535.0).abs() < 1e-6
            && deep[2] == 0.0
    );
    let gray = dir.path().join("gray.png");
    image::GrayImage::from_pixel(2, 1, image::Luma([51]))
        .save(&gray)
        .unwrap();
    assert!(
        load_image(&gray, [0.0; 3])
            .unwrap()
            .get(1, 0)
            .iter()
            .all(|v| (v - 0.2).abs() < 1e-6)
    );
    let jpg = dir.path().join("flat.jpg");
    image::RgbImage::from_pixel(16, 16, image::Rgb([40, 120, 200]))
        .save(&jpg)
        .unwrap();
    let img = load_image(&jpg, [0.0; 3]).unwrap();
    for (got, want) in img.get(8, 8).iter().zip([40.0f32, 120.0, 200.0]) {
        assert!((got * 255.0 - want).abs() < 4.0, "{:?}", img.get(8, 8));
    }
    // A PNG saved under a .jpg name is still read by its content.
    let misnamed = dir.path().join("really_png.jpg");
    std::fs::copy(&gray, &misnamed).unwrap();
    assert_eq!(load_image(&misnamed, [0.0; 3]).unwrap().width, 2);
}

#[test]
fn bad_images_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("broken.png");
    std::fs::write(&path, b"\x89PNG\r\n\x1a\nthen nothing").unwrap();
    let err = load_image(&path, [0.0; 3]).unwrap_err();
    assert!(
        matches!(err, IoError::Image { .. }) && err.to_string().contains("broken.png"),
        "{err}"
    );
    let err = load_image(&dir.path().join("absent.png"), [0.0; 3]).unwrap_err();
    assert!(
        matches!(err, IoError::Io { .. }) && err.to_string().contains("absent.png"),
        "{err}"
    );
}

#[test]
fn box_downscale_averages_blocks_and_scales_the_camera() {
    let img = ImageRgb {
        width: 4,
        height: 2,
        pixels: (0..8).map(|i| [i as f32, 0.0, 1.0]).collect(),
    };
    let half = resize_image(&img, 0.5).unwrap();
    assert_eq!((half.width, half.height), (2, 1));
    assert_eq!(half.pixels, vec![[2.5, 0.0, 1.0], [4.5, 0.0, 1.0]]);
    let third = resize_image(&ImageRgb::filled(9, 6, [0.3, 0.6, 0.9]), 1.0 / 3.0).unwrap();
    assert_eq!((third.width, third.height), (3, 2));
    assert!(
        third
            .pixels
            .iter()
            .flatten()
            .zip([0.3, 0.6, 0.9].iter().cycle())
            .all(|(a, b)| (a - b).abs() < 1e-6)
    );
    // Non-integer factors go through the filter, to Camera::scaled's size.
    let cam = Camera::look_at(10, 7, 1.0, Vec3::new(0.0, -3.0, 0.0), Vec3::ZERO, Vec3::Z);
    let odd = resize_image(&ImageRgb::filled(10, 7, [0.5; 3]), 0.75).unwrap();
    let scaled = cam.scaled(0.75);
    assert_eq!((odd.width, odd.height), (scaled.width, scaled.height));
    assert!(odd.pixels.iter().flatten().all(|&v| (v - 0.5).abs() < 1e-5));
    assert!(resize_image(&img, 0.0).is_none());
    assert!(resize_image(&img, f32::NAN).is_none());
}

#[test]
fn load_view_resizes_image_and_camera_together() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("v.png");
    save_rgba(&path, 8, 4, |x, _| [(x * 30) as u8, 0, 0, 255]);
    let cam = Camera::look_at(8, 4, 1.0, Vec3::new(0.0, -3.0, 0.0), Vec3::ZERO, Vec3::Z);
    let (img, scaled) = load_view(&path, &cam, [0.0; 3], 0.5).unwrap();
    assert_eq!(
        (img.width, img.height, scaled.width, scaled.height),
        (4, 2, 4, 2)
    );
    assert_eq!(
        (scaled.fx, scaled.cx, scaled.cy),
        (cam.fx * 0.5, cam.cx * 0.5, cam.cy * 0.5)
    );
    assert!((img.get(1, 0)[0] - (60.0 + 90.0) / 2.0 / 255.0).abs() < 1e-6);
    let err = load_view(&path, &cam, [0.0; 3], -1.0).unwrap_err();
    assert!(err.to_string().contains("v.png"), "{err}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    /// Over any colour, the image a view loads is the one over black plus the colour times the
    /// transmittance, after an exact box or a filtered resize alike.
    #[test]
    fn transmittance_recomposites_the_view_over_any_colour(
        rgba in proptest::collection::vec(any::<[u8; 4]>(), 36),
        bg in any::<[u8; 3]>(),
        filtered in any::<bool>(),
    ) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("rgba.png");
        save_rgba(&path, 6, 6, |x, y| rgba[(y * 6 + x) as usize]);
        let cam = Camera::look_at(6, 6, 1.0, Vec3::new(0.0, -3.0, 0.0), Vec3::ZERO, Vec3::Z);
        let factor = if filtered { 0.75 } else { 0.5 };
        let bg = bg.map(|v| f32::from(v) / 255.0);
        let (over_black, _) = load_view(&path, &cam, [0.0; 3], factor).unwrap();
        let (over_bg, _) = load_view(&path, &cam, bg, factor).unwrap();
        let t = load_transmittance(&path, factor).unwrap();
        prop_assert_eq!(t.len(), over_black.pixels.len());
        for ((black, want), t) in over_black.pixels.iter().zip(&over_bg.pixels).zip(&t) {
            prop_assert!((-1e-6..=1.0 + 1e-6).contains(t), "{}", t);
            for c in 0..3 {
                prop_assert!((black[c] + t * bg[c] - want[c]).abs() < 1e-5, "{:?} {:?} {}", black, want, t);
            }
        }
    }
}

#[test]
fn transmittance_is_zero_without_alpha_and_errors_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("opaque.png");
    image::RgbImage::from_pixel(4, 2, image::Rgb([9, 99, 199]))
        .save(&path)
        .unwrap();
    assert_eq!(load_transmittance(&path, 0.5).unwrap(), vec![0.0; 2]);
    let half = dir.path().join("half.png");
    save_rgba(&half, 2, 2, |x, _| [0, 0, 0, [0, 255][x as usize]]);
    assert_eq!(
        load_transmittance(&half, 1.0).unwrap(),
        vec![1.0, 0.0, 1.0, 0.0]
    );
    let err = load_transmittance(&dir.path().join("absent.png"), 1.0).unwrap_err();
    assert!(err.to_string().contains("absent.png"), "{err}");
    let err = load_transmittance(&path, 0.0).unwrap_err();
    assert!(err.to_string().contains("opaque.png"), "{err}");
}

#[test]
fn png_output_is_clamped_rounded_and_atomic() {
    assert_eq!(to_u8(-0.3), 0);
    assert_eq!(to_u8(1.7), 255);
    assert_eq!(to_u8(f32::NAN), 0);
    assert_eq!(to_u8(f32::INFINITY), 255);
    assert_eq!(to_u8(0.5), 128);
    assert_eq!(to_u8(0.5 / 255.0 - 1e-4), 0);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.png");
    let img = ImageRgb {
        width: 3,
        height: 1,
        pixels: vec![
            [0.0, 0.5, 1.0],
            [2.0, -1.0, f32::NAN],
            [10.0 / 255.0, 0.2, 0.8],
        ],
    };
    save_png(&path, &img).unwrap();
    let back = image::open(&path).unwrap().to_rgb8();
    let bytes: Vec<u8> = back.pixels().flat_map(|p| p.0).collect();
    assert_eq!(bytes, vec![0, 128, 255, 255, 0, 0, 10, 51, 204]);
    // A bad image is refused and the old file stays.
    let before = std::fs::read(&path).unwrap();
    let bad = ImageRgb { width: 4, ..img };
    let err = save_png(&path, &bad).unwrap_err();
    assert!(err.to_string().contains("out.png"), "{err}");
    assert_eq!(std::fs::read(&path).unwrap(), before);
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn an_8_bit_image_is_saved_exactly_and_errors_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("plot.png");
    let img = image::RgbImage::from_fn(3, 2, |x, y| image::Rgb([x as u8 * 80, y as u8 * 200, 7]));
    evogs_io::image_io::save_rgb8_png(&path, &img).unwrap();
    assert_eq!(image::open(&path).unwrap().to_rgb8(), img);
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    let missing = dir.path().join("no-such-dir").join("plot.png");
    let err = evogs_io::image_io::save_rgb8_png(&missing, &img).unwrap_err();
    assert!(err.to_string().contains("plot.png"), "{err}");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    /// Saving then loading returns each value to within half an 8-bit level.
    #[test]
    fn png_round_trip_within_half_a_level(w in 1u32..9, h in 1u32..9, seed in prop::collection::vec(0.0f32..1.0, 243)) {
        let pixels: Vec<[f32; 3]> = (0..(w * h) as usize).map(|i| [seed[3 * i], seed[3 * i + 1], seed[3 * i + 2]]).collect();
        let img = ImageRgb { width: w, height: h, pixels };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.png");
        save_png(&path, &img).unwrap();
        let back = load_image(&path, [0.0; 3]).unwrap();
        for (a, b) in img.pixels.iter().flatten().zip(back.pixels.iter().flatten()) {
            prop_assert!((a - b).abs() <= 0.5 / 255.0 + 1e-6);
        }
    }
}
