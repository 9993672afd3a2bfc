//! How spectra and sources look, decided once: the plots ([`super::plot`]) and the live
//! browser view ([`super::live`]) both take their colours, azimuth binning, dB scale and
//! direction conventions from here (the live view receives them in its `hello` message, so
//! the page never hard-codes them).
//!
//! - **Directions.** Azimuth = atan2(y, x) in degrees, from +x toward +y, shown on
//!   −180..180 (left to right on a sky map, bottom to top on a time plot); elevation from
//!   the x-y plane, −90..90 (bottom to top). A ring grid's polar view is seen from above
//!   with +x (0°) up and +y (90°) to the left, so azimuth runs counter-clockwise.
//! - **Colour map.** Viridis (dark blue = low, yellow = high), linear in dB between the
//!   scale's ends.
//! - **Scale.** A finished run (a plot) spans the smallest to the largest finite dB value
//!   of the whole spectrum; a live view spans those of the most recent
//!   [`LIVE_SCALE_RESULTS`] results.
//! - **Azimuth bins.** Time plots show [`AZIMUTH_BIN_DEG`]-wide azimuth bins, each the
//!   maximum over all directions in the bin (all elevations); an empty bin takes the nearest
//!   non-empty one (circularly).
//! - **Sources.** Untracked peaks are red ([`PEAK_RGB`]); a tracked source takes
//!   [`track_rgb`]`(id)`, so one id has one colour in every view.

/// Width of an azimuth bin of time plots, degrees.
pub const AZIMUTH_BIN_DEG: f64 = 2.0;

/// Results whose dB range sets a live view's colour scale.
pub const LIVE_SCALE_RESULTS: usize = 200;

/// Colour of an untracked peak.
pub const PEAK_RGB: [u8; 3] = [230, 30, 30];

/// Colour of a value that is not finite.
pub const NAN_RGB: [u8; 3] = [40, 40, 40];

/// Viridis, sampled at 9 points.
const VIRIDIS: [[u8; 3]; 9] = [
    [68, 1, 84],
    [71, 44, 122],
    [59, 81, 139],
    [44, 113, 142],
    [33, 144, 141],
    [39, 173, 129],
    [92, 200, 99],
    [170, 220, 50],
    [253, 231, 37],
];

/// Track colours (Okabe–Ito, colour-blind safe), cycled by id.
const TRACKS: [[u8; 3]; 8] = [
    [230, 159, 0],
    [86, 180, 233],
    [0, 158, 115],
    [240, 228, 66],
    [0, 114, 178],
    [213, 94, 0],
    [204, 121, 167],
    [255, 255, 255],
];

/// The colour of `x` in [0, 1] (clamped) on the colour map.
pub fn colormap(x: f64) -> [u8; 3] {
    if !x.is_finite() {
        return NAN_RGB;
    }
    let x = x.clamp(0.0, 1.0) * 8.0;
    let i = (x.floor() as usize).min(7);
    let f = x - i as f64;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    let mix = |p: u8, q: u8| (p as f64 + (q as f64 - p as f64) * f).round() as u8;
    [mix(a[0], b[0]), mix(a[1], b[1]), mix(a[2], b[2])]
}

/// The colour of `db` on the scale `lo..hi` dB.
pub fn db_rgb(db: f32, lo: f32, hi: f32) -> [u8; 3] {
    if !db.is_finite() {
        return NAN_RGB;
    }
    colormap(((db - lo) / (hi - lo)) as f64)
}

/// The colour map as `n` ≥ 2 evenly spaced entries (what the live view draws with).
pub fn colormap_table(n: usize) -> Vec<[u8; 3]> {
    let n = n.max(2);
    (0..n).map(|i| colormap(i as f64 / (n - 1) as f64)).collect()
}

/// The colour of tracked source `id` (ids cycle through the palette).
pub fn track_rgb(id: i64) -> [u8; 3] {
    TRACKS[id.rem_euclid(TRACKS.len() as i64) as usize]
}

/// The whole track palette, in id order modulo its length.
pub fn track_palette() -> &'static [[u8; 3]] {
    &TRACKS
}

/// The scale's ends for `values`: the smallest and largest finite values, (0, 1) when there
/// is none, widened to 1 dB when they coincide.
pub fn db_range(values: impl IntoIterator<Item = f32>) -> (f32, f32) {
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for v in values.into_iter().filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if hi <= lo {
        hi = lo + 1.0;
    }
    (lo, hi)
}

/// Azimuth wrapped to [−180, 180).
pub fn wrap_azimuth_deg(az: f64) -> f64 {
    (az + 180.0).rem_euclid(360.0) - 180.0
}

/// The azimuth bin (of [`AZIMUTH_BIN_DEG`]) holding `az`, 0 at −180°.
pub fn azimuth_bin(az: f64) -> usize {
    let bins = azimuth_bins();
    (((wrap_azimuth_deg(az) + 180.0) / AZIMUTH_BIN_DEG).floor() as usize).min(bins - 1)
}

/// Number of azimuth bins around the circle.
pub fn azimuth_bins() -> usize {
    (360.0 / AZIMUTH_BIN_DEG).round() as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colormap_ends_are_viridis_ends_and_it_is_monotone_in_brightness() {
        assert_eq!(colormap(0.0), [68, 1, 84]);
        assert_eq!(colormap(1.0), [253, 231, 37]);
        assert_eq!(colormap(-3.0), colormap(0.0));
        assert_eq!(colormap(f64::NAN), NAN_RGB);
        let lum = |c: [u8; 3]| 0.3 * c[0] as f64 + 0.59 * c[1] as f64 + 0.11 * c[2] as f64;
        let t = colormap_table(64);
        assert!(t.windows(2).all(|w| lum(w[1]) >= lum(w[0]) - 0.5));
        assert_eq!(db_rgb(5.0, 0.0, 10.0), colormap(0.5));
    }

    #[test]
    fn bins_ranges_and_track_colours() {
        assert_eq!(azimuth_bin(-180.0), 0);
        assert_eq!(azimuth_bin(180.0), 0);
        assert_eq!(azimuth_bin(179.9), azimuth_bins() - 1);
        assert_eq!(azimuth_bin(1.0), 90);
        assert_eq!(db_range([3.0, f32::NAN, -1.0]), (-1.0, 3.0));
        assert_eq!(db_range([2.0, 2.0]), (2.0, 3.0));
        assert_eq!(db_range([]), (0.0, 1.0));
        assert_eq!(track_rgb(0), track_rgb(8));
        assert_ne!(track_rgb(0), track_rgb(1));
        assert_eq!(track_rgb(-1), track_rgb(7));
    }
}
