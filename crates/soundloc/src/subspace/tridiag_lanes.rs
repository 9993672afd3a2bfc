//! Householder tridiagonalisation of eight n × n Hermitian matrices at once, one per f64
//! vector lane: step 1 of [`super::eigh`] for arrays of more than 16 microphones, where a
//! window's bins give many problems of one size.
//!
//! LAPACK `zhetd2` (lower): A = Q T Qᴴ, Q = H₀ ⋯ H_{n−2}, H_j = I − τ_j v_j v_jᴴ. Per step
//! j, with x = A[j+1.., j] = (α, x₂…): β = −sign(α_re)·‖x‖, τ = (β − α)/β,
//! v = (1, x₂…/(α − β)); then p = τ A₂₂ v, w = p − ½ τ (pᴴv) v, A₂₂ ← A₂₂ − v wᴴ − w vᴴ.
//! A column already reduced (x₂… = 0, α real) keeps H = I (τ = 0) without a branch.
//!
//! One problem at a time ([`super::eigh`]'s row kernels) the rows' lengths fall from n to
//! 1, so the vectors run part-empty and every dot product ends in a horizontal sum; here
//! each operation acts on the same element of eight problems, always full. Only the lower
//! triangle is stored, packed by rows (entry (i, c), c ≤ i, at i(i+1)/2 + c; 234 KB for
//! eight 60 × 60 problems, within a core's L2): p = A₂₂ v reads each entry once, as a
//! dot-product term for its row and a mirrored axpy term for its column, and the rank-2
//! update touches each once: two complex multiply-adds per entry in each (≈ 2n³/3 per
//! problem in all, zhetrd's 16n³/3 real flops).
//!
//! The two O(n²) passes per step run two rows at a time, as fused multiply-adds
//! (`F8::mul_add`: one rounding on every instruction set), so AVX-512, AVX2 with FMA and
//! the baseline build give the same bits, and a lane's result does not depend on which
//! problems share its group. (The diagonal's imaginary part, which the rank-2 update's
//! fused terms may leave at rounding level, is never read: T's diagonal is real.)

use super::eigh::Eigh;
use super::v8::{self, F8};
use crate::real::C;
use crate::{Error, Result};

/// Problems per group: eight f64 lanes.
pub const LANES: usize = 8;

/// One value per lane.
type V = [f64; LANES];
const ZERO: V = [0.0; LANES];

/// Scratch of one group of up to [`LANES`] n × n problems.
pub struct TridiagLanes {
    n: usize,
    /// Problems loaded (the other lanes repeat lane 0).
    used: usize,
    /// The loaded problems' lower triangles, packed by rows, one after the other.
    stage_re: Vec<f64>,
    stage_im: Vec<f64>,
    /// The matrices' lower triangles, packed by rows, in lanes; after the reduction column
    /// j below the diagonal holds v_j.
    re: Vec<V>,
    im: Vec<V>,
    /// τ_j.
    tr: Vec<V>,
    ti: Vec<V>,
    /// T: diagonal and real subdiagonal (e[j] couples j and j+1; e[n−1] = 0).
    d: Vec<V>,
    e: Vec<V>,
    /// Scratch: v and p (then w) of the current step.
    vr: Vec<V>,
    vi: Vec<V>,
    /// −Im v.
    vn: Vec<V>,
    pr: Vec<V>,
    pi: Vec<V>,
}

/// Where entry (i, c), c ≤ i, of the packed lower triangle sits.
#[inline(always)]
fn at(i: usize, c: usize) -> usize {
    i * (i + 1) / 2 + c
}

impl TridiagLanes {
    /// Scratch for n × n problems.
    pub fn new(n: usize) -> Self {
        let v = |len: usize| vec![ZERO; len];
        TridiagLanes {
            n,
            used: 0,
            stage_re: vec![0.0; LANES * at(n, 0)],
            stage_im: vec![0.0; LANES * at(n, 0)],
            re: v(at(n, 0)),
            im: v(at(n, 0)),
            tr: v(n),
            ti: v(n),
            d: v(n),
            e: v(n),
            vr: v(n),
            vi: v(n),
            vn: v(n),
            pr: v(n),
            pi: v(n),
        }
    }

