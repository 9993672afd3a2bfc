//! Subspace decomposition per frequency bin (HARK's `MUSIC_ALGORITHM`).
//!
//! Input: the scaled correlation matrix R_k (M × M, Hermitian, in f64 as the correlation
//! stage sums it) of one window and bin, and, for the noise-aware algorithms, the per-bin
//! whitening matrix W_k that [`crate::plan`] computes once per noise matrix K (in f64).
//! Output: every eigen/singular value (descending) and an orthonormal basis
//! E = [e_1 … e_k] of the k leading vectors — the signal subspace, which is all the
//! squared MUSIC denominator needs (see [`crate::music`]); k = M when the whole noise
//! subspace is wanted (the unsquared denominator).
//!
//! | algorithm | matrix decomposed (Hermitian, f64) | E | steering used by the spectrum |
//! |---|---|---|---|
//! | [`sevd`] | R | eigenvectors | a |
//! | [`gevd`] (textbook) | L⁻¹ R L⁻ᴴ, K = L Lᴴ | eigenvectors f_m | a_w = L⁻¹ a (≡ aᴴ e_m with e_m = L⁻ᴴ f_m) |
//! | [`gevd_hark`] | K^{-1/2} R K^{-1/2} | eigenvectors | a (no back-transform: HARK's choice) |
//! | [`gsvd`] | (K⁻¹R)(K⁻¹R)ᴴ | eigenvectors = left singular vectors of K⁻¹R, σ = √λ | a |
//!
//! Everything runs in double precision whatever the pipeline's precision: the whitening
//! products (an ε-relative error in R grows like cond(K) once whitened — rotor noise makes
//! K's condition number 10⁶–10⁸, docs/precision.md) and the partial eigensolver
//! [`eigh`]; the vectors are handed on in both precisions.

mod block;
pub mod count;
pub mod eigh;
mod gevd;
pub mod gevd_hark;
pub mod gsvd;
pub mod sevd;
pub mod simd;
pub mod tracking;
mod tridiag;
mod whiten;

use crate::config::Algorithm;
use crate::real::{Real, C};
use crate::{Error, Result};
use eigh::Eigh;
use faer::c64;

/// One bin's decomposition.
#[derive(Debug, Clone, PartialEq)]
pub struct Decomposition<T: Real> {
    /// Number of microphones M.
    pub m: usize,
    /// Number of leading vectors held (k ≤ M).
    pub dim: usize,
    /// The k leading vectors, M × k column-major (column c is e_{c+1}), in the pipeline's
    /// precision.
    pub vectors: Vec<C<T>>,
    /// The same vectors in f64 (for the spectrum's exact recomputation near peaks).
    pub vectors64: Vec<c64>,
    /// The eigen- or singular values, descending: all M from an exact decomposition, the
    /// tracked block's from [`tracking`] (the approximate mode).
    pub values: Vec<T>,
}

impl<T: Real> Decomposition<T> {
    /// An empty decomposition for M microphones holding k vectors.
    pub fn new(m: usize, k: usize) -> Self {
        let k = k.min(m);
        Decomposition {
            m,
            dim: k,
            vectors: vec![C::new(T::zero(), T::zero()); m * k],
            vectors64: vec![c64::new(0.0, 0.0); m * k],
            values: vec![T::zero(); m],
        }
    }
    /// Column c (e_{c+1}), c < k.
    pub fn vector(&self, c: usize) -> &[C<T>] {
        &self.vectors[c * self.m..(c + 1) * self.m]
    }
    /// Column c in f64.
    pub fn vector64(&self, c: usize) -> &[c64] {
        &self.vectors64[c * self.m..(c + 1) * self.m]
    }
    /// The largest value (λ_max or σ_max).
    pub fn largest(&self) -> T {
        self.values[0]
    }
}

/// Reusable scratch for one thread's decompositions of M × M matrices.
pub struct Workspace {
    m: usize,
    products: whiten::Products,
    eigh: Eigh,
}

