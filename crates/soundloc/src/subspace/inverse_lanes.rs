//! The solves of inverse iteration for up to eight shifts of one real symmetric
//! tridiagonal T at once, one shift per f64 vector lane: x_l ← (T − λ_l I)⁻¹ x_l.
//!
//! T − λI = P L U with partial pivoting (LAPACK `dgttrf`): per row i the pivot is row i
//! or row i + 1, whichever has the larger entry in column i; L has one multiplier per row
//! and U two superdiagonals. The solve is the forward elimination with the same row
//! swaps, then the back substitution x_i = (y_i − u_i x_{i+1} − u2_i x_{i+2}) / d_i, a
//! chain of n dependent divisions. One shift at a time leaves the core waiting on that
//! chain; here eight chains run in one, and the lanes that pivot differently take their
//! values by selects, not branches. The operations of each lane are plain IEEE
//! subtractions, multiplications and divisions in the order of the one-shift form (the
//! reference `TriLu` in the tests), so for finite T and shifts every lane's result has the
//! same bits as that one shift alone, on every instruction set, whatever the other lanes
//! hold. (Callers check T for finiteness; with a NaN the pivot choice could differ.)
//!
//! A pivot that is exactly zero becomes `tiny`. Where a back substitution overflows (a
//! shift on an eigenvalue: the vector is all but found), that lane's vector is rescaled
//! by its largest finite entry, and infinite entries become ±1, as the one-shift form does.

use super::v8::{self, F8};

/// Shifts per call: eight f64 lanes.
pub(super) const LANES: usize = 8;

/// One value per lane.
pub(super) type V = [f64; LANES];

/// The factors of T − λ_l I for up to [`LANES`] shifts λ_l of one T.
#[derive(Default)]
pub(super) struct TriLuLanes {
    /// U's diagonal (pivots).
    dd: Vec<V>,
    /// L's multipliers.
    dl: Vec<V>,
    /// U's first superdiagonal.
    du: Vec<V>,
    /// U's second superdiagonal (nonzero only after a swap).
    du2: Vec<V>,
    /// 1.0 where rows i and i + 1 were swapped, else 0.0.
    swap: Vec<V>,
}

impl TriLuLanes {
    /// Factor T − λ_l I (T: diagonal `d`, off-diagonal `e`, e[i] coupling i and i + 1) for
    /// every lane's shift; lanes a caller does not use take any finite shift.
    pub(super) fn factor(&mut self, d: &[f64], e: &[f64], shifts: &V, tiny: f64) {
        self.fill(d, e, shifts);
        dispatch(self, None, tiny);
    }

    /// T − λ_l I into the factors' storage, before the factorisation.
    fn fill(&mut self, d: &[f64], e: &[f64], shifts: &V) {
        let n = d.len();
        for a in [
            &mut self.dd,
            &mut self.dl,
            &mut self.du,
            &mut self.du2,
            &mut self.swap,
        ] {
            a.clear();
            a.resize(n, [0.0; LANES]);
        }
        for i in 0..n {
            self.dd[i] = shifts.map(|l| d[i] - l);
            if i + 1 < n {
                self.dl[i] = [e[i]; LANES];
                self.du[i] = [e[i]; LANES];
            }
        }
    }

    /// x_l ← (T − λ_l I)⁻¹ x_l for every lane, `x` one row of lanes per entry.
    pub(super) fn solve(&mut self, x: &mut [V]) {
        assert_eq!(x.len(), self.dd.len(), "inverse_lanes: vector of another size");
        dispatch(self, Some(x), 0.0);
    }
}