    /// Start a new group.
    pub fn clear(&mut self) {
        self.used = 0;
    }

    /// Add a problem: A as row-major split parts (n × n, Hermitian: its lower triangle and
    /// the real part of its diagonal are used). Returns its lane; a non-finite entry
    /// anywhere is an error (and the problem is not added).
    pub fn push(&mut self, ar: &[f64], ai: &[f64]) -> Result<usize> {
        let n = self.n;
        assert!(self.used < LANES, "tridiag_lanes: group full");
        assert!(ar.len() >= n * n && ai.len() >= n * n);
        // Every entry, as the one-problem solver checks (without early exits: the check
        // vectorises).
        let finite = ar[..n * n]
            .iter()
            .chain(&ai[..n * n])
            .fold(true, |f, x| f & x.is_finite());
        if !finite {
            return Err(Error::numerical(
                "decompose",
                "the matrix holds non-finite values",
            ));
        }
        let lane = self.used;
        let size = at(n, 0);
        let (sr, si) = (
            &mut self.stage_re[lane * size..(lane + 1) * size],
            &mut self.stage_im[lane * size..(lane + 1) * size],
        );
        for i in 0..n {
            let (row, dst) = (i * n, at(i, 0));
            sr[dst..=dst + i].copy_from_slice(&ar[row..=row + i]);
            si[dst..dst + i].copy_from_slice(&ai[row..row + i]);
            si[dst + i] = 0.0;
        }
        self.used += 1;
        Ok(lane)
    }

    /// Reduce every loaded problem to tridiagonal form (idle lanes repeat lane 0).
    pub fn reduce(&mut self) {
        if self.used == 0 || self.n == 0 {
            return;
        }
        // The staged problems into the lanes: eight sequential reads per written entry.
        let size = at(self.n, 0);
        let src: [usize; LANES] = std::array::from_fn(|l| if l < self.used { l * size } else { 0 });
        for k in 0..size {
            self.re[k] = src.map(|o| self.stage_re[o + k]);
            self.im[k] = src.map(|o| self.stage_im[o + k]);
        }
        reduce_lanes(self);
    }

    /// Hand problem `lane`'s T and Q over to `eigh` (an n × n solver), ready for
    /// `Eigh::finish_reduced_many`.
    pub fn store(&self, lane: usize, eigh: &mut Eigh) {
        let n = self.n;
        assert!(lane < self.used, "tridiag_lanes: lane {lane} not loaded");
        let r = eigh.reduced_mut();
        assert!(r.diag.len() == n, "tridiag_lanes: solver of another size");
        for j in 0..n {
            r.diag[j] = self.d[j][lane];
            r.off[j] = self.e[j][lane];
            r.tau[j] = C::new(self.tr[j][lane], self.ti[j][lane]);
            // v_j into row j right of the diagonal, where the back-transformation reads it.
            for i in j + 1..n {
                r.re[j * n + i] = self.re[at(i, j)][lane];
                r.im[j * n + i] = self.im[at(i, j)][lane];
            }
        }
    }
}

/// [`reduce_with`] with the lane type the CPU has.
fn reduce_lanes(s: &mut TridiagLanes) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU supports AVX-512F (checked just above).
            return unsafe { reduce_avx512(s) };
        }
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
            // SAFETY: the CPU supports AVX2 and FMA (checked just above).
            return unsafe { reduce_avx2(s) };
        }
    }
    reduce_with::<v8::Scalar>(s)
}

/// [`reduce_with`] in AVX-512 registers (the caller checks the CPU).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn reduce_avx512(s: &mut TridiagLanes) {
    reduce_with::<v8::Avx512>(s)
}

/// [`reduce_with`] in AVX2 registers (the caller checks the CPU).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn reduce_avx2(s: &mut TridiagLanes) {
    reduce_with::<v8::Avx2>(s)
}

