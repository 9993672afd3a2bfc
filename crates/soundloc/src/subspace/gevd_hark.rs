//! HARK's GEVD-MUSIC (`gevd-hark`), for reproducing HARK.
//!
//! K⁻¹ = V Λ V⁻¹, K^{-1/2} = V diag(s(λ)) V⁻¹ with s(λ) = √λ, or −√(−λ) for a negative λ
//! (precomputed once per K by the plan); then the Hermitian eigendecomposition of
//! K^{-1/2} R K^{-1/2}. HARK uses these eigenvectors directly against the raw transfer
//! functions, without the back-transform K^{-1/2} f_m: the noise subspace is then
//! orthogonal to K^{-1/2} a rather than to a. With incoherent noise (K ≈ c·I) this changes
//! little; with coherent noise close to the array it moves or erases the talkers' peaks
//! (measured in `tests/scenes.rs` and the README).

use super::eigh::Eigh;
use super::whiten::{Products, Right};
use faer::c64;

/// Form W R W, W = K^{-1/2} (Hermitian; both row-major M × M, f64), in the eigensolver.
pub(super) fn load(r: &[c64], w: &[c64], products: &mut Products, eigh: &mut Eigh) {
    let (ar, ai) = eigh.matrix_mut();
    products.form(r, w, false, Right::WAdjoint, ar, ai);
}
