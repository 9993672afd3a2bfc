//! SEVD-MUSIC: the standard eigendecomposition R = E Λ Eᴴ (no noise model).

use super::{finish, Decomposition, Workspace};
use crate::real::Real;
use crate::Result;
use faer::c64;

/// Eigendecomposition of R (row-major M × M, f64, Hermitian).
pub fn decompose<T: Real>(r: &[c64], ws: &mut Workspace, out: &mut Decomposition<T>) -> Result<()> {
    let (re, im) = ws.eigh.matrix_mut();
    for ((z, a), b) in r.iter().zip(re.iter_mut()).zip(im.iter_mut()) {
        *a = z.re;
        *b = z.im;
    }
    finish(ws, |l| l, out)
}
