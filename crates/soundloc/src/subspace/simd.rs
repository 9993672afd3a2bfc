//! Small complex vector kernels over split real/imaginary parts, and [`dispatch`], which
//! compiles a function twice: for AVX2 (chosen at run time where the CPU has it) and as
//! it is.
//!
//! The kernels fix their summation order (four partial sums, combined pairwise), so the
//! result is the same whatever vector width the compiler picks: AVX2 and the baseline
//! x86-64 build give identical numbers.

use crate::real::C;

/// `dispatch!(pub fn name(args) => imp)` (or `fn name<T: Bound>(args) => imp`, generic
/// over one type, or `fn name<const N: usize>(args) => imp`) defines `name`, which calls
/// the `#[inline(always)]` function `imp` compiled for AVX2 and FMA where the CPU has them
/// (checked at run time), else as it is. With `=> imp::<AVX2>`, `imp<const AVX2: bool>`
/// learns which variant it is, for kernels that need intrinsics ([`dot4_in`]).
/// The kernels below are `#[inline(always)]`, so they are compiled into each variant.
/// Compilers never fuse a multiply and an add on their own, so a kernel gives the same
/// bits in both variants; one that asks for `f64::mul_add` gets the FMA instruction here
/// and the C library's `fma` in the other (slower; the same bits where that is correctly
/// rounded, as glibc's is).
macro_rules! dispatch {
    // `=> imp::<AVX2>`: `imp<const AVX2: bool>` is told which variant it is compiled into,
    // so it may call `#[target_feature]` kernels such as [`dot4_avx2`] where it is true.
    ($(#[$m:meta])* $vis:vis fn $name:ident ($($a:ident: $t:ty),* $(,)?) => $imp:ident::<AVX2>) => {
        $(#[$m])* $vis fn $name ($($a: $t),*) {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx2,fma")]
                unsafe fn avx2 ($($a: $t),*) {
                    $imp::<true>($($a),*)
                }
                if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
                    // SAFETY: the CPU supports AVX2 and FMA (checked just above).
                    return unsafe { avx2($($a),*) };
                }
            }
            $imp::<false>($($a),*)
        }
    };
    ($(#[$m:meta])* $vis:vis fn $name:ident $(<$g:ident: $b:path>)? ($($a:ident: $t:ty),* $(,)?) => $imp:ident) => {
        $(#[$m])* $vis fn $name $(<$g: $b>)? ($($a: $t),*) {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx2,fma")]
                unsafe fn avx2 $(<$g: $b>)? ($($a: $t),*) {
                    $imp $(::<$g>)? ($($a),*)
                }
                if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
                    // SAFETY: the CPU supports AVX2 and FMA (checked just above).
                    return unsafe { avx2 $(::<$g>)? ($($a),*) };
                }
            }
            $imp $(::<$g>)? ($($a),*)
        }
    };
    ($(#[$m:meta])* $vis:vis fn $name:ident <const $g:ident: $b:ty> ($($a:ident: $t:ty),* $(,)?) => $imp:ident) => {
        $(#[$m])* $vis fn $name <const $g: $b> ($($a: $t),*) {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx2,fma")]
                unsafe fn avx2 <const $g: $b> ($($a: $t),*) {
                    $imp::<$g>($($a),*)
                }
                if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
                    // SAFETY: the CPU supports AVX2 and FMA (checked just above).
                    return unsafe { avx2::<$g>($($a),*) };
                }
            }
            $imp::<$g>($($a),*)
        }
    };
}
pub(crate) use dispatch;

/// Σ conj(a_i) b_i.
#[inline(always)]
pub fn dotc(ar: &[f64], ai: &[f64], br: &[f64], bi: &[f64]) -> C<f64> {
    dot4::<true>(ar, ai, br, bi)
}

