//! Textbook GEVD-MUSIC: the generalized eigenproblem R e = λ K e.
//!
//! With K = L Lᴴ (Cholesky, once per K in the plan) and W = L⁻¹, decompose the Hermitian
//! L⁻¹ R L⁻ᴴ = F Λ Fᴴ. The generalized eigenvectors are e_m = L⁻ᴴ f_m; in the signal
//! model R = A S Aᴴ + K the noise-subspace e_m are exactly orthogonal to the sources'
//! transfer functions. The spectrum uses aᴴ e_m = (L⁻¹ a)ᴴ f_m, i.e. the orthonormal f_m
//! against the whitened steering vectors a_w = L⁻¹ a that the plan precomputes, with the
//! raw ‖a‖² as numerator. This variant keeps the talkers when the noise is coherent and
//! close to the array; it is soundloc's default when a noise matrix is given.

use super::eigh::Eigh;
use super::whiten::{Products, Right};
use faer::c64;

/// Form W R Wᴴ, W = L⁻¹ (both row-major M × M, f64), in the eigensolver.
pub(super) fn load(r: &[c64], w: &[c64], products: &mut Products, eigh: &mut Eigh) {
    let (ar, ai) = eigh.matrix_mut();
    products.form(r, w, true, Right::WAdjoint, ar, ai);
}
