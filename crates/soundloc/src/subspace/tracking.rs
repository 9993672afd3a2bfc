//! Approximate mode (`LocalizeConfig::subspace_tracking`, off by default): the leading
//! vectors of a stream's consecutive windows by a warm-started Rayleigh–Ritz (block
//! Krylov) iteration instead of an exact decomposition per window.
//!
//! Per stream and used bin a block Q (M × p, orthonormal, p = k + [`OVERSAMPLE`], k the
//! vectors the spectrum needs) is carried from one window to the next. For window t, with
//! A_t the Hermitian matrix the exact decomposition would decompose — R (SEVD), W R Wᴴ
//! (GEVD, W = L⁻¹), W R Wᴴ (GEVD-HARK, W = K^{-1/2}), W R R Wᴴ (GSVD, W = K⁻¹) — applied to
//! vectors, never formed:
//!
//! 1. V = orth([Q, W x_in, W x_out]) with the frames that entered and left the window since
//!    the previous one (at most [`CHANGED_FRAMES`] of each; GSVD adds W R x): A changed by
//!    ±(W x)(W x)ᴴ/W, so span V holds the new leading vectors to first order;
//! 2. Z = A_t V; Rayleigh–Ritz: Vᴴ Z = Y Θ Yᴴ, Ritz vectors U = V Y, values θ (descending);
//! 3. accepted when each of the k leading pairs has ‖A_t u_c − θ_c u_c‖ ≤ [`TOL`]·θ₁; else V
//!    grows by the p residuals (orthogonalised) and their images under A_t, and step 2
//!    repeats — at most [`MAX_STEPS`] Rayleigh–Ritz steps (two widenings), then the exact
//!    decomposition;
//! 4. Q ← U (the p leading Ritz vectors) for the next window.
//!
//! An exact decomposition starts every stream, follows every failed check and refreshes
//! each bin once per ⌈W / PERIOD⌉ windows (by then every frame has been replaced). An
//! accepted step costs (p + changed frames) applications of A — 1 to 4 M × M products by
//! a vector — instead of the exact path's whitening products and tridiagonalisation
//! (≈ 1.5–3 M³). It pays off for large arrays with few signal vectors (60 mics, k = 2:
//! the decomposition stage ≈ 1.9–2.0× faster on the scenes of `bench::tracking`); at
//! 8 mics the exact 8 × 8 decomposition is cheaper than the bookkeeping (measured:
//! slower). What the mode gives up: the values beyond the p tracked ones (the source count
//! needs all M and is not estimated), and exactness — the accepted vectors satisfy the
//! residual bound, no more; `soundloc bench --stream --subspace-tracking` states how far
//! the spectra and peaks are from the exact path's.
//!
//! Deterministic: a stream's results depend only on its windows, in order, not on how they
//! were batched or its input cut into blocks (unless the backend drops the stream's state
//! to bound its memory — more streams than `backend::cpu` keeps — which restarts it exact).

use super::block::{mul, mul_adjoint, norm2 as simd_norm2, orth_append, Block, Square};
use super::simd::{self, dotc};
use super::{decompose_alone, Decomposition, Workspace};
use crate::config::Algorithm;
use crate::real::{Real, C};
use crate::Result;
use faer::c64;

/// Vectors tracked beyond the k the spectrum needs (they absorb the next eigenvalues, so
/// the k leading converge at the rate λ_{k+3}/λ_k rather than λ_{k+1}/λ_k).
pub const OVERSAMPLE: usize = 2;
/// At most this many entering and this many leaving frames are added to the search space.
pub const CHANGED_FRAMES: usize = 4;
/// Accepted residual ‖A u − θ u‖ of each leading Ritz pair, relative to θ₁.
pub const TOL: f64 = 1e-4;
/// Rayleigh–Ritz steps per window before the exact decomposition takes over.
pub const MAX_STEPS: usize = 3;

/// Tracking state of one stream and bin.
#[derive(Debug, Clone, Default)]
pub struct BinTrack {
    /// The carried block Q (empty: the next window decomposes exactly).
    q: Block,
    /// Windows left before the next exact refresh.
    countdown: usize,
}

impl BinTrack {
    /// Bytes held.
    pub fn bytes(&self) -> usize {
        16 * self.q.re.len()
    }
}