/// Σ a_i b_i or Σ conj(a_i) b_i, four partial sums per part (a fixed order: the result
/// does not depend on the vector width the compiler picks).
#[inline(always)]
pub fn dot4<const CONJ: bool>(ar: &[f64], ai: &[f64], br: &[f64], bi: &[f64]) -> C<f64> {
    let n = ar.len();
    let (ai, br, bi) = (&ai[..n], &br[..n], &bi[..n]);
    let sgn = if CONJ { -1.0 } else { 1.0 };
    let mut sr = [0.0f64; 4];
    let mut si = [0.0f64; 4];
    let chunks = ar
        .chunks_exact(4)
        .zip(ai.chunks_exact(4))
        .zip(br.chunks_exact(4).zip(bi.chunks_exact(4)));
    for ((xr, xi), (yr, yi)) in chunks {
        for l in 0..4 {
            // (xr + i·sgn·xi)(yr + i·yi)
            sr[l] += xr[l] * yr[l] - sgn * xi[l] * yi[l];
            si[l] += xr[l] * yi[l] + sgn * xi[l] * yr[l];
        }
    }
    dot4_finish::<CONJ>(sr, si, ar, ai, br, bi)
}

/// [`dot4`]'s end, shared by its AVX2 form: the four partial sums of each part combined
/// pairwise, then the elements past the last whole chunk of four added in order.
#[inline(always)]
fn dot4_finish<const CONJ: bool>(
    sr: [f64; 4],
    si: [f64; 4],
    ar: &[f64],
    ai: &[f64],
    br: &[f64],
    bi: &[f64],
) -> C<f64> {
    let sgn = if CONJ { -1.0 } else { 1.0 };
    let (mut tr, mut ti) = (
        (sr[0] + sr[2]) + (sr[1] + sr[3]),
        (si[0] + si[2]) + (si[1] + si[3]),
    );
    for i in ar.len() / 4 * 4..ar.len() {
        tr += ar[i] * br[i] - sgn * ai[i] * bi[i];
        ti += ar[i] * bi[i] + sgn * ai[i] * br[i];
    }
    C::new(tr, ti)
}

/// [`dot4`], in its AVX2 form ([`dot4_avx2`]) where `AVX2` says the caller was compiled
/// for AVX2 (`dispatch!`'s `=> imp::<AVX2>` form): the same bits either way.
///
/// # Safety
/// `AVX2` only where the CPU has AVX2.
#[inline(always)]
pub unsafe fn dot4_in<const AVX2: bool, const CONJ: bool>(
    ar: &[f64],
    ai: &[f64],
    br: &[f64],
    bi: &[f64],
) -> C<f64> {
    #[cfg(target_arch = "x86_64")]
    if AVX2 {
        // SAFETY: the caller's promise.
        return unsafe { dot4_avx2::<CONJ>(ar, ai, br, bi) };
    }
    dot4::<CONJ>(ar, ai, br, bi)
}

/// [`dot4`] with its four partial sums in one 256-bit register: the same operations in
/// the same order (no fused multiply-add), so the same bits. (One loop over both sums
/// had the compiler pair each real sum with its imaginary one in 128-bit registers: the
/// 60-mic tridiagonal reduction 64 → 55 µs with this, 2026-11-27.)
///
/// # Safety
/// The CPU must have AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub unsafe fn dot4_avx2<const CONJ: bool>(ar: &[f64], ai: &[f64], br: &[f64], bi: &[f64]) -> C<f64> {
    use std::arch::x86_64::*;
    let n = ar.len();
    let (ai, br, bi) = (&ai[..n], &br[..n], &bi[..n]);
    let sgn = if CONJ { -1.0 } else { 1.0 };
    let vs = _mm256_set1_pd(sgn);
    let (mut sr, mut si) = (_mm256_setzero_pd(), _mm256_setzero_pd());
    let mut i = 0;
    while i + 4 <= n {
        // SAFETY: i + 4 <= n and every slice holds n values.
        let (xr, xi, yr, yi) = unsafe {
            (
                _mm256_loadu_pd(ar.as_ptr().add(i)),
                _mm256_loadu_pd(ai.as_ptr().add(i)),
                _mm256_loadu_pd(br.as_ptr().add(i)),
                _mm256_loadu_pd(bi.as_ptr().add(i)),
            )
        };
        let sxi = _mm256_mul_pd(vs, xi);
        // sr += xr·yr − (sgn·xi)·yi; si += xr·yi + (sgn·xi)·yr.
        sr = _mm256_add_pd(sr, _mm256_sub_pd(_mm256_mul_pd(xr, yr), _mm256_mul_pd(sxi, yi)));
        si = _mm256_add_pd(si, _mm256_add_pd(_mm256_mul_pd(xr, yi), _mm256_mul_pd(sxi, yr)));
        i += 4;
    }
    let (mut a, mut b) = ([0.0f64; 4], [0.0f64; 4]);
    // SAFETY: two arrays of four f64.
    unsafe {
        _mm256_storeu_pd(a.as_mut_ptr(), sr);
        _mm256_storeu_pd(b.as_mut_ptr(), si);
    }
    dot4_finish::<CONJ>(a, b, ar, ai, br, bi)
}

