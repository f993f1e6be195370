//! Storage precision (f32 or f16) and the buffers that hold parameters and activations.
//!
//! Arithmetic is always f32: values are read into f32 scratch, computed, and written back. Writing
//! into f16 storage saturates at ±65504 ([`F16_MAX`]) instead of overflowing to infinity, and the
//! number of saturated values is returned so that networks can count them. NaN stays NaN.

use half::f16;
use half::slice::HalfFloatSliceExt;
use strum::{Display, EnumString, IntoStaticStr, VariantNames};

/// Largest finite f16 value.
pub const F16_MAX: f32 = 65504.0;

/// Storage precision of one network (parameters and cached activations).
///
/// Spelled `f32` / `f16` on the command line (`FromStr`, `Display`, derived with `strum`) and, with the
/// `serde` feature, in files.
#[derive(EnumString, Display, IntoStaticStr, VariantNames)]
#[strum(serialize_all = "lowercase", parse_err_ty = PrecisionParseError, parse_err_fn = PrecisionParseError::new)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(rename_all = "lowercase")
)]
pub enum Precision {
    /// IEEE binary32 storage.
    F32,
    /// IEEE binary16 storage (`half::f16`), f32 arithmetic; values beyond ±[`F16_MAX`] saturate.
    F16,
}

impl Precision {
    /// Bytes of one stored value.
    pub const fn bytes(self) -> usize {
        match self {
            Precision::F32 => 4,
            Precision::F16 => 2,
        }
    }
}

/// A precision spelling other than `f32` and `f16`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown value `{0}`; expected one of {expected}", expected = Precision::VARIANTS.join(", "))]
pub struct PrecisionParseError(pub String);

impl PrecisionParseError {
    fn new(value: &str) -> Self {
        Self(value.to_string())
    }
}

/// An owned buffer in one precision (`Store::default()` is an empty f32 buffer).
#[derive(Clone, Debug, PartialEq)]
pub enum Store {
    /// f32 values.
    F32(Vec<f32>),
    /// f16 values.
    F16(Vec<f16>),
}

impl Default for Store {
    fn default() -> Self {
        Store::F32(Vec::new())
    }
}

/// A borrowed read-only view of a [`Store`].
#[derive(Clone, Copy, Debug)]
pub enum StoreRef<'a> {
    /// f32 values.
    F32(&'a [f32]),
    /// f16 values.
    F16(&'a [f16]),
}

/// A borrowed mutable view of a [`Store`].
#[derive(Debug)]
pub enum StoreMut<'a> {
    /// f32 values.
    F32(&'a mut [f32]),
    /// f16 values.
    F16(&'a mut [f16]),
}

/// Clamps every finite-or-infinite value of `xs` into `[-F16_MAX, F16_MAX]` and returns how many
/// were clamped. NaN is left as it is (and not counted).
pub fn saturate_for_f16(xs: &mut [f32]) -> u64 {
    // Selects and a count of flags rather than a branch, so the loop vectorises.
    let mut n = 0u64;
    for x in xs.iter_mut() {
        let over = x.abs() > F16_MAX;
        n += u64::from(over);
        *x = if over { F16_MAX.copysign(*x) } else { *x };
    }
    n
}

/// Rounds `x` to the nearest f16 value (saturating) and back to f32.
pub fn round_to_f16(x: f32) -> f32 {
    f16::from_f32(x.clamp(-F16_MAX, F16_MAX)).to_f32()
}

impl Store {
    /// `len` zeros in precision `p`.
    pub fn zeros(p: Precision, len: usize) -> Self {
        match p {
            Precision::F32 => Store::F32(vec![0.0; len]),
            Precision::F16 => Store::F16(vec![f16::ZERO; len]),
        }
    }

    /// Builds a store from f32 values (rounded, saturating, for f16). Returns the store and the
    /// number of saturated values.
    pub fn from_f32(p: Precision, xs: &[f32]) -> (Self, u64) {
        let mut s = Store::zeros(p, xs.len());
        let sat = s.as_mut().write_from(xs);
        (s, sat)
    }

    /// Makes this store `len` values of precision `p`, reusing its memory when the precision
    /// already matches (values are unspecified afterwards: callers overwrite them).
    pub fn resize_for(&mut self, p: Precision, len: usize) {
        match (self, p) {
            (Store::F32(v), Precision::F32) => v.resize(len, 0.0),
            (Store::F16(v), Precision::F16) => v.resize(len, f16::ZERO),
            (s, p) => *s = Store::zeros(p, len),
        }
    }

    /// Precision of this store.
    pub fn precision(&self) -> Precision {
        match self {
            Store::F32(_) => Precision::F32,
            Store::F16(_) => Precision::F16,
        }
    }

    /// Number of values.
    pub fn len(&self) -> usize {
        self.as_ref().len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Read-only view.
    pub fn as_ref(&self) -> StoreRef<'_> {
        match self {
            Store::F32(v) => StoreRef::F32(v),
            Store::F16(v) => StoreRef::F16(v),
        }
    }

    /// Mutable view.
    pub fn as_mut(&mut self) -> StoreMut<'_> {
        match self {
            Store::F32(v) => StoreMut::F32(v),
            Store::F16(v) => StoreMut::F16(v),
        }
    }

    /// All values as f32.
    pub fn to_f32_vec(&self) -> Vec<f32> {
        let mut out = vec![0.0; self.len()];
        self.as_ref().read_into(&mut out);
        out
    }

    /// All values as f32, borrowed for f32 storage and widened into a new buffer for f16.
    pub fn as_f32(&self) -> std::borrow::Cow<'_, [f32]> {
        match self {
            Store::F32(v) => std::borrow::Cow::Borrowed(v),
            Store::F16(_) => std::borrow::Cow::Owned(self.to_f32_vec()),
        }
    }

    /// Splits into consecutive mutable chunks of `chunk` values (the last may be shorter).
    pub fn chunks_mut(&mut self, chunk: usize) -> Vec<StoreMut<'_>> {
        match self {
            Store::F32(v) => v.chunks_mut(chunk.max(1)).map(StoreMut::F32).collect(),
            Store::F16(v) => v.chunks_mut(chunk.max(1)).map(StoreMut::F16).collect(),
        }
    }
}

