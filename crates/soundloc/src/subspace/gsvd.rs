//! GSVD-MUSIC as HARK codes it (the seed paper's algorithm).
//!
//! Singular value decomposition of the non-Hermitian A = K⁻¹ R = U Σ Vᴴ (K⁻¹ precomputed
//! once per K by the plan). The left singular vectors u_m play the role of eigenvectors
//! and σ_m of eigenvalues (descending). Note that the noise-subspace u_m are orthogonal to
//! K⁻¹ a, not to a: with coherent noise close to the array the talkers' peaks can move or
//! vanish (see `gevd` for the unbiased form).

use super::{load_row_major, matmul_into, Decomposition, Workspace};
use crate::real::{Real, C};
use crate::{Error, Result};
use faer::dyn_stack::MemStack;
use faer::Par;

/// Left singular vectors and singular values of W R, W = K⁻¹ (row-major M × M).
pub fn decompose<T: Real>(
    r: &[C<T>],
    w: &[C<T>],
    ws: &mut Workspace<T>,
    out: &mut Decomposition<T>,
) -> Result<()> {
    let m = ws.m;
    load_row_major(&mut ws.a, r, m);
    load_row_major(&mut ws.u, w, m);
    matmul_into(&mut ws.tmp, ws.u.as_ref(), ws.a.as_ref()); // K⁻¹ R
    faer::linalg::svd::svd(
        ws.tmp.as_ref(),
        ws.s.as_mut(),
        Some(ws.u.as_mut()),
        None,
        Par::Seq,
        MemStack::new(&mut ws.mem),
        Default::default(),
    )
    .map_err(|e| Error::numerical("decompose", format!("SVD did not converge: {e:?}")))?;
    // faer returns singular values in non-increasing order already.
    for k in 0..m {
        out.values[k] = ws.s[k].re;
        for i in 0..m {
            out.vectors[k * m + i] = ws.u[(i, k)];
        }
    }
    Ok(())
}
