//! Tests of [`super`]: against faer's full decomposition, the forms' definitions, bit
//! for bit across groups and instruction sets, and the errors.

use super::*;
use crate::subspace::testing::{errors, scene};
use rand::{Rng, SeedableRng};

type Z = C<f64>;

/// Solve `a`s (one group) and return per problem its values and k vectors.
fn solve(form: Form, rs: &[Vec<Z>], w: Option<&[Z]>, n: usize, k: usize) -> Vec<(Vec<f64>, Vec<Z>)> {
    let mut s = EighLanes::new(n);
    s.clear(form);
    for r in rs {
        s.push(r, w).unwrap();
    }
    s.solve(k).unwrap();
    (0..rs.len())
        .map(|lane| {
            let mut v = vec![Z::new(0.0, 0.0); n * k];
            for c in 0..k {
                s.vector(lane, c, &mut v[c * n..(c + 1) * n]);
            }
            (s.values(lane).to_vec(), v)
        })
        .collect()
}

#[test]
fn matches_a_full_decomposition_for_every_size_and_lane() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(1);
    for n in 1..=MAX_N {
        for (strong, k) in [(vec![50.0, 20.0], 2), (vec![1e4, 3.0, 1.5], 3), (vec![100.0], n)] {
            let strong: Vec<f64> = strong.into_iter().take(n).collect();
            let k = k.min(n);
            // A full group, and a part-filled one.
            for count in [LANES, 3] {
                let rs: Vec<Vec<Z>> = (0..count)
                    .map(|_| scene(n, &strong, 1.0, 0.05, &mut rng))
                    .collect();
                for (a, (vals, vecs)) in rs.iter().zip(solve(Form::R, &rs, None, n, k)) {
                    let (val, resid, orth, sub) = errors(a, n, k, &vals, &vecs);
                    let tol = 1e-13 * n as f64;
                    assert!(val < tol, "n={n} k={k}: eigenvalues off by {val:e}");
                    assert!(resid < tol, "n={n} k={k}: residual {resid:e}");
                    assert!(orth < tol, "n={n} k={k}: orthonormality {orth:e}");
                    if k == strong.len() && k < n {
                        assert!(sub < 1e-10, "n={n} k={k}: signal subspace differs by {sub:e}");
                    }
                    assert!(vals.windows(2).all(|w| w[0] >= w[1]), "n={n}: not descending");
                }
            }
        }
    }
}

#[test]
fn clusters_multiplicity_diagonal_and_zero_matrices() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(2);
    let n = 12;
    let mut diag = vec![Z::new(0.0, 0.0); n * n];
    for i in 0..n {
        diag[i * n + i] = Z::new(i as f64 - 5.0, 0.0);
    }
    let rs = vec![
        scene(n, &[], 1.0, 0.0, &mut rng), // the identity: one eigenvalue, n times
        scene(n, &[10.0], 1.0, 0.0, &mut rng), // rank one plus the identity
        scene(n, &[], 1.0, 1e-9, &mut rng), // a tight cluster
        diag,                              // every Householder step the identity
        vec![Z::new(0.0, 0.0); n * n],     // zero
    ];
    for (i, (a, (vals, vecs))) in rs.iter().zip(solve(Form::R, &rs, None, n, n)).enumerate() {
        let (val, resid, orth, _) = errors(a, n, n, &vals, &vecs);
        assert!(
            val < 1e-14 && resid < 1e-14 && orth < 1e-14,
            "matrix {i}: {val:e} {resid:e} {orth:e}"
        );
    }
}

fn bits(r: &(Vec<f64>, Vec<Z>)) -> Vec<u64> {
    let vecs = r.1.iter().flat_map(|z| [z.re.to_bits(), z.im.to_bits()]);
    r.0.iter().map(|v| v.to_bits()).chain(vecs).collect()
}

/// Each problem's result is the same bits whichever lane it has and whichever
/// problems share its group (and with idle lanes) — also a matrix with a silent
/// microphone (a decoupled zero row and column) next to slower neighbours.
#[test]
fn a_result_does_not_depend_on_its_group() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    let n = 8;
    let mut rs: Vec<Vec<Z>> = (0..LANES)
        .map(|_| scene(n, &[30.0, 5.0], 1.0, 0.1, &mut rng))
        .collect();
    for i in 0..n {
        rs[2][i] = Z::new(0.0, 0.0);
        rs[2][i * n] = Z::new(0.0, 0.0);
    }
    let all = solve(Form::R, &rs, None, n, 3);
    let mut reversed = rs.clone();
    reversed.reverse();
    let rev = solve(Form::R, &reversed, None, n, 3);
    for (i, r) in rs.iter().enumerate() {
        let alone = solve(Form::R, std::slice::from_ref(r), None, n, 3);
        assert_eq!(bits(&alone[0]), bits(&all[i]), "problem {i} alone");
        assert_eq!(
            bits(&rev[LANES - 1 - i]),
            bits(&all[i]),
            "problem {i} in another lane"
        );
    }
}

