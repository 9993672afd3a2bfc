//! SEVD-MUSIC: Hermitian eigendecomposition R = E Λ Eᴴ of the correlation matrix.
//! E's columns sorted by descending λ; plain MUSIC, the HARK default.

use super::{hermitian_eig_into, load_row_major, Decomposition, Workspace};
use crate::real::{Real, C};
use crate::Result;

/// Eigendecomposition of R (row-major M × M).
pub fn decompose<T: Real>(r: &[C<T>], ws: &mut Workspace<T>, out: &mut Decomposition<T>) -> Result<()> {
    let m = ws.m;
    load_row_major(&mut ws.a, r, m);
    hermitian_eig_into(ws, out)
}
