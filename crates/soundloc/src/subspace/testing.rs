//! Test matrices and checks shared by the eigensolvers' tests ([`super::eigh`],
//! [`super::eigh_lanes`]).

use crate::real::C;
use rand::Rng;

type Z = C<f64>;

/// A random Hermitian Σ_s σ_s u_s u_sᴴ + floor·I + a small random Hermitian.
pub(crate) fn scene(
    n: usize,
    strong: &[f64],
    floor: f64,
    jitter: f64,
    rng: &mut rand::rngs::StdRng,
) -> Vec<Z> {
    let mut a = vec![Z::new(0.0, 0.0); n * n];
    for &sigma in strong {
        let u: Vec<Z> = (0..n)
            .map(|_| Z::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0)))
            .collect();
        for i in 0..n {
            for j in 0..n {
                a[i * n + j] += u[i] * u[j].conj() * sigma;
            }
        }
    }
    for i in 0..n {
        a[i * n + i] += Z::new(floor, 0.0);
        for j in 0..=i {
            let z = Z::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0)) * jitter;
            let z = if i == j { Z::new(z.re, 0.0) } else { z };
            a[i * n + j] += z;
            if i != j {
                a[j * n + i] += z.conj();
            }
        }
    }
    a
}

/// faer's full decomposition: eigenvalues descending, vectors in that order.
pub(crate) fn reference(a: &[Z], n: usize) -> (Vec<f64>, faer::Mat<Z>) {
    let m = faer::Mat::<Z>::from_fn(n, n, |i, j| a[i * n + j]);
    let evd = m.self_adjoint_eigen(faer::Side::Lower).unwrap();
    let vals: Vec<f64> = (0..n).rev().map(|i| evd.S()[i].re).collect();
    let u = faer::Mat::<Z>::from_fn(n, n, |i, j| evd.U()[(i, n - 1 - j)]);
    (vals, u)
}

/// Against faer: largest eigenvalue error and residual ‖A x − λ x‖ relative to ‖A‖,
/// orthonormality, and the k-subspace's distance to faer's (‖P − P_ref‖_max).
pub(crate) fn errors(a: &[Z], n: usize, k: usize, vals: &[f64], vecs: &[Z]) -> (f64, f64, f64, f64) {
    let (want, u) = reference(a, n);
    let norm = want.iter().fold(0.0f64, |x, v| x.max(v.abs())).max(1e-300);
    let val = want
        .iter()
        .zip(vals)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
        / norm;
    let (mut resid, mut orth, mut sub) = (0.0f64, 0.0f64, 0.0f64);
    for c in 0..k {
        let x = &vecs[c * n..(c + 1) * n];
        for i in 0..n {
            let ax: Z = (0..n).map(|j| a[i * n + j] * x[j]).sum();
            resid = resid.max((ax - x[i] * vals[c]).norm() / norm);
        }
        for q in 0..k {
            let y = &vecs[q * n..(q + 1) * n];
            let g: Z = x.iter().zip(y).map(|(a, b)| a.conj() * b).sum();
            orth = orth.max((g - Z::new(if q == c { 1.0 } else { 0.0 }, 0.0)).norm());
        }
    }
    for i in 0..n {
        for j in 0..n {
            let p: Z = (0..k).map(|c| vecs[c * n + i] * vecs[c * n + j].conj()).sum();
            let q: Z = (0..k).map(|c| u[(i, c)] * u[(j, c)].conj()).sum();
            sub = sub.max((p - q).norm());
        }
    }
    (val, resid, orth, sub)
}
