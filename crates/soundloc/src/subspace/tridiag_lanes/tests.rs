//! Tests of [`super`]: Q T Qᴴ = A in f64, the scalar reduction's T, a lane's bits alone
//! and in any group, every instruction set, and the errors.

use super::*;
use crate::subspace::testing::scene;
use rand::SeedableRng;

type Z = C<f64>;

/// Each lane's (T's diagonal, T's subdiagonal, τ, v_j rows) after a reduction of `rs`,
/// through [`TridiagLanes::store`] into a solver, as it is used.
fn reduce_all(rs: &[Vec<Z>], n: usize, run: impl Fn(&mut TridiagLanes)) -> Vec<Eigh> {
    let mut s = TridiagLanes::new(n);
    s.clear();
    for r in rs {
        let ar: Vec<f64> = r.iter().map(|z| z.re).collect();
        let ai: Vec<f64> = r.iter().map(|z| z.im).collect();
        s.push(&ar, &ai).unwrap();
    }
    // `reduce`'s transposition, then the reduction under test.
    let size = at(n, 0);
    for (k, (x, y)) in s.re.iter_mut().zip(s.im.iter_mut()).enumerate() {
        for l in 0..LANES {
            let o = if l < s.used { l * size } else { 0 };
            (x[l], y[l]) = (s.stage_re[o + k], s.stage_im[o + k]);
        }
    }
    run(&mut s);
    (0..rs.len())
        .map(|lane| {
            let mut e = Eigh::new(n);
            e.reduced_mut().re.fill(0.0);
            e.reduced_mut().im.fill(0.0);
            s.store(lane, &mut e);
            e
        })
        .collect()
}

/// Q T Qᴴ from a solver's reduced form (Q = H₀ ⋯ H_{n−2}, H_j = I − τ_j v_j v_jᴴ).
fn rebuild(e: &mut Eigh, n: usize) -> Vec<Z> {
    let r = e.reduced_mut();
    let mut a = vec![Z::new(0.0, 0.0); n * n];
    for i in 0..n {
        a[i * n + i] = Z::new(r.diag[i], 0.0);
        if i + 1 < n {
            a[(i + 1) * n + i] = Z::new(r.off[i], 0.0);
            a[i * n + i + 1] = Z::new(r.off[i], 0.0);
        }
    }
    // A ← H_j A H_jᴴ from the last reflector to the first.
    for j in (0..n.saturating_sub(1)).rev() {
        let tau = r.tau[j];
        let v: Vec<Z> = (0..n)
            .map(|i| {
                if i > j {
                    Z::new(r.re[j * n + i], r.im[j * n + i])
                } else {
                    Z::new(0.0, 0.0)
                }
            })
            .collect();
        // H A = A − τ v (vᴴ A); A Hᴴ = A − (A v) conj(τ) vᴴ.
        let vha: Vec<Z> = (0..n)
            .map(|c| (0..n).map(|i| v[i].conj() * a[i * n + c]).sum())
            .collect();
        for i in 0..n {
            for c in 0..n {
                a[i * n + c] -= tau * v[i] * vha[c];
            }
        }
        let av: Vec<Z> = (0..n)
            .map(|i| (0..n).map(|c| a[i * n + c] * v[c]).sum())
            .collect();
        for i in 0..n {
            for c in 0..n {
                a[i * n + c] -= av[i] * tau.conj() * v[c].conj();
            }
        }
    }
    a
}

/// A diagonal matrix whose zeros below the diagonal carry both signs: every column is
/// already reduced (τ = 0 throughout).
fn diagonal(n: usize) -> Vec<Z> {
    let mut a = vec![Z::new(0.0, 0.0); n * n];
    for i in 0..n {
        a[i * n + i] = Z::new(1.0 + i as f64, 0.0);
        for j in 0..i {
            a[i * n + j] = Z::new(if (i + j) % 2 == 0 { -0.0 } else { 0.0 }, -0.0);
            a[j * n + i] = a[i * n + j];
        }
    }
    a
}

fn bits(e: &mut Eigh, n: usize) -> Vec<u64> {
    let r = e.reduced_mut();
    let mut out: Vec<u64> = r.diag.iter().chain(r.off.iter()).map(|x| x.to_bits()).collect();
    out.extend(r.tau.iter().flat_map(|z| [z.re.to_bits(), z.im.to_bits()]));
    for j in 0..n {
        for i in j + 1..n {
            out.extend([r.re[j * n + i].to_bits(), r.im[j * n + i].to_bits()]);
        }
    }
    out
}