impl Workspace {
    /// Scratch for M × M problems (any algorithm).
    pub fn new(m: usize) -> Self {
        Workspace {
            m,
            products: whiten::Products::new(m),
            eigh: Eigh::new(m),
        }
    }
    /// The matrix size this workspace was built for.
    pub fn dim(&self) -> usize {
        self.m
    }
    /// Form A from R and W (see [`whiten`]) in the eigensolver's input.
    fn form(&mut self, r: &[c64], w: &[c64], lower: bool, right: whiten::Right) {
        let (ar, ai) = self.eigh.matrix_mut();
        self.products.form(r, w, lower, right, ar, ai);
    }
}

/// Decompose the matrix in `ws`'s eigensolver into `out`: values through `value`
/// (descending), `out.dim` leading vectors in both precisions.
fn finish<T: Real>(ws: &mut Workspace, value: impl Fn(f64) -> f64, out: &mut Decomposition<T>) -> Result<()> {
    ws.eigh.solve(out.dim, &mut out.vectors64)?;
    for (v, &l) in out.values.iter_mut().zip(ws.eigh.values()) {
        *v = T::of_f64(value(l));
    }
    for (v, z) in out.vectors.iter_mut().zip(&out.vectors64) {
        *v = C::new(T::of_f64(z.re), T::of_f64(z.im));
    }
    Ok(())
}

