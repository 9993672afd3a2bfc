//! The plan: shared steering across K updates, the whitening matrices' structure.

use super::*;
use crate::array::{freefield::free_field, Geometry, Grid};

/// Free-field transfer functions of an `m`-microphone circle (5 cm) on a ring grid.
fn circle_tf(m: usize, step_deg: f64, bins: std::ops::Range<usize>) -> TransferFunctions {
    free_field(
        &Geometry::circle(m, 0.05, 0.0),
        &Grid::ring(step_deg, 0.0, 1.0),
        512,
        16000,
        bins,
        343.0,
    )
    .unwrap()
}

#[test]
fn a_k_update_shares_the_steering_and_rebuilds_only_the_whitening() {
    let config = LocalizeConfig {
        algorithm: Algorithm::Gsvd,
        ..LocalizeConfig::default()
    };
    let tf = circle_tf(4, 10.0, config.bin_range());
    let p = Plan::<f32>::new(&config, &tf, None).unwrap();
    let mut k = NoiseMatrices::identity(4, config.bin_range());
    for b in 0..k.num_bins {
        k.data[b * 16].re = 4.0; // K = diag(4, 1, 1, 1)
    }
    let q = p.with_noise(&k).unwrap();
    assert!(Arc::ptr_eq(&p.steering, &q.steering));
    assert!(Arc::ptr_eq(&p.steering_norm2, &q.steering_norm2));
    // GSVD's W = K⁻¹ after HARK's scaling (K / max|Re K| = diag(1, 1/4, 1/4, 1/4)).
    let w = q.whitening_matrix64(0).unwrap();
    assert!(
        (w[0].re - 1.0).abs() < 1e-6 && (w[5].re - 4.0).abs() < 1e-5,
        "{:?}",
        &w[..6]
    );
    assert_eq!(p.whitening_matrix64(0).unwrap()[5].re, 1.0);
}

/// A textbook-GEVD plan built before its K is known (the identity) shares its steering
/// as the whitened steering, which is exact: the same plan given the identity K computes
/// a_w = L⁻¹a = a and ‖a_w‖² = ‖a‖² to the bit. A real K gets its own. (With coherence
/// normalisation the norms of the phase-only steering are those of its unrounded values,
/// so nothing is shared there.)
#[test]
fn the_identity_whitening_shares_the_steering_exactly() {
    let config = LocalizeConfig {
        algorithm: Algorithm::Gevd,
        ..LocalizeConfig::default()
    };
    let tf = circle_tf(6, 10.0, config.bin_range());
    let p = Plan::<f32>::new(&config, &tf, None).unwrap();
    let w = p.whitening.as_ref().unwrap();
    assert!(Arc::ptr_eq(&w.steering, &p.steering) && Arc::ptr_eq(&w.steering_norm2, &p.steering_norm2));
    let q = p
        .with_noise(&NoiseMatrices::identity(6, config.bin_range()))
        .unwrap();
    let v = q.whitening.as_ref().unwrap();
    assert!(!Arc::ptr_eq(&v.steering, &p.steering));
    assert_eq!(v.steering.len(), p.steering.len());
    for (a, b) in v.steering.iter().zip(p.steering.iter()) {
        assert_eq!((a.re, a.im), (b.re, b.im));
    }
    assert!(
        v.steering_norm2.as_slice() == p.steering_norm2.as_slice(),
        "norms differ"
    );
    assert!(q.numerator_norm2() == p.numerator_norm2(), "numerators differ");
    // With coherence normalisation the identity plan computes its own.
    let coherent = LocalizeConfig {
        coherence: true,
        ..config
    };
    let p = Plan::<f32>::new(&coherent, &tf, None).unwrap();
    assert!(!Arc::ptr_eq(&p.whitening.as_ref().unwrap().steering, &p.steering));
}

