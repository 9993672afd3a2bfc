//! Subspace decomposition per frequency bin (HARK's `MUSIC_ALGORITHM`).
//!
//! Input: the scaled correlation matrix R_k (M × M, Hermitian, in f64 as the correlation
//! stage sums it) of one window and bin, and, for the noise-aware algorithms, the per-bin
//! whitening matrix W_k that [`crate::plan`] computes once per noise matrix K (in f64).
//! Output: every eigen/singular value (descending) and an orthonormal basis
//! E = [e_1 … e_k] of the k leading vectors — the signal subspace, which is all the
//! squared MUSIC denominator needs (see [`crate::music`]); k = M when the whole noise
//! subspace is wanted (the unsquared denominator).
//!
//! | algorithm | matrix decomposed (Hermitian, f64) | E | steering used by the spectrum |
//! |---|---|---|---|
//! | [`sevd`] | R | eigenvectors | a |
//! | [`gevd`] (textbook) | L⁻¹ R L⁻ᴴ, K = L Lᴴ | eigenvectors f_m | a_w = L⁻¹ a (≡ aᴴ e_m with e_m = L⁻ᴴ f_m) |
//! | [`gevd_hark`] | K^{-1/2} R K^{-1/2} | eigenvectors | a (no back-transform: HARK's choice) |
//! | [`gsvd`] | (K⁻¹R)(K⁻¹R)ᴴ | eigenvectors = left singular vectors of K⁻¹R, σ = √λ | a |
//!
//! Everything runs in double precision whatever the pipeline's precision: the whitening
//! products (an ε-relative error in R grows like cond(K) once whitened — rotor noise makes
//! K's condition number 10⁶–10⁸, docs/precision.md) and the eigensolver; the vectors are
//! handed on in both precisions. Arrays of up to 16 microphones go through
//! [`eigh_lanes`] (products and a full eigensolver, eight problems at once in vector
//! lanes; ≈ 3× faster per 8 × 8 problem than one at a time), larger ones through the
//! partial eigensolver [`eigh`] after [`whiten`]'s products, with its first step, the
//! reduction to tridiagonal form, done for eight problems at once in vector lanes
//! ([`tridiag_lanes`]; ≈ 32 against 58 µs per 60 × 60 problem one at a time).

mod back_lanes;
mod block;
pub mod count;
pub mod eigh;
pub mod eigh_lanes;
mod gevd;
mod gevd_hark;
mod gsvd;
mod inverse_lanes;
mod sevd;
pub mod simd;
#[cfg(test)]
mod testing;
pub mod tracking;
mod tridiag;
pub mod tridiag_lanes;
mod v8;
mod whiten;

use crate::config::Algorithm;
use crate::real::{Real, C};
use crate::{Error, Result};
use eigh::Eigh;
use eigh_lanes::EighLanes;
use faer::c64;
use tridiag_lanes::TridiagLanes;

/// One bin's decomposition.
#[derive(Debug, Clone, PartialEq)]
pub struct Decomposition<T: Real> {
    /// Number of microphones M.
    pub m: usize,
    /// Number of leading vectors held (k ≤ M).
    pub dim: usize,
    /// The k leading vectors, M × k column-major (column c is e_{c+1}), in the pipeline's
    /// precision.
    pub vectors: Vec<C<T>>,
    /// The same vectors in f64 (for the spectrum's exact recomputation near peaks).
    pub vectors64: Vec<c64>,
    /// The eigen- or singular values, descending: all M from an exact decomposition, the
    /// tracked block's from [`tracking`] (the approximate mode).
    pub values: Vec<T>,
}

