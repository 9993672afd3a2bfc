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

/// Speeds of sound outside this range (m/s) get a note from [`free_field_notes`]: air is
/// 331–355 m/s from 0 to 40 °C, water about 1480 (hydrophone arrays); 34 300 (cm/s) or
/// 1 are slips.
pub const PLAUSIBLE_SPEED_OF_SOUND_M_S: std::ops::RangeInclusive<f64> = 200.0..=2000.0;

/// What looks wrong in free-field TFs asked for with `geometry` (its positions as used,
/// after [`Geometry::direction_frame`]), a grid of `radius_m` and `speed_of_sound_m_s`:
/// positions that look like millimetres ([`Geometry::units_note`]), a grid radius inside
/// the array, an implausible speed of sound. Said by `localize --geometry` and `tf make`
/// alike; the TFs are made as asked.
pub fn free_field_notes(geometry: &Geometry, radius_m: f64, speed_of_sound_m_s: f64) -> Vec<String> {
    let mut notes: Vec<String> = geometry.units_note().into_iter().collect();
    let reach = geometry
        .mics
        .iter()
        .map(|&p| super::geometry::dist(p, [0.0; 3]))
        .fold(0.0, f64::max);
    if radius_m < reach {
        notes.push(format!(
            "warning: the grid radius {radius_m} m is inside the array (its farthest microphone is {reach:.3} m \
             from the grid's centre): the directions are points among the microphones, not far-field \
             directions; HARK's free-field TFs use 1 m or more"
        ));
    }
    if speed_of_sound_m_s.is_finite() && !PLAUSIBLE_SPEED_OF_SOUND_M_S.contains(&speed_of_sound_m_s) {
        notes.push(format!(
            "warning: a speed of sound of {speed_of_sound_m_s} m/s: in air it is 331-355 m/s (343 at 20 °C, the \
             default), in water about 1480; the value is in metres per second (34300 would be cm/s)"
        ));
    }
    notes
}

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
    if nfft < 4 {
        return Err(Error::Config(format!(
            "free-field TFs: FFT length {nfft}: must be at least 4 (as the analysis needs)"
        )));
    }
    if sample_rate_hz == 0 {
        return Err(Error::Config(
            "free-field TFs: a sample rate of 0 Hz: must be positive".into(),
        ));
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
            "free-field TFs: speed of sound {speed_of_sound_m_s} m/s must be a positive, finite number"
        )));
    }
    if geometry.mics.len() < 2 || grid.is_empty() {
        return Err(Error::Config(format!(
            "free-field TFs: {} microphone(s) and {} directions: localization needs at least 2 microphones and 1 direction",
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

    /// `localize --geometry` and `tf make` share these notes (tf make said none until
    /// 2026-12-02: millimetre positions and a 1-microphone geometry went through silently).
    #[test]
    fn free_field_notes_and_a_single_microphone() {
        let ring = Geometry::circle(8, 0.0365, 0.0);
        assert!(free_field_notes(&ring, 1.0, 343.0).is_empty());
        assert!(free_field_notes(&ring, 1.0, 1480.0).is_empty());
        let mm = Geometry::circle(8, 36.5, 0.0);
        let n = free_field_notes(&mm, 1.0, 343.0);
        assert_eq!(n.len(), 2, "{n:?}");
        // Warnings: the CLI prints them under -q too, Python raises them through `warnings`.
        assert!(n.iter().all(|m| m.starts_with("warning: ")), "{n:?}");
        assert!(
            n[0].contains("millimetres") && n[1].contains("inside the array"),
            "{n:?}"
        );
        for c in [34300.0, 1.0] {
            let n = free_field_notes(&ring, 1.0, c);
            assert!(n.len() == 1 && n[0].contains("331-355 m/s"), "{c}: {n:?}");
        }
        let one = Geometry::new(vec![[0.0; 3]], std::path::Path::new("one")).unwrap();
        let e = free_field(&one, &Grid::ring(5.0, 0.0, 1.0), 512, 16000, 0..257, 343.0).unwrap_err();
        assert!(e.to_string().contains("needs at least 2 microphones"), "{e}");
    }

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
