//! Eight f64 lanes, one type per instruction set: [`Avx512`] (one 512-bit register),
//! [`Avx2`] (two 256-bit registers) and [`Scalar`] (a plain array, the baseline build).
//! All do the same IEEE operations
//! (add, subtract, multiply, divide, square root, compare, select, and a fused
//! multiply-add that only [`super::tridiag_lanes`] uses), so code written once over [`F8`]
//! gives the same bits on any of them.

use std::ops::{Add, Div, Mul, Neg, Sub};

/// Eight f64 lanes and their operations; `Mask` is a per-lane condition.
pub(crate) trait F8:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self> + Neg<Output = Self>
{
    type Mask: Copy;
    fn splat(x: f64) -> Self;
    fn load(a: &[f64; 8]) -> Self;
    fn store(self, a: &mut [f64; 8]);
    fn sqrt(self) -> Self;
    fn abs(self) -> Self;
    /// `self < o` per lane (false where either is NaN).
    fn lt(self, o: Self) -> Self::Mask;
    /// `self == o` per lane.
    fn eq(self, o: Self) -> Self::Mask;
    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    /// `m ? a : b` per lane.
    fn select(m: Self::Mask, a: Self, b: Self) -> Self;
    /// Whether any lane is set.
    fn any(m: Self::Mask) -> bool;
    /// The mask as booleans.
    fn lanes(m: Self::Mask) -> [bool; 8];
    /// `self · a + b` with one rounding (fused multiply-add; the same bits on every
    /// instruction set, given a correctly rounded `fma` in the C library for the
    /// baseline's `f64::mul_add`, as `simd.rs` assumes). The AVX2 lanes need the `fma`
    /// feature enabled where this is used. Code that promises plain IEEE multiplies and
    /// adds (the solvers that predate it) does not call it.
    fn mul_add(self, a: Self, b: Self) -> Self;
    /// `max(self, o)` as `self < o ? o : self`.
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        Self::select(self.lt(o), o, self)
    }
}

/// The baseline: eight f64 in an array.
#[derive(Clone, Copy)]
pub(crate) struct Scalar([f64; 8]);

macro_rules! scalar_op {
    ($tr:ident, $f:ident, $op:tt) => {
        impl $tr for Scalar {
            type Output = Scalar;
            #[inline(always)]
            fn $f(self, o: Scalar) -> Scalar {
                Scalar(std::array::from_fn(|l| self.0[l] $op o.0[l]))
            }
        }
    };
}
scalar_op!(Add, add, +);
scalar_op!(Sub, sub, -);
scalar_op!(Mul, mul, *);
scalar_op!(Div, div, /);

impl Neg for Scalar {
    type Output = Scalar;
    #[inline(always)]
    fn neg(self) -> Scalar {
        Scalar(self.0.map(|x| -x))
    }
}

impl F8 for Scalar {
    type Mask = [bool; 8];
    #[inline(always)]
    fn splat(x: f64) -> Self {
        Scalar([x; 8])
    }
    #[inline(always)]
    fn load(a: &[f64; 8]) -> Self {
        Scalar(*a)
    }
    #[inline(always)]
    fn store(self, a: &mut [f64; 8]) {
        *a = self.0;
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        Scalar(self.0.map(f64::sqrt))
    }
    #[inline(always)]
    fn abs(self) -> Self {
        Scalar(self.0.map(f64::abs))
    }
    #[inline(always)]
    fn lt(self, o: Self) -> [bool; 8] {
        std::array::from_fn(|l| self.0[l] < o.0[l])
    }
    #[inline(always)]
    fn eq(self, o: Self) -> [bool; 8] {
        std::array::from_fn(|l| self.0[l] == o.0[l])
    }
    #[inline(always)]
    fn and(a: [bool; 8], b: [bool; 8]) -> [bool; 8] {
        std::array::from_fn(|l| a[l] & b[l])
    }
    #[inline(always)]
    fn select(m: [bool; 8], a: Self, b: Self) -> Self {
        Scalar(std::array::from_fn(|l| if m[l] { a.0[l] } else { b.0[l] }))
    }
    #[inline(always)]
    fn any(m: [bool; 8]) -> bool {
        m.iter().any(|&x| x)
    }
    #[inline(always)]
    fn lanes(m: [bool; 8]) -> [bool; 8] {
        m
    }
    #[inline(always)]
    fn mul_add(self, a: Self, b: Self) -> Self {
        Scalar(std::array::from_fn(|l| self.0[l].mul_add(a.0[l], b.0[l])))
    }
}

