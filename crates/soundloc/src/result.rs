//! What a localization produces: plain data that outputs and tracking consume.

use serde::{Deserialize, Serialize};

/// One localized source in one result.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Source {
    /// Tracking id (None until a tracker assigns one).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub id: Option<i64>,
    /// Index of the direction in the TF grid.
    pub grid_index: usize,
    /// Azimuth in degrees, atan2(y, x) from +x toward +y, in (-180, 180].
    pub azimuth_deg: f64,
    /// Elevation in degrees from the x-y plane.
    pub elevation_deg: f64,
    /// Direction as stored in the TF grid (unit vector or measurement position), x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// MUSIC power in dB: 10·log10(P̄ + 1).
    pub power_db: f64,
    /// A tracked source not observed in this window: carried at its last observed
    /// direction and power while its PAUSE_LENGTH runs, as HARK's SourceTracker outputs
    /// it, or copied at its first direction and power into the windows before its first
    /// observation by the interval extender (PREROLL_LENGTH) (written `"held": true` in
    /// JSON; absent = false).
    #[serde(skip_serializing_if = "std::ops::Not::not", default)]
    pub held: bool,
}

/// The result of one correlation window.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LocalizationResult {
    /// The result frame c (STFT frame index; see `correlation` for how windows map to c).
    pub frame: usize,
    /// Time of frame c's start in seconds: c·hop / fs.
    pub time_s: f64,
    /// Sources, strongest first.
    pub sources: Vec<Source>,
    /// Estimated number of active sources in this window ([`crate::subspace::count`]: MDL
    /// on the eigenvalues per bin, median over the bins); `None` where not estimated
    /// (SRP-PHAT, the CUDA backend, results read from files that lack it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub num_active: Option<usize>,
}
