//! Textbook GEVD-MUSIC: the generalized eigenproblem R e = λ K e.
//!
//! With K = L Lᴴ (Cholesky, once per K in the plan) and W = L⁻¹, decompose the Hermitian
//! L⁻¹ R L⁻ᴴ = F Λ Fᴴ. The generalized eigenvectors are e_m = L⁻ᴴ f_m; in the signal
//! model R = A S Aᴴ + K the noise-subspace e_m are exactly orthogonal to the sources'
//! transfer functions. The spectrum uses aᴴ e_m = (L⁻¹ a)ᴴ f_m, i.e. the orthonormal f_m
//! against the whitened steering vectors a_w = L⁻¹ a that the plan precomputes, with the
//! raw ‖a‖² as numerator. This variant keeps the talkers when the noise is coherent and
//! close to the array; it is soundloc's default when a noise matrix is given.

use super::{hermitian_eig_into, load_row_major, matmul_into, Decomposition, Workspace};
use crate::real::{Real, C};
use crate::Result;

/// Eigendecomposition of W R Wᴴ, W = L⁻¹ (both row-major M × M).
pub fn decompose<T: Real>(
    r: &[C<T>],
    w: &[C<T>],
    ws: &mut Workspace<T>,
    out: &mut Decomposition<T>,
) -> Result<()> {
    let m = ws.m;
    load_row_major(&mut ws.a, r, m);
    load_row_major(&mut ws.u, w, m);
    matmul_into(&mut ws.tmp, ws.u.as_ref(), ws.a.as_ref()); // W R
    matmul_into(&mut ws.a, ws.tmp.as_ref(), ws.u.as_ref().adjoint()); // W R Wᴴ
    hermitian_eig_into(ws, out)
}
