//! The real symmetric tridiagonal problem that [`super::eigh`] reduces to: all eigenvalues
//! (rational QL). Its inverse iteration solves with [`super::inverse_lanes`]; the one-shift
//! factorisation here (`TriLu`) is the tests' reference for it.

use crate::{Error, Result};

/// Eigenvalues of the symmetric tridiagonal with diagonal `d` and off-diagonal e (e[i]
/// couples i and i+1) into `d`, unsorted: the implicit QL method in its rational,
/// square-root free form (EISPACK `tqlrat`, the method of LAPACK `dsterf`'s QL branch).
/// `e2` holds e[i]² for i < n − 1 on entry (its last element is set to 0; it is
/// overwritten).
#[cfg(test)]
pub(super) fn ql_values(d: &mut [f64], e2: &mut [f64]) -> Result<()> {
    ql_values_many([(d, e2)])
}

/// [`ql_values`] for N problems at once, with the same results. Each QL sweep is a chain
/// of dependent divisions that leaves most of the core idle; the sweeps of the N problems
/// run side by side in one loop (for their common length), so the core overlaps the
/// chains.
pub(super) fn ql_values_many<const N: usize>(problems: [(&mut [f64], &mut [f64]); N]) -> Result<()> {
    let mut q = problems.map(|(d, e2)| Ql::new(d, e2));
    let mut run = [false; N];
    for (r, q) in run.iter_mut().zip(q.iter_mut()) {
        *r = q.next_sweep()?;
    }
    while run.iter().any(|&r| r) {
        // Sweep p runs i = m − 1 down to l (none where it has finished).
        let mut i: [usize; N] = std::array::from_fn(|p| if run[p] { q[p].m } else { q[p].l });
        let (mut g, mut h, mut s) = (
            q.each_ref().map(|q| q.g),
            q.each_ref().map(|q| q.h),
            q.each_ref().map(|q| q.s),
        );
        let both = (0..N).map(|p| i[p] - q[p].l).min().unwrap_or(0);
        for _ in 0..both {
            for p in 0..N {
                i[p] -= 1;
                let qp = &mut q[p];
                ql_step(qp.d, qp.e2, i[p], qp.b, &mut g[p], &mut h[p], &mut s[p]);
            }
        }
        for p in 0..N {
            let qp = &mut q[p];
            while i[p] > qp.l {
                i[p] -= 1;
                ql_step(qp.d, qp.e2, i[p], qp.b, &mut g[p], &mut h[p], &mut s[p]);
            }
            if run[p] {
                (qp.g, qp.h, qp.s) = (g[p], h[p], s[p]);
                qp.end_sweep();
                run[p] = qp.next_sweep()?;
            }
        }
    }
    for qp in q {
        qp.finish()?;
    }
    Ok(())
}

/// One step i of a rational QL sweep (EISPACK `tqlrat`'s inner loop).
#[inline(always)]
fn ql_step(d: &mut [f64], e2: &mut [f64], i: usize, b: f64, g: &mut f64, h: &mut f64, s: &mut f64) {
    let p = *g * *h;
    let r = p + e2[i];
    e2[i + 1] = *s * r;
    *s = e2[i] / r;
    d[i + 1] = *h + *s * (*h + d[i]);
    *g = d[i] - e2[i] / *g;
    if *g == 0.0 {
        *g = b;
    }
    *h = *g * p / r;
}

/// `tqlrat` as a resumable state: [`Ql::next_sweep`] sets up the next sweep over
/// l … m − 1 (the caller runs [`ql_step`] for i = m − 1 down to l), [`Ql::end_sweep`]
/// checks it for convergence.
struct Ql<'a> {
    d: &'a mut [f64],
    e2: &'a mut [f64],
    /// The eigenvalue being found and the end of its unreduced block.
    l: usize,
    m: usize,
    /// Sweeps spent on l.
    j: u32,
    /// Whether l's sweeps have begun.
    started: bool,
    f: f64,
    t: f64,
    b: f64,
    c: f64,
    /// The sweep's running values.
    g: f64,
    h: f64,
    s: f64,
}

