//! The products that turn R into the Hermitian matrix each algorithm decomposes, in f64
//! over split real/imaginary rows (vectorised by [`super::simd`]):
//!
//! | algorithm | A | work (complex multiply-adds) |
//! |---|---|---|
//! | GEVD | W R Wᴴ, W = L⁻¹ lower triangular | M³/2 + M³/6 |
//! | GEVD-HARK | W R W, W = K^{-1/2} Hermitian | M³ + M³/2 |
//! | GSVD | B Bᴴ, B = W R, W = K⁻¹ | M³ + M³/2 |
//!
//! Step 1 forms T = W R row by row (row i = Σ_k W_ik · row k of R, over k ≤ i when W is
//! lower triangular); step 2 forms the lower triangle A_ij = Σ_k T_ik conj(X_jk), j ≤ i,
//! with X = W (A = T Wᴴ; Wᴴ = W for the Hermitian K^{-1/2}) or X = T (A = T Tᴴ), and
//! mirrors it, so A is exactly Hermitian. Only the k ≤ j terms are summed when X = W is
//! lower triangular.

use super::simd::{self, axpy, dotc};
use faer::c64;

/// What multiplies T = W R from the right.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Right {
    /// A = T Wᴴ.
    WAdjoint,
    /// A = T Tᴴ.
    TAdjoint,
}

/// Scratch: R, W and T as split rows.
pub struct Products {
    m: usize,
    rr: Vec<f64>,
    ri: Vec<f64>,
    wr: Vec<f64>,
    wi: Vec<f64>,
    tr: Vec<f64>,
    ti: Vec<f64>,
}

fn split(src: &[c64], re: &mut [f64], im: &mut [f64]) {
    for ((z, r), i) in src.iter().zip(re.iter_mut()).zip(im.iter_mut()) {
        *r = z.re;
        *i = z.im;
    }
}

impl Products {
    /// Scratch for M × M matrices.
    pub fn new(m: usize) -> Self {
        let z = || vec![0.0; m * m];
        Products {
            m,
            rr: z(),
            ri: z(),
            wr: z(),
            wi: z(),
            tr: z(),
            ti: z(),
        }
    }

    /// A (row-major split parts `ar`, `ai`) from R and W (row-major, f64); `lower`: W is
    /// lower triangular (its strictly upper part is zero and is skipped).
    pub fn form(&mut self, r: &[c64], w: &[c64], lower: bool, right: Right, ar: &mut [f64], ai: &mut [f64]) {
        split(r, &mut self.rr, &mut self.ri);
        split(w, &mut self.wr, &mut self.wi);
        products(self, lower, right, ar, ai);
    }
}

simd::dispatch!(
    /// A from the split R and W in `s` (see [`Products::form`]).
    fn products(s: &mut Products, lower: bool, right: Right, ar: &mut [f64], ai: &mut [f64]) => products_impl
);

#[inline(always)]
fn products_impl(s: &mut Products, lower: bool, right: Right, ar: &mut [f64], ai: &mut [f64]) {
    let m = s.m;
    {
        {
            // T = W R.
            for i in 0..m {
                let (tr, ti) = (&mut s.tr[i * m..(i + 1) * m], &mut s.ti[i * m..(i + 1) * m]);
                tr.iter_mut().chain(ti.iter_mut()).for_each(|x| *x = 0.0);
                let kend = if lower { i + 1 } else { m };
                for k in 0..kend {
                    let f = c64::new(s.wr[i * m + k], s.wi[i * m + k]);
                    axpy(f, &s.rr[k * m..(k + 1) * m], &s.ri[k * m..(k + 1) * m], tr, ti);
                }
            }
            // Lower triangle of A = T Xᴴ, mirrored.
            let (xr, xi) = match right {
                Right::WAdjoint => (&s.wr, &s.wi),
                Right::TAdjoint => (&s.tr, &s.ti),
            };
            for i in 0..m {
                for j in 0..=i {
                    let len = if lower && right == Right::WAdjoint {
                        j + 1
                    } else {
                        m
                    };
                    // Σ_k conj(X_jk) T_ik
                    let z = dotc(
                        &xr[j * m..j * m + len],
                        &xi[j * m..j * m + len],
                        &s.tr[i * m..i * m + len],
                        &s.ti[i * m..i * m + len],
                    );
                    if i == j {
                        ar[i * m + i] = z.re;
                        ai[i * m + i] = 0.0;
                    } else {
                        ar[i * m + j] = z.re;
                        ai[i * m + j] = z.im;
                        ar[j * m + i] = z.re;
                        ai[j * m + i] = -z.im;
                    }
                }
            }
        }
    }
}