/// Decompose one bin: `r` is the scaled R_k (row-major M × M, f64), `w` the plan's
/// whitening matrix W_k (row-major, f64) for the noise-aware algorithms. `out.dim` sets
/// how many leading vectors are computed.
pub fn decompose<T: Real>(
    algorithm: Algorithm,
    r: &[c64],
    w: Option<&[c64]>,
    ws: &mut Workspace,
    out: &mut Decomposition<T>,
) -> Result<()> {
    let need_w =
        || w.ok_or_else(|| Error::Config(format!("{} needs a noise correlation matrix", algorithm.name())));
    match algorithm {
        Algorithm::Sevd => sevd::decompose(r, ws, out),
        Algorithm::Gevd => gevd::decompose(r, need_w()?, ws, out),
        Algorithm::GevdHark => gevd_hark::decompose(r, need_w()?, ws, out),
        Algorithm::Gsvd => gsvd::decompose(r, need_w()?, ws, out),
        Algorithm::SrpPhat => Err(Error::Config("srp-phat has no subspace decomposition".into())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn crandn<T: Real>(rng: &mut impl Rng) -> C<T> {
        C::new(
            T::of_f64(rng.gen_range(-1.0..1.0)),
            T::of_f64(rng.gen_range(-1.0..1.0)),
        )
    }

    /// A random Hermitian positive semi-definite X Xᴴ / n (row-major), rank `rank`.
    fn random_r<T: Real>(m: usize, rank: usize, rng: &mut impl Rng) -> Vec<C<T>> {
        let x: Vec<C<T>> = (0..m * rank).map(|_| crandn(rng)).collect();
        let mut r = vec![C::new(T::zero(), T::zero()); m * m];
        for i in 0..m {
            for j in 0..m {
                let mut acc = C::new(T::zero(), T::zero());
                for k in 0..rank {
                    acc += x[i * rank + k] * x[j * rank + k].conj();
                }
                r[i * m + j] = acc / T::of_f64(rank as f64);
            }
        }
        r
    }

    /// ‖EᴴE − I‖_max and the reconstruction error ‖A E − E Λ‖_max / ‖A‖ for eig, or
    /// ‖A Aᴴ E − E Σ²‖ / ‖A‖² for the SVD's left vectors; values descending.
    fn check<T: Real>(alg: Algorithm, m: usize, seed: u64) -> (f64, f64) {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let r = random_r::<T>(m, m + 10, &mut rng);
        let w: Vec<C<T>> = (0..m * m)
            .map(|k| {
                if k % (m + 1) == 0 {
                    C::new(T::of_f64(2.0), T::zero())
                } else {
                    crandn::<T>(&mut rng) * T::of_f64(0.05)
                }
            })
            .collect();
        // Hermitian, as every whitening matrix the plan builds for GEVD-HARK is (K^{-1/2}).
        let w: Vec<C<T>> = (0..m * m)
            .map(|k| (w[k] + w[(k % m) * m + k / m].conj()) * T::of_f64(0.5))
            .collect();
        // Lower triangular for GEVD, as the plan's L⁻¹ is.
        let w: Vec<C<T>> = if alg == Algorithm::Gevd {
            (0..m * m)
                .map(|k| {
                    if k % m > k / m {
                        C::new(T::zero(), T::zero())
                    } else {
                        w[k]
                    }
                })
                .collect()
        } else {
            w
        };
        let mut ws = Workspace::new(m);
        let mut dec = Decomposition::<T>::new(m, m);
        let c64s =
            |v: &[C<T>]| -> Vec<c64> { v.iter().map(|z| c64::new(z.re.to_f64(), z.im.to_f64())).collect() };
        decompose(alg, &c64s(&r), Some(&c64s(&w)), &mut ws, &mut dec).unwrap();
        for k in 1..m {
            assert!(
                dec.values[k - 1] >= dec.values[k],
                "{alg:?}: values not descending at {k}"
            );
        }
        // The matrix actually decomposed, in f64.
        let to64 = |z: C<T>| num_complex::Complex::new(z.re.to_f64(), z.im.to_f64());
        let rm = |v: &[C<T>], i: usize, j: usize| to64(v[i * m + j]);
        let mul = |a: &dyn Fn(usize, usize) -> num_complex::Complex<f64>,
                   b: &dyn Fn(usize, usize) -> num_complex::Complex<f64>| {
            let mut o = vec![num_complex::Complex::new(0.0, 0.0); m * m];
            for i in 0..m {
                for j in 0..m {
                    for k in 0..m {
                        o[i * m + j] += a(i, k) * b(k, j);
                    }
                }
            }
            o
        };
        let a: Vec<num_complex::Complex<f64>> = match alg {
            Algorithm::Sevd | Algorithm::SrpPhat => (0..m * m).map(|k| to64(r[k])).collect(),
            Algorithm::Gevd => {
                let wr = mul(&|i, j| rm(&w, i, j), &|i, j| rm(&r, i, j));
                mul(&|i, j| wr[i * m + j], &|i, j| rm(&w, j, i).conj())
            }
            Algorithm::GevdHark => {
                let wr = mul(&|i, j| rm(&w, i, j), &|i, j| rm(&r, i, j));
                mul(&|i, j| wr[i * m + j], &|i, j| rm(&w, i, j))
            }
            Algorithm::Gsvd => {
                let wr = mul(&|i, j| rm(&w, i, j), &|i, j| rm(&r, i, j));
                // A Aᴴ, whose eigenvectors are the left singular vectors.
                mul(&|i, j| wr[i * m + j], &|i, j| wr[j * m + i].conj())
            }
        };
        let norm = a.iter().map(|z| z.norm()).fold(0.0, f64::max);
        let e = |i: usize, k: usize| to64(dec.vectors[k * m + i]);
        let mut orth = 0.0f64;
        let mut recon = 0.0f64;
        for p in 0..m {
            for q in 0..m {
                let mut g = num_complex::Complex::new(0.0, 0.0);
                for i in 0..m {
                    g += e(i, p).conj() * e(i, q);
                }
                let id = if p == q { 1.0 } else { 0.0 };
                orth = orth.max((g - id).norm());
            }
            let lam = dec.values[p].to_f64();
            let lam = if alg == Algorithm::Gsvd { lam * lam } else { lam };
            for i in 0..m {
                let mut ae = num_complex::Complex::new(0.0, 0.0);
                for k in 0..m {
                    ae += a[i * m + k] * e(k, p);
                }
                recon = recon.max((ae - e(i, p) * lam).norm() / norm);
            }
        }
        (orth, recon)
    }

    fn all_algorithms<T: Real>() {
        for alg in Algorithm::MUSIC {
            for (m, seed) in [(8, 1), (60, 2)] {
                let (orth, recon) = check::<T>(alg, m, seed);
                let tol = 200.0 * T::EPS * m as f64;
                assert!(
                    orth < tol,
                    "{alg:?} M={m} {}: orthonormality {orth:e} > {tol:e}",
                    T::NAME
                );
                assert!(
                    recon < tol,
                    "{alg:?} M={m} {}: reconstruction {recon:e} > {tol:e}",
                    T::NAME
                );
            }
        }
    }

    #[test]
    fn decompositions_are_orthonormal_sorted_and_reconstruct_f32() {
        all_algorithms::<f32>();
    }

    #[test]
    fn decompositions_are_orthonormal_sorted_and_reconstruct_f64() {
        all_algorithms::<f64>();
    }
}
