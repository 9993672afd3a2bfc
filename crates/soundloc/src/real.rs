//! One code path for `f32` and `f64`.
//!
//! [`Real`] is sealed and implemented for `f32` (the default, as HARK computes) and `f64`
//! (the reference path that verifies it). Write numeric code once as `fn f<T: Real>`; take
//! literals through [`Real::of_f64`].

use num_complex::Complex;

mod sealed {
    pub trait Sealed {}
    impl Sealed for f32 {}
    impl Sealed for f64 {}
}

/// A complex number over `T`.
pub type C<T> = Complex<T>;

/// `f32` or `f64`, with everything faer, realfft and the backends need.
pub trait Real:
    sealed::Sealed
    + faer::traits::RealField<Unit: faer::traits::ComplexField>
    + realfft::FftNum
    + num_traits::Float
    + num_traits::FloatConst
    + num_traits::NumAssign
    + std::iter::Sum
    + Copy
    + Default
    + PartialOrd
    + Send
    + Sync
    + std::fmt::Debug
    + std::fmt::Display
    + 'static
{
    /// `"f32"` or `"f64"`: used to pick kernels and name outputs.
    const NAME: &'static str;
    /// Machine epsilon.
    const EPS: f64;
    /// Largest input sample magnitude the correlation matrices hold without overflow in
    /// this precision (x → N·x by the FFT, then squared and summed over a window):
    /// 1e14 for f32 (safe to N = 4096, W = 200), unlimited for f64.
    const MAX_SAMPLE: f32;
    /// Convert from `f64` (rounding for `f32`).
    fn of_f64(x: f64) -> Self;
    /// Widen to `f64`.
    fn to_f64(self) -> f64;
    /// `s` itself when `Self` is `f32` (the way into single-precision-only kernels).
    fn cplx_f32(s: &[C<Self>]) -> Option<&[C<f32>]>;
    /// `s` itself when `Self` is `f32`.
    fn f32_mut(s: &mut [Self]) -> Option<&mut [f32]>;
}

impl Real for f32 {
    const NAME: &'static str = "f32";
    const EPS: f64 = f32::EPSILON as f64;
    const MAX_SAMPLE: f32 = 1e14;
    #[inline(always)]
    fn of_f64(x: f64) -> Self {
        x as f32
    }
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self as f64
    }
    fn cplx_f32(s: &[C<f32>]) -> Option<&[C<f32>]> {
        Some(s)
    }
    fn f32_mut(s: &mut [f32]) -> Option<&mut [f32]> {
        Some(s)
    }
}

impl Real for f64 {
    const NAME: &'static str = "f64";
    const EPS: f64 = f64::EPSILON;
    const MAX_SAMPLE: f32 = f32::MAX;
    #[inline(always)]
    fn of_f64(x: f64) -> Self {
        x
    }
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self
    }
    fn cplx_f32(_: &[C<f64>]) -> Option<&[C<f32>]> {
        None
    }
    fn f32_mut(_: &mut [f64]) -> Option<&mut [f32]> {
        None
    }
}