/// The textbook GEVD's W = L⁻¹ is exactly lower triangular (the GPU's products skip
/// the zeros above its diagonal, eigh.cu) and whitens K: W K Wᴴ = I after HARK's scaling.
#[test]
fn the_textbook_gevd_whitening_is_exactly_lower_triangular() {
    let config = LocalizeConfig {
        algorithm: Algorithm::Gevd,
        ..LocalizeConfig::default()
    };
    let m = 6;
    let tf = circle_tf(m, 30.0, config.bin_range());
    // A full, well-conditioned K: K_ij = 0.3^|i−j| e^{i(i−j)/2} + δ_ij.
    let mut k = NoiseMatrices::identity(m, config.bin_range());
    for b in 0..k.num_bins {
        for i in 0..m {
            for j in 0..m {
                let d = i as f64 - j as f64;
                let z = c64::from_polar(0.3f64.powf(d.abs()), 0.5 * d);
                k.data[b * m * m + i * m + j] = z + if i == j {
                    c64::new(1.0, 0.0)
                } else {
                    c64::new(0.0, 0.0)
                };
            }
        }
    }
    let p = Plan::<f32>::new(&config, &tf, Some(&k)).unwrap();
    let w = p.whitening_matrix64(0).unwrap();
    let kb = &k.data[..m * m];
    let mx = kb.iter().map(|z| z.re.abs()).fold(0.0, f64::max);
    for i in 0..m {
        for j in i + 1..m {
            assert_eq!(w[i * m + j], c64::new(0.0, 0.0), "W[{i}][{j}]");
        }
        for j in 0..m {
            // (W K Wᴴ)_ij with K scaled by 1 / max|Re K|
            let mut s = c64::new(0.0, 0.0);
            for a in 0..m {
                for c in 0..m {
                    s += w[i * m + a] * kb[a * m + c] / mx * w[j * m + c].conj();
                }
            }
            let want = if i == j { 1.0 } else { 0.0 };
            assert!(
                (s - c64::new(want, 0.0)).norm() < 1e-12,
                "(W K Wᴴ)[{i}][{j}] = {s}"
            );
        }
    }
}

/// Small arrays' planar steering follows the denominator's steering: for the textbook
/// GEVD the whitened one, rebuilt by a K update (equal to a plan built with that K);
/// otherwise the raw one, shared.
#[test]
fn the_planar_steering_follows_a_k_update() {
    let bins = LocalizeConfig::default().bin_range();
    let tf = circle_tf(4, 10.0, bins.clone());
    let mut k = NoiseMatrices::identity(4, bins);
    for b in 0..k.num_bins {
        k.data[b * 16].re = 4.0;
    }
    for alg in [Algorithm::Gevd, Algorithm::Gsvd] {
        let config = LocalizeConfig {
            algorithm: alg,
            ..LocalizeConfig::default()
        };
        let p = Plan::<f32>::new(&config, &tf, None).unwrap();
        let q = p.with_noise(&k).unwrap();
        let fresh = Plan::<f32>::new(&config, &tf, Some(&k)).unwrap();
        assert!(q.planar.is_some(), "{alg:?}: no planar copy for 4 mics");
        assert_eq!(q.planar, fresh.planar, "{alg:?}");
        let (old, new) = (p.planar.as_ref().unwrap(), q.planar.as_ref().unwrap());
        if alg == Algorithm::Gevd {
            assert_ne!(old, new, "the whitened steering did not change");
        } else {
            assert!(Arc::ptr_eq(old, new));
        }
    }
}

/// The AVX-512 spectrum's a_r − a_i (formed on first use) follows a K update like the
/// planar copy: for the textbook GEVD formed anew from the whitened steering (equal to a
/// plan built with that K), otherwise shared.
#[test]
fn the_steering_sums_follow_a_k_update() {
    let m = 20; // past the planar kernels' size
    let bins = LocalizeConfig::default().bin_range();
    let tf = circle_tf(m, 30.0, bins.clone());
    let mut k = NoiseMatrices::identity(m, bins);
    for b in 0..k.num_bins {
        k.data[b * m * m].re = 4.0;
    }
    let sums = |p: &Plan<f32>| -> Vec<f32> {
        p.steering_sums
            .get_or_init(|| crate::projections::steering_sums(p.denominator_steering().0))
            .clone()
    };
    for alg in [Algorithm::Gevd, Algorithm::Gsvd] {
        let config = LocalizeConfig {
            algorithm: alg,
            ..LocalizeConfig::default()
        };
        let p = Plan::<f32>::new(&config, &tf, None).unwrap();
        let before = sums(&p);
        let q = p.with_noise(&k).unwrap();
        let fresh = Plan::<f32>::new(&config, &tf, Some(&k)).unwrap();
        if alg == Algorithm::Gevd {
            assert!(q.steering_sums.get().is_none(), "GEVD kept the old sums");
            assert_eq!(sums(&q), sums(&fresh));
            assert_ne!(sums(&q), before, "the whitened steering did not change");
        } else {
            assert!(Arc::ptr_eq(&p.steering_sums, &q.steering_sums));
            assert_eq!(sums(&q), sums(&fresh));
        }
    }
}
