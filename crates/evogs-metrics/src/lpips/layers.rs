//! The layers of the LPIPS backbones on batches of NHWC f32 feature maps: convolution + ReLU
//! (im2col + `tiny_nn::linalg::matmul`, tiled over output pixels and threaded with rayon) and
//! max pooling without padding (torchvision's `MaxPool2d`, `ceil_mode = False`), each with a
//! plain loop reference for the tests.
//!
//! Not here: the network's layer order ([`super::network`]) and the LPIPS distance.

use rayon::prelude::*;
use tiny_nn::linalg::{matmul, parallelism};

/// A batch of feature maps, NHWC: element (image, y, x, channel) is at
/// `((image * height + y) * width + x) * channels + channel`.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Maps {
    /// Images in the batch.
    pub images: usize,
    /// Rows of each map.
    pub height: usize,
    /// Columns of each map.
    pub width: usize,
    /// Channels per pixel.
    pub channels: usize,
    /// The values.
    pub data: Vec<f32>,
}

impl Maps {
    /// Pixels of one image.
    pub fn pixels(&self) -> usize {
        self.height * self.width
    }

    /// The channels of pixel `pixel` (row-major within the image) of image `image`.
    pub fn pixel(&self, image: usize, pixel: usize) -> &[f32] {
        let start = (image * self.pixels() + pixel) * self.channels;
        &self.data[start..start + self.channels]
    }
}

/// Output side of a window of `window` pixels moved by `stride` over `side + 2 * pad` pixels
/// (floor, as PyTorch); `None` when the window does not fit once.
pub(crate) fn out_side(side: usize, window: usize, stride: usize, pad: usize) -> Option<usize> {
    (side + 2 * pad)
        .checked_sub(window)
        .map(|room| room / stride + 1)
}

/// A 2-D convolution followed by ReLU, square kernel, zero padding, no dilation or groups.
#[derive(Clone, Debug)]
pub(crate) struct Conv {
    /// Kernel side.
    pub kernel_side: usize,
    /// Input channels.
    pub channels_in: usize,
    /// Output channels.
    pub channels_out: usize,
    /// Stride in both directions.
    pub stride: usize,
    /// Zero padding on every side.
    pub pad: usize,
    /// Weights HWIO, i.e. row-major `[kernel_side · kernel_side · channels_in, channels_out]`:
    /// row `(ky · kernel_side + kx) · channels_in + c_in`.
    pub weight: Vec<f32>,
    /// One bias per output channel.
    pub bias: Vec<f32>,
}

/// Output pixels per tile of [`Conv::forward_relu`]: the tile's im2col block holds about 2²⁰
/// floats (4 MiB), within 64 and 4096 rows.
fn tile_rows(patch_len: usize) -> usize {
    ((1 << 20) / patch_len).clamp(64, 4096)
}

impl Conv {
    /// Length of one im2col row.
    fn patch_len(&self) -> usize {
        self.kernel_side * self.kernel_side * self.channels_in
    }

    /// Output `(height, width)` for an input of `height × width`, `None` when the kernel does
    /// not fit.
    pub fn out_shape(&self, height: usize, width: usize) -> Option<(usize, usize)> {
        let side = |s| out_side(s, self.kernel_side, self.stride, self.pad);
        Some((side(height)?, side(width)?)).filter(|&(h, w)| h > 0 && w > 0)
    }

    /// `relu(conv(x) + bias)`: output pixels in tiles, each tile's patches gathered into a
    /// row-major block (im2col) and multiplied by the HWIO weights on one thread, tiles spread
    /// over rayon's threads.
    ///
    /// # Panics
    /// Panics when `x` has another channel count or the kernel does not fit (the network
    /// checks sizes before running).
    pub fn forward_relu(&self, x: &Maps) -> Maps {
        assert_eq!(x.channels, self.channels_in);
        let (height, width) = self.out_shape(x.height, x.width).expect("kernel fits");
        let (k, n) = (self.patch_len(), self.channels_out);
        let rows = x.images * height * width;
        let mut data = vec![0.0f32; rows * n];
        let tile = tile_rows(k);
        data.par_chunks_mut(tile * n).enumerate().for_each_init(
            Vec::new,
            |cols: &mut Vec<f32>, (t, out)| {
                let m = out.len() / n;
                cols.resize(m * k, 0.0);
                self.im2col(x, (height, width), t * tile, cols);
                for row in out.chunks_exact_mut(n) {
                    row.copy_from_slice(&self.bias);
                }
                matmul(out, cols, &self.weight, (m, k, n), true, parallelism(1));
                for v in out.iter_mut() {
                    *v = v.max(0.0);
                }
            },
        );
        Maps {
            images: x.images,
            height,
            width,
            channels: n,
            data,
        }
    }

