use super::*;
use crate::subspace::tridiag::{ql_values, TriLu};
use rand::{Rng, SeedableRng};

/// A random T of size n (split at e[1] = 0) and eight shifts: some between its values, one
/// exactly on its first diagonal entry (a zero numerator in the first pivot step), one far
/// outside, one on an eigenvalue of T (nearly singular) and one 1e-9 from another.
fn case(n: usize, seed: u64) -> (Vec<f64>, Vec<f64>, V) {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let d: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect();
    let mut e: Vec<f64> = (0..n.saturating_sub(1))
        .map(|_| rng.gen_range(-0.5..0.5))
        .collect();
    if n > 3 {
        e[1] = 0.0; // T split in two
    }
    let mut shifts: V = std::array::from_fn(|_| rng.gen_range(-1.5..1.5));
    shifts[3] = d[0];
    shifts[5] = 40.0;
    let mut eig = d.clone();
    let mut e2: Vec<f64> = e.iter().map(|x| x * x).chain([0.0]).collect();
    ql_values(&mut eig, &mut e2).unwrap();
    shifts[6] = eig[0];
    shifts[7] = eig[n / 2] + 1e-9;
    (d, e, shifts)
}

/// Factor and solve with the lane type `isa` ("scalar", "avx2", "avx512f"); None where
/// this CPU lacks it.
fn by_type(isa: &str, d: &[f64], e: &[f64], shifts: &V, tiny: f64, x0: &[V]) -> Option<Vec<V>> {
    #[cfg(target_arch = "x86_64")]
    let has = match isa {
        "avx2" => std::arch::is_x86_feature_detected!("avx2"),
        "avx512f" => std::arch::is_x86_feature_detected!("avx512f"),
        _ => true,
    };
    #[cfg(not(target_arch = "x86_64"))]
    let has = isa == "scalar";
    if !has {
        println!("SKIPPED every_lane_equals_the_one_shift_solver_bit_for_bit ({isa}): not on this CPU");
        return None;
    }
    let mut lu = TriLuLanes::default();
    lu.fill(d, e, shifts);
    let mut x = x0.to_vec();
    let run = |lu: &mut TriLuLanes, x: Option<&mut [V]>| match isa {
        // SAFETY: reached only where the CPU has AVX2 (checked above).
        #[cfg(target_arch = "x86_64")]
        "avx2" => unsafe { run_avx2(lu, x, tiny) },
        // SAFETY: reached only where the CPU has AVX-512F (checked above).
        #[cfg(target_arch = "x86_64")]
        "avx512f" => unsafe { run_avx512(lu, x, tiny) },
        _ => run_with::<v8::Scalar>(lu, x, tiny),
    };
    run(&mut lu, None);
    run(&mut lu, Some(&mut x));
    Some(x)
}

