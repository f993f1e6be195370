//! Eight f32 lanes for the compositing kernels, run-time dispatch to AVX2, and a vectorised `exp`.
//!
//! The kernels are written once against the [`Simd`] trait and compiled twice: with [`Portable`]
//! lanes (plain arrays whose operations are loops over the eight lanes, for the baseline target:
//! SSE2 on x86-64, NEON on aarch64) and, on x86-64 when the CPU has AVX2 and FMA (checked at run
//! time by [`dispatch`]), with [`avx2::Avx2`] lanes, one 256-bit register each, inside a function
//! compiled with those features enabled. Both give bit-identical results: every operation is the
//! same IEEE operation per lane (no fused multiply-add: Rust never contracts `a * b + c` on its
//! own, and the AVX2 lanes do not either), `min`/`max` follow the x86 rule (`a < b ? a : b`) in
//! both, and sums across lanes have one fixed order. So results do not depend on the machine.
//!
//! What it is not: a general SIMD library. It holds the operations the kernels use and no more.

use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};

/// Lanes per vector.
pub(crate) const W: usize = 8;

/// A build of the lane operations: a zero-sized token whose value proves that its instructions
/// run on this CPU. Vectors are made from the token, so holding one proves it too.
pub(crate) trait Simd: Copy {
    /// Eight f32 lanes.
    type F: Copy
        + Add<Output = Self::F>
        + Sub<Output = Self::F>
        + Mul<Output = Self::F>
        + Div<Output = Self::F>
        + Neg<Output = Self::F>;
    /// Eight lane masks.
    type M: Copy + BitAnd<Output = Self::M> + BitOr<Output = Self::M> + Not<Output = Self::M>;
    /// Eight i32 lanes.
    type I: Copy;

    /// Every lane `v`.
    fn splat(self, v: f32) -> Self::F;
    /// The lanes of `v`.
    fn lanes(self, v: [f32; W]) -> Self::F;
    /// The lanes as an array.
    fn to_array(self, v: Self::F) -> [f32; W];
    /// Every lane `v`.
    fn splat_i(self, v: i32) -> Self::I;
    /// The lanes of `v`.
    fn lanes_i(self, v: [i32; W]) -> Self::I;
    /// The lanes as an array.
    fn to_array_i(self, v: Self::I) -> [i32; W];
    /// All lanes false.
    fn none(self) -> Self::M;
    /// `a <= b` per lane (false where either is NaN).
    fn le(self, a: Self::F, b: Self::F) -> Self::M;
    /// `a < b` per lane.
    fn lt(self, a: Self::F, b: Self::F) -> Self::M;
    /// `a >= b` per lane.
    fn ge(self, a: Self::F, b: Self::F) -> Self::M;
    /// `a > b` per lane.
    fn gt(self, a: Self::F, b: Self::F) -> Self::M;
    /// `a < b ? a : b` per lane (so `b` where either is NaN).
    fn min(self, a: Self::F, b: Self::F) -> Self::F;
    /// `a > b ? a : b` per lane (so `b` where either is NaN).
    #[cfg_attr(not(test), allow(dead_code))] // by `exp` only
    fn max(self, a: Self::F, b: Self::F) -> Self::F;
    /// `a` where `m`, else `b`.
    fn select(self, m: Self::M, a: Self::F, b: Self::F) -> Self::F;
    /// `a` where `m`, else `b`.
    fn select_i(self, m: Self::M, a: Self::I, b: Self::I) -> Self::I;
    /// `a > b` per lane.
    fn gt_i(self, a: Self::I, b: Self::I) -> Self::M;
    /// Lanes `l` with `lo <= l <= hi`.
    fn range(self, lo: u32, hi: u32) -> Self::M;
    /// Whether some lane is true.
    fn any(self, m: Self::M) -> bool;
    /// Number of true lanes.
    fn count(self, m: Self::M) -> u32;
    /// Sum of the lanes in the order `((0+4)+(2+6)) + ((1+5)+(3+7))`.
    fn sum(self, v: Self::F) -> f32;
    /// Eight sums at once: lane `i` is `sum(v[i])`, bit for bit.
    fn sum8(self, v: [Self::F; W]) -> Self::F;
    /// `acc + 1` in the lanes of `m`, `acc` in the others (wrapping).
    fn count_lanes(self, acc: Self::I, m: Self::M) -> Self::I;
    /// Per lane, the f32 with bits `(bits(t) << 23) + (127 << 23)` (wrapping).
    fn exp2_bits(self, t: Self::F) -> Self::F;
    /// `a·b + c` per lane, rounded once (a fused multiply-add, the same bits in every build).
    fn mul_add(self, a: Self::F, b: Self::F, c: Self::F) -> Self::F;
}

