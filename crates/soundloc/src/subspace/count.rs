//! How many sources are active in a window: the minimum description length (MDL) criterion
//! of Wax & Kailath (1985) on each bin's eigenvalues, then the median over the bins.
//!
//! For eigenvalues λ₁ ≥ … ≥ λ_M of a correlation estimated from N snapshots, with
//! g(k) and a(k) the geometric and arithmetic means of the M − k smallest,
//!
//! MDL(k) = −N·(M − k)·ln(g(k)/a(k)) + ½·k·(2M − k)·ln N,   k̂ = argmin_{0 ≤ k < M} MDL(k).
//!
//! N is the number of independent snapshots: overlapping STFT frames are not, so the
//! backend passes N = W·hop/N_fft (W frames advancing by `hop` of an N_fft-point window;
//! 50 × 160/512 ≈ 16 at HARK's defaults) — with N = W the criterion over-counts.
//!
//! The criterion assumes white noise of unknown level: for the noise-aware algorithms the
//! values are those of the whitened problem (generalized eigenvalues of (R, K) for GEVD,
//! K^{-1/2}RK^{-1/2} for GEVD-HARK, singular values of K⁻¹R for GSVD), so coherent noise
//! that K describes does not count as a source; for SEVD it does. Per window the estimate
//! is the median of k̂ over the bins that carry weight (the lower median for an even
//! count), which ignores bins where a talker is momentarily silent or a harmonic stands
//! alone.
//!
//! Values below `floor` × λ₁ count as noise ([`model_floor`]): a source heard from a
//! direction is not exactly one dimension of a bin's correlation, because its delays
//! between the microphones shift it within the analysis frame; the rest appears as a
//! second value of the order of (τ·fs/N)² × λ₁ (τ the largest delay across the array, N
//! the frame length; on a 10 cm ring at 16 kHz and N = 512, (τ·fs/N)² is −41 dB and the
//! value was measured at −37 dB). Above ~35 dB SNR it stands out of the noise and MDL
//! counted every source twice.

use crate::real::Real;

/// The ratio to the largest value under which [`mdl`] counts values as noise:
/// 10·(τ·fs/N)² for an array whose farthest microphones are `aperture_m` apart (τ =
/// aperture / c, c = 343 m/s), 10 dB above the order of the frame-shift residue the
/// module docs describe (6 dB above the value measured there), within 10⁻⁶ … 10⁻¹; 10⁻³
/// when the positions are not known (`aperture_m` None or 0).
pub fn model_floor(aperture_m: Option<f64>, sample_rate_hz: u32, nfft: usize) -> f64 {
    match aperture_m {
        Some(a) if a > 0.0 && a.is_finite() => {
            let c = crate::array::freefield::DEFAULT_SPEED_OF_SOUND_M_S;
            let rho = a / c * sample_rate_hz as f64 / nfft.max(1) as f64;
            (10.0 * rho * rho).clamp(1e-6, 1e-1)
        }
        _ => 1e-3,
    }
}

/// k̂ for one bin: `values` descending (any scale, either precision), `snapshots` = N ≥ 1,
/// values below `floor` × the largest taken as at that level ([`model_floor`]; 0 for the
/// plain criterion).
pub fn mdl<T: Real>(values: &[T], snapshots: usize, floor: f64) -> usize {
    let m = values.len();
    if m < 2 || snapshots == 0 {
        return 0;
    }
    let top = values.iter().map(|&x| Real::to_f64(x)).fold(0.0f64, f64::max);
    if !(top > 0.0 && top.is_finite()) {
        return 0;
    }
    // Values at or below rounding, or below what the model resolves, are clamped: they
    // are noise, not information.
    let floor = top * floor.max(1e-12);
    let n = snapshots as f64;
    // Tail sums Σ_{i ≥ k} ln λ_i and Σ_{i ≥ k} λ_i, from the smallest value up: O(M), and
    // no allocation (called per bin and window).
    let (mut sum_ln, mut sum) = (0.0f64, 0.0f64);
    let mut best = (f64::INFINITY, 0usize);
    for k in (0..m).rev() {
        let x = Real::to_f64(values[k]);
        let v = if x.is_finite() { x.max(floor) } else { floor };
        sum_ln += v.ln();
        sum += v;
        let q = (m - k) as f64;
        let (log_g, a) = (sum_ln / q, sum / q);
        let score = -n * q * (log_g - a.ln()) + 0.5 * (k as f64) * (2.0 * m as f64 - k as f64) * n.ln();
        // Ties go to the smaller k.
        if score <= best.0 {
            best = (score, k);
        }
    }
    best.1
}

/// The window's estimate from the per-bin estimates (lower median; 0 when empty).
pub fn median(mut counts: Vec<usize>) -> usize {
    if counts.is_empty() {
        return 0;
    }
    counts.sort_unstable();
    counts[(counts.len() - 1) / 2]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mdl_counts_clear_signals_above_a_flat_floor() {
        // Noise eigenvalues ≈ 1 with sampling spread, signals well above.
        let noise = [1.35, 1.25, 1.15, 1.05, 0.95, 0.85, 0.8, 0.7];
        for k in 0..=2 {
            let mut v: Vec<f64> = [40.0, 12.0][..k].to_vec();
            v.extend_from_slice(&noise[..8 - k]);
            assert_eq!(mdl(&v, 50, 0.0), k, "{v:?}");
        }
        assert_eq!(mdl(&[0.0f64; 8], 50, 0.0), 0);
        assert_eq!(mdl(&[5.0f64], 50, 0.0), 0);
        // f32 values give the same count.
        let v32: Vec<f32> = [40.0, 12.0, 1.35, 1.25, 1.15, 1.05, 0.95, 0.85].to_vec();
        assert_eq!(mdl(&v32, 50, 0.0), 2);
        // One source at 50 dB SNR with its frame-shift residue 37 dB below it (as measured
        // on a 10 cm ring): two without a floor, one with the ring's.
        let mut v = vec![1e5, 1e5 * 10f64.powf(-3.7)];
        v.extend_from_slice(&noise[..6]);
        assert_eq!(mdl(&v, 16, 0.0), 2);
        let floor = model_floor(Some(0.1), 16000, 512);
        assert!((floor.log10() * 10.0 + 30.8).abs() < 0.1, "{floor}");
        assert_eq!(mdl(&v, 16, floor), 1);
        // At 20 dB SNR the floor lies below the noise: counts as before.
        let mut v = vec![100.0, 40.0];
        v.extend_from_slice(&noise[..6]);
        assert_eq!(mdl(&v, 16, floor), mdl(&v, 16, 0.0));
        assert_eq!(model_floor(None, 16000, 512), 1e-3);
        assert_eq!(median(vec![3, 1, 2, 2]), 2);
        assert_eq!(median(vec![]), 0);
    }
}
