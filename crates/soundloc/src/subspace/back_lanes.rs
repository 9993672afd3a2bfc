//! The back-transformation x = Q z of [`super::eigh`] for many vectors at once, eight
//! vectors side by side in the lanes of [`v8::F8`].
//!
//! Q = H₀ H₁ ⋯ H_{n−2}, H_j = I − τ_j v_j v_jᴴ with v_j on rows j+1 … n−1, is applied to
//! the k tridiagonal eigenvectors z (real) from the last reflector to the first: per
//! reflector and vector, f = −τ_j Σ_i conj(v_i) y_i (rows in order) and y_i += f v_i.
//! With the vectors in lanes each row's v_i is one broadcast for eight vectors, and the
//! sums and updates are plain lane arithmetic (no horizontal sums, no short loops per
//! vector): at the robust default's 30 vectors of 60 it replaces 1 770 pairs of short dot
//! products and updates per matrix. The same IEEE operations on every instruction set
//! (no fused multiply-add), so results do not depend on it.

use super::v8::{self, F8};
use crate::real::C;

/// Vectors per lane group.
const L: usize = 8;

/// Fewest vectors worth the lanes (below, [`super::eigh`] applies the reflectors per
/// vector).
pub(crate) const MIN_VECTORS: usize = L;

/// Q's reflectors: v_j in row j (columns j+1 …) of `re`/`im` (n × n row-major), τ_j in
/// `tau`.
pub(crate) struct Reflectors<'a> {
    pub n: usize,
    pub re: &'a [f64],
    pub im: &'a [f64],
    pub tau: &'a [C<f64>],
}

/// Scratch: the vectors in lanes, `[group][row]`, real and imaginary parts.
#[derive(Default)]
pub(crate) struct BackLanes {
    yr: Vec<[f64; L]>,
    yi: Vec<[f64; L]>,
}