/// The reduction (module docs) over lane type `F`.
#[inline(always)]
fn reduce_with<F: F8>(s: &mut TridiagLanes) {
    let n = s.n;
    let zero = F::splat(0.0);
    for j in 0..n {
        s.d[j] = s.re[at(j, j)];
        s.e[j] = ZERO;
        s.tr[j] = ZERO;
        s.ti[j] = ZERO;
        if j + 1 >= n {
            break;
        }
        let len = n - j - 1;
        // x = A[j+1.., j]: column j below the diagonal.
        let x = |i: usize| at(j + 1 + i, j);
        let (ar, ai) = (F::load(&s.re[x(0)]), F::load(&s.im[x(0)]));
        let mut xnorm2 = zero;
        for i in 1..len {
            let (xr, xi) = (F::load(&s.re[x(i)]), F::load(&s.im[x(i)]));
            xnorm2 = xnorm2 + (xr * xr + xi * xi);
        }
        let (beta, (taur, taui), (scr, sci)) = reflector(ar, ai, xnorm2);
        beta.store(&mut s.e[j]);
        taur.store(&mut s.tr[j]);
        taui.store(&mut s.ti[j]);
        // v: 1, then x scaled; kept in column j (no longer needed as A).
        let (vr, vi) = (&mut s.vr[..len], &mut s.vi[..len]);
        vr[0] = [1.0; LANES];
        vi[0] = ZERO;
        for i in 1..len {
            let (xr, xi) = (F::load(&s.re[x(i)]), F::load(&s.im[x(i)]));
            (xr * scr - xi * sci).store(&mut vr[i]);
            (xr * sci + xi * scr).store(&mut vi[i]);
        }
        for i in 0..len {
            s.re[x(i)] = vr[i];
            s.im[x(i)] = vi[i];
        }
        for i in 0..len {
            (-F::load(&s.vi[i])).store(&mut s.vn[i]);
        }
        let (vr, vi, vn) = (&s.vr[..len], &s.vi[..len], &s.vn[..len]);
        // q = A₂₂ v from the lower triangle, two rows at a time.
        let (pr, pi) = (&mut s.pr[..len], &mut s.pi[..len]);
        let v = (vr, vi, vn);
        let row = |r: usize| at(j + 1 + r, j + 1);
        let mut r = 0;
        while r + 1 < len {
            matvec_rows::<F, 2>((&s.re, &s.im), [row(r), row(r + 1)], r, v, (pr, pi));
            r += 2;
        }
        if r < len {
            matvec_rows::<F, 1>((&s.re, &s.im), [row(r)], r, v, (pr, pi));
        }
        // p = τ q.
        for r in 0..len {
            let (q1, q2) = (F::load(&pr[r]), F::load(&pi[r]));
            (taur * q1 - taui * q2).store(&mut pr[r]);
            (taur * q2 + taui * q1).store(&mut pi[r]);
        }
        // w = p + a v, a = −½ τ (pᴴ v).
        let (mut dr, mut di) = (zero, zero);
        for r in 0..len {
            let (p, q) = (F::load(&pr[r]), F::load(&pi[r]));
            let (x1, x2) = (F::load(&vr[r]), F::load(&vi[r]));
            dr = dr + (p * x1 + q * x2);
            di = di + (p * x2 - q * x1);
        }
        let half = F::splat(-0.5);
        let (a0, a1) = (half * (taur * dr - taui * di), half * (taur * di + taui * dr));
        for r in 0..len {
            let (x1, x2) = (F::load(&vr[r]), F::load(&vi[r]));
            (F::load(&pr[r]) + (a0 * x1 - a1 * x2)).store(&mut pr[r]);
            (F::load(&pi[r]) + (a0 * x2 + a1 * x1)).store(&mut pi[r]);
        }
        // A₂₂ ← A₂₂ − v wᴴ − w vᴴ on the lower triangle, two rows at a time.
        let vw = (vr, vi, &s.pr[..len], &s.pi[..len]);
        let mut r = 0;
        while r + 1 < len {
            rank2_rows::<F, 2>((&mut s.re, &mut s.im), [row(r), row(r + 1)], r, vw);
            r += 2;
        }
        if r < len {
            rank2_rows::<F, 1>((&mut s.re, &mut s.im), [row(r)], r, vw);
        }
    }
}