/// The whitened forms against their definitions decomposed by faer.
#[test]
fn whitened_and_gram_forms_match_their_definitions() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(4);
    let n = 8;
    let mut w: Vec<Z> = (0..n * n)
        .map(|_| Z::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0)))
        .collect();
    let rs: Vec<Vec<Z>> = (0..5)
        .map(|_| scene(n, &[40.0, 10.0], 1.0, 0.1, &mut rng))
        .collect();
    let mul = |a: &[Z], b: &[Z]| -> Vec<Z> {
        (0..n * n)
            .map(|ij| (0..n).map(|k| a[ij / n * n + k] * b[k * n + ij % n]).sum())
            .collect()
    };
    let adj = |a: &[Z]| -> Vec<Z> { (0..n * n).map(|ij| a[ij % n * n + ij / n].conj()).collect() };
    for form in [
        Form::Whitened { lower: true },
        Form::Whitened { lower: false },
        Form::Gram,
    ] {
        if form == (Form::Whitened { lower: true }) {
            // Anything above the diagonal must be ignored.
            w[1] = Z::new(f64::NAN, 0.0);
        } else {
            w[1] = Z::new(0.3, -0.2);
        }
        let wl: Vec<Z> = (0..n * n)
            .map(|ij| {
                if form == (Form::Whitened { lower: true }) && ij % n > ij / n {
                    Z::new(0.0, 0.0)
                } else {
                    w[ij]
                }
            })
            .collect();
        for (r, (vals, vecs)) in rs.iter().zip(solve(form, &rs, Some(&w), n, 2)) {
            let t = mul(&wl, r);
            let a = match form {
                Form::Gram => mul(&t, &adj(&t)),
                _ => mul(&t, &adj(&wl)),
            };
            let (val, resid, orth, sub) = errors(&a, n, 2, &vals, &vecs);
            assert!(
                val < 1e-12 && resid < 1e-12 && orth < 1e-13,
                "{form:?}: {val:e} {resid:e} {orth:e}"
            );
            assert!(sub < 1e-9, "{form:?}: subspace {sub:e}");
        }
    }
}

/// The AVX-512 and AVX2 lanes (through the functions the solver dispatches to) and the
/// baseline's plain arrays give the same bits: full and part-filled groups, every form,
/// and a diagonal matrix whose off-diagonal zeros carry both signs.
#[test]
fn vector_and_baseline_lanes_agree_bit_for_bit() {
    #[cfg(target_arch = "x86_64")]
    {
        let has = |f: &str| match f {
            "avx2" => std::arch::is_x86_feature_detected!("avx2"),
            _ => std::arch::is_x86_feature_detected!("avx512f"),
        };
        for isa in ["avx2", "avx512f"] {
            if !has(isa) {
                println!("SKIPPED vector_and_baseline_lanes_agree_bit_for_bit ({isa}): not on this CPU");
            }
        }
        let mut rng = rand::rngs::StdRng::seed_from_u64(6);
        let n = 8;
        let w: Vec<Z> = (0..n * n)
            .map(|_| Z::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0)))
            .collect();
        let mut diagonal = vec![Z::new(0.0, 0.0); n * n];
        for i in 0..n {
            diagonal[i * n + i] = Z::new(1.0 + i as f64, 0.0);
            for j in 0..i {
                diagonal[i * n + j] = Z::new(if (i + j) % 2 == 0 { -0.0 } else { 0.0 }, -0.0);
            }
        }
        for form in [Form::R, Form::Whitened { lower: true }, Form::Gram] {
            let mut rs: Vec<Vec<Z>> = (0..LANES)
                .map(|_| scene(n, &[30.0, 5.0], 1.0, 0.1, &mut rng))
                .collect();
            rs[3] = diagonal.clone();
            for used in [LANES, 3] {
                let run = |isa: &str| {
                    let mut s = EighLanes::new(n);
                    s.clear(form);
                    for r in &rs[..used] {
                        s.push(r, Some(&w)).unwrap();
                    }
                    s.prepare(n);
                    // SAFETY: each is called only where `has` found its instruction set.
                    match isa {
                        "avx2" => unsafe { solve_avx2(&mut s, n) },
                        "avx512f" => unsafe { solve_avx512(&mut s, n) },
                        _ => solve_with::<v8::Scalar>(&mut s, n),
                    }
                    let mut out = Vec::new();
                    let mut v = vec![Z::new(0.0, 0.0); n];
                    for lane in 0..used {
                        out.extend(s.values(lane).iter().map(|v| v.to_bits()));
                        for c in 0..n {
                            s.vector(lane, c, &mut v);
                            out.extend(v.iter().flat_map(|z| [z.re.to_bits(), z.im.to_bits()]));
                        }
                    }
                    out
                };
                let baseline = run("baseline");
                for isa in ["avx2", "avx512f"] {
                    if has(isa) {
                        assert_eq!(run(isa), baseline, "{isa} {form:?}, {used} lanes");
                    }
                }
            }
        }
    }
}

#[test]
fn non_finite_input_and_missing_whitening_are_errors() {
    let n = 4;
    let mut a = vec![Z::new(1.0, 0.0); n * n];
    a[9] = Z::new(f64::INFINITY, 0.0);
    let mut s = EighLanes::new(n);
    s.clear(Form::R);
    assert!(s.push(&a, None).is_err());
    assert!(s.is_empty());
    s.clear(Form::Gram);
    assert!(s.push(&vec![Z::new(0.0, 0.0); n * n], None).is_err());
}
