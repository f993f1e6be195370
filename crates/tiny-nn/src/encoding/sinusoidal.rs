//! Sinusoidal (NeRF / D-3DGS) positional encoding.
//!
//! For an input row `x` of width `d` and `L` frequencies, the output row is
//! `[x, sin(2^0 x), cos(2^0 x), sin(2^1 x), cos(2^1 x), …, sin(2^(L-1) x), cos(2^(L-1) x)]`,
//! each block `d` wide, with no π factor: exactly D-3DGS's `get_embedder(multires = L)`
//! (`include_input = True`, `log_sampling = True`, `periodic_fns = [sin, cos]`, the frequency loop
//! outside the function loop). Width `d · (1 + 2L)`: 63 for xyz with L = 10, 13 for t with L = 6.

use rayon::prelude::*;

use super::ENC_ROWS;
use crate::error::{NnError, check_len};

/// The encoding; it has no parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sinusoidal {
    input: usize,
    freqs: usize,
}

impl Sinusoidal {
    /// An encoding of `input`-wide rows with `freqs` frequencies `2^0 … 2^(freqs-1)`.
    pub fn new(input: usize, freqs: usize) -> Result<Self, NnError> {
        if input == 0 {
            return Err(NnError::Config("sinusoidal encoding of width 0".into()));
        }
        if freqs > 64 {
            return Err(NnError::Config(format!(
                "sinusoidal encoding with {freqs} > 64 frequencies"
            )));
        }
        Ok(Self { input, freqs })
    }

    /// Input width.
    pub fn input_width(&self) -> usize {
        self.input
    }

    /// Number of frequencies.
    pub fn freqs(&self) -> usize {
        self.freqs
    }

    /// Output width `input · (1 + 2 · freqs)`.
    pub fn output_width(&self) -> usize {
        self.input * (1 + 2 * self.freqs)
    }

    /// Encodes one row `x` (input width) into `out` (output width).
    pub fn encode_row_into(&self, x: &[f32], out: &mut [f32]) {
        let d = self.input;
        out[..d].copy_from_slice(x);
        for f in 0..self.freqs {
            let scale = (1u64 << f) as f32;
            let base = d * (1 + 2 * f);
            for (i, &v) in x.iter().enumerate() {
                let (s, c) = (v * scale).sin_cos();
                out[base + i] = s;
                out[base + d + i] = c;
            }
        }
    }

    /// Writes dL/dx of one row into `gx` from the row's output gradient `go`.
    pub fn backward_row_into(&self, x: &[f32], go: &[f32], gx: &mut [f32]) {
        let d = self.input;
        gx.copy_from_slice(&go[..d]);
        for f in 0..self.freqs {
            let scale = (1u64 << f) as f32;
            let base = d * (1 + 2 * f);
            for (i, &v) in x.iter().enumerate() {
                let (s, c) = (v * scale).sin_cos();
                gx[i] += scale * (c * go[base + i] - s * go[base + d + i]);
            }
        }
    }

    /// Encodes `rows` rows of `x`.
    pub fn forward(&self, x: &[f32], rows: usize) -> Result<Vec<f32>, NnError> {
        let (d, w) = (self.input, self.output_width());
        check_len("sinusoidal input", rows * d, x.len())?;
        let mut out = vec![0f32; rows * w];
        out.par_chunks_mut(ENC_ROWS * w)
            .zip(x.par_chunks(ENC_ROWS * d))
            .for_each(|(o, xs)| {
                for (orow, xrow) in o.chunks_exact_mut(w).zip(xs.chunks_exact(d)) {
                    self.encode_row_into(xrow, orow);
                }
            });
        Ok(out)
    }

    /// dL/dx from dL/d(encoding) `d_out`, at the inputs `x`.
    pub fn backward(&self, x: &[f32], d_out: &[f32], rows: usize) -> Result<Vec<f32>, NnError> {
        let (d, w) = (self.input, self.output_width());
        check_len("sinusoidal input", rows * d, x.len())?;
        check_len("sinusoidal output gradient", rows * w, d_out.len())?;
        let mut dx = vec![0f32; rows * d];
        dx.par_chunks_mut(ENC_ROWS * d)
            .zip(x.par_chunks(ENC_ROWS * d))
            .zip(d_out.par_chunks(ENC_ROWS * w))
            .for_each(|((g, xs), go)| {
                for ((grow, xrow), orow) in g
                    .chunks_exact_mut(d)
                    .zip(xs.chunks_exact(d))
                    .zip(go.chunks_exact(w))
                {
                    self.backward_row_into(xrow, orow, grow);
                }
            });
        Ok(dx)
    }
}
