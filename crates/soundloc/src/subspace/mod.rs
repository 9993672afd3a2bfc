//! Subspace decomposition per frequency bin (HARK's `MUSIC_ALGORITHM`).
//!
//! Input: the scaled correlation matrix R_k (M × M, Hermitian) of one window and bin, and,
//! for the noise-aware algorithms, a per-bin whitening matrix W_k precomputed once per
//! noise matrix K by [`crate::plan`] (in f64). Output: an orthonormal basis
//! E = [e_1 … e_M] sorted by descending eigen/singular value; the first Ns columns span
//! the signal subspace, the remaining M − Ns the noise subspace.
//!
//! | algorithm | matrix decomposed | E | steering used by the spectrum |
//! |---|---|---|---|
//! | [`sevd`] | R | eigenvectors | a |
//! | [`gevd`] (textbook) | L⁻¹ R L⁻ᴴ, K = L Lᴴ | eigenvectors f_m | a_w = L⁻¹ a (≡ aᴴ e_m with e_m = L⁻ᴴ f_m) |
//! | [`gevd_hark`] | K^{-1/2} R K^{-1/2} | eigenvectors | a (no back-transform: HARK's choice) |
//! | [`gsvd`] | K⁻¹ R | left singular vectors | a |
//!
//! Every E is orthonormal, so the MUSIC denominator may use the signal-subspace
//! complement (see [`crate::music`]).

pub mod count;
mod gevd;
pub mod gevd_hark;
pub mod gsvd;
pub mod sevd;

use crate::config::Algorithm;
use crate::real::{Real, C};
use crate::{Error, Result};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::{Accum, Mat, Par};

/// One bin's decomposition: `vectors` is M × M column-major (column m is e_m, so
/// `vectors[m * M + i]` is component i of e_m), `values` descending.
#[derive(Debug, Clone, PartialEq)]
pub struct Decomposition<T: Real> {
    /// Number of microphones M.
    pub m: usize,
    /// Column-major basis, sorted by descending value.
    pub vectors: Vec<C<T>>,
    /// Eigen- or singular values, descending.
    pub values: Vec<T>,
}

impl<T: Real> Decomposition<T> {
    /// An empty decomposition for M microphones.
    pub fn new(m: usize) -> Self {
        Decomposition {
            m,
            vectors: vec![C::new(T::zero(), T::zero()); m * m],
            values: vec![T::zero(); m],
        }
    }
    /// Column m (e_m).
    pub fn vector(&self, m: usize) -> &[C<T>] {
        &self.vectors[m * self.m..(m + 1) * self.m]
    }
    /// The largest value (λ_max or σ_max).
    pub fn largest(&self) -> T {
        self.values[0]
    }
}

/// Reusable scratch for one thread's decompositions of M × M matrices.
pub struct Workspace<T: Real> {
    m: usize,
    a: Mat<C<T>>,
    tmp: Mat<C<T>>,
    u: Mat<C<T>>,
    s: faer::diag::Diag<C<T>>,
    mem: MemBuffer,
}

impl<T: Real> Workspace<T> {
    /// Scratch for M × M problems (any algorithm).
    pub fn new(m: usize) -> Self {
        use faer::linalg::{evd, svd};
        let par = Par::Seq;
        let req =
            evd::self_adjoint_evd_scratch::<C<T>>(m, evd::ComputeEigenvectors::Yes, par, Default::default())
                .or(svd::svd_scratch::<C<T>>(
                    m,
                    m,
                    svd::ComputeSvdVectors::Full,
                    svd::ComputeSvdVectors::No,
                    par,
                    Default::default(),
                ));
        Workspace {
            m,
            a: Mat::zeros(m, m),
            tmp: Mat::zeros(m, m),
            u: Mat::zeros(m, m),
            s: faer::diag::Diag::zeros(m),
            mem: MemBuffer::new(req),
        }
    }
    /// The matrix size this workspace was built for.
    pub fn dim(&self) -> usize {
        self.m
    }
}

fn load_row_major<T: Real>(dst: &mut Mat<C<T>>, src: &[C<T>], m: usize) {
    for i in 0..m {
        for j in 0..m {
            dst[(i, j)] = src[i * m + j];
        }
    }
}

/// Hermitian eigendecomposition of `ws.a` into `out`, sorted descending.
fn hermitian_eig_into<T: Real>(ws: &mut Workspace<T>, out: &mut Decomposition<T>) -> Result<()> {
    let m = ws.m;
    faer::linalg::evd::self_adjoint_evd(
        ws.a.as_ref(),
        ws.s.as_mut(),
        Some(ws.u.as_mut()),
        Par::Seq,
        MemStack::new(&mut ws.mem),
        Default::default(),
    )
    .map_err(|e| Error::numerical("decompose", format!("eigendecomposition failed: {e:?}")))?;
    // faer returns ascending eigenvalues; store descending.
    for k in 0..m {
        let src = m - 1 - k;
        out.values[k] = ws.s[src].re;
        for i in 0..m {
            out.vectors[k * m + i] = ws.u[(i, src)];
        }
    }
    Ok(())
}

/// ws.a ← lhs · rhs (all M × M, faer matrices).
fn matmul_into<T: Real, R: faer::traits::Conjugate<Canonical = C<T>>>(
    dst: &mut Mat<C<T>>,
    lhs: faer::MatRef<'_, C<T>>,
    rhs: faer::MatRef<'_, R>,
) {
    faer::linalg::matmul::matmul(
        dst.as_mut(),
        Accum::Replace,
        lhs,
        rhs,
        C::new(T::one(), T::zero()),
        Par::Seq,
    );
}

/// Decompose one bin: `r` is the scaled R_k (row-major M × M), `w` the plan's whitening
/// matrix W_k (row-major) for the noise-aware algorithms.
pub fn decompose<T: Real>(
    algorithm: Algorithm,
    r: &[C<T>],
    w: Option<&[C<T>]>,
    ws: &mut Workspace<T>,
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
        let mut ws = Workspace::new(m);
        let mut dec = Decomposition::new(m);
        decompose(alg, &r, Some(&w), &mut ws, &mut dec).unwrap();
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
