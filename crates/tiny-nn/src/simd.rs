//! Runtime dispatch of the crate's own row loops (the encoders inside Φ, Adam's f32 update) to AVX2.
//!
//! The crate is compiled for the baseline x86-64 target (SSE2): its own loops run 4 lanes wide
//! and `floor` is a libm call, while `gemm` picks AVX2 kernels at run time. [`vectorised`] runs a
//! [`Kernel`] inside a function compiled with AVX2 and FMA enabled when the CPU has them; the
//! kernel's `run` and the row functions it calls are `#[inline(always)]`, so they are compiled
//! 8 lanes wide there. Results are bit-identical to the baseline path: Rust never contracts
//! `a * b + c` into a fused multiply-add on its own, vectorising element-wise operations does not
//! change them, and the crate's reductions have a fixed association (`encoding::dot`).

/// A block of work to compile for the best available instruction set. Implementations mark
/// `run` `#[inline(always)]`.
pub(crate) trait Kernel {
    /// What the kernel returns.
    type Output;
    /// Does the work.
    fn run(self) -> Self::Output;
}

/// Runs `kernel`, compiled for AVX2 + FMA when the CPU supports both, else as it is.
#[inline(always)]
pub(crate) fn vectorised<K: Kernel>(kernel: K) -> K::Output {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the only requirement of calling a `#[target_feature]` function is that the
        // CPU supports the features it enables; both were detected just above.
        return unsafe { run_avx2(kernel) };
    }
    kernel.run()
}

/// `kernel.run()` compiled with AVX2 and FMA enabled.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn run_avx2<K: Kernel>(kernel: K) -> K::Output {
    kernel.run()
}

#[cfg(test)]
mod tests {
    use super::{Kernel, vectorised};

    struct Scale<'a>(&'a mut [f32], f32);

    impl Kernel for Scale<'_> {
        type Output = f32;
        #[inline(always)]
        fn run(self) -> f32 {
            self.0.iter_mut().for_each(|v| *v *= self.1);
            self.0.iter().sum()
        }
    }

    #[test]
    fn runs_the_kernel_and_returns_its_value() {
        let mut v: Vec<f32> = (0..100).map(|i| i as f32).collect();
        let s = vectorised(Scale(&mut v, 0.5));
        assert_eq!(s, 2475.0);
        assert_eq!(v[99], 49.5);
    }
}