/// Eight f32 lanes of [`Portable`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct F8(pub [f32; W]);

/// Eight lane masks of [`Portable`], each all ones (true) or all zeros (false).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct M8(pub [u32; W]);

/// Eight i32 lanes of [`Portable`].
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

/// The lane operations as loops over arrays, for any target.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Portable;

impl Simd for Portable {
    type F = F8;
    type M = M8;
    type I = I8;

    #[inline(always)]
    fn splat(self, v: f32) -> F8 {
        F8([v; W])
    }
    #[inline(always)]
    fn lanes(self, v: [f32; W]) -> F8 {
        F8(v)
    }
    #[inline(always)]
    fn to_array(self, v: F8) -> [f32; W] {
        v.0
    }
    #[inline(always)]
    fn splat_i(self, v: i32) -> I8 {
        I8([v; W])
    }
    #[inline(always)]
    fn lanes_i(self, v: [i32; W]) -> I8 {
        I8(v)
    }
    #[inline(always)]
    fn to_array_i(self, v: I8) -> [i32; W] {
        v.0
    }
    #[inline(always)]
    fn none(self) -> M8 {
        M8([0; W])
    }
    #[inline(always)]
    fn le(self, a: F8, b: F8) -> M8 {
        M8(map2(a.0, b.0, |a, b| mask(a <= b)))
    }
    #[inline(always)]
    fn lt(self, a: F8, b: F8) -> M8 {
        M8(map2(a.0, b.0, |a, b| mask(a < b)))
    }
    #[inline(always)]
    fn ge(self, a: F8, b: F8) -> M8 {
        M8(map2(a.0, b.0, |a, b| mask(a >= b)))
    }
    #[inline(always)]
    fn gt(self, a: F8, b: F8) -> M8 {
        M8(map2(a.0, b.0, |a, b| mask(a > b)))
    }
    #[inline(always)]
    fn min(self, a: F8, b: F8) -> F8 {
        F8(map2(a.0, b.0, |a, b| if a < b { a } else { b }))
    }
    #[inline(always)]
    fn max(self, a: F8, b: F8) -> F8 {
        F8(map2(a.0, b.0, |a, b| if a > b { a } else { b }))
    }
    #[inline(always)]
    fn select(self, m: M8, a: F8, b: F8) -> F8 {
        let mut out = [0f32; W];
        for (l, o) in out.iter_mut().enumerate() {
            let (x, y) = (a.0[l].to_bits(), b.0[l].to_bits());
            *o = f32::from_bits((x & m.0[l]) | (y & !m.0[l]));
        }
        F8(out)
    }
    #[inline(always)]
    fn select_i(self, m: M8, a: I8, b: I8) -> I8 {
        let mut out = [0i32; W];
        for (l, o) in out.iter_mut().enumerate() {
            *o = if m.0[l] != 0 { a.0[l] } else { b.0[l] };
        }
        I8(out)
    }
    #[inline(always)]
    fn gt_i(self, a: I8, b: I8) -> M8 {
        M8(map2(a.0, b.0, |a, b| mask(a > b)))
    }
    #[inline(always)]
    fn range(self, lo: u32, hi: u32) -> M8 {
        let mut out = [0u32; W];
        for (l, m) in out.iter_mut().enumerate() {
            *m = mask(lo <= l as u32 && l as u32 <= hi);
        }
        M8(out)
    }
    #[inline(always)]
    fn any(self, m: M8) -> bool {
        m.0.iter().fold(0, |a, &b| a | b) != 0
    }
    #[inline(always)]
    fn count(self, m: M8) -> u32 {
        m.0.iter().map(|m| m & 1).sum()
    }
    #[inline(always)]
    fn sum(self, v: F8) -> f32 {
        let v = v.0;
        let s = [v[0] + v[4], v[1] + v[5], v[2] + v[6], v[3] + v[7]];
        (s[0] + s[2]) + (s[1] + s[3])
    }
    #[inline(always)]
    fn sum8(self, v: [F8; W]) -> F8 {
        F8(v.map(|v| self.sum(v)))
    }
    #[inline(always)]
    fn count_lanes(self, acc: I8, m: M8) -> I8 {
        I8(map2(acc.0, m.0, |a, m| a.wrapping_add((m & 1) as i32)))
    }
    #[inline(always)]
    fn exp2_bits(self, t: F8) -> F8 {
        F8(t.0.map(|t| f32::from_bits((t.to_bits() << 23).wrapping_add(127 << 23))))
    }
    /// [`f32::mul_add`] per lane: one instruction where the target has a fused multiply-add
    /// (aarch64, or x86-64 built with FMA), else the C library's correctly rounded `fmaf`.
    #[inline(always)]
    fn mul_add(self, a: F8, b: F8, c: F8) -> F8 {
        F8(std::array::from_fn(|l| a.0[l].mul_add(b.0[l], c.0[l])))
    }
}

