//! The products that turn R into the Hermitian matrix each algorithm decomposes, in f64
//! (faer's complex products, which skip the zero half of a triangular factor and compute
//! only the lower triangle of A), for arrays of more than 16 microphones; smaller ones
//! form the same products in vector lanes inside [`super::eigh_lanes`]:
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

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// A = (W R) Xᴴ by the definition, in plain complex arithmetic.
    fn reference(m: usize, r: &[c64], w: &[c64], right: Right) -> Vec<c64> {
        let mul = |a: &[c64], b: &[c64]| {
            let mut c = vec![c64::new(0.0, 0.0); m * m];
            for i in 0..m {
                for j in 0..m {
                    c[i * m + j] = (0..m).map(|k| a[i * m + k] * b[k * m + j]).sum();
                }
            }
            c
        };
        let adj = |a: &[c64]| -> Vec<c64> { (0..m * m).map(|i| a[(i % m) * m + i / m].conj()).collect() };
        let t = mul(w, r);
        match right {
            Right::WAdjoint => mul(&t, &adj(w)),
            Right::TAdjoint => mul(&t, &adj(&t)),
        }
    }

    /// Against the definition:
    /// GEVD (lower-triangular W, A = T Wᴴ), GEVD-HARK (full W, A = T Wᴴ), GSVD (A = T Tᴴ).
    #[test]
    fn products_match_the_definition() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        for m in [1, 3, 8, 16, 17, 24] {
            let mut c = || c64::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0));
            let x: Vec<c64> = (0..m * m).map(|_| c()).collect();
            // R = X Xᴴ: Hermitian positive semidefinite, like a correlation matrix.
            let r: Vec<c64> = (0..m * m)
                .map(|i| {
                    (0..m)
                        .map(|k| x[(i / m) * m + k] * x[(i % m) * m + k].conj())
                        .sum()
                })
                .collect();
            let full: Vec<c64> = (0..m * m).map(|_| c()).collect();
            let lower: Vec<c64> = (0..m * m)
                .map(|i| {
                    if i % m <= i / m {
                        full[i]
                    } else {
                        c64::new(0.0, 0.0)
                    }
                })
                .collect();
            for (w, is_lower, right) in [
                (&lower, true, Right::WAdjoint),
                (&full, false, Right::WAdjoint),
                (&full, false, Right::TAdjoint),
            ] {
                let want = reference(m, &r, w, right);
                let (mut ar, mut ai) = (vec![f64::NAN; m * m], vec![f64::NAN; m * m]);
                Products::new(m).form(&r, w, is_lower, right, &mut ar, &mut ai);
                let scale = want.iter().map(|z| z.norm()).fold(0.0, f64::max);
                for i in 0..m {
                    for j in 0..m {
                        let got = c64::new(ar[i * m + j], ai[i * m + j]);
                        // The lower triangle is computed and mirrored: exactly Hermitian.
                        let want_ij = if i >= j {
                            want[i * m + j]
                        } else {
                            want[j * m + i].conj()
                        };
                        let want_ij = if i == j {
                            c64::new(want_ij.re, 0.0)
                        } else {
                            want_ij
                        };
                        assert!(
                            (got - want_ij).norm() <= 1e-13 * scale,
                            "m={m} lower={is_lower} ({i},{j}): {got} vs {want_ij}"
                        );
                    }
                }
            }
        }
    }
}