/// [`factor_with`] (`x` None) or [`solve_with`] with the lane type the CPU has.
fn dispatch(s: &mut TriLuLanes, x: Option<&mut [V]>, tiny: f64) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU supports AVX-512F (checked just above).
            return unsafe { run_avx512(s, x, tiny) };
        }
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            return unsafe { run_avx2(s, x, tiny) };
        }
    }
    run_with::<v8::Scalar>(s, x, tiny)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn run_avx512(s: &mut TriLuLanes, x: Option<&mut [V]>, tiny: f64) {
    run_with::<v8::Avx512>(s, x, tiny)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn run_avx2(s: &mut TriLuLanes, x: Option<&mut [V]>, tiny: f64) {
    run_with::<v8::Avx2>(s, x, tiny)
}

#[inline(always)]
fn run_with<F: F8>(s: &mut TriLuLanes, x: Option<&mut [V]>, tiny: f64) {
    match x {
        None => factor_with::<F>(s, tiny),
        Some(x) => solve_with::<F>(s, x),
    }
}

/// The factorisation in place of `s` (which holds T − λI: `dd` its diagonal, `dl` = `du`
/// its off-diagonal, `du2` and `swap` zero).
#[inline(always)]
fn factor_with<F: F8>(s: &mut TriLuLanes, tiny: f64) {
    let n = s.dd.len();
    let (zero, one, tiny) = (F::splat(0.0), F::splat(1.0), F::splat(tiny));
    for i in 0..n.saturating_sub(1) {
        let ddi = F::load(&s.dd[i]);
        let dli = F::load(&s.dl[i]);
        let dui = F::load(&s.du[i]);
        let ddn = F::load(&s.dd[i + 1]);
        // Pivot on row i unless row i + 1's entry is larger (|d_i| ≥ |l_i| keeps).
        let sw = ddi.abs().lt(dli.abs());
        let ddz = F::select(ddi.eq(zero), tiny, ddi);
        let fact = F::select(sw, ddi, dli) / F::select(sw, dli, ddz);
        F::select(sw, dli, ddz).store(&mut s.dd[i]);
        fact.store(&mut s.dl[i]);
        F::select(sw, dui - fact * ddn, ddn - fact * dui).store(&mut s.dd[i + 1]);
        F::select(sw, ddn, dui).store(&mut s.du[i]);
        if i + 2 < n {
            let dun = F::load(&s.du[i + 1]);
            F::select(sw, dun, zero).store(&mut s.du2[i]);
            F::select(sw, dun * -fact, dun).store(&mut s.du[i + 1]);
        }
        F::select(sw, one, zero).store(&mut s.swap[i]);
    }
    if n > 0 {
        let d = F::load(&s.dd[n - 1]);
        F::select(d.eq(zero), tiny, d).store(&mut s.dd[n - 1]);
    }
}

/// Forward elimination with the factorisation's swaps, then back substitution.
#[inline(always)]
fn solve_with<F: F8>(s: &TriLuLanes, x: &mut [V]) {
    let n = x.len();
    let one = F::splat(1.0);
    for i in 0..n.saturating_sub(1) {
        let (xi, xn) = (F::load(&x[i]), F::load(&x[i + 1]));
        let dl = F::load(&s.dl[i]);
        let sw = F::load(&s.swap[i]).eq(one);
        F::select(sw, xn, xi).store(&mut x[i]);
        F::select(sw, xi - dl * xn, xn - dl * xi).store(&mut x[i + 1]);
    }
    let inf = F::splat(f64::INFINITY);
    for i in (0..n).rev() {
        let mut v = F::load(&x[i]);
        if i + 1 < n {
            v = v - F::load(&s.du[i]) * F::load(&x[i + 1]);
        }
        if i + 2 < n {
            v = v - F::load(&s.du2[i]) * F::load(&x[i + 2]);
        }
        let xi = v / F::load(&s.dd[i]);
        xi.store(&mut x[i]);
        let finite = F::lanes(xi.abs().lt(inf));
        if finite.contains(&false) {
            for (l, _) in finite.iter().enumerate().filter(|(_, f)| !**f) {
                rescale_lane(x, l);
            }
        }
    }
}

/// Lane `l` of `x` scaled by its largest finite entry; infinite entries become ±1.
#[cold]
fn rescale_lane(x: &mut [V], l: usize) {
    let mx = x.iter().fold(
        0.0f64,
        |a, r| {
            if r[l].is_finite() {
                a.max(r[l].abs())
            } else {
                a
            }
        },
    );
    let s = if mx > 0.0 { 1.0 / mx } else { 1.0 };
    for r in x.iter_mut() {
        r[l] = if r[l].is_finite() { r[l] * s } else { r[l].signum() };
    }
}

#[cfg(test)]
mod tests;