/// The lane operations in AVX2 registers (x86-64).
#[cfg(target_arch = "x86_64")]
pub(crate) mod avx2 {
    use std::arch::x86_64::*;
    use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};

    use super::{Simd, W};

    /// The AVX2 token. Only [`super::dispatch`] makes one, after checking that the CPU has AVX2
    /// and FMA, so every intrinsic below runs on a CPU that supports it.
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct Avx2(());

    impl Avx2 {
        /// The token.
        ///
        /// # Safety
        /// The CPU must support AVX2 and FMA.
        #[inline(always)]
        pub(super) unsafe fn new_unchecked() -> Self {
            Avx2(())
        }
    }

    /// Eight f32 lanes of [`Avx2`].
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct Fa(__m256);

    /// Eight lane masks of [`Avx2`].
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct Ma(__m256);

    /// Eight i32 lanes of [`Avx2`].
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct Ia(__m256i);

    // SAFETY (every `unsafe` block in this module): values of `Fa`, `Ma` and `Ia` are made only
    // through an `Avx2` token, which exists only on a CPU with AVX2 and FMA (see `Avx2`), so the
    // AVX/AVX2 intrinsics called on them are supported; the transmutes are between 32-byte types
    // (`__m256`, `__m256i`, `[f32; 8]`, `[i32; 8]`) for which every bit pattern is valid.
    macro_rules! avx_op {
        ($ty:ident, $trait:ident, $method:ident, $intrinsic:ident) => {
            impl $trait for $ty {
                type Output = $ty;
                #[inline(always)]
                fn $method(self, o: $ty) -> $ty {
                    // SAFETY: see the module's note above.
                    $ty(unsafe { $intrinsic(self.0, o.0) })
                }
            }
        };
    }

    avx_op!(Fa, Add, add, _mm256_add_ps);
    avx_op!(Fa, Sub, sub, _mm256_sub_ps);
    avx_op!(Fa, Mul, mul, _mm256_mul_ps);
    avx_op!(Fa, Div, div, _mm256_div_ps);
    avx_op!(Ma, BitAnd, bitand, _mm256_and_ps);
    avx_op!(Ma, BitOr, bitor, _mm256_or_ps);

    impl Neg for Fa {
        type Output = Fa;
        #[inline(always)]
        fn neg(self) -> Fa {
            // SAFETY: see the module's note above.
            Fa(unsafe { _mm256_xor_ps(self.0, _mm256_set1_ps(-0.0)) })
        }
    }

    impl Not for Ma {
        type Output = Ma;
        #[inline(always)]
        fn not(self) -> Ma {
            // SAFETY: see the module's note above.
            Ma(unsafe { _mm256_xor_ps(self.0, _mm256_castsi256_ps(_mm256_set1_epi32(-1))) })
        }
    }

    impl Simd for Avx2 {
        type F = Fa;
        type M = Ma;
        type I = Ia;

        #[inline(always)]
        fn splat(self, v: f32) -> Fa {
            // SAFETY: see the module's note above.
            Fa(unsafe { _mm256_set1_ps(v) })
        }
        #[inline(always)]
        fn lanes(self, v: [f32; W]) -> Fa {
            // SAFETY: see the module's note above.
            Fa(unsafe { std::mem::transmute::<[f32; W], __m256>(v) })
        }
        #[inline(always)]
        fn to_array(self, v: Fa) -> [f32; W] {
            // SAFETY: see the module's note above.
            unsafe { std::mem::transmute::<__m256, [f32; W]>(v.0) }
        }
        #[inline(always)]
        fn splat_i(self, v: i32) -> Ia {
            // SAFETY: see the module's note above.
            Ia(unsafe { _mm256_set1_epi32(v) })
        }
        #[inline(always)]
        fn lanes_i(self, v: [i32; W]) -> Ia {
            // SAFETY: see the module's note above.
            Ia(unsafe { std::mem::transmute::<[i32; W], __m256i>(v) })
        }
        #[inline(always)]
        fn to_array_i(self, v: Ia) -> [i32; W] {
            // SAFETY: see the module's note above.
            unsafe { std::mem::transmute::<__m256i, [i32; W]>(v.0) }
        }
        #[inline(always)]
        fn none(self) -> Ma {
            // SAFETY: see the module's note above.
            Ma(unsafe { _mm256_setzero_ps() })
        }
        #[inline(always)]
        fn le(self, a: Fa, b: Fa) -> Ma {
            // SAFETY: see the module's note above.
            Ma(unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(a.0, b.0) })
        }
        #[inline(always)]
        fn lt(self, a: Fa, b: Fa) -> Ma {
            // SAFETY: see the module's note above.
            Ma(unsafe { _mm256_cmp_ps::<_CMP_LT_OQ>(a.0, b.0) })
        }
        #[inline(always)]
        fn ge(self, a: Fa, b: Fa) -> Ma {
            // SAFETY: see the module's note above.
            Ma(unsafe { _mm256_cmp_ps::<_CMP_GE_OQ>(a.0, b.0) })
        }
        #[inline(always)]
        fn gt(self, a: Fa, b: Fa) -> Ma {
            // SAFETY: see the module's note above.
            Ma(unsafe { _mm256_cmp_ps::<_CMP_GT_OQ>(a.0, b.0) })
        }
        #[inline(always)]
        fn min(self, a: Fa, b: Fa) -> Fa {
            // SAFETY: see the module's note above.
            Fa(unsafe { _mm256_min_ps(a.0, b.0) })
        }
        #[inline(always)]
        fn max(self, a: Fa, b: Fa) -> Fa {
            // SAFETY: see the module's note above.
            Fa(unsafe { _mm256_max_ps(a.0, b.0) })
        }
        #[inline(always)]
        fn select(self, m: Ma, a: Fa, b: Fa) -> Fa {
            // SAFETY: see the module's note above.
            Fa(unsafe { _mm256_blendv_ps(b.0, a.0, m.0) })
        }
        #[inline(always)]
        fn select_i(self, m: Ma, a: Ia, b: Ia) -> Ia {
            // SAFETY: see the module's note above.
            Ia(unsafe {
                _mm256_castps_si256(_mm256_blendv_ps(
                    _mm256_castsi256_ps(b.0),
                    _mm256_castsi256_ps(a.0),
                    m.0,
                ))
            })
        }
        #[inline(always)]
        fn gt_i(self, a: Ia, b: Ia) -> Ma {
            // SAFETY: see the module's note above.
            Ma(unsafe { _mm256_castsi256_ps(_mm256_cmpgt_epi32(a.0, b.0)) })
        }
        #[inline(always)]
        fn range(self, lo: u32, hi: u32) -> Ma {
            // Lane indices 0..8 compared as i32 (`lo`, `hi` < 2^31 in the kernels).
            // SAFETY: see the module's note above.
            unsafe {
                let iota = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
                let above = _mm256_cmpgt_epi32(iota, _mm256_set1_epi32(lo as i32 - 1));
                let below = _mm256_cmpgt_epi32(_mm256_set1_epi32(hi as i32 + 1), iota);
                Ma(_mm256_castsi256_ps(_mm256_and_si256(above, below)))
            }
        }
        #[inline(always)]
        fn any(self, m: Ma) -> bool {
            // SAFETY: see the module's note above.
            unsafe { _mm256_movemask_ps(m.0) != 0 }
        }
        #[inline(always)]
        fn count(self, m: Ma) -> u32 {
            // SAFETY: see the module's note above.
            unsafe { _mm256_movemask_ps(m.0) }.count_ones()
        }
        #[inline(always)]
        fn sum(self, v: Fa) -> f32 {
            // SAFETY: see the module's note above.
            unsafe {
                // [0+4, 1+5, 2+6, 3+7], then [(0+4)+(2+6), (1+5)+(3+7), ..], then their sum.
                let s = _mm_add_ps(_mm256_castps256_ps128(v.0), _mm256_extractf128_ps::<1>(v.0));
                let s = _mm_add_ps(s, _mm_movehl_ps(s, s));
                _mm_cvtss_f32(_mm_add_ss(s, _mm_shuffle_ps::<0b01>(s, s)))
            }
        }
        #[inline(always)]
        fn sum8(self, v: [Fa; W]) -> Fa {
            // The additions of `sum` for eight vectors at once, in the same pairs (IEEE addition
            // is commutative, so the order of the two operands does not matter).
            // SAFETY: see the module's note above.
            unsafe {
                // Vector k in the low half, k + 4 in the high half: [0+4, 1+5, 2+6, 3+7].
                let h: [__m256; 4] = std::array::from_fn(|k| {
                    let (a, b) = (v[k].0, v[k + 4].0);
                    _mm256_add_ps(
                        _mm256_permute2f128_ps::<0x20>(a, b),
                        _mm256_permute2f128_ps::<0x31>(a, b),
                    )
                });
                // Per half, [(0+4)+(2+6) of k, of k+1, (1+5)+(3+7) of k, of k+1], k = 0 and 2.
                let q01 = _mm256_add_ps(
                    _mm256_unpacklo_ps(h[0], h[1]),
                    _mm256_unpackhi_ps(h[0], h[1]),
                );
                let q23 = _mm256_add_ps(
                    _mm256_unpacklo_ps(h[2], h[3]),
                    _mm256_unpackhi_ps(h[2], h[3]),
                );
                // ((0+4)+(2+6)) + ((1+5)+(3+7)) of vectors 0..4 (low half) and 4..8 (high half).
                Fa(_mm256_add_ps(
                    _mm256_shuffle_ps::<0b01_00_01_00>(q01, q23),
                    _mm256_shuffle_ps::<0b11_10_11_10>(q01, q23),
                ))
            }
        }
        #[inline(always)]
        fn count_lanes(self, acc: Ia, m: Ma) -> Ia {
            // A true lane is -1 as an i32.
            // SAFETY: see the module's note above.
            Ia(unsafe { _mm256_sub_epi32(acc.0, _mm256_castps_si256(m.0)) })
        }
        #[inline(always)]
        fn exp2_bits(self, t: Fa) -> Fa {
            // SAFETY: see the module's note above.
            Fa(unsafe {
                let bits = _mm256_slli_epi32::<23>(_mm256_castps_si256(t.0));
                _mm256_castsi256_ps(_mm256_add_epi32(bits, _mm256_set1_epi32(127 << 23)))
            })
        }
        #[inline(always)]
        fn mul_add(self, a: Fa, b: Fa, c: Fa) -> Fa {
            // SAFETY: see the module's note above.
            Fa(unsafe { _mm256_fmadd_ps(a.0, b.0, c.0) })
        }
    }
}

