//! Per-bin whitening from the noise matrix K (f64, once per K): K ← K / max|Re K_ij|
//! (HARK's scaling, after optional diagonal loading), its Cholesky factor K = L Lᴴ, and the
//! algorithm's whitening matrix W_k: K⁻¹ (GSVD), L⁻¹ (GEVD, with the whitened steering
//! a_w = L⁻¹ a and ‖a_w‖²) or K^{-1/2} (GEVD-HARK). A K that is not positive definite, or
//! singular to rounding, is refused with a diagnosis ([`super::singular`]).

use super::singular::{self, not_positive_definite};
use super::Whitening;
use crate::config::{Algorithm, LocalizeConfig};
use crate::noise::NoiseMatrices;
use crate::real::{Real, C};
use crate::{Error, Result};
use faer::linalg::solvers::DenseSolveCore;
use faer::{c64, Mat, Side};
use rayon::prelude::*;
use std::ops::Range;

pub(super) fn whitening<T: Real>(
    config: &LocalizeConfig,
    noise: &NoiseMatrices,
    bins: &Range<usize>,
    m: usize,
    d: usize,
    steering: &[C<T>],
) -> Result<Whitening<T>> {
    if noise.num_mics != m {
        return Err(Error::Mismatch(format!(
            "noise correlation matrix has {} channels, the transfer functions {}",
            noise.num_mics, m
        )));
    }
    if bins.start < noise.first_bin || bins.end > noise.first_bin + noise.num_bins {
        return Err(Error::Mismatch(format!(
            "noise correlation matrix holds bins {}..{}, the analysis uses {}..{}",
            noise.first_bin,
            noise.first_bin + noise.num_bins,
            bins.start,
            bins.end
        )));
    }
    let alg = config.algorithm;
    let nb = bins.len();
    let per_bin: Vec<Result<BinWhitening<T>>> = (0..nb)
        .into_par_iter()
        .map(|b| {
            let bin = bins.start + b;
            let hz = bin as f64 * config.sample_rate_hz as f64 / config.nfft as f64;
            // Every bin in range is held (checked above).
            let kraw = noise.bin(bin).unwrap_or(&[]);
            bin_whitening::<T>(
                alg,
                kraw,
                m,
                d,
                config.diagonal_loading,
                config.coherence,
                &steering[b * d * m..(b + 1) * d * m],
            )
            .map_err(|msg| {
                Error::numerical(
                    "noise",
                    format!("noise correlation matrix K at bin {bin} ({hz:.0} Hz): {msg}"),
                )
            })
        })
        .collect();
    let mut w = Whitening {
        matrix64: Vec::with_capacity(nb * m * m),
        steering: Vec::new(),
        steering_norm2: Vec::new(),
        numerator_norm2: Vec::new(),
    };
    for r in per_bin {
        let (mat, st, n2) = r?;
        w.matrix64.extend(mat);
        w.steering.extend(st);
        w.steering_norm2.extend(n2);
    }
    Ok(w)
}

/// W (row-major, f64), the whitened steering and its norms.
type BinWhitening<T> = (Vec<c64>, Vec<C<T>>, Vec<T>);

