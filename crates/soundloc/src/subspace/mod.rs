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

/// N [`decompose`] calls at once — the same results, bit for bit — as one group
/// ([`decompose_group`]).
pub fn decompose_many<T: Real, const N: usize>(
    algorithm: Algorithm,
    r: [&[c64]; N],
    w: [Option<&[c64]>; N],
    ws: &mut Workspace,
    out: [&mut Decomposition<T>; N],
) -> Result<()> {
    let mut items: Vec<Item<'_, T>> = r
        .into_iter()
        .zip(w)
        .zip(out)
        .map(|((r, w), out)| Item { r, w, out })
        .collect();
    decompose_group(algorithm, &mut items, ws)
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
        group.clear();
        while next < items.len() && group.len() < tridiag_lanes::LANES {
            let it = &mut items[next];
            if needs_full_svd(algorithm, ws, it.out) {
                let w =
                    it.w.ok_or_else(|| Error::Config("gsvd needs a noise correlation matrix".into()))?;
                gsvd::full_svd(it.r, w, it.out)?;
            } else {
                let eigh = &mut ws.eigh[0];
                value = load(algorithm, it.r, it.w, &mut ws.products, eigh)?;
                let (ar, ai) = eigh.matrix_mut();
                wide.push(ar, ai)?;
                group.push(next);
            }
            next += 1;
        }
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
        group.clear();
        while next < items.len() && group.len() < eigh_lanes::LANES {
            let it = &mut items[next];
            if needs_full_svd(algorithm, ws, it.out) {
                let w =
                    it.w.ok_or_else(|| Error::Config("gsvd needs a noise correlation matrix".into()))?;
                gsvd::full_svd(it.r, w, it.out)?;
            } else {
                lanes.push(it.r, it.w)?;
                group.push(next);
            }
            next += 1;
        }
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
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn crandn<T: Real>(rng: &mut impl Rng) -> C<T> {
        C::new(
            T::of_f64(rng.gen_range(-1.0..1.0)),
            T::of_f64(rng.gen_range(-1.0..1.0)),
        )
    }

    /// A random Hermitian positive semi-definite X Xᴴ / n (row-major), rank `rank`.
    fn random_r<T: Real>(m: usize, rank: usize, rng: &mut impl Rng) -> Vec<C<T>> {
        let x: Vec<C<T>> = (0..m * rank).map(|_| crandn(rng)).collect();
        let mut r = vec![C::new(T::zero(), T::zero()); m * m];
        for i in 0..m {
            for j in 0..m {
                let mut acc = C::new(T::zero(), T::zero());
                for k in 0..rank {
                    acc += x[i * rank + k] * x[j * rank + k].conj();
                }
                r[i * m + j] = acc / T::of_f64(rank as f64);
            }
        }
        r
    }

    /// ‖EᴴE − I‖_max and the reconstruction error ‖A E − E Λ‖_max / ‖A‖ for eig, or
    /// ‖A Aᴴ E − E Σ²‖ / ‖A‖² for the SVD's left vectors; values descending.
    fn check<T: Real>(alg: Algorithm, m: usize, seed: u64) -> (f64, f64) {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let r = random_r::<T>(m, m + 10, &mut rng);
        let w: Vec<C<T>> = (0..m * m)
            .map(|k| {
                if k % (m + 1) == 0 {
                    C::new(T::of_f64(2.0), T::zero())
                } else {
                    crandn::<T>(&mut rng) * T::of_f64(0.05)
                }
            })
            .collect();
        // Hermitian, as every whitening matrix the plan builds for GEVD-HARK is (K^{-1/2}).
        let w: Vec<C<T>> = (0..m * m)
            .map(|k| (w[k] + w[(k % m) * m + k / m].conj()) * T::of_f64(0.5))
            .collect();
        // Lower triangular for GEVD, as the plan's L⁻¹ is.
        let w: Vec<C<T>> = if alg == Algorithm::Gevd {
            (0..m * m)
                .map(|k| {
                    if k % m > k / m {
                        C::new(T::zero(), T::zero())
                    } else {
                        w[k]
                    }
                })
                .collect()
        } else {
            w
        };
        let mut ws = Workspace::new(m);
        let mut dec = Decomposition::<T>::new(m, m);
        let c64s =
            |v: &[C<T>]| -> Vec<c64> { v.iter().map(|z| c64::new(z.re.to_f64(), z.im.to_f64())).collect() };
        decompose(alg, &c64s(&r), Some(&c64s(&w)), &mut ws, &mut dec).unwrap();
        for k in 1..m {
            assert!(
                dec.values[k - 1] >= dec.values[k],
                "{alg:?}: values not descending at {k}"
            );
        }
        // The matrix actually decomposed, in f64.
        let to64 = |z: C<T>| num_complex::Complex::new(z.re.to_f64(), z.im.to_f64());
        let rm = |v: &[C<T>], i: usize, j: usize| to64(v[i * m + j]);
        let mul = |a: &dyn Fn(usize, usize) -> num_complex::Complex<f64>,
                   b: &dyn Fn(usize, usize) -> num_complex::Complex<f64>| {
            let mut o = vec![num_complex::Complex::new(0.0, 0.0); m * m];
            for i in 0..m {
                for j in 0..m {
                    for k in 0..m {
                        o[i * m + j] += a(i, k) * b(k, j);
                    }
                }
            }
            o
        };
        let a: Vec<num_complex::Complex<f64>> = match alg {
            Algorithm::Sevd | Algorithm::SrpPhat => (0..m * m).map(|k| to64(r[k])).collect(),
            Algorithm::Gevd => {
                let wr = mul(&|i, j| rm(&w, i, j), &|i, j| rm(&r, i, j));
                mul(&|i, j| wr[i * m + j], &|i, j| rm(&w, j, i).conj())
            }
            Algorithm::GevdHark => {
                let wr = mul(&|i, j| rm(&w, i, j), &|i, j| rm(&r, i, j));
                mul(&|i, j| wr[i * m + j], &|i, j| rm(&w, i, j))
            }
            Algorithm::Gsvd => {
                let wr = mul(&|i, j| rm(&w, i, j), &|i, j| rm(&r, i, j));
                // A Aᴴ, whose eigenvectors are the left singular vectors.
                mul(&|i, j| wr[i * m + j], &|i, j| wr[j * m + i].conj())
            }
        };
        let norm = a.iter().map(|z| z.norm()).fold(0.0, f64::max);
        let e = |i: usize, k: usize| to64(dec.vectors[k * m + i]);
        let mut orth = 0.0f64;
        let mut recon = 0.0f64;
        for p in 0..m {
            for q in 0..m {
                let mut g = num_complex::Complex::new(0.0, 0.0);
                for i in 0..m {
                    g += e(i, p).conj() * e(i, q);
                }
                let id = if p == q { 1.0 } else { 0.0 };
                orth = orth.max((g - id).norm());
            }
            let lam = dec.values[p].to_f64();
            let lam = if alg == Algorithm::Gsvd { lam * lam } else { lam };
            for i in 0..m {
                let mut ae = num_complex::Complex::new(0.0, 0.0);
                for k in 0..m {
                    ae += a[i * m + k] * e(k, p);
                }
                recon = recon.max((ae - e(i, p) * lam).norm() / norm);
            }
        }
        (orth, recon)
    }

    fn all_algorithms<T: Real>() {
        for alg in Algorithm::MUSIC {
            for (m, seed) in [(8, 1), (60, 2)] {
                let (orth, recon) = check::<T>(alg, m, seed);
                let tol = 200.0 * T::EPS * m as f64;
                assert!(
                    orth < tol,
                    "{alg:?} M={m} {}: orthonormality {orth:e} > {tol:e}",
                    T::NAME
                );
                assert!(
                    recon < tol,
                    "{alg:?} M={m} {}: reconstruction {recon:e} > {tol:e}",
                    T::NAME
                );
            }
        }
    }

    /// Problems decomposed side by side (two and four) give the same bits as one at a
    /// time (values and vectors in f64), for every algorithm, sizes 8 and 60, and unlike
    /// matrices (full rank, rank 3, rank 1). GSVD with every vector (k = M) takes the
    /// direct SVD either way.
    #[test]
    fn a_group_equals_single_decompositions() {
        let c64s = |v: &[C<f64>]| -> Vec<c64> { v.iter().map(|z| c64::new(z.re, z.im)).collect() };
        let bits = |d: &Decomposition<f64>| {
            let v: Vec<u64> = d
                .vectors64
                .iter()
                .flat_map(|z| [z.re.to_bits(), z.im.to_bits()])
                .collect();
            (v, d.values.iter().map(|x| x.to_bits()).collect::<Vec<_>>())
        };
        for alg in Algorithm::MUSIC {
            for (m, k, seed) in [(8, 2, 3u64), (8, 4, 7), (8, 8, 4), (60, 2, 5), (60, 30, 6)] {
                let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
                let rs: Vec<Vec<c64>> = [m + 10, 3, m + 1, 1]
                    .iter()
                    .map(|&rank| c64s(&random_r::<f64>(m, rank, &mut rng)))
                    .collect();
                let w = c64s(&random_r::<f64>(m, 2 * m, &mut rng));
                // Lower triangular for GEVD, as the plan's L⁻¹ is.
                let w: Vec<c64> = (0..m * m)
                    .map(|i| {
                        if alg == Algorithm::Gevd && i % m > i / m {
                            c64::new(0.0, 0.0)
                        } else {
                            w[i]
                        }
                    })
                    .collect();
                let mut ws = Workspace::new(m);
                let single: Vec<Decomposition<f64>> = rs
                    .iter()
                    .map(|r| {
                        let mut d = Decomposition::new(m, k);
                        decompose(alg, r, Some(&w), &mut ws, &mut d).unwrap();
                        d
                    })
                    .collect();
                let mut p: Vec<Decomposition<f64>> = (0..2).map(|_| Decomposition::new(m, k)).collect();
                let [p0, p1] = &mut p[..] else { unreachable!() };
                decompose_many(alg, [&rs[0], &rs[1]], [Some(&w); 2], &mut ws, [p0, p1]).unwrap();
                let mut q: Vec<Decomposition<f64>> = (0..4).map(|_| Decomposition::new(m, k)).collect();
                let [q0, q1, q2, q3] = &mut q[..] else {
                    unreachable!()
                };
                let r4 = [&rs[0][..], &rs[1], &rs[2], &rs[3]];
                decompose_many(alg, r4, [Some(&w); 4], &mut ws, [q0, q1, q2, q3]).unwrap();
                for (i, a) in single.iter().enumerate() {
                    if i < 2 {
                        assert_eq!(bits(a), bits(&p[i]), "{alg:?} M {m} k {k}: pair, problem {i}");
                    }
                    assert_eq!(bits(a), bits(&q[i]), "{alg:?} M {m} k {k}: four, problem {i}");
                    assert!(a.values[0] > 0.0, "{alg:?} M {m}: a trivial decomposition");
                }
            }
        }
    }

    #[test]
    fn decompositions_are_orthonormal_sorted_and_reconstruct_f32() {
        all_algorithms::<f32>();
    }

    #[test]
    fn decompositions_are_orthonormal_sorted_and_reconstruct_f64() {
        all_algorithms::<f64>();
    }
}