// `exp` and its range are what the tests check; the kernels call `exp_in_range` (see there).
/// Inputs below this are clamped to it (`e^EXP_MIN ≈ 1.8e-35` is still a normal f32).
#[cfg_attr(not(test), allow(dead_code))]
pub(crate) const EXP_MIN: f32 = -80.0;

/// `e^x` per lane for `x` in `[EXP_MIN, 0]`, within 1.2e-7 relative error (the test
/// `exp_error_is_bounded` measures 8.5e-8, under 1.5 ulp of the result); inputs outside the
/// range are clamped to it, and NaN gives `e^EXP_MIN`.
///
/// Cody–Waite reduction `x = n ln2 + r`, `|r| <= ln2 / 2`, with `n` rounded to nearest by the
/// 1.5·2²³ trick (no rounding instruction needed on the baseline target), the degree-5 Cephes
/// `expf` polynomial for `e^r` evaluated by Estrin's scheme, and `2^n` built in the exponent
/// bits. Every multiply-add is fused ([`Simd::mul_add`]): the kernels wait on this chain of
/// dependent operations (it is the longest in a block), and fusing and Estrin's pairing shorten
/// it from 20 dependent operations to 10.
#[cfg_attr(not(test), allow(dead_code))]
#[inline(always)]
pub(crate) fn exp<S: Simd>(s: S, x: S::F) -> S::F {
    // max(NaN, EXP_MIN) = EXP_MIN by the x86 rule.
    let x = s.min(s.max(x, s.splat(EXP_MIN)), s.splat(0.0));
    exp_in_range(s, &ExpConsts::new(s), x)
}

