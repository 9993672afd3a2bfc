//! Hermitian eigendecomposition of small matrices (n ≤ [`MAX_N`], an array of up to 16
//! microphones), [`LANES`] problems at once, one per vector lane, in f64: every
//! eigenvalue and the eigenvectors of the k largest.
//!
//! For an 8-microphone array a decomposition is a few hundred operations spread over
//! chains of dependent divisions and square roots: one problem at a time leaves the core
//! idle (≈ 3 µs per 8 × 8 problem with [`super::eigh`], 2026-11-27). Here every operation
//! acts on the same element of eight problems at once, and no step branches on the data:
//! a step one problem needs runs for all and its result is kept only where needed. Each
//! lane's operations are those it would run alone, so its result does not depend on
//! which problems share its group.
//!
//! 1. **Householder tridiagonalisation** (LAPACK `zhetd2`, lower, in full storage):
//!    A = Q T Qᴴ, Q = H₀ ⋯ H_{n−2}, H_j = I − τ_j v_j v_jᴴ; per step p = τ A₂₂ v,
//!    w = p − ½ τ (pᴴv) v, A₂₂ ← A₂₂ − v wᴴ − w vᴴ. A column that is already reduced
//!    gets τ = 0 (H = I) without a branch.
//! 2. **Implicit QL with Wilkinson-type shifts and the rotations accumulated** (EISPACK
//!    `tql2`): T = Z Λ Zᵀ with every eigenvector of T. Each sweep runs from the bottom of
//!    the matrix to the eigenvalue l being found (a sweep through a negligible
//!    off-diagonal element stays an orthogonal similarity, so no lane needs its own
//!    splitting point); a lane whose l has converged takes identity rotations and keeps
//!    its values. At most [`MAX_SWEEPS`] sweeps per eigenvalue, else an error.
//! 3. **Sort and back-transform**: per lane the eigenvalues descending, and for the k
//!    largest x = Q z (the reflectors applied from the last to the first).
//!
//! Operations are plain IEEE multiplies and adds (no fused multiply-add), so AVX-512
//! (≈ 12 % faster than AVX2 on Zen 4), AVX2 and the baseline build give the same bits.

use super::tridiag_lanes::reflector;
use super::v8::{self, F8};
use crate::real::C;
use crate::{Error, Result};

/// Problems per group: eight f64 lanes (one AVX-512 register, two AVX2 registers).
pub const LANES: usize = 8;
/// The largest matrix this solver takes.
pub const MAX_N: usize = 16;
/// Sweeps allowed per eigenvalue.
const MAX_SWEEPS: usize = 60;

/// One value per lane.
type V = [f64; LANES];
const ZERO: V = [0.0; LANES];

/// What a group decomposes, from each problem's R and whitening matrix W (all f64).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Form {
    /// R itself (SEVD).
    R,
    /// W R Wᴴ; `lower`: W is lower triangular (textbook GEVD's L⁻¹; GEVD-HARK's
    /// Hermitian K^{-1/2} gives W R W = W R Wᴴ).
    Whitened {
        /// W is lower triangular (its strictly upper part is skipped).
        lower: bool,
    },
    /// B Bᴴ with B = W R (GSVD, W = K⁻¹).
    Gram,
}

/// Scratch and results of one group of up to [`LANES`] n × n problems.
pub struct EighLanes {
    n: usize,
    /// Problems loaded (the other lanes repeat lane 0).
    used: usize,
    /// What the group decomposes.
    form: Form,
    /// R and W as given, then T = W R (row-major, full storage).
    rr: Vec<V>,
    ri: Vec<V>,
    wr: Vec<V>,
    wi: Vec<V>,
    mr: Vec<V>,
    mi: Vec<V>,
    /// The matrices decomposed, row-major, full storage.
    re: Vec<V>,
    im: Vec<V>,
    /// Householder vectors, row j holds v_j (entries j+1 … n−1), and τ_j.
    hr: Vec<V>,
    hi: Vec<V>,
    tr: Vec<V>,
    ti: Vec<V>,
    /// T: diagonal, off-diagonal (e[i] couples i and i+1; e[n−1] = 0), then Λ.
    d: Vec<V>,
    e: Vec<V>,
    /// Eigenvectors of T, column-major (column i contiguous).
    z: Vec<V>,
    /// Scratch vectors (p, w).
    pr: Vec<V>,
    pi: Vec<V>,
    /// The k leading vectors during the back-transformation, column c at c·n.
    yr: Vec<V>,
    yi: Vec<V>,
    /// Per lane: eigenvalues descending and their columns in `z`.
    values: [Vec<f64>; LANES],
    order: [Vec<usize>; LANES],
    /// Per lane: the eigenvalue iteration did not converge.
    failed: [bool; LANES],
}

