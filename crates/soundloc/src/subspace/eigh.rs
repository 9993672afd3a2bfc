//! Partial Hermitian eigendecomposition in f64: every eigenvalue, and the eigenvectors of
//! the k largest only — what the MUSIC spectrum (signal-subspace complement) and the
//! source count need, at a fraction of a full decomposition's cost. Used for arrays of
//! more than 16 microphones (smaller ones: [`super::eigh_lanes`]) and for the approximate
//! mode's projected problems. Where a caller has many problems, step 1 runs eight at a
//! time in vector lanes ([`super::tridiag_lanes`], handing T and Q over through
//! `Eigh::reduced_mut`) and steps 2–4 here (`Eigh::finish_reduced_many`).
//!
//! 1. **Householder tridiagonalisation** (LAPACK `zhetd2`, lower): A = Q T Qᴴ with T real
//!    symmetric tridiagonal and Q = H₀ H₁ ⋯ H_{n−2}, H_j = I − τ_j v_j v_jᴴ. Per step j,
//!    with v spanning rows j+1 … n−1: p = τ A₂₂ v, w = p − ½ τ (pᴴv) v,
//!    A₂₂ ← A₂₂ − v wᴴ − w vᴴ. Only the lower triangle is kept and updated (split real and
//!    imaginary parts, rows contiguous): the product A₂₂ v reads each row once, as a dot
//!    product for its own entry and an axpy for the mirrored upper part, so both loops run
//!    over contiguous memory and vectorise (AVX2 where the CPU has it; the same operations
//!    in the same order either way, so results do not depend on the instruction set).
//!    ≈ n³/2 complex multiply-adds (the rank-2 update on half the matrix), and half the
//!    memory traffic of full storage.
//! 2. **Eigenvalues of T** by the rational (square-root free) implicit QL method
//!    (EISPACK `tqlrat`), no vectors: O(n²), but a chain of dependent divisions (≈ 35 µs of
//!    a ≈ 110 µs solve at n = 60); `Eigh::finish_reduced_many` runs several problems'
//!    chains side by side (two at n = 60: ≈ 23 µs each, same results).
//! 3. **The k largest eigenvectors of T** by inverse iteration (LAPACK `dstein`'s shifts
//!    and clusters: clusters closer than 10⁻³‖T‖₁, equal eigenvalues perturbed apart by
//!    10ε|λ|): three rounds of solving every vector, eight shifts at once in vector lanes
//!    ([`super::inverse_lanes`]: the solves are chains of dependent divisions), then
//!    orthonormalising each vector against the earlier ones of its cluster, in rank
//!    order. Orthonormalising between the rounds keeps the vectors of close values apart
//!    (the GPU's eigensolver also orthonormalises between its rounds, against every earlier
//!    vector). O(n·k) plus the cluster work.
//! 4. **Back-transformation** x = Q z: O(n²·k); from eight vectors on in vector lanes
//!    ([`super::back_lanes`]).
//!
//! A full decomposition with vectors adds ≈ 3–4 n³ (the QL rotations applied to all n
//! vectors, then Q applied to all of them). Measured on the 2-core development machine
//! (2026-11-26, n = 60, one thread): tridiagonalisation 85–117 µs in full storage (the
//! lower-triangle form since does about half the arithmetic), eigenvalues 31–33 µs,
//! k = 2 vectors a few µs, against faer's `self_adjoint_evd` with vectors at 278 µs (c32)
//! and 415 µs (c64).

use super::back_lanes::{self, BackLanes, Reflectors};
use super::inverse_lanes::{self, TriLuLanes};
use super::simd::{self, axpy, axpy_real, conj_axpy, dot_real, dotc, rank2_row};
use super::tridiag::ql_values_many;
use crate::real::C;
use crate::{Error, Result};