/// What happened to one window.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// Decomposed exactly (stream start, refresh or fallback).
    Exact,
    /// Tracked, accepted after this many Rayleigh–Ritz steps.
    Tracked(usize),
}

/// Per-thread scratch.
pub struct Tracker {
    m: usize,
    r: Square,
    w: Square,
    v: Block,
    z: Block,
    t1: Block,
    t2: Block,
    u: Block,
    res: Block,
    x: Block,
    zn: Block,
    theta: Vec<f64>,
    /// Small eigensolvers by size.
    small: Vec<super::eigh::Eigh>,
    y: Vec<c64>,
    exact: Option<Decomposition<f64>>,
}

impl Tracker {
    /// Scratch for M microphones.
    pub fn new(m: usize) -> Self {
        let b = || Block::new(m);
        Tracker {
            m,
            r: Square::default(),
            w: Square::default(),
            v: b(),
            z: b(),
            t1: b(),
            t2: b(),
            u: b(),
            res: b(),
            x: b(),
            zn: b(),
            theta: Vec::new(),
            small: Vec::new(),
            y: Vec::new(),
            exact: None,
        }
    }

    /// Z's columns `from..` = A V's (R and W already loaded; Z keeps the first `from`).
    fn apply(&mut self, alg: Algorithm, from: usize) {
        let m = self.m;
        self.x.zeros(m, self.v.cols - from);
        self.x.re.copy_from_slice(&self.v.re[from * m..]);
        self.x.im.copy_from_slice(&self.v.im[from * m..]);
        let (src, dst) = (&self.x, &mut self.zn);
        let (r, w, t1, t2) = (&self.r, &self.w, &mut self.t1, &mut self.t2);
        match alg {
            Algorithm::Sevd | Algorithm::SrpPhat => mul(r, false, src, dst),
            Algorithm::Gevd => {
                mul_adjoint(w, true, src, t1);
                mul(r, false, t1, t2);
                mul(w, true, t2, dst);
            }
            Algorithm::GevdHark => {
                // A = W R Wᴴ, as the exact path forms it (W = K^{-1/2} is Hermitian up to
                // rounding).
                mul_adjoint(w, false, src, t1);
                mul(r, false, t1, t2);
                mul(w, false, t2, dst);
            }
            Algorithm::Gsvd => {
                // A = (W R)(W R)ᴴ = W R R Wᴴ (W = K⁻¹).
                mul_adjoint(w, false, src, t1);
                mul(r, false, t1, t2);
                mul(r, false, t2, t1);
                mul(w, false, t1, dst);
            }
        }
        self.z.cols = from;
        self.z.m = m;
        self.z.re.truncate(from * m);
        self.z.im.truncate(from * m);
        self.z.cols += self.zn.cols;
        self.z.re.extend_from_slice(&self.zn.re);
        self.z.im.extend_from_slice(&self.zn.im);
    }
}

/// Everything one window's tracked decomposition reads.
pub struct Window<'a, T: Real> {
    /// The algorithm (a MUSIC one).
    pub algorithm: Algorithm,
    /// Scaled R (row-major M × M, f64).
    pub r: &'a [c64],
    /// The plan's whitening matrix (row-major, f64), for the noise-aware algorithms.
    pub w: Option<&'a [c64]>,
    /// The frames at this bin (length M each) that entered the window or left it since the
    /// stream's previous window, as far as the caller has them.
    pub changed: &'a [&'a [C<T>]],
    /// An exact decomposition every `refresh` windows (`refresh − 1` tracked between).
    pub refresh: usize,
}