/// Q T Qᴴ = A to f64 rounding, and T and the reflectors are those of the one-problem
/// reduction ([`Eigh`]'s row kernels; the same steps, other summation orders), on
/// MUSIC-like matrices of several sizes, a diagonal one among them.
#[test]
fn reduction_rebuilds_a_and_matches_the_scalar_reduction() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(11);
    for n in [17, 24, 33, 60] {
        let mut rs: Vec<Vec<Z>> = (0..LANES)
            .map(|l| scene(n, &[1e4, 300.0, 20.0][..1 + l % 3], 1.0, 0.05, &mut rng))
            .collect();
        rs[5] = diagonal(n);
        let mut got = reduce_all(&rs, n, |s| s.reduce());
        for (lane, (a, e)) in rs.iter().zip(got.iter_mut()).enumerate() {
            let norm = a.iter().fold(0.0f64, |m, z| m.max(z.norm()));
            let back = rebuild(e, n);
            let err = a
                .iter()
                .zip(&back)
                .fold(0.0f64, |m, (x, y)| m.max((x - y).norm()));
            assert!(
                err <= 1e-13 * norm,
                "n={n} lane {lane}: ‖QTQᴴ − A‖ = {err:e} of {norm:e}"
            );
            // The one-problem reduction of the same matrix.
            let mut one = Eigh::new(n);
            let (ar, ai) = one.matrix_mut();
            for (k, z) in a.iter().enumerate() {
                ar[k] = z.re;
                ai[k] = z.im;
            }
            super::super::eigh::tridiagonalize(&mut one);
            let (x, y) = (e.reduced_mut(), one.reduced_mut());
            for j in 0..n {
                assert!(
                    (x.diag[j] - y.diag[j]).abs() <= 1e-12 * norm,
                    "n={n} lane {lane} d[{j}]"
                );
                assert!(
                    (x.off[j] - y.off[j]).abs() <= 1e-12 * norm,
                    "n={n} lane {lane} e[{j}]"
                );
                if lane == 5 {
                    // The diagonal matrix: every column already reduced, H_j = I.
                    assert_eq!((x.tau[j], x.off[j]), (C::new(0.0, 0.0), 0.0), "n={n} τ[{j}]");
                    continue;
                }
                // τ moves with its column's rounding relative to the column's norm |β_j|.
                let tol = 1e-12 * norm / y.off[j].abs();
                assert!(
                    (x.tau[j] - y.tau[j]).norm() <= tol,
                    "n={n} lane {lane} τ[{j}]: {} vs {}",
                    x.tau[j],
                    y.tau[j]
                );
            }
        }
    }
}

/// A problem's bits do not depend on which problems share its group or how many there
/// are (idle lanes repeat lane 0).
#[test]
fn a_lane_does_not_depend_on_its_group() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(12);
    let n = 29;
    let rs: Vec<Vec<Z>> = (0..LANES)
        .map(|_| scene(n, &[50.0, 3.0], 1.0, 0.1, &mut rng))
        .collect();
    let mut full = reduce_all(&rs, n, |s| s.reduce());
    for l in [0, 4, 7] {
        let mut alone = reduce_all(&rs[l..l + 1], n, |s| s.reduce());
        assert_eq!(bits(&mut alone[0], n), bits(&mut full[l], n), "lane {l}");
    }
    let mut mixed: Vec<Vec<Z>> = rs[..3].to_vec();
    mixed.insert(1, diagonal(n));
    let mut part = reduce_all(&mixed, n, |s| s.reduce());
    assert_eq!(bits(&mut part[0], n), bits(&mut full[0], n));
    assert_eq!(bits(&mut part[3], n), bits(&mut full[2], n));
}

/// AVX-512, AVX2 and the baseline's plain arrays give the same bits: full and part-filled
/// groups, with a diagonal matrix among them.
#[test]
fn vector_and_baseline_lanes_agree_bit_for_bit() {
    #[cfg(target_arch = "x86_64")]
    {
        let has = |f: &str| match f {
            "avx2" => {
                std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
            }
            _ => std::arch::is_x86_feature_detected!("avx512f"),
        };
        for isa in ["avx2", "avx512f"] {
            if !has(isa) {
                println!("SKIPPED vector_and_baseline_lanes_agree_bit_for_bit ({isa}): not on this CPU");
            }
        }
        let mut rng = rand::rngs::StdRng::seed_from_u64(13);
        let n = 21;
        let mut rs: Vec<Vec<Z>> = (0..LANES)
            .map(|_| scene(n, &[30.0, 5.0], 1.0, 0.1, &mut rng))
            .collect();
        rs[3] = diagonal(n);
        for used in [LANES, 3] {
            let run = |isa: &str| {
                let mut got = reduce_all(&rs[..used], n, |s| match isa {
                    // SAFETY: each is called only where `has` found its instruction set.
                    "avx2" => unsafe { reduce_avx2(s) },
                    "avx512f" => unsafe { reduce_avx512(s) },
                    _ => reduce_with::<v8::Scalar>(s),
                });
                got.iter_mut().flat_map(|e| bits(e, n)).collect::<Vec<u64>>()
            };
            let baseline = run("baseline");
            for isa in ["avx2", "avx512f"] {
                if has(isa) {
                    assert_eq!(run(isa), baseline, "{isa}, {used} lanes");
                }
            }
        }
    }
}

/// A non-finite entry anywhere (either triangle, either part, the diagonal) is an error,
/// and the problem is not loaded: the next one takes its lane.
#[test]
fn non_finite_input_is_an_error() {
    let n = 18;
    let mut s = TridiagLanes::new(n);
    let (ar, ai) = (vec![0.5; n * n], vec![0.0; n * n]);
    for (imag, at) in [
        (false, 5 * n + 2),
        (true, 5 * n + 2),
        (false, 2 * n + 5),
        (true, 7 * n + 7),
    ] {
        for bad in [f64::INFINITY, f64::NAN] {
            let (mut r, mut i) = (ar.clone(), ai.clone());
            if imag {
                i[at] = bad;
            } else {
                r[at] = bad;
            }
            assert!(s.push(&r, &i).is_err(), "{bad} at {at} (imaginary: {imag})");
        }
    }
    assert_eq!(s.push(&ar, &ai).unwrap(), 0);
    assert_eq!(s.push(&ar, &ai).unwrap(), 1);
}