/// Scratch and result of one partial decomposition of an n × n Hermitian matrix.
pub struct Eigh {
    n: usize,
    /// The matrix, row-major, real and imaginary parts; row j holds v_j after step j.
    re: Vec<f64>,
    im: Vec<f64>,
    tau: Vec<C<f64>>,
    diag: Vec<f64>,
    off: Vec<f64>,
    /// Squared off-diagonal, scratch for the eigenvalues.
    e2: Vec<f64>,
    /// Eigenvalues, descending.
    values: Vec<f64>,
    /// Eigenvectors of T (k of them, n each), then scratch for the solver.
    z: Vec<f64>,
    /// The k vectors during the back-transformation, split parts.
    yr: Vec<f64>,
    yi: Vec<f64>,
    /// Shift and cluster start per wanted vector.
    shifts: Vec<(f64, usize)>,
    /// The factors of T − λI for each group of eight shifts.
    lu: Vec<TriLuLanes>,
    /// Eight vectors in lanes during a solve.
    xl: Vec<inverse_lanes::V>,
    vr: Vec<f64>,
    vi: Vec<f64>,
    pr: Vec<f64>,
    pi: Vec<f64>,
    /// The back-transformation's lanes for many vectors.
    back: BackLanes,
}

impl Eigh {
    /// Scratch for n × n problems.
    pub fn new(n: usize) -> Self {
        Eigh {
            n,
            re: vec![0.0; n * n],
            im: vec![0.0; n * n],
            tau: vec![C::new(0.0, 0.0); n],
            diag: vec![0.0; n],
            off: vec![0.0; n],
            e2: vec![0.0; n],
            values: vec![0.0; n],
            z: Vec::new(),
            yr: Vec::new(),
            yi: Vec::new(),
            shifts: Vec::new(),
            lu: Vec::new(),
            xl: Vec::new(),
            vr: vec![0.0; n],
            vi: vec![0.0; n],
            pr: vec![0.0; n],
            pi: vec![0.0; n],
            back: BackLanes::default(),
        }
    }

    /// The matrix size.
    pub fn dim(&self) -> usize {
        self.n
    }

    /// The matrix to decompose, row-major real and imaginary parts (n × n each). A must be
    /// Hermitian; only its lower triangle (and the real part of the diagonal) is read.
    pub fn matrix_mut(&mut self) -> (&mut [f64], &mut [f64]) {
        (&mut self.re, &mut self.im)
    }

    /// Eigenvalues of the last [`Eigh::solve`], descending.
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// Decompose the matrix in [`Eigh::matrix_mut`] (destroyed): every eigenvalue into
    /// [`Eigh::values`] (descending), and the eigenvectors of the `k` largest into
    /// `vectors` (n × k column-major: column c is the eigenvector of the c-th largest
    /// eigenvalue, unit norm).
    pub fn solve(&mut self, k: usize, vectors: &mut [C<f64>]) -> Result<()> {
        assert!(k <= self.n && vectors.len() >= self.n * k);
        if self.n == 0 {
            return Ok(());
        }
        self.reduce()?;
        Eigh::finish_reduced_many([(self, k, vectors)])
    }

    /// Steps 2–4 for N problems already reduced to T (by [`super::tridiag_lanes`], through
    /// [`Eigh::reduced_mut`]), with the same results as one at a time: the N eigenvalue
    /// iterations, chains of dependent divisions, run side by side
    /// (`tridiag::ql_values_many`).
    pub(super) fn finish_reduced_many<const N: usize>(
        problems: [(&mut Eigh, usize, &mut [C<f64>]); N],
    ) -> Result<()> {
        let mut problems = problems;
        for (e, k, v) in problems.iter_mut() {
            assert!(*k <= e.n && v.len() >= e.n * *k);
            e.values.copy_from_slice(&e.diag);
            for (e2, x) in e.e2.iter_mut().zip(&e.off) {
                *e2 = x * x;
            }
        }
        ql_values_many(problems.each_mut().map(|p| {
            let e: &mut Eigh = p.0;
            (&mut e.values[..], &mut e.e2[..])
        }))?;
        for (e, k, v) in problems {
            e.finish(k, v);
        }
        Ok(())
    }

