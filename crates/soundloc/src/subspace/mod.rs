//! Subspace decomposition per frequency bin (HARK's `MUSIC_ALGORITHM`).
//!
//! Input: the scaled correlation matrix R_k (M × M, Hermitian) of one window and bin, and,
//! for the noise-aware algorithms, a per-bin whitening matrix W_k precomputed once per
//! noise matrix K by [`crate::plan`] (in f64). Output: an orthonormal basis
//! E = [e_1 … e_M] sorted by descending eigen/singular value; the first Ns columns span
//! the signal subspace, the remaining M − Ns the noise subspace.
//!
//! | algorithm | matrix decomposed | E | steering used by the spectrum |
//! |---|---|---|---|
//! | [`sevd`] | R | eigenvectors | a |
//! | [`gevd`] (textbook) | L⁻¹ R L⁻ᴴ, K = L Lᴴ | eigenvectors f_m | a_w = L⁻¹ a (≡ aᴴ e_m with e_m = L⁻ᴴ f_m) |
//! | [`gevd_hark`] | K^{-1/2} R K^{-1/2} | eigenvectors | a (no back-transform: HARK's choice) |
//! | [`gsvd`] | K⁻¹ R | left singular vectors | a |
//!
//! Every E is orthonormal, so the MUSIC denominator may use the signal-subspace
//! complement (see [`crate::music`]).

pub mod gevd;
pub mod gevd_hark;
pub mod gsvd;
pub mod sevd;

use crate::config::Algorithm;
use crate::real::{Real, C};
use crate::{Error, Result};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::{Accum, Mat, Par};

/// One bin's decomposition: `vectors` is M × M column-major (column m is e_m, so
/// `vectors[m * M + i]` is component i of e_m), `values` descending.
#[derive(Debug, Clone, PartialEq)]
pub struct Decomposition<T: Real> {
    /// Number of microphones M.
    pub m: usize,
    /// Column-major basis, sorted by descending value.
    pub vectors: Vec<C<T>>,
    /// Eigen- or singular values, descending.
    pub values: Vec<T>,
}

impl<T: Real> Decomposition<T> {
    /// An empty decomposition for M microphones.
    pub fn new(m: usize) -> Self {
        Decomposition {
            m,
            vectors: vec![C::new(T::zero(), T::zero()); m * m],
            values: vec![T::zero(); m],
        }
    }
    /// Column m (e_m).
    pub fn vector(&self, m: usize) -> &[C<T>] {
        &self.vectors[m * self.m..(m + 1) * self.m]
    }
    /// The largest value (λ_max or σ_max).
    pub fn largest(&self) -> T {
        self.values[0]
    }
}

/// Reusable scratch for one thread's decompositions of M × M matrices.
pub struct Workspace<T: Real> {
    m: usize,
    a: Mat<C<T>>,
    tmp: Mat<C<T>>,
    u: Mat<C<T>>,
    s: faer::diag::Diag<C<T>>,
    mem: MemBuffer,
}

impl<T: Real> Workspace<T> {
    /// Scratch for M × M problems (any algorithm).
    pub fn new(m: usize) -> Self {
        use faer::linalg::{evd, svd};
        let par = Par::Seq;
        let req = evd::self_adjoint_evd_scratch::<C<T>>(
            m,
            evd::ComputeEigenvectors::Yes,
            par,
            Default::default(),
        )
        .or(svd::svd_scratch::<C<T>>(
            m,
            m,
            svd::ComputeSvdVectors::Full,
            svd::ComputeSvdVectors::No,
            par,
            Default::default(),
        ));
        Workspace {
            m,
            a: Mat::zeros(m, m),
            tmp: Mat::zeros(m, m),
            u: Mat::zeros(m, m),
            s: faer::diag::Diag::zeros(m),
            mem: MemBuffer::new(req),
        }
    }
    /// The matrix size this workspace was built for.
    pub fn dim(&self) -> usize {
        self.m
    }
}

fn load_row_major<T: Real>(dst: &mut Mat<C<T>>, src: &[C<T>], m: usize) {
    for i in 0..m {
        for j in 0..m {
            dst[(i, j)] = src[i * m + j];
        }
    }
}

/// Hermitian eigendecomposition of `ws.a` into `out`, sorted descending.
fn hermitian_eig_into<T: Real>(ws: &mut Workspace<T>, out: &mut Decomposition<T>) -> Result<()> {
    let m = ws.m;
    faer::linalg::evd::self_adjoint_evd(
        ws.a.as_ref(),
        ws.s.as_mut(),
        Some(ws.u.as_mut()),
        Par::Seq,
        MemStack::new(&mut ws.mem),
        Default::default(),
    )
    .map_err(|e| Error::numerical("decompose", format!("eigendecomposition failed: {e:?}")))?;
    // faer returns ascending eigenvalues; store descending.
    for k in 0..m {
        let src = m - 1 - k;
        out.values[k] = ws.s[src].re;
        for i in 0..m {
            out.vectors[k * m + i] = ws.u[(i, src)];
        }
    }
    Ok(())
}

/// ws.a ← lhs · rhs (all M × M, faer matrices).
fn matmul_into<T: Real, R: faer::traits::Conjugate<Canonical = C<T>>>(
    dst: &mut Mat<C<T>>,
    lhs: faer::MatRef<'_, C<T>>,
    rhs: faer::MatRef<'_, R>,
) {
    faer::linalg::matmul::matmul(
        dst.as_mut(),
        Accum::Replace,
        lhs,
        rhs,
        C::new(T::one(), T::zero()),
        Par::Seq,
    );
}

/// Decompose one bin: `r` is the scaled R_k (row-major M × M), `w` the plan's whitening
/// matrix W_k (row-major) for the noise-aware algorithms.
pub fn decompose<T: Real>(
    algorithm: Algorithm,
    r: &[C<T>],
    w: Option<&[C<T>]>,
    ws: &mut Workspace<T>,
    out: &mut Decomposition<T>,
) -> Result<()> {
    let need_w = || {
        w.ok_or_else(|| {
            Error::Config(format!(
                "{} needs a noise correlation matrix",
                algorithm.name()
            ))
        })
    };
    match algorithm {
        Algorithm::Sevd => sevd::decompose(r, ws, out),
        Algorithm::Gevd => gevd::decompose(r, need_w()?, ws, out),
        Algorithm::GevdHark => gevd_hark::decompose(r, need_w()?, ws, out),
        Algorithm::Gsvd => gsvd::decompose(r, need_w()?, ws, out),
    }
}