/// One bin: scale K, factor it, and build W (and the whitened steering for GEVD).
fn bin_whitening<T: Real>(
    alg: Algorithm,
    kraw: &[c64],
    m: usize,
    d: usize,
    loading: f64,
    coherence: bool,
    steering: &[C<T>],
) -> std::result::Result<BinWhitening<T>, String> {
    if kraw.len() != m * m {
        return Err("missing".into());
    }
    if kraw.iter().any(|z| !(z.re.is_finite() && z.im.is_finite())) {
        return Err("contains non-finite values".into());
    }
    let mut k = Mat::<c64>::from_fn(m, m, |i, j| (kraw[i * m + j] + kraw[j * m + i].conj()) * 0.5);
    // Coherence normalisation with K (the textbook GEVD, [`LocalizeConfig::coherence`]):
    // the steering vectors (already phase-only) take the magnitudes of K's channel levels,
    // √(K_mm / geometric mean of K's diagonal), the gains of the array as recorded; R and K
    // stay as they are; taken before any diagonal loading. (Against the geometric mean,
    // frequency-flat channel gains change every bin's steering by the same factor, so the
    // bins keep their weights.)
    let gains: Vec<f64> = {
        let kd: Vec<f64> = (0..m).map(|i| k[(i, i)].re).collect();
        let ok = coherence && kd.iter().all(|&x| x > 0.0 && x.is_finite());
        let gm = (kd.iter().map(|x| x.ln()).sum::<f64>() / m as f64).exp();
        kd.iter()
            .map(|&x| if ok { (x / gm).sqrt() } else { 1.0 })
            .collect()
    };
    if loading > 0.0 {
        let mean_diag = (0..m).map(|i| k[(i, i)].re).sum::<f64>() / m as f64;
        for i in 0..m {
            k[(i, i)].re += loading * mean_diag;
        }
    }
    // HARK's scaling for GEVD/GSVD: K ← K / max_ij |Re K_ij|.
    let mut mx = 0.0f64;
    for j in 0..m {
        for i in 0..m {
            mx = mx.max(k[(i, j)].re.abs());
        }
    }
    if mx <= 0.0 {
        return Err("is zero (silent noise recording?)".into());
    }
    for j in 0..m {
        for i in 0..m {
            k[(i, j)] /= mx;
        }
    }
    let llt = k.llt(Side::Lower).map_err(|_| not_positive_definite(&k))?;
    if let Some(why) = singular::numerically_singular(&k, llt.L()) {
        return Err(why);
    }
    let row_major = |w: &Mat<c64>| -> Vec<c64> {
        let mut v = Vec::with_capacity(m * m);
        for i in 0..m {
            for j in 0..m {
                v.push(w[(i, j)]);
            }
        }
        v
    };
    match alg {
        Algorithm::Sevd | Algorithm::SrpPhat => Ok((Vec::new(), Vec::new(), Vec::new())),
        Algorithm::Gsvd => {
            let kinv = llt.inverse();
            Ok((row_major(&kinv), Vec::new(), Vec::new()))
        }
        Algorithm::GevdHark => {
            let kinv = llt.inverse();
            let kinv = Mat::<c64>::from_fn(m, m, |i, j| (kinv[(i, j)] + kinv[(j, i)].conj()) * 0.5);
            let evd = kinv
                .self_adjoint_eigen(Side::Lower)
                .map_err(|e| format!("eigendecomposition of K⁻¹ failed: {e:?}"))?;
            let (v, s) = (evd.U(), evd.S());
            let sl: Vec<f64> = (0..m)
                .map(|i| {
                    let l = s[i].re;
                    if l >= 0.0 {
                        l.sqrt()
                    } else {
                        -(-l).sqrt()
                    }
                })
                .collect();
            let w = Mat::<c64>::from_fn(m, m, |i, j| {
                let mut acc = c64::new(0.0, 0.0);
                for t in 0..m {
                    acc += v[(i, t)] * sl[t] * v[(j, t)].conj();
                }
                acc
            });
            Ok((row_major(&w), Vec::new(), Vec::new()))
        }
        Algorithm::Gevd => {
            let l = llt.L();
            let mut linv = Mat::<c64>::zeros(m, m);
            faer::linalg::triangular_inverse::invert_lower_triangular(linv.as_mut(), l, faer::Par::Seq);
            // Exactly lower triangular: the GPU's products skip the zeros above (eigh.cu).
            for j in 1..m {
                for i in 0..j {
                    linv[(i, j)] = c64::new(0.0, 0.0);
                }
            }
            // Whitened steering a_w = L⁻¹ a for every direction.
            let a = Mat::<c64>::from_fn(m, d, |i, dir| {
                let z = steering[dir * m + i];
                c64::new(z.re.to_f64() * gains[i], z.im.to_f64() * gains[i])
            });
            let mut aw = Mat::<c64>::zeros(m, d);
            faer::linalg::matmul::matmul(
                aw.as_mut(),
                faer::Accum::Replace,
                linv.as_ref(),
                a.as_ref(),
                c64::new(1.0, 0.0),
                faer::Par::Seq,
            );
            crate::avx::clear_upper();
            let mut st = Vec::with_capacity(d * m);
            let mut n2 = Vec::with_capacity(d);
            for dir in 0..d {
                let mut acc = 0.0;
                for i in 0..m {
                    let z = aw[(i, dir)];
                    acc += z.re * z.re + z.im * z.im;
                    st.push(C::new(T::of_f64(z.re), T::of_f64(z.im)));
                }
                n2.push(T::of_f64(acc));
            }
            Ok((row_major(&linv), st, n2))
        }
    }
}
