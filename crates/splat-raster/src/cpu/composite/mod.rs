//! Per-tile compositing: front-to-back blending of a tile's depth-ordered list over a block of
//! 16×16 pixels, and its back-to-front backward pass that recovers each pixel's transmittance by
//! division. Two implementations of each kernel:
//! - [`scalar`]: the plain reference, one pixel at a time (gsplat style: the readable definition
//!   the fast kernels are tested against);
//! - [`lanes`]: the fast kernels, eight pixels of a tile row at a time (see [`crate::cpu::simd`]).
//!
//! Which of the two a pass runs is chosen here too: [`CpuKernel`] (the user's choice) and
//! [`Kernels`] (the kernels that run, kept in the forward pass's state so that its backward pass
//! runs the same).
//!
//! What it is not: projection, binning or the per-Gaussian backward (see `project`, `tiles`).

pub(crate) mod lanes;
pub(crate) mod scalar;

use super::simd::Isa;
use crate::constants::TILE;
use crate::frame::Frame;

/// Which compositing kernels [`CpuRasterizer`](crate::CpuRasterizer) runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum CpuKernel {
    /// Eight pixels at a time with a vectorised `exp`, compiled for AVX2 + FMA when the CPU has
    /// them (chosen at run time) and for the baseline target otherwise, with identical results.
    #[default]
    Simd,
    /// The plain reference kernels, one pixel at a time with the standard library's `exp`: the
    /// CPU backend's kernels before the SIMD ones, kept to check and to measure those against.
    Scalar,
}

/// The kernels that run: the scalar ones with an `exp`, or the SIMD ones built for an
/// instruction set.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Kernels {
    Scalar { exp: fn(f32) -> f32 },
    Lanes(Isa),
}

impl Kernels {
    /// The kernels that run for `kernel` ([`CpuKernel::Simd`]: the best build this CPU runs).
    pub(crate) fn of(kernel: CpuKernel) -> Self {
        match kernel {
            CpuKernel::Simd => Kernels::Lanes(Isa::best()),
            CpuKernel::Scalar => Kernels::Scalar { exp: f32::exp },
        }
    }
}

/// Pixels per tile.
pub(crate) const LANES: usize = (TILE * TILE) as usize;

/// A tile's pixel range `[x0, x_end) × [y0, y_end)`, clipped to the image.
#[derive(Clone, Copy)]
pub(crate) struct TileRect {
    pub x0: u32,
    pub y0: u32,
    pub x_end: u32,
    pub y_end: u32,
}

impl TileRect {
    pub fn new(frame: &Frame, tile: usize) -> Self {
        let x0 = (tile % frame.tiles_x as usize) as u32 * TILE;
        let y0 = (tile / frame.tiles_x as usize) as u32 * TILE;
        Self {
            x0,
            y0,
            x_end: (x0 + TILE).min(frame.width),
            y_end: (y0 + TILE).min(frame.height),
        }
    }

    pub fn pixels(&self) -> usize {
        ((self.x_end - self.x0) * (self.y_end - self.y0)) as usize
    }

    /// Lane of pixel (x, y): row-major within the 16×16 tile.
    pub fn lane(&self, x: u32, y: u32) -> usize {
        ((y - self.y0) * TILE + (x - self.x0)) as usize
    }

    /// The part of a Gaussian's pixel bounding box inside this tile, `[x0, x1] × [y0, y1]`
    /// inclusive, or None.
    pub fn clip(&self, bbox: [u32; 4]) -> Option<[u32; 4]> {
        let r = [
            bbox[0].max(self.x0),
            bbox[1].max(self.y0),
            bbox[2].min(self.x_end - 1),
            bbox[3].min(self.y_end - 1),
        ];
        (r[0] <= r[2] && r[1] <= r[3]).then_some(r)
    }
}

/// One tile's forward output, tile-major (lane order).
pub(crate) struct TileOut<'a> {
    pub color: &'a mut [[f32; 3]],
    pub depth: &'a mut [f32],
    pub final_t: &'a mut [f32],
    /// One past the list position of the last blended Gaussian, per lane (0 = none).
    pub last: &'a mut [u32],
}