    /// Where a reduction done elsewhere hands T and Q over: v_j in row j right of the
    /// diagonal of `re`/`im`, τ_j, T's diagonal and real subdiagonal.
    pub(super) fn reduced_mut(&mut self) -> Reduced<'_> {
        Reduced {
            re: &mut self.re,
            im: &mut self.im,
            tau: &mut self.tau,
            diag: &mut self.diag,
            off: &mut self.off,
        }
    }

    /// Check the input and reduce it to T.
    fn reduce(&mut self) -> Result<()> {
        if self.re.iter().chain(&self.im).any(|x| !x.is_finite()) {
            return Err(Error::numerical(
                "decompose",
                "the matrix holds non-finite values",
            ));
        }
        tridiagonalize(self);
        Ok(())
    }

    /// Sort the eigenvalues (descending) and compute the k leading vectors.
    fn finish(&mut self, k: usize, vectors: &mut [C<f64>]) {
        self.values.sort_by(|a, b| b.total_cmp(a));
        leading_vectors(self, k, vectors);
    }

    /// Eigenvectors of T for the k largest eigenvalues into `self.z` by inverse iteration.
    #[inline(always)]
    fn tridiagonal_vectors(&mut self, k: usize) {
        let n = self.n;
        self.z.clear();
        self.z.resize(n * k, 0.0);
        let (d, e) = (&self.diag, &self.off[..n - 1]);
        let norm1 = (0..n)
            .map(|i| {
                d[i].abs()
                    + if i > 0 { e[i - 1].abs() } else { 0.0 }
                    + if i + 1 < n { e[i].abs() } else { 0.0 }
            })
            .fold(0.0, f64::max);
        if norm1 == 0.0 {
            // T = 0: every vector is an eigenvector.
            for c in 0..k {
                self.z[c * n + c] = 1.0;
            }
            return;
        }
        let ortol = 1e-3 * norm1;
        let tiny = f64::EPSILON * norm1;
        // Shifts and clusters first (dstein's rules), in order.
        self.shifts.clear();
        let mut cluster_start = 0;
        let mut prev = f64::INFINITY;
        for c in 0..k {
            let mut lam = self.values[c];
            if c > 0 {
                if prev - lam > ortol {
                    cluster_start = c;
                }
                let pertol = 10.0 * (f64::EPSILON * lam).abs().max(tiny);
                if prev - lam < pertol {
                    lam = prev - pertol;
                }
            }
            prev = lam;
            self.shifts.push((lam, cluster_start));
        }
        // A fixed, non-degenerate start per vector (dstein starts from random numbers).
        for (c, x) in self.z.chunks_mut(n).enumerate() {
            let mut s = 0x9e37_79b9_7f4a_7c15u64 ^ (c as u64).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            for xi in x.iter_mut() {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                *xi = (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            }
        }
        // T − λI factored once per shift, eight shifts per factorisation (unused lanes
        // repeat the group's last shift).
        let groups = k.div_ceil(inverse_lanes::LANES);
        if self.lu.len() < groups {
            self.lu.resize_with(groups, TriLuLanes::default);
        }
        for (g, lu) in self.lu.iter_mut().enumerate().take(groups) {
            let c0 = g * inverse_lanes::LANES;
            let shifts = std::array::from_fn(|l| self.shifts[(c0 + l).min(k - 1)].0);
            lu.factor(d, e, &shifts, tiny);
        }
        self.xl.resize(n, [0.0; inverse_lanes::LANES]);
        for _ in 0..3 {
            // Solve every vector (each of unit norm after the previous round, or its start),
            // eight at a time; lanes past the last vector solve for zero.
            for (g, lu) in self.lu.iter_mut().enumerate().take(groups) {
                let c0 = g * inverse_lanes::LANES;
                let cn = (k - c0).min(inverse_lanes::LANES);
                for l in 0..inverse_lanes::LANES {
                    if l >= cn {
                        self.xl.iter_mut().for_each(|row| row[l] = 0.0);
                        continue;
                    }
                    for (row, v) in self.xl.iter_mut().zip(&self.z[(c0 + l) * n..][..n]) {
                        row[l] = *v;
                    }
                }
                lu.solve(&mut self.xl);
                for l in 0..cn {
                    for (v, row) in self.z[(c0 + l) * n..][..n].iter_mut().zip(&self.xl) {
                        *v = row[l];
                    }
                }
            }
            // Orthonormalise in rank order within each cluster (each vector scaled to max 1
            // first, so that neither its dot products nor its norm can overflow: the earlier
            // vectors are unit); a vector that vanishes or is not finite becomes e_c at
            // once, before the later vectors of its cluster use it.
            for c in 0..k {
                let (done, rest) = self.z.split_at_mut(c * n);
                let x = &mut rest[..n];
                scale_to_max_one(x);
                for q in self.shifts[c].1..c {
                    let zq = &done[q * n..(q + 1) * n];
                    let dot = dot_real(zq, x);
                    axpy_real(-dot, zq, x);
                }
                let nrm = dot_real(x, x).sqrt();
                if nrm > 0.0 && nrm.is_finite() {
                    let s = 1.0 / nrm;
                    x.iter_mut().for_each(|v| *v *= s);
                } else {
                    x.iter_mut().for_each(|v| *v = 0.0);
                    x[c.min(n - 1)] = 1.0;
                }
            }
        }
    }
}

