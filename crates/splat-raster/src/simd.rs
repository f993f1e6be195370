//! Eight f32 lanes for the compositing kernels, run-time dispatch to AVX2, and a vectorised `exp`.
//!
//! The lane types are plain arrays whose operations are `#[inline(always)]` loops over the eight
//! lanes. The kernels are written once against them and compiled twice: as they are (the
//! baseline target, SSE2 on x86-64 or NEON on aarch64) and, on x86-64 when the CPU has AVX2 and
//! FMA, inside a `#[target_feature(enable = "avx2,fma")]` function ([`dispatch`]), where each lane
//! operation becomes one 256-bit instruction. Both builds give bit-identical results: every
//! operation is an IEEE operation per lane, and Rust never contracts `a * b + c` into a fused
//! multiply-add on its own. So results do not depend on the machine's instruction set either.
//!
//! What it is not: a general SIMD library. It holds the operations the kernels use and no more.

use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};

/// Lanes per vector.
pub(crate) const W: usize = 8;

/// Eight f32 lanes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct F8(pub [f32; W]);

/// Eight lane masks, each all ones (true) or all zeros (false).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct M8(pub [u32; W]);

/// Eight i32 lanes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct I8(pub [i32; W]);

#[inline(always)]
fn map2<T: Copy, U: Copy, R: Copy + Default>(
    a: [T; W],
    b: [U; W],
    f: impl Fn(T, U) -> R,
) -> [R; W] {
    let mut out = [R::default(); W];
    for l in 0..W {
        out[l] = f(a[l], b[l]);
    }
    out
}

#[inline(always)]
fn mask(b: bool) -> u32 {
    if b { u32::MAX } else { 0 }
}

impl F8 {
    /// Every lane `v`.
    #[inline(always)]
    pub fn splat(v: f32) -> Self {
        Self([v; W])
    }

    /// `self <= o` per lane (false where either is NaN).
    #[inline(always)]
    pub fn le(self, o: Self) -> M8 {
        M8(map2(self.0, o.0, |a, b| mask(a <= b)))
    }

    /// `self < o` per lane (false where either is NaN).
    #[inline(always)]
    pub fn lt(self, o: Self) -> M8 {
        M8(map2(self.0, o.0, |a, b| mask(a < b)))
    }

    /// `self > o` per lane (false where either is NaN).
    #[inline(always)]
    pub fn gt(self, o: Self) -> M8 {
        M8(map2(self.0, o.0, |a, b| mask(a > b)))
    }

    /// `self >= o` per lane (false where either is NaN).
    #[inline(always)]
    pub fn ge(self, o: Self) -> M8 {
        M8(map2(self.0, o.0, |a, b| mask(a >= b)))
    }

    /// `o` where `self > o`, else `self`: the minimum, `self` where either is NaN.
    #[inline(always)]
    pub fn min(self, o: Self) -> Self {
        Self(map2(self.0, o.0, |a, b| if b < a { b } else { a }))
    }

    /// `o` where `self < o`, else `self`: the maximum, `self` where either is NaN.
    #[inline(always)]
    pub fn max(self, o: Self) -> Self {
        Self(map2(self.0, o.0, |a, b| if b > a { b } else { a }))
    }

    /// Sum of the lanes in a fixed order: `((0+4)+(2+6)) + ((1+5)+(3+7))`.
    #[inline(always)]
    pub fn sum(self) -> f32 {
        let v = self.0;
        let s = [v[0] + v[4], v[1] + v[5], v[2] + v[6], v[3] + v[7]];
        (s[0] + s[2]) + (s[1] + s[3])
    }

    /// The lanes' bits.
    #[inline(always)]
    fn to_bits(self) -> [u32; W] {
        self.0.map(f32::to_bits)
    }
}

macro_rules! lane_op {
    ($ty:ident, $trait:ident, $method:ident, $op:tt) => {
        impl $trait for $ty {
            type Output = $ty;
            #[inline(always)]
            fn $method(self, o: $ty) -> $ty {
                $ty(map2(self.0, o.0, |a, b| a $op b))
            }
        }
    };
}

lane_op!(F8, Add, add, +);
lane_op!(F8, Sub, sub, -);
lane_op!(F8, Mul, mul, *);
lane_op!(F8, Div, div, /);
lane_op!(M8, BitAnd, bitand, &);
lane_op!(M8, BitOr, bitor, |);

impl Neg for F8 {
    type Output = F8;
    #[inline(always)]
    fn neg(self) -> F8 {
        F8(self.0.map(|v| -v))
    }
}

impl Not for M8 {
    type Output = M8;
    #[inline(always)]
    fn not(self) -> M8 {
        M8(self.0.map(|m| !m))
    }
}