/// Decompose one window approximately into `out` (`out.dim` leading vectors, values of
/// the tracked block), carrying `state` to the next window of the stream.
pub fn decompose_tracked<T: Real>(
    win: &Window<'_, T>,
    state: &mut BinTrack,
    ws: &mut Workspace,
    tr: &mut Tracker,
    out: &mut Decomposition<T>,
) -> Result<Outcome> {
    let m = tr.m;
    let k = out.dim;
    let p = (k + OVERSAMPLE).min(m.saturating_sub(1)).max(k);
    if state.countdown > 0 && state.q.cols == p {
        state.countdown -= 1;
        if let Some(steps) = track(win, state, tr, p, out) {
            return Ok(Outcome::Tracked(steps));
        }
    }
    // Exact: p leading vectors, all values; Q ← them.
    let exact = tr.exact.get_or_insert_with(|| Decomposition::new(m, p));
    if exact.dim != p {
        *exact = Decomposition::new(m, p);
    }
    decompose_alone(win.algorithm, win.r, win.w, ws, exact)?;
    out.values.clear();
    out.values.extend(exact.values.iter().map(|&v| T::of_f64(v)));
    out.vectors64.copy_from_slice(&exact.vectors64[..m * k]);
    for (v, z) in out.vectors.iter_mut().zip(&out.vectors64) {
        *v = C::new(T::of_f64(z.re), T::of_f64(z.im));
    }
    state.q.m = m;
    state.q.clear();
    for c in 0..p {
        let i = state.q.push_zero();
        let (qr, qi) = state.q.col_mut(i);
        for (j, z) in exact.vector64(c).iter().enumerate() {
            qr[j] = z.re;
            qi[j] = z.im;
        }
    }
    state.countdown = win.refresh.saturating_sub(1);
    Ok(Outcome::Exact)
}

