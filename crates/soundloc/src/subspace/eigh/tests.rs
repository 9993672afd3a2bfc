//! Tests of [`super`]: against a full decomposition on MUSIC-like matrices, clusters and
//! exact multiplicity, every vector, and the errors.

use super::*;
use crate::subspace::testing::{self, reference};
use rand::{Rng, SeedableRng};

type Z = C<f64>;

/// [`testing::scene`] from a seed.
fn scene(n: usize, strong: &[f64], floor: f64, jitter: f64, seed: u64) -> Vec<Z> {
    testing::scene(
        n,
        strong,
        floor,
        jitter,
        &mut rand::rngs::StdRng::seed_from_u64(seed),
    )
}

/// A solver holding the row-major matrix `a`.
fn loaded(a: &[Z], n: usize) -> Eigh {
    let mut s = Eigh::new(n);
    let (re, im) = s.matrix_mut();
    for (i, z) in a.iter().enumerate() {
        re[i] = z.re;
        im[i] = z.im;
    }
    s
}

/// Solve `a` for k vectors; [`testing::errors`] against faer.
fn check(a: &[Z], n: usize, k: usize) -> (f64, f64, f64, f64) {
    let mut s = loaded(a, n);
    let mut vecs = vec![Z::new(0.0, 0.0); n * k];
    s.solve(k, &mut vecs).unwrap();
    testing::errors(a, n, k, s.values(), &vecs)
}

#[test]
fn matches_a_full_decomposition_on_music_like_matrices() {
    for (n, strong, k, seed) in [
        (8, vec![50.0, 20.0], 2, 1u64),
        (8, vec![50.0, 20.0], 4, 2),
        (8, vec![1e4, 3.0, 1.5], 8, 3),
        (16, vec![100.0, 90.0, 10.0], 5, 4),
        (60, vec![1e3, 300.0], 2, 5),
        (60, vec![1e3, 300.0, 40.0, 39.0], 30, 6),
        (60, vec![1e6, 2.0], 4, 7),
        (3, vec![5.0], 3, 8),
        (1, vec![5.0], 1, 9),
        (2, vec![], 2, 10),
    ] {
        let a = scene(n, &strong, 1.0, 0.05, seed);
        let (val, resid, orth, sub) = check(&a, n, k);
        let tol = 1e-12 * n as f64;
        assert!(val < tol, "n={n} k={k}: eigenvalues off by {val:e}");
        assert!(resid < tol, "n={n} k={k}: residual {resid:e}");
        assert!(orth < tol, "n={n} k={k}: orthonormality {orth:e}");
        if k == strong.len() {
            assert!(sub < 1e-9, "n={n} k={k}: signal subspace differs by {sub:e}");
        }
    }
}

#[test]
fn clusters_and_exact_multiplicity_give_orthonormal_vectors() {
    // Identity (every eigenvalue equal), rank-one plus identity, and a diagonal with
    // a tight cluster: inverse iteration must still return an orthonormal basis.
    for (n, strong, jitter, k) in [
        (12, vec![], 0.0, 12),
        (12, vec![10.0], 0.0, 6),
        (40, vec![], 1e-9, 20),
    ] {
        let a = scene(n, &strong, 1.0, jitter, 11);
        let (val, resid, orth, _) = check(&a, n, k);
        assert!(val < 1e-12, "n={n}: eigenvalues off by {val:e}");
        assert!(resid < 1e-10, "n={n}: residual {resid:e}");
        assert!(orth < 1e-10, "n={n}: orthonormality {orth:e}");
    }
    // Already diagonal (every Householder step is the identity) and zero.
    let n = 5;
    let mut a = vec![Z::new(0.0, 0.0); n * n];
    for i in 0..n {
        a[i * n + i] = Z::new(i as f64 - 2.0, 0.0);
    }
    let (val, resid, orth, _) = check(&a, n, n);
    assert!(val < 1e-15 && resid < 1e-15 && orth < 1e-15);
    let z = vec![Z::new(0.0, 0.0); 16];
    let (val, _, orth, _) = check(&z, 4, 4);
    assert!(val == 0.0 && orth < 1e-15);
}

/// Σ_noise |aᴴe_m| (the unsquared MUSIC denominator) depends on each noise vector, not
/// only on the subspace: it must match a full decomposition's vectors.
#[test]
fn every_vector_matches_a_full_decomposition() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(21);
    for (n, strong, jitter) in [
        (8, vec![40.0, 10.0], 0.3),
        (8, vec![40.0], 0.02),
        (60, vec![500.0, 80.0], 0.1),
    ] {
        let a = scene(n, &strong, 1.0, jitter, 13);
        let mut s = loaded(&a, n);
        let mut v = vec![Z::new(0.0, 0.0); n * n];
        s.solve(n, &mut v).unwrap();
        let (vals, u) = reference(&a, n);
        for c in 0..n {
            // Same vector up to a phase where the eigenvalue is isolated.
            let gap = (0..n)
                .filter(|&q| q != c)
                .map(|q| (vals[q] - vals[c]).abs())
                .fold(f64::INFINITY, f64::min);
            let ov: Z = (0..n).map(|i| v[c * n + i].conj() * u[(i, c)]).sum();
            let tol = 1e-10 * vals[0].abs() / gap;
            assert!(
                (ov.norm() - 1.0).abs() < tol.max(1e-12),
                "n={n} vector {c}: |overlap| {} (gap {gap:e})",
                ov.norm()
            );
        }
        for _ in 0..5 {
            let st: Vec<Z> = (0..n)
                .map(|_| Z::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0)))
                .collect();
            let ns = strong.len();
            let sum = |e: &dyn Fn(usize, usize) -> Z| -> f64 {
                (ns..n)
                    .map(|c| (0..n).map(|i| st[i].conj() * e(i, c)).sum::<Z>().norm())
                    .sum()
            };
            let mine = sum(&|i, c| v[c * n + i]);
            let want = sum(&|i, c| u[(i, c)]);
            assert!(
                (mine - want).abs() < 1e-9 * want,
                "n={n}: unsquared sum {mine} vs {want}"
            );
        }
    }
}

#[test]
fn non_finite_input_is_an_error_not_a_panic() {
    let mut s = Eigh::new(3);
    s.matrix_mut().0[4] = f64::NAN;
    let mut v = vec![Z::new(0.0, 0.0); 3];
    assert!(s.solve(1, &mut v).is_err());
}