/// LAPACK `zlarfg` in lanes, from α (the column's first entry below the diagonal) and
/// ‖x₂…‖²: β = −sign(α_re)·‖(α, x)‖ (T's subdiagonal entry), τ = (β − α)/β, and the scale
/// 1/(α − β) = conj(α − β)/|α − β|² of v = (1, x₂…/(α − β)). A column already reduced
/// (x₂… = 0, α real) keeps H = I without a branch: β = α, τ = 0, scale 0 (the other
/// values' 0/0 are discarded). Also [`super::eigh_lanes`]'s, with the same operations.
#[inline(always)]
pub(super) fn reflector<F: F8>(ar: F, ai: F, xnorm2: F) -> (F, (F, F), (F, F)) {
    let zero = F::splat(0.0);
    let reduced = F::and(xnorm2.eq(zero), ai.eq(zero));
    let nrm = (ar * ar + ai * ai + xnorm2).sqrt();
    let b = F::select(ar.lt(zero), nrm, -nrm);
    let (dr, di) = (ar - b, ai);
    let den = dr * dr + di * di;
    (
        F::select(reduced, ar, b),
        (
            F::select(reduced, zero, (b - ar) / b),
            F::select(reduced, zero, -ai / b),
        ),
        (
            F::select(reduced, zero, dr / den),
            F::select(reduced, zero, -di / den),
        ),
    )
}

/// Rows r … r+R−1 of q = A₂₂ v (`start`: where each row's column 0 of A₂₂ sits; `v`:
/// its real part, imaginary part and negated imaginary part): their dot products with v
/// left of the block, the mirrored terms conj(A_kc) v_k into q_c for c < r, the block's
/// own triangle and diagonal. Each row's q is assigned (later rows add their mirrored
/// terms to it); four accumulators per row keep the fused multiply-adds' chains short.
#[inline(always)]
fn matvec_rows<F: F8, const R: usize>(
    a: (&[V], &[V]),
    start: [usize; R],
    r: usize,
    v: (&[V], &[V], &[V]),
    p: (&mut [V], &mut [V]),
) {
    let ((are, aim), (vr, vi, vn), (pr, pi)) = (a, v, p);
    let zero = F::splat(0.0);
    let v1: [F; R] = std::array::from_fn(|k| F::load(&vr[r + k]));
    let v2: [F; R] = std::array::from_fn(|k| F::load(&vi[r + k]));
    let nv1: [F; R] = std::array::from_fn(|k| -v1[k]);
    // q_k = (Σ a x₁, Σ b (−x₂), Σ a x₂, Σ b x₁): re = [0] + [1], im = [2] + [3].
    let mut q = [[zero; 4]; R];
    for c in 0..r {
        let (x1, x2, xn2) = (F::load(&vr[c]), F::load(&vi[c]), F::load(&vn[c]));
        let (mut p1, mut p2) = (F::load(&pr[c]), F::load(&pi[c]));
        for k in 0..R {
            let (a, b) = (F::load(&are[start[k] + c]), F::load(&aim[start[k] + c]));
            q[k][0] = a.mul_add(x1, q[k][0]);
            q[k][1] = b.mul_add(xn2, q[k][1]);
            q[k][2] = a.mul_add(x2, q[k][2]);
            q[k][3] = b.mul_add(x1, q[k][3]);
            // conj(A_kc) v_k = (a v₁ + b v₂) + i (a v₂ − b v₁)
            p1 = b.mul_add(v2[k], a.mul_add(v1[k], p1));
            p2 = b.mul_add(nv1[k], a.mul_add(v2[k], p2));
        }
        p1.store(&mut pr[c]);
        p2.store(&mut pi[c]);
    }
    // The block's own entries below its diagonal couple its rows both ways.
    for k in 0..R {
        for i in 0..k {
            let (a, b) = (F::load(&are[start[k] + r + i]), F::load(&aim[start[k] + r + i]));
            q[k][0] = a.mul_add(v1[i], q[k][0]);
            q[k][1] = b.mul_add(-v2[i], q[k][1]);
            q[k][2] = a.mul_add(v2[i], q[k][2]);
            q[k][3] = b.mul_add(v1[i], q[k][3]);
            q[i][0] = a.mul_add(v1[k], q[i][0]);
            q[i][1] = b.mul_add(v2[k], q[i][1]);
            q[i][2] = a.mul_add(v2[k], q[i][2]);
            q[i][3] = b.mul_add(nv1[k], q[i][3]);
        }
    }
    // The diagonal is real.
    for k in 0..R {
        let d = F::load(&are[start[k] + r + k]);
        d.mul_add(v1[k], q[k][0] + q[k][1]).store(&mut pr[r + k]);
        d.mul_add(v2[k], q[k][2] + q[k][3]).store(&mut pi[r + k]);
    }
}