impl<'a> Ql<'a> {
    fn new(d: &'a mut [f64], e2: &'a mut [f64]) -> Self {
        let n = d.len();
        if n > 0 {
            e2[n - 1] = 0.0;
        }
        Ql {
            d,
            e2,
            l: 0,
            m: 0,
            j: 0,
            started: false,
            f: 0.0,
            t: 0.0,
            b: 0.0,
            c: 0.0,
            g: 0.0,
            h: 0.0,
            s: 0.0,
        }
    }

    /// The first m ≥ l whose squared subdiagonal is negligible.
    fn block_end(&self) -> usize {
        let n = self.d.len();
        let mut m = self.l;
        while m < n - 1 && self.e2[m] > self.c {
            m += 1;
        }
        m
    }

    /// Set up the next sweep (shift applied; `g`, `h`, `s` initialised): false when every
    /// eigenvalue is found.
    fn next_sweep(&mut self) -> Result<bool> {
        let n = self.d.len();
        if n < 2 {
            return Ok(false);
        }
        loop {
            if !self.started {
                if self.l == n {
                    return Ok(false);
                }
                let l = self.l;
                self.j = 0;
                let h = self.d[l].abs() + self.e2[l].sqrt();
                if self.t < h {
                    self.t = h;
                    self.b = f64::EPSILON * self.t;
                    self.c = self.b * self.b;
                }
                self.m = self.block_end();
                if self.m == l {
                    self.d[l] += self.f;
                    self.l += 1;
                    continue;
                }
                self.started = true;
            }
            if self.j == 60 {
                return Err(Error::numerical(
                    "decompose",
                    "tridiagonal QL did not converge in 60 iterations",
                ));
            }
            self.j += 1;
            let (l, m) = (self.l, self.m);
            let d = &mut *self.d;
            // Form the shift.
            let s = self.e2[l].sqrt();
            let g = d[l];
            let p = (d[l + 1] - g) / (2.0 * s);
            let r = (p * p + 1.0).sqrt();
            d[l] = s / (p + if p >= 0.0 { r } else { -r });
            let h = g - d[l];
            for di in &mut d[l + 1..] {
                *di -= h;
            }
            self.f += h;
            // The rational QL transformation's start.
            let mut g = d[m];
            if g == 0.0 {
                g = self.b;
            }
            (self.g, self.h, self.s) = (g, g, 0.0);
            return Ok(true);
        }
    }

    /// After a sweep: whether l converged (then the next [`Ql::next_sweep`] moves on).
    fn end_sweep(&mut self) {
        let l = self.l;
        self.e2[l] = self.s * self.g;
        self.d[l] = self.h;
        let h = self.h;
        // Guard against underflow in the convergence test.
        let done = if h == 0.0 || self.e2[l].abs() <= (self.c / h).abs() {
            true
        } else {
            self.e2[l] *= h;
            // Look again for a small squared subdiagonal element.
            self.e2[l] == 0.0 || {
                self.m = self.block_end();
                self.m == l
            }
        };
        if done {
            self.d[l] += self.f;
            self.l += 1;
            self.started = false;
        }
    }

    fn finish(self) -> Result<()> {
        if self.d.iter().any(|x| !x.is_finite()) {
            return Err(Error::numerical("decompose", "non-finite eigenvalue"));
        }
        Ok(())
    }
}

/// LU factorisation with partial pivoting of a shifted tridiagonal T − λI (LAPACK
/// `dgttrf`), for inverse iteration, one shift at a time; zero pivots are replaced by a
/// tiny value. The reference for [`super::inverse_lanes`], which solves for eight shifts
/// at once with the same bits in each.
#[cfg(test)]
pub(super) struct TriLu {
    dl: Vec<f64>,
    dd: Vec<f64>,
    du: Vec<f64>,
    du2: Vec<f64>,
    swap: Vec<bool>,
}

#[cfg(test)]
impl TriLu {
    pub(super) fn new(n: usize) -> Self {
        TriLu {
            dl: vec![0.0; n],
            dd: vec![0.0; n],
            du: vec![0.0; n],
            du2: vec![0.0; n],
            swap: vec![false; n],
        }
    }