    /// Gathers the patches of output pixels `first..first + cols.len() / patch_len` (batch-wide
    /// row-major index) into `cols`, one row each, zeros where the patch leaves the image.
    fn im2col(&self, x: &Maps, (height, width): (usize, usize), first: usize, cols: &mut [f32]) {
        let (ks, c) = (self.kernel_side, self.channels_in);
        let k = self.patch_len();
        for (r, row) in cols.chunks_exact_mut(k).enumerate() {
            let out_index = first + r;
            let image = out_index / (height * width);
            let (oy, ox) = ((out_index / width) % height, out_index % width);
            // Input columns of the patch, as signed offsets from the image's left edge.
            let x0 = (ox * self.stride) as isize - self.pad as isize;
            let kx_lo = (-x0).max(0) as usize;
            let kx_hi = ((x.width as isize - x0).min(ks as isize)).max(0) as usize;
            for ky in 0..ks {
                let dst = &mut row[ky * ks * c..(ky + 1) * ks * c];
                let iy = (oy * self.stride + ky) as isize - self.pad as isize;
                if iy < 0 || iy >= x.height as isize || kx_lo >= kx_hi {
                    dst.fill(0.0);
                    continue;
                }
                dst[..kx_lo * c].fill(0.0);
                dst[kx_hi * c..].fill(0.0);
                let ix_lo = (x0 + kx_lo as isize) as usize;
                let src = ((image * x.height + iy as usize) * x.width + ix_lo) * c;
                dst[kx_lo * c..kx_hi * c].copy_from_slice(&x.data[src..src + (kx_hi - kx_lo) * c]);
            }
        }
    }

    /// Plain loop reference of [`Conv::forward_relu`] (f64 accumulation).
    #[cfg(test)]
    pub fn forward_relu_reference(&self, x: &Maps) -> Maps {
        let (height, width) = self.out_shape(x.height, x.width).expect("kernel fits");
        let (ks, n) = (self.kernel_side, self.channels_out);
        let mut data = Vec::with_capacity(x.images * height * width * n);
        for image in 0..x.images {
            for oy in 0..height {
                for ox in 0..width {
                    for co in 0..n {
                        let mut sum = f64::from(self.bias[co]);
                        for ky in 0..ks {
                            for kx in 0..ks {
                                let iy = (oy * self.stride + ky) as isize - self.pad as isize;
                                let ix = (ox * self.stride + kx) as isize - self.pad as isize;
                                if iy < 0 || ix < 0 || iy >= x.height as isize {
                                    continue;
                                }
                                if ix >= x.width as isize {
                                    continue;
                                }
                                let p = x.pixel(image, iy as usize * x.width + ix as usize);
                                for (ci, &v) in p.iter().enumerate() {
                                    let w = self.weight
                                        [((ky * ks + kx) * self.channels_in + ci) * n + co];
                                    sum += f64::from(v) * f64::from(w);
                                }
                            }
                        }
                        data.push(sum.max(0.0) as f32);
                    }
                }
            }
        }
        Maps {
            images: x.images,
            height,
            width,
            channels: n,
            data,
        }
    }
}

/// Max pooling over `window × window` windows moved by `stride`, no padding, floor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct MaxPool {
    /// Window side.
    pub window: usize,
    /// Stride.
    pub stride: usize,
}

impl MaxPool {
    /// Output `(height, width)`, `None` when the window does not fit.
    pub fn out_shape(&self, height: usize, width: usize) -> Option<(usize, usize)> {
        let side = |s| out_side(s, self.window, self.stride, 0);
        Some((side(height)?, side(width)?)).filter(|&(h, w)| h > 0 && w > 0)
    }

