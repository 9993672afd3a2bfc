//! Free-field (geometric) transfer functions from a geometry and a grid.
//!
//! For grid point s (metres), microphone position p_m (metres) and bin k of an N-point
//! FFT at fs Hz (f_k = k·fs/N):
//!
//! ```text
//! r_m    = |s − p_m|                       (metres)
//! a_m(k) = exp(−j·2π·f_k·r_m / c)          (|a_m(k)| = 1)
//! ```
//!
//! This is a point source at the grid position itself, and it is exactly HARK's
//! geometric-TF convention, established from tamago_geotf.zip (HARKTOOL5): magnitude 1
//! for every mic and bin (no 1/r spreading — "normalization type" 1), phase = −ω·r_m/c
//! with the absolute source-to-microphone distance (no array-centre reference), so the
//! nearer microphone has the more positive phase; c = 343 m/s fits (340 or 344 do not).
//! With the file's own positions (4 decimals in its XML) our values match its f32 numbers
//! within 3·10⁻⁵ absolute.
//!
//! Unit-vector grids ([`super::Grid::sphere`]`(n, 1.0)`) are therefore sources **1 m
//! away** — as HARKTOOL's default geometric TFs — not plane waves; build the grid with a
//! larger radius for a farther source.
//!
//! Phases are computed in f64 and reduced modulo 2π before rounding to f32.

use super::{Geometry, Grid, TransferFunctions};
use crate::{Error, Result};
use num_complex::Complex;
use std::ops::Range;

/// Speed of sound used by HARK's geometric TFs (fits tamago_geotf.zip), m/s.
pub const DEFAULT_SPEED_OF_SOUND_M_S: f64 = 343.0;

