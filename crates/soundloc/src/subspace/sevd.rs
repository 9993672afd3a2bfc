//! SEVD-MUSIC: the standard eigendecomposition R = E Λ Eᴴ (no noise model).

use super::eigh::Eigh;
use faer::c64;

/// Load R (row-major M × M, f64, Hermitian) into the eigensolver: it is decomposed as it is.
pub(super) fn load(r: &[c64], eigh: &mut Eigh) {
    let (re, im) = eigh.matrix_mut();
    for ((z, a), b) in r.iter().zip(re.iter_mut()).zip(im.iter_mut()) {
        *a = z.re;
        *b = z.im;
    }
}