/// x / max|x_i| where that max is positive and finite (exact powers aside, a rescaling:
/// its direction is what inverse iteration keeps); otherwise x unchanged.
fn scale_to_max_one(x: &mut [f64]) {
    let mx = x.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    if mx > 0.0 && mx.is_finite() {
        let s = 1.0 / mx;
        if s.is_finite() {
            x.iter_mut().for_each(|v| *v *= s);
        } else {
            x.iter_mut().for_each(|v| *v /= mx);
        }
    }
}

/// [`Eigh::reduced_mut`]: T and Q's reflectors of one problem.
pub(super) struct Reduced<'a> {
    /// Row-major split parts; v_j in row j, columns j+1 ….
    pub re: &'a mut [f64],
    pub im: &'a mut [f64],
    /// τ_j (zero: H_j = I).
    pub tau: &'a mut [C<f64>],
    /// T's diagonal and subdiagonal (off[j] couples j and j+1).
    pub diag: &'a mut [f64],
    pub off: &'a mut [f64],
}

simd::dispatch!(
    /// The k leading eigenvectors: of T by inverse iteration, then x = Q z for all of them
    /// together (each reflector is applied to every vector while it is in cache).
    fn leading_vectors(s: &mut Eigh, k: usize, vectors: &mut [C<f64>]) => leading_vectors_impl::<AVX2>
);

#[inline(always)]
fn leading_vectors_impl<const AVX2: bool>(s: &mut Eigh, k: usize, vectors: &mut [C<f64>]) {
    let n = s.n;
    s.tridiagonal_vectors(k);
    if k >= back_lanes::MIN_VECTORS {
        // Many vectors: eight at a time in vector lanes.
        let q = Reflectors {
            n,
            re: &s.re,
            im: &s.im,
            tau: &s.tau,
        };
        s.back.apply(&q, k, &s.z, vectors);
        return;
    }
    // Y = Z (real), split parts, one row per vector.
    s.yr.clear();
    s.yr.extend_from_slice(&s.z[..n * k]);
    s.yi.clear();
    s.yi.resize(n * k, 0.0);
    for j in (0..n.saturating_sub(1)).rev() {
        let t = s.tau[j];
        if t == C::new(0.0, 0.0) {
            continue;
        }
        // y ← y − τ v (vᴴ y) on rows j+1 …; v_j is stored in row j, columns j+1 …
        let (hr, hi) = (
            &s.re[j * n + j + 1..(j + 1) * n],
            &s.im[j * n + j + 1..(j + 1) * n],
        );
        for c in 0..k {
            let (yr, yi) = (
                &mut s.yr[c * n + j + 1..(c + 1) * n],
                &mut s.yi[c * n + j + 1..(c + 1) * n],
            );
            // SAFETY: AVX2 is true only in the variant run where the CPU has AVX2.
            let f = -(t * unsafe { simd::dot4_in::<AVX2, true>(hr, hi, yr, yi) });
            axpy(f, hr, hi, yr, yi);
        }
    }
    for (v, (a, b)) in vectors[..n * k].iter_mut().zip(s.yr.iter().zip(&s.yi)) {
        *v = C::new(*a, *b);
    }
}

simd::dispatch!(
    /// Householder reduction of `s.re/s.im` to tridiagonal form: diagonal into `s.diag`,
    /// the (real) subdiagonal into `s.off`, v_j into row j and τ_j into `s.tau`.
    pub(super) fn tridiagonalize(s: &mut Eigh) => tridiagonalize_impl::<AVX2>
);