impl M8 {
    /// Lanes `l` with `lo <= l <= hi` true.
    #[inline(always)]
    pub fn range(lo: u32, hi: u32) -> M8 {
        let mut out = [0u32; W];
        for (l, m) in out.iter_mut().enumerate() {
            *m = mask(lo <= l as u32 && l as u32 <= hi);
        }
        M8(out)
    }

    /// Whether some lane is true.
    #[inline(always)]
    pub fn any(self) -> bool {
        // A fixed-shape or-reduction vectorises where `iter().any` may not.
        let v = self.0;
        ((v[0] | v[4]) | (v[2] | v[6])) | ((v[1] | v[5]) | (v[3] | v[7])) != 0
    }

    /// Number of true lanes.
    #[inline(always)]
    pub fn count(self) -> u32 {
        self.0.iter().map(|m| m & 1).sum()
    }

    /// `a` where true, else `b`.
    #[inline(always)]
    pub fn select(self, a: F8, b: F8) -> F8 {
        let bits = map2(a.to_bits(), b.to_bits(), |x, y| (x, y));
        let mut out = [0f32; W];
        for l in 0..W {
            let (x, y) = bits[l];
            out[l] = f32::from_bits((x & self.0[l]) | (y & !self.0[l]));
        }
        F8(out)
    }

    /// `a` where true, else `b`.
    #[inline(always)]
    pub fn select_i(self, a: I8, b: I8) -> I8 {
        let mut out = [0i32; W];
        for l in 0..W {
            out[l] = if self.0[l] != 0 { a.0[l] } else { b.0[l] };
        }
        I8(out)
    }
}

impl I8 {
    /// Every lane `v`.
    #[inline(always)]
    pub fn splat(v: i32) -> Self {
        Self([v; W])
    }

    /// `self > o` per lane.
    #[inline(always)]
    pub fn gt(self, o: Self) -> M8 {
        M8(map2(self.0, o.0, |a, b| mask(a > b)))
    }
}

/// Inputs below this are clamped to it (`e^EXP_MIN ≈ 1.8e-35` is still a normal f32).
pub(crate) const EXP_MIN: f32 = -80.0;

/// `e^x` per lane for `x` in `[EXP_MIN, 0]`, within 1.2e-7 relative error (the test
/// `exp_error_is_bounded` measures 8.0e-8, under 1.5 ulp of the result); inputs
/// outside the range are clamped to it, NaN gives an unspecified finite or NaN value.
///
/// Cody–Waite reduction `x = n ln2 + r`, `|r| <= ln2 / 2`, with `n` rounded to nearest by the
/// 1.5·2²³ trick (no rounding instruction needed on the baseline target), the degree-5 Cephes
/// `expf` polynomial for `e^r`, and `2^n` built in the exponent bits.
#[inline(always)]
pub(crate) fn exp(x: F8) -> F8 {
    const LOG2E: f32 = std::f32::consts::LOG2_E;
    const MAGIC: f32 = 12_582_912.0; // 1.5 · 2^23
    const LN2_HI: f32 = 0.693_359_4; // 355 / 512, exact with few bits
    const LN2_LO: f32 = -2.121_944_4e-4;
    const P: [f32; 6] = [
        1.987_569_1e-4,
        1.398_199_9e-3,
        8.333_452e-3,
        4.166_579_6e-2,
        1.666_666_5e-1,
        5.000_000_1e-1,
    ];
    let x = x.max(F8::splat(EXP_MIN)).min(F8::splat(0.0));
    // t = round(x / ln2) + 1.5·2^23 exactly: its low mantissa bits hold the integer n.
    let t = x * F8::splat(LOG2E) + F8::splat(MAGIC);
    let n = t - F8::splat(MAGIC);
    let r = (x - n * F8::splat(LN2_HI)) - n * F8::splat(LN2_LO);
    let mut p = F8::splat(P[0]);
    for &c in &P[1..] {
        p = p * r + F8::splat(c);
    }
    let e_r = (p * (r * r) + r) + F8::splat(1.0);
    // (bits(t) << 23) = n << 23 modulo 2^32, since the low 9 bits of bits(1.5·2^23) are zero.
    let scale = t
        .to_bits()
        .map(|b| f32::from_bits((b << 23).wrapping_add(127 << 23)));
    e_r * F8(scale)
}

/// A computation to compile for the best available instruction set. Implementations mark `run`
/// `#[inline(always)]`.
pub(crate) trait Kernel {
    /// What it returns.
    type Output;
    /// Does the work.
    fn run(self) -> Self::Output;
}

/// Which build of the kernels [`dispatch`] runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Isa {
    /// Compiled for the baseline target.
    Portable,
    /// Compiled with AVX2 and FMA enabled (x86-64, chosen at run time).
    #[cfg(target_arch = "x86_64")]
    Avx2,
}

