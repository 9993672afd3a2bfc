//! Tests of [`super`]: each algorithm's decomposition against its definition, and a
//! group's results against one problem at a time.

use super::*;
use rand::{Rng, SeedableRng};

fn crandn<T: Real>(rng: &mut impl Rng) -> C<T> {
    C::new(
        T::of_f64(rng.gen_range(-1.0..1.0)),
        T::of_f64(rng.gen_range(-1.0..1.0)),
    )
}

/// A random Hermitian positive semi-definite X Xᴴ / n (row-major), rank `rank`.
fn random_r<T: Real>(m: usize, rank: usize, rng: &mut impl Rng) -> Vec<C<T>> {
    let x: Vec<C<T>> = (0..m * rank).map(|_| crandn(rng)).collect();
    let mut r = vec![C::new(T::zero(), T::zero()); m * m];
    for i in 0..m {
        for j in 0..m {
            let mut acc = C::new(T::zero(), T::zero());
            for k in 0..rank {
                acc += x[i * rank + k] * x[j * rank + k].conj();
            }
            r[i * m + j] = acc / T::of_f64(rank as f64);
        }
    }
    r
}

/// ‖EᴴE − I‖_max and the reconstruction error ‖A E − E Λ‖_max / ‖A‖ for eig, or
/// ‖A Aᴴ E − E Σ²‖ / ‖A‖² for the SVD's left vectors; values descending.
fn check<T: Real>(alg: Algorithm, m: usize, seed: u64) -> (f64, f64) {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let r = random_r::<T>(m, m + 10, &mut rng);
    let w: Vec<C<T>> = (0..m * m)
        .map(|k| {
            if k % (m + 1) == 0 {
                C::new(T::of_f64(2.0), T::zero())
            } else {
                crandn::<T>(&mut rng) * T::of_f64(0.05)
            }
        })
        .collect();
    // Hermitian, as every whitening matrix the plan builds for GEVD-HARK is (K^{-1/2}).
    let w: Vec<C<T>> = (0..m * m)
        .map(|k| (w[k] + w[(k % m) * m + k / m].conj()) * T::of_f64(0.5))
        .collect();
    // Lower triangular for GEVD, as the plan's L⁻¹ is.
    let w: Vec<C<T>> = if alg == Algorithm::Gevd {
        (0..m * m)
            .map(|k| {
                if k % m > k / m {
                    C::new(T::zero(), T::zero())
                } else {
                    w[k]
                }
            })
            .collect()
    } else {
        w
    };
    let mut ws = Workspace::new(m);
    let mut dec = Decomposition::<T>::new(m, m);
    let c64s =
        |v: &[C<T>]| -> Vec<c64> { v.iter().map(|z| c64::new(z.re.to_f64(), z.im.to_f64())).collect() };
    decompose(alg, &c64s(&r), Some(&c64s(&w)), &mut ws, &mut dec).unwrap();
    for k in 1..m {
        assert!(
            dec.values[k - 1] >= dec.values[k],
            "{alg:?}: values not descending at {k}"
        );
    }
    // The matrix actually decomposed, in f64.
    let to64 = |z: C<T>| num_complex::Complex::new(z.re.to_f64(), z.im.to_f64());
    let rm = |v: &[C<T>], i: usize, j: usize| to64(v[i * m + j]);
    let mul = |a: &dyn Fn(usize, usize) -> num_complex::Complex<f64>,
               b: &dyn Fn(usize, usize) -> num_complex::Complex<f64>| {
        let mut o = vec![num_complex::Complex::new(0.0, 0.0); m * m];
        for i in 0..m {
            for j in 0..m {
                for k in 0..m {
                    o[i * m + j] += a(i, k) * b(k, j);
                }
            }
        }
        o
    };
    let a: Vec<num_complex::Complex<f64>> = match alg {
        Algorithm::Sevd | Algorithm::SrpPhat => (0..m * m).map(|k| to64(r[k])).collect(),
        Algorithm::Gevd => {
            let wr = mul(&|i, j| rm(&w, i, j), &|i, j| rm(&r, i, j));
            mul(&|i, j| wr[i * m + j], &|i, j| rm(&w, j, i).conj())
        }
        Algorithm::GevdHark => {
            let wr = mul(&|i, j| rm(&w, i, j), &|i, j| rm(&r, i, j));
            mul(&|i, j| wr[i * m + j], &|i, j| rm(&w, i, j))
        }
        Algorithm::Gsvd => {
            let wr = mul(&|i, j| rm(&w, i, j), &|i, j| rm(&r, i, j));
            // A Aᴴ, whose eigenvectors are the left singular vectors.
            mul(&|i, j| wr[i * m + j], &|i, j| wr[j * m + i].conj())
        }
    };
    let norm = a.iter().map(|z| z.norm()).fold(0.0, f64::max);
    let e = |i: usize, k: usize| to64(dec.vectors[k * m + i]);
    let mut orth = 0.0f64;
    let mut recon = 0.0f64;
    for p in 0..m {
        for q in 0..m {
            let mut g = num_complex::Complex::new(0.0, 0.0);
            for i in 0..m {
                g += e(i, p).conj() * e(i, q);
            }
            let id = if p == q { 1.0 } else { 0.0 };
            orth = orth.max((g - id).norm());
        }
        let lam = dec.values[p].to_f64();
        let lam = if alg == Algorithm::Gsvd { lam * lam } else { lam };
        for i in 0..m {
            let mut ae = num_complex::Complex::new(0.0, 0.0);
            for k in 0..m {
                ae += a[i * m + k] * e(k, p);
            }
            recon = recon.max((ae - e(i, p) * lam).norm() / norm);
        }
    }
    (orth, recon)
}

