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
use std::sync::Arc;

/// A plan's steering and norms, shared as the whitened ones where K is the identity.
pub(super) type SharedSteering<'a, T> = (&'a Arc<Vec<C<T>>>, &'a Arc<Vec<T>>);

pub(super) fn whitening<T: Real>(
    config: &LocalizeConfig,
    noise: &NoiseMatrices,
    bins: &Range<usize>,
    m: usize,
    d: usize,
    steering: &[C<T>],
    identity: Option<SharedSteering<'_, T>>,
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
    // The textbook GEVD's whitened steering is written in place, bin by bin (88 MB at 60
    // mics and 2522 directions in f32: collected per bin and then copied, the peak was
    // three times that).
    // With K the identity (a plan built before its K is known) L = I and a_w = a exactly:
    // the plan's own steering and norms are shared instead.
    let gevd = alg == Algorithm::Gevd && identity.is_none();
    let mut steering_w = vec![C::new(T::zero(), T::zero()); if gevd { nb * d * m } else { 0 }];
    let mut norm2_w = vec![T::zero(); if gevd { nb * d } else { 0 }];
    let st_parts: Vec<&mut [C<T>]> = if gevd {
        steering_w.chunks_mut(d * m).collect()
    } else {
        (0..nb).map(|_| Default::default()).collect()
    };
    let n2_parts: Vec<&mut [T]> = if gevd {
        norm2_w.chunks_mut(d).collect()
    } else {
        (0..nb).map(|_| Default::default()).collect()
    };
    let per_bin: Vec<Result<Vec<c64>>> = st_parts
        .into_par_iter()
        .zip(n2_parts.into_par_iter())
        .enumerate()
        .map(|(b, (st, n2))| {
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
                st,
                n2,
            )
            .map_err(|msg| {
                Error::numerical(
                    "noise",
                    format!("the correlation matrix K at bin {bin} ({hz:.0} Hz): {msg}"),
                )
            })
        })
        .collect();
    let (steering_w, norm2_w) = match identity {
        Some((st, n2)) if alg == Algorithm::Gevd => (st.clone(), n2.clone()),
        _ => (Arc::new(steering_w), Arc::new(norm2_w)),
    };
    let mut w = Whitening {
        matrix64: Vec::with_capacity(nb * m * m),
        steering: steering_w,
        steering_norm2: norm2_w,
        numerator_norm2: Vec::new(),
    };
    for r in per_bin {
        w.matrix64.extend(r?);
    }
    Ok(w)
}

/// One bin: scale K, factor it, and return W (row-major, f64); for GEVD the whitened
/// steering a_w = L⁻¹a (`[dir][mic]`) and ‖a_w‖² go into `st` and `n2` (empty otherwise).
#[allow(clippy::too_many_arguments)]
fn bin_whitening<T: Real>(
    alg: Algorithm,
    kraw: &[c64],
    m: usize,
    d: usize,
    loading: f64,
    coherence: bool,
    steering: &[C<T>],
    st: &mut [C<T>],
    n2: &mut [T],
) -> std::result::Result<Vec<c64>, String> {
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
        Algorithm::Sevd | Algorithm::SrpPhat => Ok(Vec::new()),
        Algorithm::Gsvd => {
            let kinv = llt.inverse();
            Ok(row_major(&kinv))
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
            Ok(row_major(&w))
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
            if st.is_empty() {
                // K is the identity: the caller shares the plan's steering (a_w = a).
                return Ok(row_major(&linv));
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
            for dir in 0..d {
                let mut acc = 0.0;
                for i in 0..m {
                    let z = aw[(i, dir)];
                    acc += z.re * z.re + z.im * z.im;
                    st[dir * m + i] = C::new(T::of_f64(z.re), T::of_f64(z.im));
                }
                n2[dir] = T::of_f64(acc);
            }
            Ok(row_major(&linv))
        }
    }
}