/// The constants of [`exp_in_range`] as vectors.
///
/// A kernel makes them once with [`ExpConsts::opaque`], outside its loops: the compiler then
/// cannot rematerialise them, so under register pressure it reloads them as memory operands of
/// the arithmetic (one instruction each) instead of broadcasting each constant again before its
/// use (two). The values, and so the results, are the same either way.
#[derive(Clone, Copy)]
pub(crate) struct ExpConsts<S: Simd> {
    log2e: S::F,
    magic: S::F,
    neg_ln2_hi: S::F,
    neg_ln2_lo: S::F,
    p: [S::F; 6],
    one: S::F,
}

impl<S: Simd> ExpConsts<S> {
    /// The constants, hidden from the optimiser by [`std::hint::black_box`] (which returns its
    /// argument unchanged).
    #[inline(always)]
    pub fn opaque(s: S) -> Self {
        std::hint::black_box(Self::new(s))
    }

    #[inline(always)]
    fn new(s: S) -> Self {
        Self {
            log2e: s.splat(std::f32::consts::LOG2_E),
            magic: s.splat(12_582_912.0),      // 1.5 · 2^23
            neg_ln2_hi: s.splat(-0.693_359_4), // -355 / 512, exact with few bits
            neg_ln2_lo: s.splat(2.121_944_4e-4),
            p: [
                1.987_569_1e-4,
                1.398_199_9e-3,
                8.333_452e-3,
                4.166_579_6e-2,
                1.666_666_5e-1,
                0.5,
            ]
            .map(|c| s.splat(c)),
            one: s.splat(1.0),
        }
    }
}