impl<T: Real> Decomposition<T> {
    /// An empty decomposition for M microphones holding k vectors.
    pub fn new(m: usize, k: usize) -> Self {
        let k = k.min(m);
        Decomposition {
            m,
            dim: k,
            vectors: vec![C::new(T::zero(), T::zero()); m * k],
            vectors64: vec![c64::new(0.0, 0.0); m * k],
            values: vec![T::zero(); m],
        }
    }
    /// Column c (e_{c+1}), c < k.
    pub fn vector(&self, c: usize) -> &[C<T>] {
        &self.vectors[c * self.m..(c + 1) * self.m]
    }
    /// Column c in f64.
    pub fn vector64(&self, c: usize) -> &[c64] {
        &self.vectors64[c * self.m..(c + 1) * self.m]
    }
    /// The largest value (λ_max or σ_max).
    pub fn largest(&self) -> T {
        self.values[0]
    }
}

/// Reusable scratch for one thread's decompositions of M × M matrices.
pub struct Workspace {
    m: usize,
    products: whiten::Products,
    /// Eigensolvers for arrays of more than 16 microphones: the products are formed in the
    /// first, and a group's problems finish two at a time (`Eigh::finish_reduced_many`).
    eigh: [Eigh; 2],
    /// More than 16 microphones: the lane reduction every decomposition goes through.
    wide: Option<TridiagLanes>,
    /// Up to 16 microphones: the lane solver every decomposition goes through.
    lanes: Option<EighLanes>,
}

impl Workspace {
    /// Scratch for M × M problems (any algorithm).
    pub fn new(m: usize) -> Self {
        let small = m <= eigh_lanes::MAX_N;
        Workspace {
            m,
            products: whiten::Products::new(m),
            eigh: std::array::from_fn(|_| Eigh::new(if small { 0 } else { m })),
            wide: (!small).then(|| TridiagLanes::new(m)),
            lanes: small.then(|| EighLanes::new(m)),
        }
    }
    /// The matrix size this workspace was built for.
    pub fn dim(&self) -> usize {
        self.m
    }
}

/// Form the Hermitian matrix `algorithm` decomposes (table above) in `eigh`; returns how
/// its eigenvalues map to the reported values.
fn load(
    algorithm: Algorithm,
    r: &[c64],
    w: Option<&[c64]>,
    products: &mut whiten::Products,
    eigh: &mut Eigh,
) -> Result<fn(f64) -> f64> {
    let need_w =
        || w.ok_or_else(|| Error::Config(format!("{} needs a noise correlation matrix", algorithm.name())));
    let same: fn(f64) -> f64 = |l| l;
    match algorithm {
        Algorithm::Sevd => sevd::load(r, eigh),
        Algorithm::Gevd => gevd::load(r, need_w()?, products, eigh),
        Algorithm::GevdHark => gevd_hark::load(r, need_w()?, products, eigh),
        Algorithm::Gsvd => {
            gsvd::load(r, need_w()?, products, eigh);
            return Ok(gsvd::singular_value);
        }
        Algorithm::SrpPhat => return Err(Error::Config("srp-phat has no subspace decomposition".into())),
    }
    Ok(same)
}

/// Values through `value` (descending) and the vectors in the pipeline's precision, from
/// a solved eigensolver whose f64 vectors are already in `out.vectors64`.
fn store<T: Real>(eigh: &Eigh, value: fn(f64) -> f64, out: &mut Decomposition<T>) {
    for (v, &l) in out.values.iter_mut().zip(eigh.values()) {
        *v = T::of_f64(value(l));
    }
    for (v, z) in out.vectors.iter_mut().zip(&out.vectors64) {
        *v = C::new(T::of_f64(z.re), T::of_f64(z.im));
    }
}

/// GSVD with every vector wanted (the unsquared denominator) is a direct SVD instead
/// (gsvd.rs says why).
fn needs_full_svd<T: Real>(algorithm: Algorithm, ws: &Workspace, out: &Decomposition<T>) -> bool {
    algorithm == Algorithm::Gsvd && out.dim == ws.m
}