    /// The pooled maps, output rows spread over rayon's threads.
    ///
    /// # Panics
    /// Panics when the window does not fit.
    pub fn forward(&self, x: &Maps) -> Maps {
        let (height, width) = self.out_shape(x.height, x.width).expect("window fits");
        let c = x.channels;
        let mut data = vec![f32::NEG_INFINITY; x.images * height * width * c];
        data.par_chunks_mut(width * c)
            .enumerate()
            .for_each(|(row_index, out)| {
                let (image, oy) = (row_index / height, row_index % height);
                for dy in 0..self.window {
                    let iy = oy * self.stride + dy;
                    for (ox, dst) in out.chunks_exact_mut(c).enumerate() {
                        for dx in 0..self.window {
                            let src = x.pixel(image, iy * x.width + ox * self.stride + dx);
                            for (d, &s) in dst.iter_mut().zip(src) {
                                *d = d.max(s);
                            }
                        }
                    }
                }
            });
        Maps {
            images: x.images,
            height,
            width,
            channels: c,
            data,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_maps(
        rng: &mut ChaCha8Rng,
        images: usize,
        height: usize,
        width: usize,
        channels: usize,
    ) -> Maps {
        Maps {
            images,
            height,
            width,
            channels,
            data: (0..images * height * width * channels)
                .map(|_| rng.random_range(-1.0..1.0))
                .collect(),
        }
    }

    fn random_conv(
        rng: &mut ChaCha8Rng,
        kernel_side: usize,
        channels_in: usize,
        channels_out: usize,
        stride: usize,
        pad: usize,
    ) -> Conv {
        let k = kernel_side * kernel_side * channels_in;
        Conv {
            kernel_side,
            channels_in,
            channels_out,
            stride,
            pad,
            weight: (0..k * channels_out)
                .map(|_| rng.random_range(-0.5..0.5))
                .collect(),
            bias: (0..channels_out)
                .map(|_| rng.random_range(-0.2..0.2))
                .collect(),
        }
    }

    #[test]
    fn conv_matches_the_plain_loops() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        // (kernel, c_in, c_out, stride, pad, height, width): AlexNet's first layer's geometry,
        // VGG's, a kernel as large as the padded image, and a tile boundary inside an image.
        for (ks, ci, co, stride, pad, h, w) in [
            (11, 3, 5, 4, 2, 23, 19),
            (3, 4, 6, 1, 1, 9, 7),
            (5, 2, 3, 1, 2, 1, 3),
            (3, 8, 4, 1, 1, 70, 3),
            (1, 3, 2, 2, 0, 5, 6),
        ] {
            let conv = random_conv(&mut rng, ks, ci, co, stride, pad);
            let x = random_maps(&mut rng, 2, h, w, ci);
            let (fast, slow) = (conv.forward_relu(&x), conv.forward_relu_reference(&x));
            assert_eq!((fast.height, fast.width), (slow.height, slow.width));
            let err = fast
                .data
                .iter()
                .zip(&slow.data)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f32::max);
            assert!(
                err < 1e-5,
                "kernel {ks} stride {stride} pad {pad} {h}x{w}: {err}"
            );
            assert!(fast.data.iter().any(|&v| v > 0.0) && fast.data.contains(&0.0));
        }
    }

    #[test]
    fn conv_shapes_follow_pytorch_floor() {
        let conv = Conv {
            kernel_side: 11,
            channels_in: 3,
            channels_out: 1,
            stride: 4,
            pad: 2,
            weight: vec![0.0; 363],
            bias: vec![0.0],
        };
        assert_eq!(conv.out_shape(224, 224), Some((55, 55)));
        assert_eq!(conv.out_shape(400, 401), Some((99, 99)));
        assert_eq!(conv.out_shape(7, 8), Some((1, 1)));
        assert_eq!(conv.out_shape(6, 8), None);
    }

    #[test]
    fn max_pool_matches_the_plain_loops() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for (window, stride, h, w) in [(3, 2, 9, 8), (2, 2, 7, 5), (3, 2, 3, 3)] {
            let pool = MaxPool { window, stride };
            let x = random_maps(&mut rng, 2, h, w, 3);
            let y = pool.forward(&x);
            assert_eq!(
                (y.height, y.width),
                ((h - window) / stride + 1, (w - window) / stride + 1)
            );
            for image in 0..2 {
                for oy in 0..y.height {
                    for ox in 0..y.width {
                        for c in 0..3 {
                            let mut best = f32::NEG_INFINITY;
                            for dy in 0..window {
                                for dx in 0..window {
                                    let p =
                                        x.pixel(image, (oy * stride + dy) * w + ox * stride + dx);
                                    best = best.max(p[c]);
                                }
                            }
                            assert_eq!(y.pixel(image, oy * y.width + ox)[c], best);
                        }
                    }
                }
            }
        }
        assert_eq!(
            MaxPool {
                window: 3,
                stride: 2
            }
            .out_shape(2, 9),
            None
        );
    }
}