impl EighLanes {
    /// Scratch for n × n problems, n ≤ [`MAX_N`].
    pub fn new(n: usize) -> Self {
        assert!(n <= MAX_N, "eigh_lanes: n = {n} > {MAX_N}");
        let v = |len: usize| vec![ZERO; len];
        EighLanes {
            n,
            used: 0,
            form: Form::R,
            rr: v(n * n),
            ri: v(n * n),
            wr: v(n * n),
            wi: v(n * n),
            mr: v(n * n),
            mi: v(n * n),
            re: v(n * n),
            im: v(n * n),
            hr: v(n * n),
            hi: v(n * n),
            tr: v(n),
            ti: v(n),
            d: v(n),
            e: v(n),
            z: v(n * n),
            pr: v(n),
            pi: v(n),
            yr: Vec::new(),
            yi: Vec::new(),
            values: std::array::from_fn(|_| vec![0.0; n]),
            order: std::array::from_fn(|_| (0..n).collect()),
            failed: [false; LANES],
        }
    }

    /// The matrix size.
    pub fn dim(&self) -> usize {
        self.n
    }

    /// Start a new group of problems of one form.
    pub fn clear(&mut self, form: Form) {
        self.used = 0;
        self.form = form;
    }

    /// Problems loaded in this group.
    pub fn len(&self) -> usize {
        self.used
    }

    /// Whether no problem is loaded.
    pub fn is_empty(&self) -> bool {
        self.used == 0
    }

    /// Add a problem: R (row-major n × n, Hermitian: its lower triangle and the real part
    /// of its diagonal are read) and, unless the form is [`Form::R`], W (row-major n × n;
    /// its lower triangle only where the form says it is lower triangular). Returns its
    /// lane.
    pub fn push(&mut self, r: &[C<f64>], w: Option<&[C<f64>]>) -> Result<usize> {
        let n = self.n;
        assert!(self.used < LANES, "eigh_lanes: group full");
        assert!(r.len() >= n * n);
        let lane = self.used;
        let direct = self.form == Form::R;
        let (xr, xi) = if direct {
            (&mut self.re, &mut self.im)
        } else {
            (&mut self.rr, &mut self.ri)
        };
        let mut finite = true;
        for i in 0..n {
            for j in 0..=i {
                let z = r[i * n + j];
                let (a, b) = (z.re, if i == j { 0.0 } else { z.im });
                finite &= a.is_finite() & b.is_finite();
                xr[i * n + j][lane] = a;
                xi[i * n + j][lane] = b;
                xr[j * n + i][lane] = a;
                xi[j * n + i][lane] = -b;
            }
        }
        if !direct {
            let w = w.ok_or_else(|| Error::Config(format!("{:?} needs a whitening matrix", self.form)))?;
            assert!(w.len() >= n * n);
            let lower = self.form == (Form::Whitened { lower: true });
            for i in 0..n {
                for j in 0..n {
                    let z = if lower && j > i {
                        C::new(0.0, 0.0)
                    } else {
                        w[i * n + j]
                    };
                    finite &= z.re.is_finite() & z.im.is_finite();
                    self.wr[i * n + j][lane] = z.re;
                    self.wi[i * n + j][lane] = z.im;
                }
            }
        }
        if !finite {
            return Err(Error::numerical(
                "decompose",
                "the matrix holds non-finite values",
            ));
        }
        self.used += 1;
        Ok(lane)
    }