#[cfg(target_arch = "x86_64")]
pub(crate) use avx2::Avx2;

#[cfg(target_arch = "x86_64")]
mod avx2 {
    //! SAFETY (every `unsafe` block below): an [`Avx2`] value exists only in code the
    //! caller runs after checking that the CPU has AVX2 (`is_x86_feature_detected!`),
    //! and the loads and stores go through references to whole `[f64; 8]` arrays.
    use super::F8;
    use std::arch::x86_64::*;
    use std::ops::{Add, Div, Mul, Neg, Sub};

    /// Eight f64 lanes in two AVX2 registers (use only where the CPU has AVX2: every
    /// value starts from `splat` or `load`, which check that in debug builds).
    #[derive(Clone, Copy)]
    pub(crate) struct Avx2(__m256d, __m256d);

    macro_rules! avx_op {
        ($tr:ident, $f:ident, $intr:ident) => {
            impl $tr for Avx2 {
                type Output = Avx2;
                #[inline(always)]
                fn $f(self, o: Avx2) -> Avx2 {
                    unsafe { Avx2($intr(self.0, o.0), $intr(self.1, o.1)) }
                }
            }
        };
    }
    avx_op!(Add, add, _mm256_add_pd);
    avx_op!(Sub, sub, _mm256_sub_pd);
    avx_op!(Mul, mul, _mm256_mul_pd);
    avx_op!(Div, div, _mm256_div_pd);

    impl Neg for Avx2 {
        type Output = Avx2;
        #[inline(always)]
        fn neg(self) -> Avx2 {
            unsafe {
                let s = _mm256_set1_pd(-0.0);
                Avx2(_mm256_xor_pd(self.0, s), _mm256_xor_pd(self.1, s))
            }
        }
    }