/// Each lane's solution has the bits of the one-shift solver, on every lane type this CPU
/// has (AVX-512, AVX2) and on the baseline, whatever the other lanes hold.
#[test]
fn every_lane_equals_the_one_shift_solver_bit_for_bit() {
    for n in [1, 2, 3, 5, 16, 60] {
        for seed in 0..6 {
            let (d, e, shifts) = case(n, seed);
            let tiny = f64::EPSILON * 2.0;
            let mut rng = rand::rngs::StdRng::seed_from_u64(100 + seed);
            let x0: Vec<V> = (0..n)
                .map(|_| std::array::from_fn(|_| rng.gen_range(-1.0..1.0)))
                .collect();
            let mut lu = TriLuLanes::default();
            lu.factor(&d, &e, &shifts, tiny);
            let mut x = x0.clone();
            lu.solve(&mut x);
            // Each lane type by name: the baseline, and the vector types this CPU has.
            let typed: Vec<(&str, Vec<V>)> = ["scalar", "avx2", "avx512f"]
                .into_iter()
                .filter_map(|isa| by_type(isa, &d, &e, &shifts, tiny, &x0).map(|x| (isa, x)))
                .collect();
            for l in 0..LANES {
                let mut one = TriLu::new(n);
                one.factor(&d, &e, shifts[l], tiny);
                let mut y: Vec<f64> = x0.iter().map(|r| r[l]).collect();
                one.solve(&mut y);
                for i in 0..n {
                    assert_eq!(
                        x[i][l].to_bits(),
                        y[i].to_bits(),
                        "n {n} seed {seed} lane {l} row {i}"
                    );
                    for (isa, xt) in &typed {
                        assert_eq!(
                            xt[i][l].to_bits(),
                            y[i].to_bits(),
                            "{isa}: n {n} seed {seed} lane {l}"
                        );
                    }
                }
            }
            // The far shift (lane 5) is well conditioned: its solution solves its system.
            for i in 0..n {
                let mut r = (d[i] - shifts[5]) * x[i][5];
                if i > 0 {
                    r += e[i - 1] * x[i - 1][5];
                }
                if i + 1 < n {
                    r += e[i] * x[i + 1][5];
                }
                assert!(
                    (r - x0[i][5]).abs() < 1e-12,
                    "n {n} seed {seed} row {i}: {r} vs {}",
                    x0[i][5]
                );
            }
            // Lane independence: lane 0 alone among copies of another lane's problem.
            let mut shifts2 = [shifts[1]; LANES];
            shifts2[0] = shifts[0];
            let mut lu2 = TriLuLanes::default();
            lu2.factor(&d, &e, &shifts2, tiny);
            let mut x2: Vec<V> = x0
                .iter()
                .map(|r| [r[0], r[1], r[1], r[1], r[1], r[1], r[1], r[1]])
                .collect();
            lu2.solve(&mut x2);
            for i in 0..n {
                assert_eq!(
                    x2[i][0].to_bits(),
                    x[i][0].to_bits(),
                    "n {n} seed {seed}: lane 0 depends on the others"
                );
            }
        }
    }
}

/// A shift exactly on an eigenvalue of a split T: with a tiny pivot the solve returns
/// that eigenvector (up to scale); with a pivot so tiny that the back substitution
/// overflows, the lane is rescaled as the one-shift solver rescales it (same bits,
/// finite), and the other lanes are untouched by it.
#[test]
fn a_shift_on_an_eigenvalue() {
    let d = [3.0, 1.0, 2.0, -1.0];
    let e = [0.0, 0.0, 0.0];
    let shifts: V = [1.0, 3.0, 2.0, -1.0, 0.5, 1.0, 1.0, 1.0];
    let which = |s: f64| d.iter().position(|&x| x == s);
    for tiny in [1e-300, 1e-320] {
        let mut lu = TriLuLanes::default();
        lu.factor(&d, &e, &shifts, tiny);
        let mut x: Vec<V> = vec![[1.0; LANES]; 4];
        lu.solve(&mut x);
        for (l, &s) in shifts.iter().enumerate() {
            let mut one = TriLu::new(4);
            one.factor(&d, &e, s, tiny);
            let mut y = vec![1.0; 4];
            one.solve(&mut y);
            for i in 0..4 {
                assert!(x[i][l].is_finite(), "tiny {tiny:e} lane {l} row {i}: {}", x[i][l]);
                assert_eq!(
                    x[i][l].to_bits(),
                    y[i].to_bits(),
                    "tiny {tiny:e} lane {l} row {i}"
                );
            }
            if let (Some(k), 1e-300) = (which(s), tiny) {
                let mx = x.iter().fold(0.0f64, |a, r| a.max(r[l].abs()));
                for (i, r) in x.iter().enumerate() {
                    let want = if i == k { 1.0 } else { 0.0 };
                    assert!(
                        (r[l].abs() / mx - want).abs() < 1e-200,
                        "lane {l} row {i}: {}",
                        r[l]
                    );
                }
            }
        }
    }
}