    /// Decompose the loaded problems: every eigenvalue ([`EighLanes::values`]) and the
    /// eigenvectors of the `k` largest ([`EighLanes::vector`]).
    pub fn solve(&mut self, k: usize) -> Result<()> {
        let n = self.n;
        assert!(k <= n);
        if self.used == 0 || n == 0 {
            return Ok(());
        }
        self.prepare(k);
        solve_lanes(self, k);
        for l in 0..self.used {
            if self.failed[l] {
                return Err(Error::numerical(
                    "decompose",
                    format!("tridiagonal QL did not converge in {MAX_SWEEPS} sweeps per eigenvalue"),
                ));
            }
            if self.values[l].iter().any(|x| !x.is_finite()) {
                return Err(Error::numerical("decompose", "non-finite eigenvalue"));
            }
        }
        Ok(())
    }

    /// Before a solve for `k` vectors: idle lanes repeat lane 0 (known to be finite) in
    /// what the form reads; the vectors' storage is sized.
    fn prepare(&mut self, k: usize) {
        if self.used < LANES {
            let loaded: [&mut Vec<V>; 4] = if self.form == Form::R {
                [&mut self.re, &mut self.im, &mut Vec::new(), &mut Vec::new()]
            } else {
                [&mut self.rr, &mut self.ri, &mut self.wr, &mut self.wi]
            };
            for x in loaded.into_iter().flat_map(|v| v.iter_mut()) {
                for l in self.used..LANES {
                    x[l] = x[0];
                }
            }
        }
        self.yr.resize(self.n * k, ZERO);
        self.yi.resize(self.n * k, ZERO);
    }

    /// Eigenvalues of problem `lane`, descending.
    pub fn values(&self, lane: usize) -> &[f64] {
        assert!(lane < self.used, "eigh_lanes: lane {lane} not loaded");
        &self.values[lane]
    }

    /// Eigenvector c (of the c-th largest eigenvalue, c < k, unit norm) of problem `lane`
    /// into `out` (n values).
    pub fn vector(&self, lane: usize, c: usize, out: &mut [C<f64>]) {
        let n = self.n;
        assert!(
            lane < self.used && (c + 1) * n <= self.yr.len(),
            "eigh_lanes: no vector {c} of lane {lane}"
        );
        // + 0: a zero's sign may depend on whether the group's other lanes were still
        // iterating (their identity rotations turn −0 into +0); no other bit does.
        for (row, o) in out[..n].iter_mut().enumerate() {
            *o = C::new(self.yr[c * n + row][lane] + 0.0, self.yi[c * n + row][lane] + 0.0);
        }
    }
}

/// Steps 1–3 for every lane (module docs), with the lane type the CPU has.
fn solve_lanes(s: &mut EighLanes, k: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU supports AVX-512F (checked just above).
            return unsafe { solve_avx512(s, k) };
        }
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            return unsafe { solve_avx2(s, k) };
        }
    }
    solve_with::<v8::Scalar>(s, k)
}

/// [`solve_with`] in AVX-512 registers (the caller checks the CPU): faster than AVX2 on
/// Zen 4 and on an Intel Xeon (2026-11-27; BENCHMARKS.md, seventh session).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn solve_avx512(s: &mut EighLanes, k: usize) {
    solve_with::<v8::Avx512>(s, k)
}

/// [`solve_with`] in AVX2 registers (the caller checks the CPU).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn solve_avx2(s: &mut EighLanes, k: usize) {
    solve_with::<v8::Avx2>(s, k)
}

#[inline(always)]
fn solve_with<F: F8>(s: &mut EighLanes, k: usize) {
    if s.form != Form::R {
        products::<F>(s);
    }
    tridiagonalize::<F>(s);
    ql::<F>(s);
    sort(s);
    back_transform::<F>(s, k);
}

