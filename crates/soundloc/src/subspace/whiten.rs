//! The products that turn R into the Hermitian matrix each algorithm decomposes, in f64
//! (faer's complex products, which skip the zero half of a triangular factor and compute
//! only the lower triangle of A; up to 16 microphones plain loops over split parts,
//! [`form_small`], where faer's set-up per call would cost more than the arithmetic):
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

/// Up to this size the products run as plain loops over split parts ([`form_small`]):
/// for an 8-microphone array faer's set-up per call costs more than the arithmetic.
const SMALL_M: usize = 16;

/// What multiplies T = W R from the right.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Right {
    /// A = T Wᴴ.
    WAdjoint,
    /// A = T Tᴴ.
    TAdjoint,
}

/// Scratch: T and A (faer), or split parts of R, W and T ([`form_small`]).
pub struct Products {
    m: usize,
    t: faer::Mat<c64>,
    a: faer::Mat<c64>,
    small: Small,
}

/// [`form_small`]'s scratch, split real and imaginary parts, M × M each.
#[derive(Default)]
struct Small {
    rr: Vec<f64>,
    ri: Vec<f64>,
    wr: Vec<f64>,
    wi: Vec<f64>,
    tr: Vec<f64>,
    ti: Vec<f64>,
}

impl Products {
    /// Scratch for M × M matrices.
    pub fn new(m: usize) -> Self {
        Products {
            m,
            t: faer::Mat::zeros(m, m),
            a: faer::Mat::zeros(m, m),
            small: if m <= SMALL_M {
                let z = || vec![0.0; m * m];
                Small {
                    rr: z(),
                    ri: z(),
                    wr: z(),
                    wi: z(),
                    tr: z(),
                    ti: z(),
                }
            } else {
                Small::default()
            },
        }
    }

    /// A (row-major split parts `ar`, `ai`) from R and W (row-major, f64); `lower`: W is
    /// lower triangular (its strictly upper part is zero and is skipped).
    pub fn form(&mut self, r: &[c64], w: &[c64], lower: bool, right: Right, ar: &mut [f64], ai: &mut [f64]) {
        let m = self.m;
        if m <= SMALL_M {
            return form_small(m, r, w, lower, right, &mut self.small, ar, ai);
        }
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

/// [`Products::form`] for M ≤ [`SMALL_M`]: T = W R row by row (row i of T is Σ_k w_ik ·
/// row k of R, k ≤ i when W is lower triangular), then the lower triangle of A = T Xᴴ as
/// dot products of rows (a_ij = Σ_k t_ik conj(x_jk)), mirrored; the same products in a
/// fixed order, so a bin's A does not depend on the batch.
#[allow(clippy::too_many_arguments)]
fn form_small(
    m: usize,
    r: &[c64],
    w: &[c64],
    lower: bool,
    right: Right,
    s: &mut Small,
    ar: &mut [f64],
    ai: &mut [f64],
) {
    let mm = m * m;
    let Small {
        rr,
        ri,
        wr,
        wi,
        tr,
        ti,
    } = s;
    for (i, (z, y)) in r[..mm].iter().zip(&w[..mm]).enumerate() {
        (rr[i], ri[i], wr[i], wi[i]) = (z.re, z.im, y.re, y.im);
    }
    tr.fill(0.0);
    ti.fill(0.0);
    for i in 0..m {
        let (t_r, t_i) = (&mut tr[i * m..(i + 1) * m], &mut ti[i * m..(i + 1) * m]);
        let ks = if lower { i + 1 } else { m };
        for k in 0..ks {
            let (a, b) = (wr[i * m + k], wi[i * m + k]);
            let (x_r, x_i) = (&rr[k * m..(k + 1) * m], &ri[k * m..(k + 1) * m]);
            for j in 0..m {
                t_r[j] += a * x_r[j] - b * x_i[j];
                t_i[j] += a * x_i[j] + b * x_r[j];
            }
        }
    }
    let (xr, xi) = match right {
        Right::WAdjoint => (&*wr, &*wi),
        Right::TAdjoint => (&*tr, &*ti),
    };
    for i in 0..m {
        for j in 0..=i {
            // a_ij = Σ_k t_ik conj(x_jk); x_jk = 0 for k > j when X = W is lower triangular.
            let ks = if lower && right == Right::WAdjoint {
                j + 1
            } else {
                m
            };
            let (mut sr, mut si) = (0.0, 0.0);
            for k in 0..ks {
                let (a, b, c, d) = (tr[i * m + k], ti[i * m + k], xr[j * m + k], xi[j * m + k]);
                sr += a * c + b * d;
                si += b * c - a * d;
            }
            ar[i * m + j] = sr;
            ar[j * m + i] = sr;
            if i == j {
                ai[i * m + i] = 0.0;
            } else {
                ai[i * m + j] = si;
                ai[j * m + i] = -si;
            }
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

    /// Both paths (plain loops up to 16 microphones, faer above) against the definition:
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