/// Σ a_i b_i over reals, four partial sums.
#[inline(always)]
pub fn dot_real(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len();
    let b = &b[..n];
    let mut s = [0.0f64; 4];
    for (x, y) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        for l in 0..4 {
            s[l] += x[l] * y[l];
        }
    }
    let mut t = (s[0] + s[2]) + (s[1] + s[3]);
    for i in n / 4 * 4..n {
        t += a[i] * b[i];
    }
    t
}

/// y ← y + f·x over reals.
#[inline(always)]
pub fn axpy_real(f: f64, x: &[f64], y: &mut [f64]) {
    let n = x.len();
    for (yi, xi) in y[..n].iter_mut().zip(x) {
        *yi += f * xi;
    }
}

/// y ← y + f·x.
#[inline(always)]
pub fn axpy(f: C<f64>, xr: &[f64], xi: &[f64], yr: &mut [f64], yi: &mut [f64]) {
    let n = xr.len();
    let (xr, xi, yr, yi) = (&xr[..n], &xi[..n], &mut yr[..n], &mut yi[..n]);
    for i in 0..n {
        yr[i] += f.re * xr[i] - f.im * xi[i];
        yi[i] += f.re * xi[i] + f.im * xr[i];
    }
}

/// y ← y + f·conj(x).
#[inline(always)]
pub fn conj_axpy(f: C<f64>, xr: &[f64], xi: &[f64], yr: &mut [f64], yi: &mut [f64]) {
    let n = xr.len();
    let (xi, yr, yi) = (&xi[..n], &mut yr[..n], &mut yi[..n]);
    for i in 0..n {
        yr[i] += f.re * xr[i] + f.im * xi[i];
        yi[i] += f.im * xr[i] - f.re * xi[i];
    }
}

/// Row i of A ← A − v wᴴ − w vᴴ: a_k −= v_i conj(w_k) + w_i conj(v_k).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub fn rank2_row(
    ar: &mut [f64],
    ai: &mut [f64],
    v: C<f64>,
    w: C<f64>,
    vr: &[f64],
    vi: &[f64],
    wr: &[f64],
    wi: &[f64],
) {
    let n = ar.len();
    let (ai, vr, vi, wr, wi) = (&mut ai[..n], &vr[..n], &vi[..n], &wr[..n], &wi[..n]);
    for k in 0..n {
        // v conj(w_k) + w conj(v_k)
        let re = v.re * wr[k] + v.im * wi[k] + w.re * vr[k] + w.im * vi[k];
        let im = v.im * wr[k] - v.re * wi[k] + w.im * vr[k] - w.re * vi[k];
        ar[k] -= re;
        ai[k] -= im;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// The AVX2 dot product gives the plain one's bits, for every length's remainder.
    #[test]
    fn avx2_dot_products_equal_the_plain_ones_bit_for_bit() {
        #[cfg(target_arch = "x86_64")]
        {
            if !std::arch::is_x86_feature_detected!("avx2") {
                println!("SKIPPED avx2_dot_products_equal_the_plain_ones_bit_for_bit: no AVX2 on this CPU");
                return;
            }
            let mut rng = rand::rngs::StdRng::seed_from_u64(9);
            let mut v = |n: usize| -> Vec<f64> { (0..n).map(|_| rng.gen_range(-1e3..1e3)).collect() };
            for n in 0..23 {
                let (ar, ai, br, bi) = (v(n), v(n), v(n), v(n));
                let bits = |z: C<f64>| (z.re.to_bits(), z.im.to_bits());
                // SAFETY: the CPU has AVX2 (checked above).
                let (x, y) = unsafe {
                    (
                        dot4_avx2::<false>(&ar, &ai, &br, &bi),
                        dot4_avx2::<true>(&ar, &ai, &br, &bi),
                    )
                };
                assert_eq!(bits(x), bits(dot4::<false>(&ar, &ai, &br, &bi)), "n = {n}");
                assert_eq!(
                    bits(y),
                    bits(dot4::<true>(&ar, &ai, &br, &bi)),
                    "n = {n}, conjugated"
                );
            }
        }
    }
}