    pub(super) fn factor(&mut self, d: &[f64], e: &[f64], lam: f64, tiny: f64) {
        let n = d.len();
        for i in 0..n {
            self.dd[i] = d[i] - lam;
            self.dl[i] = if i + 1 < n { e[i] } else { 0.0 };
            self.du[i] = if i + 1 < n { e[i] } else { 0.0 };
            self.du2[i] = 0.0;
            self.swap[i] = false;
        }
        for i in 0..n.saturating_sub(1) {
            if self.dd[i].abs() >= self.dl[i].abs() {
                if self.dd[i] == 0.0 {
                    self.dd[i] = tiny;
                }
                let fact = self.dl[i] / self.dd[i];
                self.dl[i] = fact;
                self.dd[i + 1] -= fact * self.du[i];
            } else {
                let fact = self.dd[i] / self.dl[i];
                self.dd[i] = self.dl[i];
                self.dl[i] = fact;
                let temp = self.du[i];
                self.du[i] = self.dd[i + 1];
                self.dd[i + 1] = temp - fact * self.dd[i + 1];
                if i + 2 < n {
                    self.du2[i] = self.du[i + 1];
                    self.du[i + 1] *= -fact;
                }
                self.swap[i] = true;
            }
        }
        if self.dd[n - 1] == 0.0 {
            self.dd[n - 1] = tiny;
        }
    }

    /// Row i of the back substitution (with the rescale after an overflow).
    #[inline(always)]
    fn back_step(&self, x: &mut [f64], i: usize) {
        let n = x.len();
        let mut v = x[i];
        if i + 1 < n {
            v -= self.du[i] * x[i + 1];
        }
        if i + 2 < n {
            v -= self.du2[i] * x[i + 2];
        }
        x[i] = v / self.dd[i];
        if !x[i].is_finite() {
            // Overflow from a tiny pivot: the vector is all but found; rescale.
            let mx = x
                .iter()
                .fold(0.0f64, |a, v| if v.is_finite() { a.max(v.abs()) } else { a });
            let s = if mx > 0.0 { 1.0 / mx } else { 1.0 };
            for v in x.iter_mut() {
                *v = if v.is_finite() { *v * s } else { v.signum() };
            }
        }
    }

