//! The real symmetric tridiagonal problem that [`super::eigh`] reduces to: all eigenvalues
//! (rational QL) and the shifted LU factorisation its inverse iteration solves with.

use crate::{Error, Result};

/// Eigenvalues of the symmetric tridiagonal with diagonal `d` and off-diagonal e (e[i]
/// couples i and i+1) into `d`, unsorted: the implicit QL method in its rational,
/// square-root free form (EISPACK `tqlrat`, the method of LAPACK `dsterf`'s QL branch).
/// `e2` holds e[i]² for i < n − 1 on entry (its last element is set to 0; it is
/// overwritten).
pub(super) fn ql_values(d: &mut [f64], e2: &mut [f64]) -> Result<()> {
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

/// LU factorisation with partial pivoting of a shifted tridiagonal T − λI (LAPACK
/// `dgttrf`), for inverse iteration; zero pivots are replaced by a tiny value.
pub(super) struct TriLu {
    dl: Vec<f64>,
    dd: Vec<f64>,
    du: Vec<f64>,
    du2: Vec<f64>,
    swap: Vec<bool>,
}

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
    }
}