/// Decompose one bin: `r` is the scaled R_k (row-major M × M, f64), `w` the plan's
/// whitening matrix W_k (row-major, f64) for the noise-aware algorithms. `out.dim` sets
/// how many leading vectors are computed.
/// This is a lane group of one ([`decompose_group`], the same bits as in any group),
/// which costs as much as a full group of eight: callers with many problems hand them
/// over together.
pub fn decompose<T: Real>(
    algorithm: Algorithm,
    r: &[c64],
    w: Option<&[c64]>,
    ws: &mut Workspace,
    out: &mut Decomposition<T>,
) -> Result<()> {
    decompose_group(algorithm, &mut [Item { r, w, out }], ws)
}

/// One problem on its own, for a caller that never has more than one at a time (the
/// approximate mode's exact refreshes, [`tracking`]): above 16 microphones through the
/// one-problem solver ([`Eigh::solve`], an eighth of a lane group's work), whose results
/// agree with [`decompose`]'s to rounding but not bit for bit; up to 16 microphones it is
/// [`decompose`].
pub fn decompose_alone<T: Real>(
    algorithm: Algorithm,
    r: &[c64],
    w: Option<&[c64]>,
    ws: &mut Workspace,
    out: &mut Decomposition<T>,
) -> Result<()> {
    if ws.lanes.is_some() || needs_full_svd(algorithm, ws, out) {
        return decompose(algorithm, r, w, ws, out);
    }
    let eigh = &mut ws.eigh[0];
    let value = load(algorithm, r, w, &mut ws.products, eigh)?;
    eigh.solve(out.dim, &mut out.vectors64)?;
    store(eigh, value, out);
    Ok(())
}

/// One problem of [`decompose_group`]: R, the whitening matrix, the result.
pub struct Item<'a, T: Real> {
    /// The scaled R_k, row-major M × M.
    pub r: &'a [c64],
    /// The whitening matrix W_k (noise-aware algorithms).
    pub w: Option<&'a [c64]>,
    /// The result; its `dim` sets how many leading vectors are computed.
    pub out: &'a mut Decomposition<T>,
}