    /// x ← (T − λI)⁻¹ x.
    pub(super) fn solve(&self, x: &mut [f64]) {
        let n = x.len();
        for i in 0..n.saturating_sub(1) {
            if self.swap[i] {
                let t = x[i];
                x[i] = x[i + 1];
                x[i + 1] = t - self.dl[i] * x[i];
            } else {
                x[i + 1] -= self.dl[i] * x[i];
            }
        }
        for i in (0..n).rev() {
            self.back_step(x, i);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// tqlrat as it was written before it became a resumable state (straight-line EISPACK
    /// form), the reference for the test below.
    fn straight_line_ql(d: &mut [f64], e2: &mut [f64]) -> Result<()> {
        let n = d.len();
        if n < 2 {
            return Ok(());
        }
        e2[n - 1] = 0.0;
        let (mut f, mut t) = (0.0f64, 0.0f64);
        let (mut b, mut c) = (0.0f64, 0.0f64);
        for l in 0..n {
            let mut j = 0;
            let h = d[l].abs() + e2[l].sqrt();
            if t < h {
                t = h;
                b = f64::EPSILON * t;
                c = b * b;
            }
            let mut m = l;
            while m < n - 1 && e2[m] > c {
                m += 1;
            }
            if m != l {
                loop {
                    if j == 60 {
                        return Err(Error::numerical(
                            "decompose",
                            "tridiagonal QL did not converge in 60 iterations",
                        ));
                    }
                    j += 1;
                    // Form the shift.
                    let s = e2[l].sqrt();
                    let g = d[l];
                    let p = (d[l + 1] - g) / (2.0 * s);
                    let r = (p * p + 1.0).sqrt();
                    d[l] = s / (p + if p >= 0.0 { r } else { -r });
                    let h = g - d[l];
                    for di in &mut d[l + 1..] {
                        *di -= h;
                    }
                    f += h;
                    // Rational QL transformation.
                    let mut g = d[m];
                    if g == 0.0 {
                        g = b;
                    }
                    let mut h = g;
                    let mut s = 0.0;
                    for i in (l..m).rev() {
                        let p = g * h;
                        let r = p + e2[i];
                        e2[i + 1] = s * r;
                        s = e2[i] / r;
                        d[i + 1] = h + s * (h + d[i]);
                        g = d[i] - e2[i] / g;
                        if g == 0.0 {
                            g = b;
                        }
                        h = g * p / r;
                    }
                    e2[l] = s * g;
                    d[l] = h;
                    // Guard against underflow in the convergence test.
                    if h == 0.0 || e2[l].abs() <= (c / h).abs() {
                        break;
                    }
                    e2[l] *= h;
                    if e2[l] == 0.0 {
                        break;
                    }
                    // Look again for a small squared subdiagonal element.
                    m = l;
                    while m < n - 1 && e2[m] > c {
                        m += 1;
                    }
                    if m == l {
                        break;
                    }
                }
            }
            d[l] += f;
        }
        if d.iter().any(|x| !x.is_finite()) {
            return Err(Error::numerical("decompose", "non-finite eigenvalue"));
        }
        Ok(())
    }

    /// The resumable QL, alone and with two or three problems side by side, gives the same
    /// bits as the straight-line tqlrat, on random tridiagonals of sizes 1–70, some with
    /// zero couplings (split blocks) and repeated diagonals.
    #[test]
    fn resumable_ql_equals_the_straight_line_form() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let mut problem = |n: usize| -> (Vec<f64>, Vec<f64>) {
            let kind = rng.gen_range(0..3);
            let d: Vec<f64> = (0..n)
                .map(|i| {
                    if kind == 2 {
                        (i % 3) as f64
                    } else {
                        rng.gen_range(-2.0..2.0)
                    }
                })
                .collect();
            let e2: Vec<f64> = (0..n)
                .map(|i| {
                    if kind == 1 && i % 5 == 4 {
                        0.0
                    } else {
                        let e: f64 = rng.gen_range(-1.0..1.0);
                        e * e
                    }
                })
                .collect();
            (d, e2)
        };
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        for n in (1..=70).chain([60; 20]) {
            let probs: Vec<(Vec<f64>, Vec<f64>)> = (0..3).map(|k| problem(n + k % 2)).collect();
            let want: Vec<Vec<f64>> = probs
                .iter()
                .map(|(d, e2)| {
                    let (mut d, mut e2) = (d.clone(), e2.clone());
                    straight_line_ql(&mut d, &mut e2).unwrap();
                    d
                })
                .collect();
            let (mut d0, mut e0) = probs[0].clone();
            ql_values(&mut d0, &mut e0).unwrap();
            assert_eq!(bits(&d0), bits(&want[0]), "n {n}: alone");
            let [(mut a, mut ea), (mut b, mut eb), (mut c, mut ec)] =
                [probs[0].clone(), probs[1].clone(), probs[2].clone()];
            ql_values_many([(&mut a, &mut ea), (&mut b, &mut eb)]).unwrap();
            assert_eq!(
                (bits(&a), bits(&b)),
                (bits(&want[0]), bits(&want[1])),
                "n {n}: pair"
            );
            let [(mut a, mut ea), (mut b, mut eb)] = [probs[0].clone(), probs[1].clone()];
            ql_values_many([(&mut a, &mut ea), (&mut b, &mut eb), (&mut c, &mut ec)]).unwrap();
            assert_eq!(
                (bits(&a), bits(&b), bits(&c)),
                (bits(&want[0]), bits(&want[1]), bits(&want[2])),
                "n {n}: three"
            );
            // A real decomposition, not a no-op: the trace is kept.
            let tr: f64 = probs[0].0.iter().sum();
            let got: f64 = want[0].iter().sum();
            assert!(
                (tr - got).abs() <= 1e-9 * (1.0 + tr.abs()),
                "n {n}: trace {tr} vs {got}"
            );
        }
    }

    /// A solve solves: (T − λI) x = b for a well-conditioned shift.
    #[test]
    fn a_shifted_solve_solves() {
        let (d, e) = (vec![4.0, 5.0, 6.0, 7.0], vec![1.0, -0.5, 0.25]);
        let mut lu = TriLu::new(4);
        lu.factor(&d, &e, 0.5, f64::EPSILON);
        let b = [1.0, -2.0, 0.5, 3.0];
        let mut x = b.to_vec();
        lu.solve(&mut x);
        for i in 0..4 {
            let mut r = (d[i] - 0.5) * x[i];
            if i > 0 {
                r += e[i - 1] * x[i - 1];
            }
            if i + 1 < 4 {
                r += e[i] * x[i + 1];
            }
            assert!((r - b[i]).abs() < 1e-12, "row {i}: {r} vs {}", b[i]);
        }
    }
}