/// Steps 1–4 of the module doc; `None` when the residual bound is not met (or the window
/// is degenerate), leaving the exact decomposition to the caller.
fn track<T: Real>(
    win: &Window<'_, T>,
    state: &mut BinTrack,
    tr: &mut Tracker,
    p: usize,
    out: &mut Decomposition<T>,
) -> Option<usize> {
    let m = tr.m;
    let k = out.dim;
    let alg = win.algorithm;
    tr.r.load(win.r);
    if let Some(w) = win.w {
        tr.w.load(w);
    } else if alg != Algorithm::Sevd {
        return None;
    }
    // 1. V = orth([Q, W x_new]), Z = A V.
    tr.v.m = m;
    tr.v.clear();
    orth_append(&mut tr.v, &state.q, 0..state.q.cols);
    if tr.v.cols < p {
        return None;
    }
    if !win.changed.is_empty() {
        // The frames that entered or left since the previous window: A changed by
        // ±(W x)(W x)ᴴ (GSVD: also W R x), so with them V stays nearly invariant.
        tr.x.zeros(m, win.changed.len());
        for (c, f) in win.changed.iter().enumerate() {
            let (xr, xi) = tr.x.col_mut(c);
            for (j, z) in f.iter().enumerate() {
                xr[j] = z.re.to_f64();
                xi[j] = z.im.to_f64();
            }
        }
        let cols = tr.x.cols;
        match alg {
            Algorithm::Sevd | Algorithm::SrpPhat => orth_append(&mut tr.v, &tr.x, 0..cols),
            Algorithm::Gevd | Algorithm::GevdHark => {
                mul(&tr.w, alg == Algorithm::Gevd, &tr.x, &mut tr.t1);
                orth_append(&mut tr.v, &tr.t1, 0..cols);
            }
            Algorithm::Gsvd => {
                mul(&tr.w, false, &tr.x, &mut tr.t1);
                orth_append(&mut tr.v, &tr.t1, 0..cols);
                mul(&tr.r, false, &tr.x, &mut tr.t2);
                mul(&tr.w, false, &tr.t2, &mut tr.t1);
                orth_append(&mut tr.v, &tr.t1, 0..cols);
            }
        }
    }
    tr.apply(alg, 0);
    for step in 1..=MAX_STEPS {
        // 2. Rayleigh–Ritz over span V.
        let q = tr.v.cols;
        if tr.small.len() <= q {
            tr.small.resize_with(q + 1, || super::eigh::Eigh::new(0));
        }
        if tr.small[q].dim() != q {
            tr.small[q] = super::eigh::Eigh::new(q);
        }
        let eig = &mut tr.small[q];
        {
            let (hr, hi) = eig.matrix_mut();
            for i in 0..q {
                for j in i..q {
                    let (vr, vi) = tr.v.col(i);
                    let (zr, zi) = tr.z.col(j);
                    let a = dotc(vr, vi, zr, zi);
                    let (vr, vi) = tr.v.col(j);
                    let (zr, zi) = tr.z.col(i);
                    let b = dotc(vr, vi, zr, zi);
                    // (Vᴴ A V)_ij, made exactly Hermitian.
                    let h = (a + b.conj()) * 0.5;
                    hr[i * q + j] = h.re;
                    hi[i * q + j] = if i == j { 0.0 } else { h.im };
                    hr[j * q + i] = h.re;
                    hi[j * q + i] = if i == j { 0.0 } else { -h.im };
                }
            }
        }
        tr.y.clear();
        tr.y.resize(q * p, c64::new(0.0, 0.0));
        eig.solve(p, &mut tr.y).ok()?;
        tr.theta.clear();
        tr.theta.extend_from_slice(&eig.values()[..p]);
        let top = tr.theta[0];
        if !(top > 0.0 && top.is_finite()) {
            return None;
        }
        // U = V Y, residuals A u − θ u = Z Y − θ U (the p leading pairs).
        tr.u.zeros(m, p);
        tr.res.zeros(m, p);
        for c in 0..p {
            for l in 0..q {
                let f = tr.y[c * q + l];
                let (vr, vi) = tr.v.col(l);
                let (ur, ui) = tr.u.col_mut(c);
                simd::axpy(f, vr, vi, ur, ui);
                let (zr, zi) = tr.z.col(l);
                let (yr, yi) = tr.res.col_mut(c);
                simd::axpy(f, zr, zi, yr, yi);
            }
            let th = tr.theta[c];
            let (ur, ui) = (&tr.u.re[c * m..(c + 1) * m], &tr.u.im[c * m..(c + 1) * m]);
            let (rr, ri) = tr.res.col_mut(c);
            simd::axpy(C::new(-th, 0.0), ur, ui, rr, ri);
        }
        // 3. Accept when the k leading residuals are small.
        // (NaN-safe: a residual that is not ≤ the bound fails.)
        let worst = (0..k)
            .map(|c| {
                let (rr, ri) = tr.res.col(c);
                simd_norm2(rr, ri).sqrt()
            })
            .fold(0.0, |a: f64, b| {
                if a.is_nan() || b.is_nan() {
                    f64::NAN
                } else {
                    a.max(b)
                }
            });
        if worst <= TOL * top {
            let value = |l: f64| {
                if alg == Algorithm::Gsvd {
                    l.max(0.0).sqrt()
                } else {
                    l
                }
            };
            out.values.clear();
            out.values.extend(tr.theta.iter().map(|&l| T::of_f64(value(l))));
            for c in 0..k {
                let (ur, ui) = tr.u.col(c);
                for j in 0..m {
                    let z = c64::new(ur[j], ui[j]);
                    out.vectors64[c * m + j] = z;
                    out.vectors[c * m + j] = C::new(T::of_f64(z.re), T::of_f64(z.im));
                }
            }
            // 4. The Ritz vectors start the next window.
            std::mem::swap(&mut state.q, &mut tr.u);
            return Some(step);
        }
        if step == MAX_STEPS {
            break;
        }
        // Not yet: widen V by the residuals (a block Krylov step) and apply A to them.
        let before = tr.v.cols;
        orth_append(&mut tr.v, &tr.res, 0..p);
        if tr.v.cols == before {
            return None;
        }
        tr.apply(alg, before);
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn crandn(rng: &mut rand::rngs::StdRng) -> c64 {
        c64::new(rng.gen::<f64>() - 0.5, rng.gen::<f64>() - 0.5)
    }

    /// Frames of `m` mics: two fixed directions with random amplitudes plus noise.
    fn frames(m: usize, n: usize, seed: u64) -> Vec<Vec<c64>> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let a1: Vec<c64> = (0..m).map(|_| crandn(&mut rng)).collect();
        let a2: Vec<c64> = (0..m).map(|_| crandn(&mut rng)).collect();
        (0..n)
            .map(|_| {
                let (s1, s2) = (crandn(&mut rng) * 10.0, crandn(&mut rng) * 5.0);
                (0..m)
                    .map(|i| a1[i] * s1 + a2[i] * s2 + crandn(&mut rng) * 0.3)
                    .collect()
            })
            .collect()
    }

    fn corr(fr: &[Vec<c64>]) -> Vec<c64> {
        let m = fr[0].len();
        let mut r = vec![c64::new(0.0, 0.0); m * m];
        for x in fr {
            for i in 0..m {
                for j in 0..m {
                    r[i * m + j] += x[i] * x[j].conj() / fr.len() as f64;
                }
            }
        }
        r
    }

    /// The plan-like whitening matrix for `alg`: lower triangular for GEVD (L⁻¹),
    /// Hermitian positive definite otherwise (K^{-1/2}, K⁻¹).
    fn whitening(alg: Algorithm, m: usize, seed: u64) -> Vec<c64> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let g: Vec<c64> = (0..m * m).map(|_| crandn(&mut rng) * 0.1).collect();
        (0..m * m)
            .map(|k| {
                let (i, j) = (k / m, k % m);
                let h = (g[i * m + j] + g[j * m + i].conj()) * 0.5;
                let d = if i == j {
                    c64::new(1.0 + 0.1 * i as f64, 0.0)
                } else {
                    h
                };
                if alg == Algorithm::Gevd && j > i {
                    c64::new(0.0, 0.0)
                } else {
                    d
                }
            })
            .collect()
    }

    /// Tracked against exact over `n` sliding windows (PERIOD 1) of `m` mics with two
    /// sources, k leading vectors: (‖U Uᴴ − E Eᴴ‖_max, value error / λ₁, windows tracked).
    fn compare(alg: Algorithm, m: usize, k: usize, n: usize) -> (f64, f64, usize) {
        let w = 50;
        let fr = frames(m, n + w, 7);
        let wm = whitening(alg, m, 3);
        let wopt = (alg != Algorithm::Sevd).then_some(wm.as_slice());
        let mut st = BinTrack::default();
        let (mut ws, mut tr) = (Workspace::new(m), Tracker::new(m));
        let mut out = Decomposition::<f64>::new(m, k);
        let mut ex = Decomposition::<f64>::new(m, k);
        let (mut tracked, mut worst_p, mut worst_v) = (0, 0.0f64, 0.0f64);
        for t in 0..n {
            let win = &fr[t..t + w];
            let r = corr(win);
            let mut changed: Vec<&[c64]> = vec![win[w - 1].as_slice()];
            if t > 0 {
                changed.push(&fr[t - 1]);
            }
            let o = decompose_tracked(
                &Window {
                    algorithm: alg,
                    r: &r,
                    w: wopt,
                    changed: &changed,
                    refresh: 50,
                },
                &mut st,
                &mut ws,
                &mut tr,
                &mut out,
            )
            .unwrap();
            tracked += matches!(o, Outcome::Tracked(_)) as usize;
            super::super::decompose(alg, &r, wopt, &mut ws, &mut ex).unwrap();
            for i in 0..m {
                for j in 0..m {
                    let mut d = c64::new(0.0, 0.0);
                    for c in 0..k {
                        d += out.vector64(c)[i] * out.vector64(c)[j].conj()
                            - ex.vector64(c)[i] * ex.vector64(c)[j].conj();
                    }
                    worst_p = worst_p.max(d.norm());
                }
            }
            for c in 0..k {
                worst_v = worst_v.max((out.values[c] - ex.values[c]).abs() / ex.values[0]);
            }
        }
        (worst_p, worst_v, tracked)
    }

    /// With two sources the tracked vectors span the exact signal subspace and the tracked
    /// values equal the exact ones, for every algorithm, and most windows are tracked rather
    /// than decomposed exactly.
    #[test]
    fn tracked_vectors_span_the_exact_signal_subspace() {
        for alg in Algorithm::MUSIC {
            let (worst_p, worst_v, tracked) = compare(alg, 12, 2, 170);
            assert!(worst_p < 3e-5, "{alg:?}: projector off by {worst_p:e}");
            assert!(
                worst_v < 1e-9,
                "{alg:?}: values off by {worst_v:e} of the largest"
            );
            assert!(tracked >= 150, "{alg:?}: only {tracked} of 170 windows tracked");
        }
    }

    /// Tiny arrays, and k up to M − 1 (no room to oversample), are served as well.
    #[test]
    fn tiny_arrays_and_k_next_to_m_are_served() {
        for (m, k) in [(2, 1), (3, 2), (4, 3)] {
            for alg in Algorithm::MUSIC {
                let (worst_p, worst_v, _) = compare(alg, m, k, 60);
                assert!(
                    worst_p < 1e-4,
                    "{alg:?} M={m} k={k}: projector off by {worst_p:e}"
                );
                assert!(worst_v < 1e-8, "{alg:?} M={m} k={k}: values off by {worst_v:e}");
            }
        }
    }
}