/// Step 0: the Hermitian matrix of the group's [`Form`] into `re`/`im`: M = W R, then
/// a_ij = Σ_k m_ik conj(x_jk) for j ≤ i with X = W or M, mirrored (A exactly Hermitian,
/// real diagonal). Where W is lower triangular its zero half is skipped.
#[inline(always)]
fn products<F: F8>(s: &mut EighLanes) {
    let n = s.n;
    let zero = F::splat(0.0);
    let lower = s.form == (Form::Whitened { lower: true });
    for i in 0..n {
        let ks = if lower { i + 1 } else { n };
        for j in 0..n {
            let (mut tr, mut ti) = (zero, zero);
            for k in 0..ks {
                let (a, b) = (F::load(&s.wr[i * n + k]), F::load(&s.wi[i * n + k]));
                let (x, y) = (F::load(&s.rr[k * n + j]), F::load(&s.ri[k * n + j]));
                tr = tr + (a * x - b * y);
                ti = ti + (a * y + b * x);
            }
            tr.store(&mut s.mr[i * n + j]);
            ti.store(&mut s.mi[i * n + j]);
        }
    }
    let gram = s.form == Form::Gram;
    for i in 0..n {
        for j in 0..=i {
            let ks = if lower { j + 1 } else { n };
            let (mut sr, mut si) = (zero, zero);
            for k in 0..ks {
                let (a, b) = (F::load(&s.mr[i * n + k]), F::load(&s.mi[i * n + k]));
                let (c, d) = if gram {
                    (F::load(&s.mr[j * n + k]), F::load(&s.mi[j * n + k]))
                } else {
                    (F::load(&s.wr[j * n + k]), F::load(&s.wi[j * n + k]))
                };
                sr = sr + (a * c + b * d);
                si = si + (b * c - a * d);
            }
            if i == j {
                si = zero;
            }
            sr.store(&mut s.re[i * n + j]);
            sr.store(&mut s.re[j * n + i]);
            si.store(&mut s.im[i * n + j]);
            (-si).store(&mut s.im[j * n + i]);
        }
    }
}

/// Step 1: T in `d`, `e`; v_j in row j of `hr`/`hi`, τ_j in `tr`/`ti`.
#[inline(always)]
fn tridiagonalize<F: F8>(s: &mut EighLanes) {
    let n = s.n;
    let zero = F::splat(0.0);
    for j in 0..n {
        s.d[j] = s.re[j * n + j];
        s.e[j] = ZERO;
        s.tr[j] = ZERO;
        s.ti[j] = ZERO;
        if j + 1 >= n {
            break;
        }
        let len = n - j - 1;
        let at = |i: usize| (j + 1 + i) * n + j;
        let (ar, ai) = (F::load(&s.re[at(0)]), F::load(&s.im[at(0)]));
        let mut xnorm2 = zero;
        for i in 1..len {
            let (xr, xi) = (F::load(&s.re[at(i)]), F::load(&s.im[at(i)]));
            xnorm2 = xnorm2 + (xr * xr + xi * xi);
        }
        // zlarfg (a column already reduced keeps H = I).
        let (beta, (taur, taui), (scr, sci)) = reflector(ar, ai, xnorm2);
        beta.store(&mut s.e[j]);
        taur.store(&mut s.tr[j]);
        taui.store(&mut s.ti[j]);
        // v (row j of h): 1, then x scaled.
        let h0 = j * n + j + 1;
        s.hr[h0] = [1.0; LANES];
        s.hi[h0] = ZERO;
        for i in 1..len {
            let (xr, xi) = (F::load(&s.re[at(i)]), F::load(&s.im[at(i)]));
            (xr * scr - xi * sci).store(&mut s.hr[h0 + i]);
            (xr * sci + xi * scr).store(&mut s.hi[h0 + i]);
        }
        let (vr, vi) = (&s.hr[h0..h0 + len], &s.hi[h0..h0 + len]);
        // p = τ A₂₂ v.
        for r in 0..len {
            let row = (j + 1 + r) * n + j + 1;
            let (rr, ri) = (&s.re[row..row + len], &s.im[row..row + len]);
            let (mut qr, mut qi) = (zero, zero);
            for c in 0..len {
                let (a, b) = (F::load(&rr[c]), F::load(&ri[c]));
                let (x, y) = (F::load(&vr[c]), F::load(&vi[c]));
                qr = qr + (a * x - b * y);
                qi = qi + (a * y + b * x);
            }
            (taur * qr - taui * qi).store(&mut s.pr[r]);
            (taur * qi + taui * qr).store(&mut s.pi[r]);
        }
        // w = p + a v, a = −½ τ (pᴴ v).
        let (mut dr, mut di) = (zero, zero);
        for r in 0..len {
            let (p, q) = (F::load(&s.pr[r]), F::load(&s.pi[r]));
            let (x, y) = (F::load(&vr[r]), F::load(&vi[r]));
            dr = dr + (p * x + q * y);
            di = di + (p * y - q * x);
        }
        let half = F::splat(-0.5);
        let (a0, a1) = (half * (taur * dr - taui * di), half * (taur * di + taui * dr));
        for r in 0..len {
            let (x, y) = (F::load(&vr[r]), F::load(&vi[r]));
            (F::load(&s.pr[r]) + (a0 * x - a1 * y)).store(&mut s.pr[r]);
            (F::load(&s.pi[r]) + (a0 * y + a1 * x)).store(&mut s.pi[r]);
        }
        // A₂₂ ← A₂₂ − v wᴴ − w vᴴ (both triangles: A stays exactly Hermitian).
        let (wr, wi) = (&s.pr[..len], &s.pi[..len]);
        for r in 0..len {
            let row = (j + 1 + r) * n + j + 1;
            let (rr, ri) = (&mut s.re[row..row + len], &mut s.im[row..row + len]);
            let (v1, v2) = (F::load(&vr[r]), F::load(&vi[r]));
            let (w1, w2) = (F::load(&wr[r]), F::load(&wi[r]));
            for c in 0..len {
                let (x1, x2) = (F::load(&vr[c]), F::load(&vi[c]));
                let (y1, y2) = (F::load(&wr[c]), F::load(&wi[c]));
                // v_r conj(w_c) + w_r conj(v_c)
                let ur = (v1 * y1 + v2 * y2) + (w1 * x1 + w2 * x2);
                let ui = (v2 * y1 - v1 * y2) + (w2 * x1 - w1 * x2);
                (F::load(&rr[c]) - ur).store(&mut rr[c]);
                (F::load(&ri[c]) - ui).store(&mut ri[c]);
            }
        }
    }
}