/// Any number of [`decompose`] calls, eight at a time in vector lanes: for arrays of up
/// to 16 microphones the whole solve ([`eigh_lanes`]), for larger ones the reduction to
/// tridiagonal form ([`tridiag_lanes`]), then the rest per problem ([`eigh`]). Each
/// result is the same whichever problems share its group.
pub fn decompose_group<T: Real>(
    algorithm: Algorithm,
    items: &mut [Item<'_, T>],
    ws: &mut Workspace,
) -> Result<()> {
    if let Some(mut lanes) = ws.lanes.take() {
        let result = lane_groups(algorithm, items, ws, &mut lanes);
        ws.lanes = Some(lanes);
        return result;
    }
    let mut wide = ws
        .wide
        .take()
        .expect("a workspace has one of the two lane solvers");
    let result = wide_groups(algorithm, items, ws, &mut wide);
    ws.wide = Some(wide);
    result
}

/// [`decompose_group`] for more than 16 microphones: per group of up to eight, each
/// problem's matrix is formed ([`load`]) and loaded into the lanes, the group reduced
/// together, and each problem finished (eigenvalues, vectors) two at a time.
fn wide_groups<T: Real>(
    algorithm: Algorithm,
    items: &mut [Item<'_, T>],
    ws: &mut Workspace,
    wide: &mut TridiagLanes,
) -> Result<()> {
    let mut group: Vec<usize> = Vec::with_capacity(tridiag_lanes::LANES);
    let mut value: fn(f64) -> f64 = |l| l;
    let mut next = 0;
    while next < items.len() {
        wide.clear();
        fill_group(algorithm, items, &mut next, &mut group, ws, |it, ws| {
            let eigh = &mut ws.eigh[0];
            value = load(algorithm, it.r, it.w, &mut ws.products, eigh)?;
            let (ar, ai) = eigh.matrix_mut();
            wide.push(ar, ai).map(drop)
        })?;
        wide.reduce();
        for (pair, lanes) in group.chunks(2).zip((0..).step_by(2)) {
            let [e0, e1] = &mut ws.eigh;
            match *pair {
                [a, b] => {
                    wide.store(lanes, e0);
                    wide.store(lanes + 1, e1);
                    let (x, y) = two_mut(items, a, b);
                    Eigh::finish_reduced_many([
                        (e0, x.out.dim, &mut x.out.vectors64[..]),
                        (e1, y.out.dim, &mut y.out.vectors64[..]),
                    ])?;
                    store(e0, value, x.out);
                    store(e1, value, y.out);
                }
                [a] => {
                    wide.store(lanes, e0);
                    let x = &mut items[a];
                    Eigh::finish_reduced_many([(e0, x.out.dim, &mut x.out.vectors64[..])])?;
                    store(e0, value, x.out);
                }
                _ => {}
            }
        }
    }
    Ok(())
}

/// The next lane group from `items[*next..]`: up to eight problems, each loaded by `push`,
/// their indices into `group`; GSVD's every-vector problems met on the way take the direct
/// SVD instead (gsvd.rs says why) and stay out of the group.
fn fill_group<T: Real>(
    algorithm: Algorithm,
    items: &mut [Item<'_, T>],
    next: &mut usize,
    group: &mut Vec<usize>,
    ws: &mut Workspace,
    mut push: impl FnMut(&mut Item<'_, T>, &mut Workspace) -> Result<()>,
) -> Result<()> {
    group.clear();
    while *next < items.len() && group.len() < tridiag_lanes::LANES {
        let it = &mut items[*next];
        if needs_full_svd(algorithm, ws, it.out) {
            let w =
                it.w.ok_or_else(|| Error::Config("gsvd needs a noise correlation matrix".into()))?;
            gsvd::full_svd(it.r, w, it.out)?;
        } else {
            push(it, ws)?;
            group.push(*next);
        }
        *next += 1;
    }
    Ok(())
}

/// Two distinct items, mutably (a < b).
fn two_mut<'s, 'a, T: Real>(
    items: &'s mut [Item<'a, T>],
    a: usize,
    b: usize,
) -> (&'s mut Item<'a, T>, &'s mut Item<'a, T>) {
    let (lo, hi) = items.split_at_mut(b);
    (&mut lo[a], &mut hi[0])
}

/// [`decompose_group`] through the lane solver.
fn lane_groups<T: Real>(
    algorithm: Algorithm,
    items: &mut [Item<'_, T>],
    ws: &mut Workspace,
    lanes: &mut EighLanes,
) -> Result<()> {
    use eigh_lanes::Form;
    let (form, value): (Form, fn(f64) -> f64) = match algorithm {
        Algorithm::Sevd => (Form::R, |l| l),
        Algorithm::Gevd => (Form::Whitened { lower: true }, |l| l),
        Algorithm::GevdHark => (Form::Whitened { lower: false }, |l| l),
        Algorithm::Gsvd => (Form::Gram, gsvd::singular_value),
        Algorithm::SrpPhat => return Err(Error::Config("srp-phat has no subspace decomposition".into())),
    };
    let mut group: Vec<usize> = Vec::with_capacity(eigh_lanes::LANES);
    let mut next = 0;
    while next < items.len() {
        lanes.clear(form);
        fill_group(algorithm, items, &mut next, &mut group, ws, |it, _| {
            lanes.push(it.r, it.w).map(drop)
        })?;
        if group.is_empty() {
            continue;
        }
        let k = group.iter().map(|&i| items[i].out.dim).max().unwrap_or(0);
        lanes.solve(k)?;
        for (lane, &i) in group.iter().enumerate() {
            let out = &mut *items[i].out;
            let m = out.m;
            for (v, &l) in out.values.iter_mut().zip(lanes.values(lane)) {
                *v = T::of_f64(value(l));
            }
            for c in 0..out.dim {
                lanes.vector(lane, c, &mut out.vectors64[c * m..(c + 1) * m]);
            }
            for (v, z) in out.vectors.iter_mut().zip(&out.vectors64) {
                *v = C::new(T::of_f64(z.re), T::of_f64(z.im));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests;
