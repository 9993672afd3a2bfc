//! The products that turn R into the Hermitian matrix each algorithm decomposes, in f64
//! (faer's complex products, which skip the zero half of a triangular factor and compute
//! only the lower triangle of A):
//!
//! | algorithm | A | work (complex multiply-adds) |
//! |---|---|---|
//! | GEVD | W R Wᴴ, W = L⁻¹ lower triangular | M³/2 + M³/6 |
//! | GEVD-HARK | W R W, W = K^{-1/2} Hermitian | M³ + M³/2 |
//! | GSVD | B Bᴴ, B = W R, W = K⁻¹ | M³ + M³/2 |
//!
//! Step 1 forms T = W R; step 2 the lower triangle of A = T Xᴴ with X = W (A = T Wᴴ;
//! Wᴴ = W for the Hermitian K^{-1/2}) or X = T (A = T Tᴴ), mirrored into the upper one,
//! so A is exactly Hermitian with a real diagonal. Each product has a fixed shape per
//! plan, so a bin's A does not depend on which other bins or windows run with it.
//! Measured on the 2-core development machine (2026-11-26, seed config, batch 16): the
//! decomposition stage per localization GSVD 9.0 → 6.0 ms, GEVD-HARK 9.3 → 6.1 ms, GEVD
//! 6.9 → 6.4 ms against the earlier hand-written row kernels (2–3× this machine's f64
//! rate from faer's register-blocked kernels).

use faer::c64;
use faer::linalg::matmul::triangular::{matmul, BlockStructure as B};
use faer::{Accum, MatRef, Par};

/// What multiplies T = W R from the right.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Right {
    /// A = T Wᴴ.
    WAdjoint,
    /// A = T Tᴴ.
    TAdjoint,
}

/// Scratch: T and A.
pub struct Products {
    m: usize,
    t: faer::Mat<c64>,
    a: faer::Mat<c64>,
}

impl Products {
    /// Scratch for M × M matrices.
    pub fn new(m: usize) -> Self {
        Products {
            m,
            t: faer::Mat::zeros(m, m),
            a: faer::Mat::zeros(m, m),
        }
    }

    /// A (row-major split parts `ar`, `ai`) from R and W (row-major, f64); `lower`: W is
    /// lower triangular (its strictly upper part is zero and is skipped).
    pub fn form(&mut self, r: &[c64], w: &[c64], lower: bool, right: Right, ar: &mut [f64], ai: &mut [f64]) {
        let m = self.m;
        let one = c64::new(1.0, 0.0);
        let rm = MatRef::from_row_major_slice(r, m, m);
        let wm = MatRef::from_row_major_slice(w, m, m);
        matmul(
            self.t.as_mut(),
            B::Rectangular,
            Accum::Replace,
            wm,
            if lower { B::TriangularLower } else { B::Rectangular },
            rm,
            B::Rectangular,
            one,
            Par::Seq,
        );
        crate::avx::clear_upper();
        let (x, xs) = match right {
            Right::WAdjoint => (wm, if lower { B::TriangularUpper } else { B::Rectangular }),
            Right::TAdjoint => (self.t.as_ref(), B::Rectangular),
        };
        matmul(
            self.a.as_mut(),
            B::TriangularLower,
            Accum::Replace,
            self.t.as_ref(),
            B::Rectangular,
            x.adjoint(),
            xs,
            one,
            Par::Seq,
        );
        crate::avx::clear_upper();
        for i in 0..m {
            for k in 0..i {
                let z = self.a[(i, k)];
                ar[i * m + k] = z.re;
                ai[i * m + k] = z.im;
                ar[k * m + i] = z.re;
                ai[k * m + i] = -z.im;
            }
            ar[i * m + i] = self.a[(i, i)].re;
            ai[i * m + i] = 0.0;
        }
    }
}