/// Step 2: Λ into `d` (unsorted), the eigenvectors of T into `z`.
#[inline(always)]
fn ql<F: F8>(s: &mut EighLanes) {
    let n = s.n;
    for (i, col) in s.z.chunks_exact_mut(n).enumerate() {
        col.fill(ZERO);
        col[i] = [1.0; LANES];
    }
    let (zero, one) = (F::splat(0.0), F::splat(1.0));
    let eps = F::splat(f64::EPSILON);
    // A lane whose T is not finite fails (its sweeps could stop on a NaN test).
    let mut failed = [false; LANES];
    for x in s.d.iter().chain(&s.e) {
        for (fl, v) in failed.iter_mut().zip(x) {
            *fl |= !v.is_finite();
        }
    }
    let (mut f, mut tst1) = (zero, zero);
    for l in 0..n {
        tst1 = tst1.max(F::load(&s.d[l]).abs() + F::load(&s.e[l]).abs());
        let mut sweeps = 0;
        loop {
            let el = F::load(&s.e[l]);
            let active = (eps * tst1).lt(el.abs());
            if !F::any(active) {
                break;
            }
            if sweeps == MAX_SWEEPS {
                for (x, a) in failed.iter_mut().zip(F::lanes(active)) {
                    *x |= a;
                }
                break;
            }
            sweeps += 1;
            // The shift: the eigenvalue of T's leading 2 × 2 block at l nearer d[l].
            let g = F::load(&s.d[l]);
            let p = (F::load(&s.d[l + 1]) - g) / (F::splat(2.0) * el);
            let ap = p.abs();
            let ip = one / p;
            // hypot(p, 1) without overflow.
            let r = F::select(one.lt(ap), ap * (one + ip * ip).sqrt(), (p * p + one).sqrt());
            let pr = F::select(p.lt(zero), p - r, p + r);
            let (dl, dl1) = (el / pr, el * pr);
            let h = F::select(active, g - dl, zero);
            F::select(active, dl, g).store(&mut s.d[l]);
            F::select(active, dl1, F::load(&s.d[l + 1])).store(&mut s.d[l + 1]);
            for di in &mut s.d[l + 2..n] {
                (F::load(di) - h).store(di);
            }
            f = f + h;
            // The sweep, i = n − 2 down to l.
            let el1 = F::load(&s.e[l + 1]);
            let mut p = F::load(&s.d[n - 1]);
            let (mut c, mut c2, mut c3) = (one, one, one);
            let (mut sn, mut s2) = (zero, zero);
            for i in (l..n - 1).rev() {
                c3 = c2;
                c2 = c;
                s2 = sn;
                let (ei, di) = (F::load(&s.e[i]), F::load(&s.d[i]));
                let g = c * ei;
                let hh = c * p;
                let r = (p * p + ei * ei).sqrt();
                F::select(active, sn * r, F::load(&s.e[i + 1])).store(&mut s.e[i + 1]);
                let rz = r.eq(zero);
                sn = F::select(rz, zero, ei / r);
                c = F::select(rz, one, p / r);
                p = c * di - sn * g;
                let d1 = hh + sn * (c * g + sn * di);
                F::select(active, d1, F::load(&s.d[i + 1])).store(&mut s.d[i + 1]);
                // Z ← Z G on columns i, i+1 (identity in lanes at rest).
                let (cs, ss) = (F::select(active, c, one), F::select(active, sn, zero));
                let (left, right) = s.z.split_at_mut((i + 1) * n);
                for (a, b) in left[i * n..].iter_mut().zip(right[..n].iter_mut()) {
                    let (x, y) = (F::load(a), F::load(b));
                    (ss * x + cs * y).store(b);
                    (cs * x - ss * y).store(a);
                }
            }
            let pl = -sn * s2 * c3 * el1 * el / dl1;
            F::select(active, sn * pl, el).store(&mut s.e[l]);
            F::select(active, c * pl, F::load(&s.d[l])).store(&mut s.d[l]);
        }
        (F::load(&s.d[l]) + f).store(&mut s.d[l]);
        s.e[l] = ZERO;
    }
    s.failed = failed;
}

