//! The vector unit's state after faer.
//!
//! faer's matrix products on x86-64 run assembly kernels (`private-gemm-x86`) that return
//! with the upper halves of the vector registers in use ("dirty"). Code compiled for the
//! baseline x86-64 target — all of this crate outside its AVX2 kernels — uses legacy SSE
//! encodings, which keep those upper halves: each such instruction then waits on the
//! register's previous value, so loops that should overlap run one iteration at a time.
//! Measured on this project's AMD Zen 4 machines, 2026-11-27: the phase transform of an
//! SRP-PHAT call on 8 microphones (44 800 square roots and divisions) took 0.57 ms after a
//! faer product and 0.18 ms after `vzeroupper` (0.13 ms in a program without faer).
//! [`clear_upper`] is called after every faer call on a hot path.

/// `vzeroupper` where the CPU has AVX (checked at run time, cached); nothing elsewhere.
/// Marks every caller-saved register clobbered, so it is safe inside AVX-compiled code:
/// in the System V ABI every vector register is caller-saved. Not on Windows, whose ABI
/// keeps xmm6–15 (but not their upper halves, which `vzeroupper` clears) across calls.
#[inline(always)]
pub fn clear_upper() {
    #[cfg(all(target_arch = "x86_64", not(windows)))]
    if std::arch::is_x86_feature_detected!("avx") {
        // SAFETY: the CPU has AVX (checked just above); `vzeroupper` touches only vector
        // registers, all declared clobbered by the C ABI clause.
        unsafe {
            std::arch::asm!(
                "vzeroupper",
                clobber_abi("C"),
                options(nomem, nostack, preserves_flags)
            )
        }
    }
}

#[cfg(test)]
mod tests {
    /// Values live in vector registers across the call stay intact, in baseline code and
    /// in AVX2-compiled code (where the compiler keeps them in the upper halves that
    /// `vzeroupper` clears, unless the clobbers say otherwise).
    #[test]
    fn clearing_keeps_live_values() {
        #[inline(always)]
        fn sums(x: &[f64]) -> [f64; 4] {
            let mut s = [0.0; 4];
            for c in x.chunks_exact(4) {
                for l in 0..4 {
                    s[l] += c[l] * c[l];
                }
                super::clear_upper();
            }
            s
        }
        let x: Vec<f64> = (0..64).map(|i| (i as f64 * 0.37).sin()).collect();
        let want = {
            let mut s = [0.0; 4];
            for c in x.chunks_exact(4) {
                for l in 0..4 {
                    s[l] += c[l] * c[l];
                }
            }
            s
        };
        assert_eq!(sums(&x), want);
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            #[target_feature(enable = "avx2")]
            unsafe fn sums_avx2(x: &[f64]) -> [f64; 4] {
                sums(x)
            }
            // SAFETY: the CPU has AVX2 (checked just above).
            assert_eq!(unsafe { sums_avx2(&x) }, want);
        }
    }
}
