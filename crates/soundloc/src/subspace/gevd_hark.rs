//! HARK's GEVD-MUSIC (`gevd-hark`), for reproducing HARK.
//!
//! K⁻¹ = V Λ V⁻¹, K^{-1/2} = V diag(s(λ)) V⁻¹ with s(λ) = √λ, or −√(−λ) for a negative λ
//! (precomputed once per K by the plan); then the Hermitian eigendecomposition of
//! K^{-1/2} R K^{-1/2}. HARK uses these eigenvectors directly against the raw transfer
//! functions, without the back-transform K^{-1/2} f_m: the noise subspace is then
//! orthogonal to K^{-1/2} a rather than to a. With incoherent noise (K ≈ c·I) this changes
//! little; with coherent noise close to the array it moves or erases the talkers' peaks
//! (measured in `tests/scenes.rs` and the README).

use super::{hermitian_eig_into, load_row_major, matmul_into, Decomposition, Workspace};
use crate::real::{Real, C};
use crate::Result;

/// Eigendecomposition of W R W, W = K^{-1/2} (Hermitian; both row-major M × M).
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
    matmul_into(&mut ws.a, ws.tmp.as_ref(), ws.u.as_ref()); // W R W
    hermitian_eig_into(ws, out)
}