#[inline(always)]
fn tridiagonalize_impl<const AVX2: bool>(s: &mut Eigh) {
    let n = s.n;
    for j in 0..n {
        s.diag[j] = s.re[j * n + j];
        s.off[j] = 0.0;
        s.tau[j] = C::new(0.0, 0.0);
        if j + 1 >= n {
            break;
        }
        let len = n - j - 1;
        let row = j * n + j + 1;
        // x = A[j+1.., j]: column j below the diagonal (only the lower triangle is kept).
        let at = |i: usize| (j + 1 + i) * n + j;
        let alpha = C::new(s.re[at(0)], s.im[at(0)]);
        let xnorm2: f64 = (1..len).map(|i| s.re[at(i)].powi(2) + s.im[at(i)].powi(2)).sum();
        if xnorm2 == 0.0 && alpha.im == 0.0 {
            // Already reduced: H = I.
            s.off[j] = alpha.re;
            s.re[row] = 1.0;
            s.im[row] = 0.0;
            for i in 1..len {
                s.re[row + i] = 0.0;
                s.im[row + i] = 0.0;
            }
            continue;
        }
        let nrm = (alpha.norm_sqr() + xnorm2).sqrt();
        let beta = if alpha.re >= 0.0 { -nrm } else { nrm };
        let tau = C::new((beta - alpha.re) / beta, -alpha.im / beta);
        let scale = C::new(1.0, 0.0) / (alpha - beta);
        let (vr, vi) = (&mut s.vr[..len], &mut s.vi[..len]);
        vr[0] = 1.0;
        vi[0] = 0.0;
        for i in 1..len {
            let x = C::new(s.re[at(i)], s.im[at(i)]) * scale;
            vr[i] = x.re;
            vi[i] = x.im;
        }
        s.off[j] = beta;
        s.tau[j] = tau;
        // q = A₂₂ v from the lower triangle, row by row: row i gives q_i its part left
        // of the diagonal (a dot product) and q_k, k < i, the mirrored part conj(A_ik) v_i
        // (an axpy); every element is read once.
        let (pr, pi) = (&mut s.pr[..len], &mut s.pi[..len]);
        pr.iter_mut().chain(pi.iter_mut()).for_each(|x| *x = 0.0);
        for i in 0..len {
            let r0 = (j + 1 + i) * n + j + 1;
            let (ar, ai) = (&s.re[r0..r0 + i], &s.im[r0..r0 + i]);
            let vi_ = C::new(vr[i], vi[i]);
            // SAFETY: AVX2 is true only in the variant run where the CPU has AVX2.
            let left = unsafe { simd::dot4_in::<AVX2, false>(ar, ai, &vr[..i], &vi[..i]) };
            conj_axpy(vi_, ar, ai, &mut pr[..i], &mut pi[..i]);
            let d = s.re[r0 + i];
            pr[i] += left.re + d * vi_.re;
            pi[i] += left.im + d * vi_.im;
        }
        // p = τ q; w = p − ½ τ (pᴴ v) v.
        for i in 0..len {
            let p = tau * C::new(pr[i], pi[i]);
            pr[i] = p.re;
            pi[i] = p.im;
        }
        let a = tau * dotc(pr, pi, vr, vi) * -0.5;
        axpy(a, vr, vi, pr, pi);
        // A₂₂ ← A₂₂ − v wᴴ − w vᴴ on the lower triangle (the diagonal included).
        for i in 0..len {
            let r0 = (j + 1 + i) * n + j + 1;
            let (v, w) = (C::new(vr[i], vi[i]), C::new(pr[i], pi[i]));
            rank2_row(
                &mut s.re[r0..r0 + i + 1],
                &mut s.im[r0..r0 + i + 1],
                v,
                w,
                vr,
                vi,
                pr,
                pi,
            );
        }
        // Keep v_j in row j (right of the diagonal, unused by the lower triangle) for the
        // back-transformation.
        s.re[row..row + len].copy_from_slice(vr);
        s.im[row..row + len].copy_from_slice(vi);
    }
}

#[cfg(test)]
mod tests;