impl<'a> StoreRef<'a> {
    /// Number of values.
    pub fn len(&self) -> usize {
        match self {
            StoreRef::F32(v) => v.len(),
            StoreRef::F16(v) => v.len(),
        }
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Sub-range `start..start + len`.
    #[must_use]
    pub fn slice(&self, start: usize, len: usize) -> StoreRef<'a> {
        match *self {
            StoreRef::F32(v) => StoreRef::F32(&v[start..start + len]),
            StoreRef::F16(v) => StoreRef::F16(&v[start..start + len]),
        }
    }

    /// Converts into `out` (same length).
    pub fn read_into(&self, out: &mut [f32]) {
        match self {
            StoreRef::F32(v) => out.copy_from_slice(v),
            StoreRef::F16(v) => v.convert_to_f32_slice(out),
        }
    }

    /// All values as f32.
    pub fn to_vec_f32(&self) -> Vec<f32> {
        let mut out = vec![0.0; self.len()];
        self.read_into(&mut out);
        out
    }

    /// The values as an f32 slice: borrowed for f32 storage, widened into `buf` for f16.
    pub fn view_f32<'b>(&self, buf: &'b mut Vec<f32>) -> &'b [f32]
    where
        'a: 'b,
    {
        match *self {
            StoreRef::F32(v) => v,
            StoreRef::F16(v) => {
                buf.resize(v.len(), 0.0);
                v.convert_to_f32_slice(buf);
                buf
            }
        }
    }

    /// One value as f32.
    pub fn get(&self, i: usize) -> f32 {
        match self {
            StoreRef::F32(v) => v[i],
            StoreRef::F16(v) => v[i].to_f32(),
        }
    }
}

impl StoreMut<'_> {
    /// Number of values.
    pub fn len(&self) -> usize {
        match self {
            StoreMut::F32(v) => v.len(),
            StoreMut::F16(v) => v.len(),
        }
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Read-only view.
    pub fn as_ref(&self) -> StoreRef<'_> {
        match self {
            StoreMut::F32(v) => StoreRef::F32(v),
            StoreMut::F16(v) => StoreRef::F16(v),
        }
    }

    /// Writes `src` (same length), saturating for f16; returns the number of saturated values.
    pub fn write_from(&mut self, src: &[f32]) -> u64 {
        match self {
            StoreMut::F32(v) => {
                v.copy_from_slice(src);
                0
            }
            StoreMut::F16(v) => {
                const BLOCK: usize = 1024;
                let mut tmp = [0f32; BLOCK];
                let mut sat = 0;
                for (dst, s) in v.chunks_mut(BLOCK).zip(src.chunks(BLOCK)) {
                    let t = &mut tmp[..s.len()];
                    t.copy_from_slice(s);
                    sat += saturate_for_f16(t);
                    dst.convert_from_f32_slice(t);
                }
                sat
            }
        }
    }

    /// Writes `src` into the sub-range starting at `start`; returns the saturation count.
    pub fn write_at(&mut self, start: usize, src: &[f32]) -> u64 {
        let len = src.len();
        match self {
            StoreMut::F32(v) => StoreMut::F32(&mut v[start..start + len]).write_from(src),
            StoreMut::F16(v) => StoreMut::F16(&mut v[start..start + len]).write_from(src),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn precision_spellings() {
        for p in [Precision::F32, Precision::F16] {
            assert_eq!(p.to_string().parse::<Precision>().unwrap(), p);
        }
        let e = "f64".parse::<Precision>().unwrap_err().to_string();
        assert_eq!(e, "unknown value `f64`; expected one of f32, f16");
    }
}