/// Step 3a: per lane the eigenvalues descending and their columns of `z`.
fn sort(s: &mut EighLanes) {
    let n = s.n;
    for ln in 0..LANES {
        let order = &mut s.order[ln];
        order.clear();
        order.extend(0..n);
        let d = &s.d;
        order.sort_by(|&a, &b| d[b][ln].total_cmp(&d[a][ln]));
        for (v, &i) in s.values[ln].iter_mut().zip(order.iter()) {
            *v = d[i][ln];
        }
    }
}

/// Step 3b: the k leading eigenvectors x = Q z into `yr`/`yi`.
#[inline(always)]
fn back_transform<F: F8>(s: &mut EighLanes, k: usize) {
    let n = s.n;
    for c in 0..k {
        for row in 0..n {
            s.yr[c * n + row] = std::array::from_fn(|ln| s.z[s.order[ln][c] * n + row][ln]);
            s.yi[c * n + row] = ZERO;
        }
    }
    let zero = F::splat(0.0);
    for j in (0..n.saturating_sub(1)).rev() {
        let len = n - j - 1;
        let h0 = j * n + j + 1;
        let (vr, vi) = (&s.hr[h0..h0 + len], &s.hi[h0..h0 + len]);
        let (tr, ti) = (F::load(&s.tr[j]), F::load(&s.ti[j]));
        for c in 0..k {
            let y0 = c * n + j + 1;
            let (yr, yi) = (&mut s.yr[y0..y0 + len], &mut s.yi[y0..y0 + len]);
            // f = −τ (vᴴ y); y ← y + f v.
            let (mut dr, mut di) = (zero, zero);
            for r in 0..len {
                let (a, b) = (F::load(&vr[r]), F::load(&vi[r]));
                let (x, y) = (F::load(&yr[r]), F::load(&yi[r]));
                dr = dr + (a * x + b * y);
                di = di + (a * y - b * x);
            }
            let (fr, fi) = (-(tr * dr - ti * di), -(tr * di + ti * dr));
            for r in 0..len {
                let (a, b) = (F::load(&vr[r]), F::load(&vi[r]));
                (F::load(&yr[r]) + (fr * a - fi * b)).store(&mut yr[r]);
                (F::load(&yi[r]) + (fr * b + fi * a)).store(&mut yi[r]);
            }
        }
    }
}

#[cfg(test)]
mod tests;