    impl F8 for Avx2 {
        type Mask = (__m256d, __m256d);
        #[inline(always)]
        fn splat(x: f64) -> Self {
            debug_assert!(std::arch::is_x86_feature_detected!("avx2"));
            unsafe { Avx2(_mm256_set1_pd(x), _mm256_set1_pd(x)) }
        }
        #[inline(always)]
        fn load(a: &[f64; 8]) -> Self {
            debug_assert!(std::arch::is_x86_feature_detected!("avx2"));
            unsafe { Avx2(_mm256_loadu_pd(a.as_ptr()), _mm256_loadu_pd(a.as_ptr().add(4))) }
        }
        #[inline(always)]
        fn store(self, a: &mut [f64; 8]) {
            unsafe {
                _mm256_storeu_pd(a.as_mut_ptr(), self.0);
                _mm256_storeu_pd(a.as_mut_ptr().add(4), self.1);
            }
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            unsafe { Avx2(_mm256_sqrt_pd(self.0), _mm256_sqrt_pd(self.1)) }
        }
        #[inline(always)]
        fn abs(self) -> Self {
            unsafe {
                let s = _mm256_set1_pd(-0.0);
                Avx2(_mm256_andnot_pd(s, self.0), _mm256_andnot_pd(s, self.1))
            }
        }
        #[inline(always)]
        fn lt(self, o: Self) -> Self::Mask {
            unsafe {
                (
                    _mm256_cmp_pd::<_CMP_LT_OQ>(self.0, o.0),
                    _mm256_cmp_pd::<_CMP_LT_OQ>(self.1, o.1),
                )
            }
        }
        #[inline(always)]
        fn eq(self, o: Self) -> Self::Mask {
            unsafe {
                (
                    _mm256_cmp_pd::<_CMP_EQ_OQ>(self.0, o.0),
                    _mm256_cmp_pd::<_CMP_EQ_OQ>(self.1, o.1),
                )
            }
        }
        #[inline(always)]
        fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask {
            unsafe { (_mm256_and_pd(a.0, b.0), _mm256_and_pd(a.1, b.1)) }
        }
        #[inline(always)]
        fn select(m: Self::Mask, a: Self, b: Self) -> Self {
            unsafe { Avx2(_mm256_blendv_pd(b.0, a.0, m.0), _mm256_blendv_pd(b.1, a.1, m.1)) }
        }
        #[inline(always)]
        fn any(m: Self::Mask) -> bool {
            unsafe { (_mm256_movemask_pd(m.0) | _mm256_movemask_pd(m.1)) != 0 }
        }
        #[inline(always)]
        fn lanes(m: Self::Mask) -> [bool; 8] {
            let bits = unsafe { _mm256_movemask_pd(m.0) | (_mm256_movemask_pd(m.1) << 4) };
            std::array::from_fn(|l| (bits >> l) & 1 == 1)
        }
        #[inline(always)]
        fn mul_add(self, a: Self, b: Self) -> Self {
            debug_assert!(std::arch::is_x86_feature_detected!("fma"));
            unsafe {
                Avx2(
                    _mm256_fmadd_pd(self.0, a.0, b.0),
                    _mm256_fmadd_pd(self.1, a.1, b.1),
                )
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
pub(crate) use avx512::Avx512;

#[cfg(target_arch = "x86_64")]
mod avx512 {
    //! SAFETY (every `unsafe` block below): an [`Avx512`] value exists only in code the
    //! caller runs after checking that the CPU has AVX-512F (`is_x86_feature_detected!`),
    //! and the loads and stores go through references to whole `[f64; 8]` arrays.
    use super::F8;
    use std::arch::x86_64::*;
    use std::ops::{Add, Div, Mul, Neg, Sub};

    /// Eight f64 lanes in one AVX-512 register (use only where the CPU has AVX-512F:
    /// every value starts from `splat` or `load`, which check that in debug builds).
    #[derive(Clone, Copy)]
    pub(crate) struct Avx512(__m512d);

    macro_rules! avx_op {
        ($tr:ident, $f:ident, $intr:ident) => {
            impl $tr for Avx512 {
                type Output = Avx512;
                #[inline(always)]
                fn $f(self, o: Avx512) -> Avx512 {
                    unsafe { Avx512($intr(self.0, o.0)) }
                }
            }
        };
    }
    avx_op!(Add, add, _mm512_add_pd);
    avx_op!(Sub, sub, _mm512_sub_pd);
    avx_op!(Mul, mul, _mm512_mul_pd);
    avx_op!(Div, div, _mm512_div_pd);

    impl Neg for Avx512 {
        type Output = Avx512;
        /// The sign bit flipped (as `-x`, not `0 − x`: −0 for +0).
        #[inline(always)]
        fn neg(self) -> Avx512 {
            unsafe {
                let s = _mm512_set1_epi64(i64::MIN);
                Avx512(_mm512_castsi512_pd(_mm512_xor_si512(
                    _mm512_castpd_si512(self.0),
                    s,
                )))
            }
        }
    }

    impl F8 for Avx512 {
        type Mask = __mmask8;
        #[inline(always)]
        fn splat(x: f64) -> Self {
            debug_assert!(std::arch::is_x86_feature_detected!("avx512f"));
            unsafe { Avx512(_mm512_set1_pd(x)) }
        }
        #[inline(always)]
        fn load(a: &[f64; 8]) -> Self {
            debug_assert!(std::arch::is_x86_feature_detected!("avx512f"));
            unsafe { Avx512(_mm512_loadu_pd(a.as_ptr())) }
        }
        #[inline(always)]
        fn store(self, a: &mut [f64; 8]) {
            unsafe { _mm512_storeu_pd(a.as_mut_ptr(), self.0) }
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            unsafe { Avx512(_mm512_sqrt_pd(self.0)) }
        }
        #[inline(always)]
        fn abs(self) -> Self {
            unsafe { Avx512(_mm512_abs_pd(self.0)) }
        }
        #[inline(always)]
        fn lt(self, o: Self) -> Self::Mask {
            unsafe { _mm512_cmp_pd_mask::<_CMP_LT_OQ>(self.0, o.0) }
        }
        #[inline(always)]
        fn eq(self, o: Self) -> Self::Mask {
            unsafe { _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(self.0, o.0) }
        }
        #[inline(always)]
        fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask {
            a & b
        }
        #[inline(always)]
        fn select(m: Self::Mask, a: Self, b: Self) -> Self {
            // Lanes of the second operand where the mask is set.
            unsafe { Avx512(_mm512_mask_blend_pd(m, b.0, a.0)) }
        }
        #[inline(always)]
        fn any(m: Self::Mask) -> bool {
            m != 0
        }
        #[inline(always)]
        fn lanes(m: Self::Mask) -> [bool; 8] {
            std::array::from_fn(|l| (m >> l) & 1 == 1)
        }
        #[inline(always)]
        fn mul_add(self, a: Self, b: Self) -> Self {
            unsafe { Avx512(_mm512_fmadd_pd(self.0, a.0, b.0)) }
        }
    }
}