impl BackLanes {
    /// x = Q z for the k vectors `z` (row c: z_c, n values) into `vectors` (n × k
    /// column-major).
    pub(crate) fn apply(&mut self, q: &Reflectors<'_>, k: usize, z: &[f64], vectors: &mut [C<f64>]) {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: the CPU supports AVX-512F (checked just above).
                return unsafe { self.apply_avx512(q, k, z, vectors) };
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU supports AVX2 (checked just above).
                return unsafe { self.apply_avx2(q, k, z, vectors) };
            }
        }
        self.apply_with::<v8::Scalar>(q, k, z, vectors)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    unsafe fn apply_avx512(&mut self, q: &Reflectors<'_>, k: usize, z: &[f64], vectors: &mut [C<f64>]) {
        self.apply_with::<v8::Avx512>(q, k, z, vectors)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn apply_avx2(&mut self, q: &Reflectors<'_>, k: usize, z: &[f64], vectors: &mut [C<f64>]) {
        self.apply_with::<v8::Avx2>(q, k, z, vectors)
    }

    #[inline(always)]
    fn apply_with<V: F8>(&mut self, q: &Reflectors<'_>, k: usize, z: &[f64], vectors: &mut [C<f64>]) {
        let Reflectors { n, re, im, tau } = *q;
        assert!(z.len() >= n * k && re.len() >= n * n && im.len() >= n * n && tau.len() + 1 >= n);
        assert!(vectors.len() >= n * k);
        let groups = k.div_ceil(L);
        self.yr.clear();
        self.yr.resize(groups * n, [0.0; L]);
        self.yi.clear();
        self.yi.resize(groups * n, [0.0; L]);
        for c in 0..k {
            for i in 0..n {
                self.yr[(c / L) * n + i][c % L] = z[c * n + i];
            }
        }
        for j in (0..n.saturating_sub(1)).rev() {
            let t = tau[j];
            if t == C::new(0.0, 0.0) {
                continue;
            }
            let (hr, hi) = (&re[j * n..(j + 1) * n], &im[j * n..(j + 1) * n]);
            let (tr, ti) = (V::splat(t.re), V::splat(t.im));
            for g in 0..groups {
                let (yr, yi) = (&mut self.yr[g * n..(g + 1) * n], &mut self.yi[g * n..(g + 1) * n]);
                // w = Σ_i conj(v_i) y_i
                let (mut wr, mut wi) = (V::splat(0.0), V::splat(0.0));
                for i in j + 1..n {
                    let (vr, vi) = (V::splat(hr[i]), V::splat(hi[i]));
                    let (ar, ai) = (V::load(&yr[i]), V::load(&yi[i]));
                    wr = wr + (vr * ar + vi * ai);
                    wi = wi + (vr * ai - vi * ar);
                }
                // f = −τ w; y_i += f v_i
                let fr = -(tr * wr - ti * wi);
                let fi = -(tr * wi + ti * wr);
                for i in j + 1..n {
                    let (vr, vi) = (V::splat(hr[i]), V::splat(hi[i]));
                    let (ar, ai) = (V::load(&yr[i]), V::load(&yi[i]));
                    (ar + (fr * vr - fi * vi)).store(&mut yr[i]);
                    (ai + (fr * vi + fi * vr)).store(&mut yi[i]);
                }
            }
        }
        for c in 0..k {
            for i in 0..n {
                let o = (c / L) * n + i;
                vectors[c * n + i] = C::new(self.yr[o][c % L], self.yi[o][c % L]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Every instruction set gives the same bits, equal to applying H_{n−2}, …, H₀ to each
    /// vector in turn in complex arithmetic (to rounding), for k off and on a group size.
    #[test]
    fn lanes_equal_the_reflectors_applied_per_vector() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        for (n, k) in [(9, 8), (24, 13), (60, 30), (64, 64)] {
            let mut u = || rng.gen_range(-1.0..1.0);
            let re: Vec<f64> = (0..n * n).map(|_| u()).collect();
            let im: Vec<f64> = (0..n * n).map(|_| u()).collect();
            let mut tau: Vec<C<f64>> = (0..n - 1).map(|_| C::new(u(), u())).collect();
            tau[n / 2] = C::new(0.0, 0.0); // a skipped reflector
            let z: Vec<f64> = (0..n * k).map(|_| u()).collect();
            // Reference: y ← H_j y for j = n−2 … 0, H_j = I − τ v vᴴ.
            let mut want = vec![C::new(0.0, 0.0); n * k];
            for c in 0..k {
                let mut y: Vec<C<f64>> = (0..n).map(|i| C::new(z[c * n + i], 0.0)).collect();
                for j in (0..n - 1).rev() {
                    let v: Vec<C<f64>> = (j + 1..n).map(|i| C::new(re[j * n + i], im[j * n + i])).collect();
                    let w: C<f64> = v.iter().zip(&y[j + 1..]).map(|(a, b)| a.conj() * b).sum();
                    for (yi, vi) in y[j + 1..].iter_mut().zip(&v) {
                        *yi -= tau[j] * w * vi;
                    }
                }
                want[c * n..(c + 1) * n].copy_from_slice(&y);
            }
            let mut runs: Vec<Vec<C<f64>>> = Vec::new();
            let mut b = BackLanes::default();
            let mut out = vec![C::new(0.0, 0.0); n * k];
            let q = Reflectors {
                n,
                re: &re,
                im: &im,
                tau: &tau,
            };
            b.apply_with::<v8::Scalar>(&q, k, &z, &mut out);
            runs.push(out.clone());
            #[cfg(target_arch = "x86_64")]
            {
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU has AVX2 (checked just above).
                    unsafe { b.apply_avx2(&q, k, &z, &mut out) };
                    runs.push(out.clone());
                } else {
                    println!("SKIPPED lanes_equal_the_reflectors_applied_per_vector (AVX2 part): no AVX2");
                }
                if std::arch::is_x86_feature_detected!("avx512f") {
                    // SAFETY: the CPU has AVX-512F (checked just above).
                    unsafe { b.apply_avx512(&q, k, &z, &mut out) };
                    runs.push(out.clone());
                } else {
                    println!(
                        "SKIPPED lanes_equal_the_reflectors_applied_per_vector (AVX-512 part): no AVX-512F"
                    );
                }
            }
            let scale = want.iter().map(|x| x.norm()).fold(0.0, f64::max);
            for (got, w) in runs[0].iter().zip(&want) {
                assert!((got - w).norm() <= 1e-12 * scale, "n {n} k {k}: {got} vs {w}");
            }
            let bits = |v: &[C<f64>]| {
                v.iter()
                    .flat_map(|x| [x.re.to_bits(), x.im.to_bits()])
                    .collect::<Vec<_>>()
            };
            for r in &runs[1..] {
                assert_eq!(bits(r), bits(&runs[0]), "n {n} k {k}: instruction sets differ");
            }
        }
    }
}