/// Free-field TFs for `geometry` and `grid` over the absolute `bins` of an `nfft`-point
/// FFT at `sample_rate_hz` (see the module docs for the formula). Errors when the bins
/// are empty or beyond nfft/2, when the speed of sound or sample rate is not positive,
/// when the grid or geometry is empty or holds non-finite positions.
pub fn free_field(
    geometry: &Geometry,
    grid: &Grid,
    nfft: usize,
    sample_rate_hz: u32,
    bins: Range<usize>,
    speed_of_sound_m_s: f64,
) -> Result<TransferFunctions> {
    if nfft < 2 || sample_rate_hz == 0 {
        return Err(Error::Config(format!(
            "free-field TFs: nfft {nfft} and sample rate {sample_rate_hz} Hz must be positive (nfft ≥ 2)"
        )));
    }
    if bins.start >= bins.end || bins.end > nfft / 2 + 1 {
        return Err(Error::Config(format!(
            "free-field TFs: bins {}..{} must be non-empty and within 0..{} (nfft {nfft})",
            bins.start,
            bins.end,
            nfft / 2 + 1
        )));
    }
    if !(speed_of_sound_m_s.is_finite() && speed_of_sound_m_s > 0.0) {
        return Err(Error::Config(format!(
            "free-field TFs: speed of sound {speed_of_sound_m_s} m/s must be positive"
        )));
    }
    if geometry.mics.is_empty() || grid.is_empty() {
        return Err(Error::Config(format!(
            "free-field TFs: {} microphones and {} directions: need at least one of each",
            geometry.mics.len(),
            grid.len()
        )));
    }
    let values = grid
        .len()
        .saturating_mul(geometry.mics.len())
        .saturating_mul(bins.len());
    if values > super::MAX_TF_VALUES {
        return Err(Error::Config(format!(
            "free-field TFs: {} directions × {} microphones × {} bins = {values} values, more than the {} allowed \
             (2 GiB): use a coarser grid or fewer bins",
            grid.len(),
            geometry.mics.len(),
            bins.len(),
            super::MAX_TF_VALUES
        )));
    }
    if let Some(i) = geometry
        .mics
        .iter()
        .position(|p| p.iter().any(|v| !v.is_finite()))
    {
        return Err(Error::Config(format!(
            "free-field TFs: microphone {i} position is not finite"
        )));
    }
    if let Some(i) = grid.points.iter().position(|p| p.iter().any(|v| !v.is_finite())) {
        return Err(Error::Config(format!(
            "free-field TFs: grid point {i} is not finite"
        )));
    }
    let m = geometry.mics.len();
    let nb = bins.end - bins.start;
    let two_pi = std::f64::consts::TAU;
    // Phase per metre per bin: 2π·fs/(N·c).
    let per_m_per_bin = two_pi * sample_rate_hz as f64 / (nfft as f64 * speed_of_sound_m_s);
    let mut data = Vec::with_capacity(grid.len() * m * nb);
    for s in &grid.points {
        for p in &geometry.mics {
            let r = super::geometry::dist(*s, *p);
            for k in bins.clone() {
                let phase = -(per_m_per_bin * r * k as f64).rem_euclid(two_pi);
                data.push(Complex::new(phase.cos() as f32, phase.sin() as f32));
            }
        }
    }
    Ok(TransferFunctions {
        nfft,
        sample_rate_hz,
        grid: grid.clone(),
        mic_positions: geometry.mics.clone(),
        num_mics: m,
        first_bin: bins.start,
        num_bins: nb,
        data,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sign_magnitude_and_delay() {
        let geo = Geometry::circle(4, 0.05, 0.0);
        let grid = Grid::ring(90.0, 0.0, 2.0);
        let tf = free_field(&geo, &grid, 512, 16000, 0..257, 343.0).unwrap();
        assert_eq!((tf.num_mics, tf.num_dirs(), tf.num_bins), (4, 4, 257));
        tf.validate().unwrap();
        // Bin 0 is 1 for every mic; magnitude is 1 everywhere.
        assert!(tf.data.iter().all(|c| (c.norm() - 1.0).abs() < 1e-6));
        assert_eq!(tf.get(0, 0, 0), Complex::new(1.0, 0.0));
        // Source at +x (dir 0): mic 0 at +x is nearest, mic 2 at −x farthest. At bin 1
        // (31.25 Hz) phases are small and unwrapped: nearer ⇒ more positive.
        let ph = |mic| tf.get(0, mic, 1).arg() as f64;
        assert!(ph(0) > ph(1) && ph(1) > ph(2));
        assert!((ph(1) - ph(3)).abs() < 1e-6, "symmetric mics");
        // Exact value: phase = −2π·31.25·(2 − 0.05)/343.
        let want = -std::f64::consts::TAU * 31.25 * 1.95 / 343.0;
        assert!((ph(0) - want).abs() < 1e-6);
        // Restricted bins equal the same bins of the full set.
        let part = free_field(&geo, &grid, 512, 16000, 16..89, 343.0).unwrap();
        assert_eq!(part.bins(), 16..89);
        assert_eq!(part.get(3, 2, 40), tf.get(3, 2, 40));
        assert_eq!(
            part.restrict_bins(20..30).unwrap(),
            tf.restrict_bins(20..30).unwrap()
        );
    }

    #[test]
    fn bad_inputs() {
        let geo = Geometry::circle(4, 0.05, 0.0);
        let grid = Grid::ring(90.0, 0.0, 1.0);
        assert!(free_field(&geo, &grid, 512, 16000, 0..258, 343.0).is_err());
        assert!(free_field(&geo, &grid, 512, 16000, 5..5, 343.0).is_err());
        assert!(free_field(&geo, &grid, 512, 16000, 0..10, 0.0).is_err());
        assert!(free_field(&geo, &grid, 512, 0, 0..10, 343.0).is_err());
        let mut g2 = grid.clone();
        g2.points[1][0] = f64::NAN;
        let e = free_field(&geo, &g2, 512, 16000, 0..10, 343.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("grid point 1"), "{e}");
    }
}