/// [`exp`] without its clamp: bit for bit the same for `x` in `[EXP_MIN, 0]`, meaningless
/// elsewhere (for the kernels, whose lanes outside that range are masked off by a select).
#[inline(always)]
pub(crate) fn exp_in_range<S: Simd>(s: S, k: &ExpConsts<S>, x: S::F) -> S::F {
    // t = round(x / ln2) + 1.5·2^23 exactly: its low mantissa bits hold the integer n.
    let t = s.mul_add(x, k.log2e, k.magic);
    let n = t - k.magic;
    let r = s.mul_add(n, k.neg_ln2_lo, s.mul_add(n, k.neg_ln2_hi, x));
    // P(r) = p0 r^5 + … + p5 as (p0 r + p1) r^4 + (p2 r + p3) r^2 + (p4 r + p5).
    let r2 = r * r;
    let [p0, p1, p2, p3, p4, p5] = k.p;
    let hi = s.mul_add(s.mul_add(p0, r, p1), r2, s.mul_add(p2, r, p3));
    let p = s.mul_add(hi, r2, s.mul_add(p4, r, p5));
    let e_r = s.mul_add(p, r2, r) + k.one;
    // (bits(t) << 23) = n << 23 modulo 2^32, since the low 9 bits of bits(1.5·2^23) are zero.
    e_r * s.exp2_bits(t)
}

