//! GSVD-MUSIC as HARK codes it (the seed paper's algorithm).
//!
//! Singular value decomposition of the non-Hermitian B = K⁻¹ R = U Σ Vᴴ (K⁻¹ precomputed
//! once per K by the plan). The left singular vectors u_m play the role of eigenvectors
//! and σ_m of eigenvalues (descending). They are computed as the eigenvectors of the
//! Hermitian B Bᴴ = U Σ² Uᴴ, σ = √λ, in double precision — the GPU backend does the same
//! (squaring in f64 keeps σ to ~10⁻⁸ of σ_max, below single precision's resolution). Where
//! every vector is wanted (the unsquared denominator sums |aᴴu_m| over each noise vector,
//! whose small σ squaring would blur), a direct SVD in f64 is used instead.
//! Note that the noise-subspace u_m are orthogonal to K⁻¹ a, not to a: with coherent noise
//! close to the array the talkers' peaks can move or vanish (see `gevd` for the unbiased
//! form).

use super::eigh::Eigh;
use super::whiten::{Products, Right};
use super::Decomposition;
use crate::real::Real;
use crate::Result;
use faer::c64;

/// Form B Bᴴ, B = W R, W = K⁻¹ (row-major M × M, f64), in the eigensolver; its
/// eigenvalues λ are σ² ([`singular_value`]). For every vector (the unsquared
/// denominator) [`full_svd`] is used instead.
pub(super) fn load(r: &[c64], w: &[c64], products: &mut Products, eigh: &mut Eigh) {
    let (ar, ai) = eigh.matrix_mut();
    products.form(r, w, false, Right::TAdjoint, ar, ai);
}

/// σ = √λ from an eigenvalue of B Bᴴ (rounding below zero clamped).
pub(super) fn singular_value(lambda: f64) -> f64 {
    lambda.max(0.0).sqrt()
}

/// B = W R and its full SVD in f64 (faer), left vectors and values into `out`.
pub(super) fn full_svd<T: Real>(r: &[c64], w: &[c64], out: &mut Decomposition<T>) -> Result<()> {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::svd::{self, ComputeSvdVectors};
    use faer::{Accum, Mat, Par};
    let m = out.m;
    let load = |v: &[c64]| Mat::<c64>::from_fn(m, m, |i, j| v[i * m + j]);
    let (rm, wm) = (load(r), load(w));
    let mut b = Mat::<c64>::zeros(m, m);
    let one = c64::new(1.0, 0.0);
    faer::linalg::matmul::matmul(
        b.as_mut(),
        Accum::Replace,
        wm.as_ref(),
        rm.as_ref(),
        one,
        Par::Seq,
    );
    crate::avx::clear_upper();
    let mut s = faer::diag::Diag::<c64>::zeros(m);
    let mut u = Mat::<c64>::zeros(m, m);
    let (full, no) = (ComputeSvdVectors::Full, ComputeSvdVectors::No);
    let req = svd::svd_scratch::<c64>(m, m, full, no, Par::Seq, Default::default());
    let mut mem = MemBuffer::new(req);
    let stack = MemStack::new(&mut mem);
    let status = svd::svd(
        b.as_ref(),
        s.as_mut(),
        Some(u.as_mut()),
        None,
        Par::Seq,
        stack,
        Default::default(),
    )
    .map_err(|e| crate::Error::numerical("decompose", format!("SVD did not converge: {e:?}")));
    crate::avx::clear_upper();
    status?;
    // faer returns singular values in non-increasing order.
    for k in 0..m {
        out.values[k] = T::of_f64(s[k].re);
        for i in 0..m {
            let z = u[(i, k)];
            out.vectors64[k * m + i] = z;
            out.vectors[k * m + i] = crate::real::C::new(T::of_f64(z.re), T::of_f64(z.im));
        }
    }
    Ok(())
}