/// Rows r … r+R−1 of A₂₂ ← A₂₂ − v wᴴ − w vᴴ (`vw`: v's and w's parts), columns 0 to
/// each row's diagonal, as fused multiply-adds on the stored entry.
#[inline(always)]
fn rank2_rows<F: F8, const R: usize>(
    a: (&mut [V], &mut [V]),
    start: [usize; R],
    r: usize,
    vw: (&[V], &[V], &[V], &[V]),
) {
    let ((are, aim), (vr, vi, wr, wi)) = (a, vw);
    let v1: [F; R] = std::array::from_fn(|k| F::load(&vr[r + k]));
    let v2: [F; R] = std::array::from_fn(|k| F::load(&vi[r + k]));
    let w1: [F; R] = std::array::from_fn(|k| F::load(&wr[r + k]));
    let w2: [F; R] = std::array::from_fn(|k| F::load(&wi[r + k]));
    let (nv1, nv2, nw1, nw2) = (v1.map(|x| -x), v2.map(|x| -x), w1.map(|x| -x), w2.map(|x| -x));
    let n = [nv1, nv2, nw1, nw2, v1, w1];
    for c in 0..=r {
        for k in 0..R {
            rank2_entry((are, aim), start[k] + c, (vr, vi, wr, wi), c, n.map(|x| x[k]));
        }
    }
    for k in 1..R {
        for c in r + 1..=r + k {
            rank2_entry((are, aim), start[k] + c, (vr, vi, wr, wi), c, n.map(|x| x[k]));
        }
    }
}

/// One entry of [`rank2_rows`]: A_kc −= v_k conj(w_c) + w_k conj(v_c), i.e.
/// re −= v₁y₁ + v₂y₂ + w₁x₁ + w₂x₂, im −= v₂y₁ − v₁y₂ + w₂x₁ − w₁x₂ (x = v_c, y = w_c;
/// `k`: −v₁, −v₂, −w₁, −w₂, v₁, w₁ of row k).
#[inline(always)]
fn rank2_entry<F: F8>(a: (&mut [V], &mut [V]), at: usize, vw: (&[V], &[V], &[V], &[V]), c: usize, k: [F; 6]) {
    let ((are, aim), (vr, vi, wr, wi)) = (a, vw);
    let [nv1, nv2, nw1, nw2, v1, w1] = k;
    let (x1, x2) = (F::load(&vr[c]), F::load(&vi[c]));
    let (y1, y2) = (F::load(&wr[c]), F::load(&wi[c]));
    let t = F::load(&are[at]);
    let t = nw2.mul_add(x2, nw1.mul_add(x1, nv2.mul_add(y2, nv1.mul_add(y1, t))));
    t.store(&mut are[at]);
    let u = F::load(&aim[at]);
    let u = w1.mul_add(x2, nw2.mul_add(x1, v1.mul_add(y2, nv2.mul_add(y1, u))));
    u.store(&mut aim[at]);
}

#[cfg(test)]
mod tests;