/// A computation to compile for each build of the lane operations. Implementations mark `run`
/// `#[inline(always)]`.
pub(crate) trait Kernel {
    /// What it returns.
    type Output;
    /// Does the work with the lane operations of `s`.
    fn run<S: Simd>(self, s: S) -> Self::Output;
}

/// Which build of the kernels [`dispatch`] runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Isa {
    /// [`Portable`] lanes, compiled for the baseline target.
    Portable,
    /// AVX2 lanes, compiled with AVX2 and FMA enabled (x86-64, chosen at run time).
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

/// Runs `kernel` with the lanes of `isa` ([`Isa::best`] unless a test asks for another).
#[inline(always)]
pub(crate) fn dispatch<K: Kernel>(isa: Isa, kernel: K) -> K::Output {
    match isa {
        Isa::Portable => kernel.run(Portable),
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

/// `kernel.run(Avx2)` compiled with AVX2 and FMA enabled.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn run_avx2<K: Kernel>(kernel: K) -> K::Output {
    // SAFETY: this function has the features enabled, so it runs only where the CPU has them.
    kernel.run(unsafe { avx2::Avx2::new_unchecked() })
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
        fn run<S: Simd>(self, s: S) -> Vec<f32> {
            self.0
                .chunks_exact(W)
                .flat_map(|c| s.to_array(exp(s, s.lanes(c.try_into().unwrap()))))
                .collect()
        }
    }

    /// The lanes `d` of [`Ops`]' fused multiply-add `d·d - round(d·d)`.
    const MUL_ADD_INPUTS: [f32; W] = [1.1, 0.1, -3.3, 1e-3, 7.77, 1.0, -0.0, 123.456];

    /// Every lane operation on fixed inputs, as arrays.
    struct Ops;

    impl Kernel for Ops {
        type Output = Vec<[u32; W]>;
        #[inline(always)]
        fn run<S: Simd>(self, s: S) -> Vec<[u32; W]> {
            let a = s.lanes([0.0, 1.0, -2.0, f32::NAN, 4.0, -0.0, 6.0, f32::INFINITY]);
            let b = s.lanes([0.5, 1.0, 2.0, 3.0, f32::NAN, 0.0, -6.5, 1e30]);
            let (ia, ib) = (s.lanes_i([0, 1, 2, 3, 4, 5, 6, 7]), s.splat_i(3));
            let m = s.lt(a, b) | s.ge(a, s.splat(6.0));
            let c = s.lanes([1e30, 1.0, -1e30, 2.0, 0.5, 3.0, 0.25, 4.0]);
            let d = s.lanes(MUL_ADD_INPUTS);
            let f = |v: S::F| s.to_array(v).map(f32::to_bits);
            let mk = |m: S::M| {
                let v = s.to_array(s.select(m, s.splat(1.0), s.splat(0.0)));
                v.map(f32::to_bits)
            };
            vec![
                f(a + b),
                f(a - b),
                f(a * b),
                f(a / b),
                f(-a),
                f(s.min(a, b)),
                f(s.max(a, b)),
                f(s.select(m, a, b)),
                f(s.exp2_bits(a)),
                mk(s.le(a, b)),
                mk(s.lt(a, b)),
                mk(s.ge(a, b)),
                mk(s.gt(a, b)),
                mk(!m),
                mk(m & s.gt_i(ia, ib)),
                mk(s.range(2, 5)),
                mk(s.none()),
                s.to_array_i(s.select_i(m, ia, ib)).map(|v| v as u32),
                s.to_array_i(s.count_lanes(s.count_lanes(ia, m), s.gt_i(ia, ib)))
                    .map(|v| v as u32),
                f(s.sum8([a, b, c, a + c, b * c, a - b, c - b, c * c])),
                [
                    s.any(m) as u32,
                    s.any(s.none()) as u32,
                    s.count(m),
                    s.sum(c).to_bits(),
                    0,
                    0,
                    0,
                    0,
                ],
                // Fused: the rounding error of d·d, which an unfused multiply and add lose.
                f(s.mul_add(d, d, -(d * d))),
            ]
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
            -0.346_573_5,
        ]);
        while !xs.len().is_multiple_of(W) {
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
            f32::NAN,
            0.0,
            -0.0,
        ]);
        let y = exp(Portable, x).0;
        for v in &y[..3] {
            assert!((v - 1.0).abs() < 1e-6, "{v}");
        }
        for v in &y[3..6] {
            assert!(*v > 0.0 && *v < 2e-35, "{v}");
        }
        assert_eq!(&y[6..], &[1.0, 1.0]);
    }

    #[test]
    fn lane_operations_are_bit_identical_in_every_build() {
        let want = dispatch(Isa::Portable, Ops);
        // Spot checks of the portable lanes against plain f32 arithmetic.
        assert_eq!(f32::from_bits(want[0][1]), 2.0);
        assert_eq!(f32::from_bits(want[5][0]), 0.0);
        assert_eq!(f32::from_bits(want[5][3]), 3.0, "min(NaN, b) = b");
        assert!(f32::from_bits(want[6][4]).is_nan(), "max(4, NaN) = NaN");
        assert_eq!(
            want[15].map(f32::from_bits),
            [0.0, 0.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0]
        );
        assert_eq!(want[20][..3], [1, 0, 4]);
        assert_eq!(
            f32::from_bits(want[20][3]),
            10.0,
            "((0+4)+(2+6)) + ((1+5)+(3+7))"
        );
        assert_eq!(want[18], [1, 1, 3, 3, 5, 6, 8, 9], "count_lanes");
        // mul_add is fused: d·d - round(d·d) is the exact rounding error (nonzero for 1.1).
        for (l, d) in MUL_ADD_INPUTS.iter().enumerate() {
            let exact = f64::from(*d) * f64::from(*d) - f64::from(d * d);
            assert_eq!(
                f64::from(f32::from_bits(want[21][l])),
                exact,
                "mul_add lane {l}"
            );
        }
        assert_ne!(want[21][0], 0.0f32.to_bits(), "1.1² is not exact in f32");
        // sum8 is `sum` of each vector.
        let vs = [
            [0.0, 1.0, -2.0, f32::NAN, 4.0, -0.0, 6.0, f32::INFINITY],
            [0.5, 1.0, 2.0, 3.0, f32::NAN, 0.0, -6.5, 1e30],
            [1e30, 1.0, -1e30, 2.0, 0.5, 3.0, 0.25, 4.0],
        ];
        for (k, v) in vs.iter().enumerate() {
            assert_eq!(want[19][k], Portable.sum(F8(*v)).to_bits(), "sum8 lane {k}");
        }
        for isa in isas() {
            assert_eq!(dispatch(isa, Ops), want, "{isa:?}");
        }
    }
}
