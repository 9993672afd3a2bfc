//! GSVD-MUSIC as HARK codes it (the seed paper's algorithm).
//!
//! Singular value decomposition of the non-Hermitian B = K⁻¹ R = U Σ Vᴴ (K⁻¹ precomputed
//! once per K by the plan). The left singular vectors u_m play the role of eigenvectors
//! and σ_m of eigenvalues (descending). They are computed as the eigenvectors of the
//! Hermitian B Bᴴ = U Σ² Uᴴ, σ = √λ, in double precision — the GPU backend does the same
//! (squaring in f64 keeps σ to ~10⁻⁸ of σ_max, below single precision's resolution).
//! Note that the noise-subspace u_m are orthogonal to K⁻¹ a, not to a: with coherent noise
//! close to the array the talkers' peaks can move or vanish (see `gevd` for the unbiased
//! form).

use super::whiten::Right;
use super::{finish, Decomposition, Workspace};
use crate::real::Real;
use crate::Result;
use faer::c64;

/// Left singular vectors and singular values of W R, W = K⁻¹ (row-major M × M, f64).
pub fn decompose<T: Real>(
    r: &[c64],
    w: &[c64],
    ws: &mut Workspace,
    out: &mut Decomposition<T>,
) -> Result<()> {
    ws.form(r, w, false, Right::TAdjoint);
    finish(ws, |l| l.max(0.0).sqrt(), out)
}