impl Isa {
    /// The best build this CPU runs.
    pub fn best() -> Self {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            return Isa::Avx2;
        }
        Isa::Portable
    }
}

/// Runs `kernel` compiled for `isa` ([`Isa::best`] unless a test asks for another).
#[inline(always)]
pub(crate) fn dispatch<K: Kernel>(isa: Isa, kernel: K) -> K::Output {
    match isa {
        Isa::Portable => kernel.run(),
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => {
            assert!(
                std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma"),
                "the AVX2 kernels need AVX2 and FMA"
            );
            // SAFETY: calling a `#[target_feature]` function requires only that the CPU supports
            // the features it enables; both were checked just above.
            unsafe { run_avx2(kernel) }
        }
    }
}

/// `kernel.run()` compiled with AVX2 and FMA enabled.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn run_avx2<K: Kernel>(kernel: K) -> K::Output {
    kernel.run()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Largest relative error of [`exp`] against the exact exponential on `[EXP_MIN, 0]`.
    const EXP_REL_ERROR: f64 = 1.2e-7;

    struct ExpGrid(Vec<f32>);

    impl Kernel for ExpGrid {
        type Output = Vec<f32>;
        #[inline(always)]
        fn run(self) -> Vec<f32> {
            self.0
                .chunks_exact(W)
                .flat_map(|c| exp(F8(c.try_into().unwrap())).0)
                .collect()
        }
    }

    fn isas() -> Vec<Isa> {
        let mut v = vec![Isa::Portable];
        if Isa::best() != Isa::Portable {
            v.push(Isa::best());
        }
        v
    }

    #[test]
    fn exp_error_is_bounded() {
        // Every f32 in [-1, 0] at a stride, and a fine grid over [EXP_MIN, -1].
        let mut xs: Vec<f32> = (0..1u32 << 20)
            .map(|i| -(i as f32) / (1u32 << 20) as f32)
            .collect();
        xs.extend((0..1u32 << 21).map(|i| EXP_MIN * i as f32 / (1u32 << 21) as f32));
        xs.extend([
            EXP_MIN,
            -0.0,
            -f32::MIN_POSITIVE,
            -87.0 + 7.0,
            -0.346_573_6,
            -0.346_573_58,
        ]);
        while xs.len() % W != 0 {
            xs.push(0.0);
        }
        let mut outs = Vec::new();
        for isa in isas() {
            let ys = dispatch(isa, ExpGrid(xs.clone()));
            let mut worst = 0.0f64;
            for (&x, &y) in xs.iter().zip(&ys) {
                let want = f64::from(x).exp();
                let rel = (f64::from(y) - want).abs() / want;
                worst = worst.max(rel);
            }
            assert!(
                worst <= EXP_REL_ERROR,
                "{isa:?}: worst relative error {worst:e}"
            );
            // Tight: the bound is not loose by more than 2x.
            assert!(worst > EXP_REL_ERROR / 2.0, "{isa:?}: {worst:e}");
            outs.push(ys);
        }
        // The builds agree bit for bit.
        let bits = |v: &Vec<f32>| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert!(outs.windows(2).all(|w| bits(&w[0]) == bits(&w[1])));
    }

    #[test]
    fn exp_clamps_out_of_range_inputs() {
        let x = F8([
            1.0,
            50.0,
            f32::INFINITY,
            -1e30,
            f32::NEG_INFINITY,
            -100.0,
            0.0,
            -0.0,
        ]);
        let y = exp(x).0;
        for v in &y[..3] {
            assert!((v - 1.0).abs() < 1e-6, "{v}");
        }
        for v in &y[3..6] {
            assert!(*v > 0.0 && *v < 2e-35, "{v}");
        }
        assert_eq!(&y[6..], &[1.0, 1.0]);
    }

    #[test]
    fn masks_sums_and_selects() {
        let a = F8([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);
        let m = a.lt(F8::splat(3.0)) | a.ge(F8::splat(6.5));
        assert_eq!(m.count(), 4);
        assert!(m.any() && !(m & !m).any());
        assert_eq!(
            m.select(a, F8::splat(-1.0)).0,
            [0.0, 1.0, 2.0, -1.0, -1.0, -1.0, -1.0, 7.0]
        );
        assert_eq!(M8::range(2, 4).count(), 3);
        assert_eq!(a.sum(), 28.0);
        assert_eq!(
            F8::splat(f32::NAN).min(a).0[0].to_bits(),
            f32::NAN.to_bits()
        );
        assert_eq!(I8::splat(3).gt(I8([0, 1, 2, 3, 4, 5, 6, 7])).count(), 3);
    }
}
