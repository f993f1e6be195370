//! Per-frame blocks of N × D values in f32 or f16: the buffer of corrected states `B[k][i] ∈ R^D`
//! and, beside it, the residual memory `M[k][i]` (DESIGN §4.2, §4.8), each one contiguous block per frame.
//! Exactly `Storage::bytes() · D` bytes per Gaussian per frame.

use half::f16;
use rayon::prelude::*;

use crate::config::Storage;
use splat_core::{NewRows, RowPlan, RowPlanError};

/// Largest finite f16 value; f16 storage saturates here (tiny-nn's, whose f16 network storage
/// saturates at the same bound).
pub use tiny_nn::F16_MAX;

/// One frame's block in its storage type.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Block {
    F32(Vec<f32>),
    F16(Vec<f16>),
}

impl Block {
    fn zeros(storage: Storage, len: usize) -> Self {
        match storage {
            Storage::F32 => Block::F32(vec![0.0; len]),
            Storage::F16 => Block::F16(vec![f16::ZERO; len]),
        }
    }

    pub(crate) fn byte_len(&self) -> usize {
        match self {
            Block::F32(v) => v.len() * 4,
            Block::F16(v) => v.len() * 2,
        }
    }
}

/// Per-frame blocks of values (corrected states, or residual memory).
#[derive(Debug, Clone, PartialEq)]
pub struct StateBuffer {
    pub(crate) storage: Storage,
    pub(crate) rows: usize,
    pub(crate) dim: usize,
    pub(crate) blocks: Vec<Block>,
}

/// Read access to one frame's block, converting to f64.
#[derive(Clone, Copy)]
pub(crate) enum FrameRef<'a> {
    F32(&'a [f32]),
    F16(&'a [f16]),
}

impl FrameRef<'_> {
    /// Copies row `i` (D values) into `out`.
    #[inline]
    pub(crate) fn read_row(&self, i: usize, out: &mut [f64]) {
        let d = out.len();
        match self {
            FrameRef::F32(v) => {
                for (o, &x) in out.iter_mut().zip(&v[i * d..i * d + d]) {
                    *o = x as f64;
                }
            }
            FrameRef::F16(v) => {
                for (o, &x) in out.iter_mut().zip(&v[i * d..i * d + d]) {
                    *o = x.to_f64();
                }
            }
        }
    }
}

/// Converts to f16, saturating at ±65504. Returns the value and whether it saturated.
#[inline]
pub fn saturate_f16(x: f32) -> (f16, bool) {
    if x > F16_MAX {
        (f16::MAX, true)
    } else if x < -F16_MAX {
        (f16::MIN, true)
    } else {
        (f16::from_f32(x), false)
    }
}

impl StateBuffer {
    /// A zeroed buffer of `frames` blocks of `rows` × `dim`.
    pub fn new(storage: Storage, frames: usize, rows: usize, dim: usize) -> Self {
        let blocks = (0..frames)
            .map(|_| Block::zeros(storage, rows * dim))
            .collect();
        Self {
            storage,
            rows,
            dim,
            blocks,
        }
    }

    /// Bytes held by the stored states (all frames).
    pub fn byte_len(&self) -> usize {
        self.blocks.iter().map(Block::byte_len).sum()
    }

    pub(crate) fn frame(&self, k: usize) -> FrameRef<'_> {
        match &self.blocks[k] {
            Block::F32(v) => FrameRef::F32(v),
            Block::F16(v) => FrameRef::F16(v),
        }
    }

    /// Reads row `i` of frame `k` as f32 (for inspection and tests).
    pub fn row(&self, k: usize, i: usize) -> Vec<f32> {
        let mut out = vec![0.0f64; self.dim];
        self.frame(k).read_row(i, &mut out);
        out.into_iter().map(|x| x as f32).collect()
    }

    /// Writes a whole frame from f32 values; returns the number of saturated values (f16).
    pub(crate) fn write_frame(&mut self, k: usize, values: &[f32]) -> u64 {
        match &mut self.blocks[k] {
            Block::F32(v) => {
                v.copy_from_slice(values);
                0
            }
            Block::F16(v) => {
                use half::slice::HalfFloatSliceExt;
                // Clamp a chunk into scratch, then convert it with half's slice conversion
                // (hardware F16C where available); count what the clamp changed.
                let mut saturated = 0u64;
                let mut scratch = [0.0f32; 4096];
                for (out, src) in v
                    .chunks_mut(scratch.len())
                    .zip(values.chunks(scratch.len()))
                {
                    let tmp = &mut scratch[..src.len()];
                    for (t, &x) in tmp.iter_mut().zip(src) {
                        saturated += (x.abs() > F16_MAX) as u64;
                        *t = x.clamp(-F16_MAX, F16_MAX);
                    }
                    out.convert_from_f32_slice(tmp);
                }
                saturated
            }
        }
    }

    /// Sets every value of frame `k` to zero.
    pub(crate) fn clear_frame(&mut self, k: usize) {
        match &mut self.blocks[k] {
            Block::F32(v) => v.fill(0.0),
            Block::F16(v) => v.fill(f16::ZERO),
        }
    }

    /// Applies a row plan to every frame: new rows copy their parent's rows in all frames.
    pub(crate) fn apply_rows(&mut self, plan: &RowPlan) -> Result<(), RowPlanError> {
        // Validate once before touching anything, so an error leaves the buffer unchanged.
        plan.validate(self.rows)?;
        // Frames are independent arrays: apply the plan to them in parallel, each in place.
        let dim = self.dim;
        self.blocks
            .par_iter_mut()
            .try_for_each(|block| match block {
                Block::F32(v) => plan.apply(v, dim, NewRows::CopyParent),
                Block::F16(v) => plan.apply(v, dim, NewRows::CopyParent),
            })?;
        self.rows = plan.new_len();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_per_gaussian_per_frame_are_exactly_storage_times_dim() {
        for (storage, bytes) in [(Storage::F32, 4), (Storage::F16, 2)] {
            for dim in [1, 3, 10, 14] {
                let (frames, rows) = (7, 13);
                let buffer = StateBuffer::new(storage, frames, rows, dim);
                assert_eq!(buffer.byte_len(), bytes * dim * frames * rows);
            }
        }
    }

    #[test]
    fn f16_saturates_and_counts() {
        let mut buffer = StateBuffer::new(Storage::F16, 1, 2, 2);
        let saturated = buffer.write_frame(0, &[1e5, -7e4, 65504.0, 1.5]);
        assert_eq!(saturated, 2);
        assert_eq!(buffer.row(0, 0), vec![65504.0, -65504.0]);
        assert_eq!(buffer.row(0, 1), vec![65504.0, 1.5]);
    }
}