fn all_algorithms<T: Real>() {
    for alg in Algorithm::MUSIC {
        for (m, seed) in [(8, 1), (60, 2)] {
            let (orth, recon) = check::<T>(alg, m, seed);
            let tol = 200.0 * T::EPS * m as f64;
            assert!(
                orth < tol,
                "{alg:?} M={m} {}: orthonormality {orth:e} > {tol:e}",
                T::NAME
            );
            assert!(
                recon < tol,
                "{alg:?} M={m} {}: reconstruction {recon:e} > {tol:e}",
                T::NAME
            );
        }
    }
}

/// Problems decomposed side by side (two and four) give the same bits as one at a
/// time (values and vectors in f64), for every algorithm, sizes 8 and 60, and unlike
/// matrices (full rank, rank 3, rank 1). GSVD with every vector (k = M) takes the
/// direct SVD either way.
#[test]
fn a_group_equals_single_decompositions() {
    let c64s = |v: &[C<f64>]| -> Vec<c64> { v.iter().map(|z| c64::new(z.re, z.im)).collect() };
    let bits = |d: &Decomposition<f64>| {
        let v: Vec<u64> = d
            .vectors64
            .iter()
            .flat_map(|z| [z.re.to_bits(), z.im.to_bits()])
            .collect();
        (v, d.values.iter().map(|x| x.to_bits()).collect::<Vec<_>>())
    };
    for alg in Algorithm::MUSIC {
        for (m, k, seed) in [(8, 2, 3u64), (8, 4, 7), (8, 8, 4), (60, 2, 5), (60, 30, 6)] {
            let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
            let rs: Vec<Vec<c64>> = [m + 10, 3, m + 1, 1]
                .iter()
                .map(|&rank| c64s(&random_r::<f64>(m, rank, &mut rng)))
                .collect();
            let w = c64s(&random_r::<f64>(m, 2 * m, &mut rng));
            // Lower triangular for GEVD, as the plan's L⁻¹ is.
            let w: Vec<c64> = (0..m * m)
                .map(|i| {
                    if alg == Algorithm::Gevd && i % m > i / m {
                        c64::new(0.0, 0.0)
                    } else {
                        w[i]
                    }
                })
                .collect();
            let mut ws = Workspace::new(m);
            let single: Vec<Decomposition<f64>> = rs
                .iter()
                .map(|r| {
                    let mut d = Decomposition::new(m, k);
                    decompose(alg, r, Some(&w), &mut ws, &mut d).unwrap();
                    d
                })
                .collect();
            // The first two, then all four, as one group.
            let group = |n: usize, ws: &mut Workspace| -> Vec<Decomposition<f64>> {
                let mut out: Vec<Decomposition<f64>> = (0..n).map(|_| Decomposition::new(m, k)).collect();
                let mut items: Vec<Item<'_, f64>> = rs
                    .iter()
                    .zip(out.iter_mut())
                    .map(|(r, out)| Item { r, w: Some(&w), out })
                    .collect();
                decompose_group(alg, &mut items, ws).unwrap();
                out
            };
            let (p, q) = (group(2, &mut ws), group(4, &mut ws));
            for (i, a) in single.iter().enumerate() {
                if i < 2 {
                    assert_eq!(bits(a), bits(&p[i]), "{alg:?} M {m} k {k}: pair, problem {i}");
                }
                assert_eq!(bits(a), bits(&q[i]), "{alg:?} M {m} k {k}: four, problem {i}");
                assert!(a.values[0] > 0.0, "{alg:?} M {m}: a trivial decomposition");
            }
        }
    }
}

#[test]
fn decompositions_are_orthonormal_sorted_and_reconstruct_f32() {
    all_algorithms::<f32>();
}

#[test]
fn decompositions_are_orthonormal_sorted_and_reconstruct_f64() {
    all_algorithms::<f64>();
}

/// A plan-like whitening matrix for `alg`: random Hermitian positive definite, lower
/// triangular for GEVD (as the plan's L⁻¹ is).
fn whitening(alg: Algorithm, m: usize, rng: &mut impl Rng) -> Vec<c64> {
    let w: Vec<c64> = random_r::<f64>(m, 2 * m, rng)
        .iter()
        .map(|z| c64::new(z.re, z.im))
        .collect();
    (0..m * m)
        .map(|i| {
            if alg == Algorithm::Gevd && i % m > i / m {
                c64::new(0.0, 0.0)
            } else {
                w[i]
            }
        })
        .collect()
}

/// One call with more problems than a lane group, of mixed sizes — GSVD's every-vector
/// problems take the direct SVD in the middle of a group — gives each problem the bits
/// it gets alone.
#[test]
fn a_long_mixed_group_equals_single_decompositions() {
    let bits = |d: &Decomposition<f64>| -> Vec<u64> {
        d.vectors64
            .iter()
            .flat_map(|z| [z.re.to_bits(), z.im.to_bits()])
            .chain(d.values.iter().map(|x| x.to_bits()))
            .collect()
    };
    for alg in Algorithm::MUSIC {
        for m in [8, 24] {
            let mut rng = rand::rngs::StdRng::seed_from_u64(21);
            let w = whitening(alg, m, &mut rng);
            let rs: Vec<Vec<c64>> = (0..11)
                .map(|i| {
                    random_r::<f64>(m, [m + 10, 3, 1][i % 3], &mut rng)
                        .iter()
                        .map(|z| c64::new(z.re, z.im))
                        .collect()
                })
                .collect();
            let dims = |i: usize| if i % 4 == 2 { m } else { 1 + i % 5 };
            let mut ws = Workspace::new(m);
            let mut group: Vec<Decomposition<f64>> =
                (0..11).map(|i| Decomposition::new(m, dims(i))).collect();
            let mut items: Vec<Item<'_, f64>> = rs
                .iter()
                .zip(group.iter_mut())
                .map(|(r, out)| Item { r, w: Some(&w), out })
                .collect();
            decompose_group(alg, &mut items, &mut ws).unwrap();
            for (i, (r, g)) in rs.iter().zip(&group).enumerate() {
                let mut alone = Decomposition::new(m, dims(i));
                decompose(alg, r, Some(&w), &mut ws, &mut alone).unwrap();
                assert_eq!(bits(&alone), bits(g), "{alg:?} M {m}: problem {i} of 11");
            }
        }
    }
}

/// [`decompose_alone`] (the one-problem solver above 16 mics) agrees with the group path
/// to rounding: the same eigenvalues and the same signal subspace, on rank-3 problems
/// whose subspace is far from the rest of the spectrum (so the projector is well
/// conditioned: both solvers are backward stable, and their difference is a few ε·M
/// relative; the bound leaves the whitening's conditioning a factor 10⁴).
#[test]
fn decompose_alone_agrees_with_the_group_path() {
    for alg in Algorithm::MUSIC {
        for m in [24, 60] {
            let mut rng = rand::rngs::StdRng::seed_from_u64(22);
            let w = whitening(alg, m, &mut rng);
            let r: Vec<c64> = random_r::<f64>(m, 3, &mut rng)
                .iter()
                .map(|z| c64::new(z.re, z.im))
                .collect();
            let mut ws = Workspace::new(m);
            let (mut a, mut b) = (Decomposition::<f64>::new(m, 3), Decomposition::<f64>::new(m, 3));
            decompose(alg, &r, Some(&w), &mut ws, &mut a).unwrap();
            decompose_alone(alg, &r, Some(&w), &mut ws, &mut b).unwrap();
            // GSVD reports σ = √λ: compared as λ (a rounding-level λ has a σ of √ε).
            let v = |x: f64| if alg == Algorithm::Gsvd { x * x } else { x };
            let top = v(a.values[0]);
            for (x, y) in a.values.iter().zip(&b.values) {
                assert!(
                    (v(*x) - v(*y)).abs() <= 1e-11 * top,
                    "{alg:?} M {m}: values {x} vs {y}"
                );
            }
            let proj = |d: &Decomposition<f64>, i: usize, j: usize| -> c64 {
                (0..3).map(|c| d.vector64(c)[i] * d.vector64(c)[j].conj()).sum()
            };
            for i in 0..m {
                for j in 0..m {
                    let e = (proj(&a, i, j) - proj(&b, i, j)).norm();
                    assert!(e <= 1e-11, "{alg:?} M {m}: projector ({i}, {j}) differs by {e:e}");
                }
            }
        }
    }
}
