//! Tracking: peaks over time → sources with ids (HARK's `SourceTracker` and
//! `SourceIntervalExtender`), plus a per-source summary.
//!
//! Input: a sequence of [`LocalizationResult`]s in increasing `frame` order (the STFT frame
//! index c of each result). Output: the same results with `Source::id` set.
//!
//! ## [`SourceTracker`] (HARK `SourceTracker`)
//! Parameters ([`TrackerConfig`]), HARK names and defaults:
//!
//! | field | HARK | default | unit |
//! |---|---|---|---|
//! | `thresh_db` | `THRESH` | none in HARK; 0 here (accepts every peak, since powers are 10·log10(P̄+1) ≥ 0) | dB |
//! | `pause_length` | `PAUSE_LENGTH` | 800 | tenths of an STFT frame (see below) |
//! | `min_src_interval_deg` | `MIN_SRC_INTERVAL` | 20 | degrees |
//! | `min_id` | `MIN_ID` | 0 | — |
//!
//! Per result:
//! 1. Peaks with `power_db ≥ THRESH` are *eligible*; the others are dropped (they never
//!    appear in the output). Every tracked (alive) source is paired with eligible peaks
//!    by the angle between direction vectors (x, y, z normalised; azimuth/elevation when
//!    the vector is zero). Pairs with angle < `MIN_SRC_INTERVAL` are assigned greedily,
//!    **closest pair first** (ties: lower id, then earlier peak), so a peak is claimed by
//!    at most one source and a source claims at most one peak. Without conflicts this is
//!    exactly HARK's "each source takes its nearest peak". A source that claims a peak
//!    takes the peak's position and power and its remaining life is reset to
//!    `PAUSE_LENGTH`.
//! 2. A source that claims nothing is **carried**: it stays at its last position and
//!    power, and its remaining life drops by 10 per STFT frame elapsed since the previous
//!    result (10 when frames are consecutive or not increasing). When the remaining life
//!    drops below 0 the source ends and its id is never reused.
//! 3. Each unclaimed eligible peak (strongest first) whose angle to every alive source
//!    (at its position after steps 1–2, including sources started earlier in this step) is
//!    ≥ `MIN_SRC_INTERVAL` starts a new source with the next id (`MIN_ID`, `MIN_ID`+1, …).
//!    An unclaimed peak closer than that to a source is a duplicate of it and is dropped.
//!    (Angles within [`ANGLE_TOL_DEG`] of `MIN_SRC_INTERVAL` count as equal to it, in
//!    steps 1 and 3: grid directions a whole number of steps apart must not depend on
//!    rounding.)
//!
//! The output holds every alive source — claimed, new **and carried** — as HARK's
//! SourceTracker outputs its whole source list each frame: a carried source appears at its
//! last position with its last power, which bridges short pauses in speech for downstream
//! separation, marked [`Source::held`]. Sources are sorted strongest first (ties: lower id).
//!
//! **Unit of `PAUSE_LENGTH`.** HARK runs SourceTracker once per STFT frame (LocalizeMUSIC
//! holds its last result between PERIODs) and subtracts 10 per call, so `PAUSE_LENGTH` is in
//! tenths of a frame: 800 keeps an unmatched source for 80 frames = 0.8 s at HARK's
//! defaults (16 kHz, ADVANCE 160, i.e. 10 ms per frame — hence "ms" in HARK's docs). soundloc
//! results come every PERIOD frames, so the tracker subtracts 10 × (frames elapsed), which
//! gives the same lifetime in time. Precisely: after its last claimed peak at frame c, a
//! source is output for results with frame ≤ c + ⌊PAUSE_LENGTH/10⌋ and ends at the first
//! later result.
//!
//! **Crossing sources.** The tracker has no motion model (as HARK): matching is by
//! proximity to the last position. Two sources whose paths cross on the sphere at
//! different times (distinct angular speeds, so they are never at the crossing point
//! together) keep their ids as long as each moves less per result than the distance to the
//! other. Two sources meeting head-on on one circle at the same time are ambiguous to a
//! proximity tracker: ids stay in angular order, i.e. they *bounce* — at the first result
//! after the crossing each id takes the peak nearest its last position, which is the other
//! source's. When both sources fall into one peak (closer than the grid/peak resolution),
//! the source nearer that peak claims it and the other is carried. For head-on crossings
//! enable [`SourceTracker::with_motion_prediction`] (not in HARK): each source is matched
//! against its position extrapolated with its last angular velocity (azimuth and elevation
//! degrees per frame), which keeps ids through a crossing at constant speeds.
//!
//! **Confirmation** (not in HARK; [`TrackerConfig::confirm_frames`]). With
//! `confirm_frames` = C > 0, step 3 starts a *tentative* source instead: it claims peaks
//! in steps 1–2 after every tracked source (a peak within MIN_SRC_INTERVAL of both goes
//! to the tracked source, even where the tentative one is closer) but has no id and is
//! not output. It gets the next
//! id, and is output from that result on, at the first result that claims a peak for it at
//! least C frames after its first sighting. It is dropped when it claims nothing for C
//! frames (or, when results are further apart than C frames, at the next result that
//! does not claim a peak for it); its ids are never used up. A peak of a few windows — a
//! reflection, a noise burst, a sidelobe — then starts no track. A
//! [`crate::Localizer`] sets C to the window length W (two sightings from windows that
//! share no audio) when no algorithm is named and to 0 for a named algorithm; measured
//! with `soundloc bench --tracks` (docs/accuracy.md, "Confirming new tracks").
//!
//! ## [`extend`] / [`IntervalExtender`] (HARK `SourceIntervalExtender`)
//! `PREROLL_LENGTH` ([`IntervalExtenderConfig::preroll_length`], default 50, in STFT
//! frames): a source first seen at frame f is also emitted — at its first position and
//! power — in every earlier result with frame in [f − PREROLL_LENGTH, f), so that downstream
//! separation does not miss its onset; these copies are marked `held` (not observed in
//! that window), so [`summarize`] starts the source at its first observation. Only a
//! source's first appearance is extended.
//! [`extend`] does this on a whole run; [`IntervalExtender`] streams with a delay of
//! PREROLL_LENGTH frames.
//!
//! ## [`summarize`]
//! One [`SourceSummary`] per id: first/last frame and time, mean direction (the circular
//! mean of the azimuths, the mean of the elevations), maximum power, number of results,
//! and (given the tracker's [`TrackStart`]s: [`summarize_with_starts`],
//! [`Summarizer::started`]) when the tracker first saw it, before confirming it.

mod extender;
mod summary;
mod tracker;

pub use extender::{extend, IntervalExtender};
pub use summary::{summarize, summarize_with_starts, SourceSummary, Summarizer};
pub use tracker::SourceTracker;

use serde::Serialize;

use crate::error::{Error, Result};
use crate::result::Source;

/// When the tracker first saw a source that has just been given its id: with
/// confirmation ([`TrackerConfig::confirm_frames`] = C) that sighting is C frames or more
/// before the first result carrying the id; without it, that result's own. From
/// [`SourceTracker::take_started`]; [`Summarizer::started`] takes it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TrackStart {
    /// The id just given.
    pub id: i64,
    /// Frame of the result of the first sighting.
    pub frame: usize,
    /// `time_s` of that result, seconds.
    pub time_s: f64,
}

/// HARK SourceTracker parameters. See the [module docs](self) for semantics.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct TrackerConfig {
    /// `THRESH`: peaks below this power (dB) are ignored. HARK has no default; the
    /// [`Default`] here is 0 dB, which accepts every peak.
    pub thresh_db: f64,
    /// `PAUSE_LENGTH` (800): life of a source without peaks, in tenths of an STFT frame
    /// (10 are subtracted per frame; 800 = 80 frames = 0.8 s at 16 kHz and ADVANCE 160).
    pub pause_length: f64,
    /// `MIN_SRC_INTERVAL` (20): angle in degrees below which a peak belongs to a tracked
    /// source; at or above it a peak starts a new source.
    pub min_src_interval_deg: f64,
    /// `MIN_ID` (0): the first id assigned.
    pub min_id: i64,
    /// Not in HARK: how many STFT frames a new source must be seen over before it gets
    /// an id (see the [module docs](self), "Confirmation"). `Some(0)`: at once, as HARK.
    /// `None`: the choice of whoever builds the stream — a
    /// [`crate::Localizer`] makes it the window length W in its defaults (no algorithm
    /// named) and 0 for a named algorithm; [`SourceTracker`] alone takes it as 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub confirm_frames: Option<usize>,
}

impl Default for TrackerConfig {
    fn default() -> Self {
        TrackerConfig {
            thresh_db: 0.0,
            pause_length: 800.0,
            min_src_interval_deg: 20.0,
            min_id: 0,
            confirm_frames: None,
        }
    }
}

impl TrackerConfig {
    /// HARK's defaults with `THRESH` = `thresh_db`.
    pub fn with_thresh(thresh_db: f64) -> Self {
        TrackerConfig {
            thresh_db,
            ..Self::default()
        }
    }

    /// Checks that every value is finite and `PAUSE_LENGTH`, `MIN_SRC_INTERVAL` are ≥ 0.
    pub fn validate(&self) -> Result<()> {
        if !self.thresh_db.is_finite() {
            return Err(Error::Config(format!(
                "tracker THRESH must be finite, got {}",
                self.thresh_db
            )));
        }
        if !(self.pause_length.is_finite() && self.pause_length >= 0.0) {
            return Err(Error::Config(format!(
                "tracker PAUSE_LENGTH must be finite and >= 0, got {}",
                self.pause_length
            )));
        }
        if !(self.min_src_interval_deg.is_finite() && self.min_src_interval_deg >= 0.0) {
            return Err(Error::Config(format!(
                "tracker MIN_SRC_INTERVAL must be finite and >= 0 degrees, got {}",
                self.min_src_interval_deg
            )));
        }
        if self.confirm_frames.is_some_and(|c| c > 0) && self.min_src_interval_deg == 0.0 {
            return Err(Error::Config(
                "tracker confirmation (confirm_frames > 0) needs MIN_SRC_INTERVAL > 0 degrees: \
                 a new source is confirmed by a later peak within that angle (or set it to 0: --confirm 0, tracker_confirm_frames=0)"
                    .into(),
            ));
        }
        // Ids go out as 32-bit integers (HARK's streams and logs, ODAS): room for 10⁹ more.
        // HARK's logs and stream, and Python's arrays, write −1 for "no id", so ids start at
        // 0 or above.
        if !(0..=MAX_MIN_ID).contains(&self.min_id) {
            return Err(Error::Config(format!(
                "tracker MIN_ID must be within 0..={MAX_MIN_ID} (ids are 32-bit integers in HARK's and ODAS's outputs, \
                 and HARK's logs and stream mark a source without an id by −1), got {}",
                self.min_id
            )));
        }
        Ok(())
    }
}

/// Angles within this many degrees of `MIN_SRC_INTERVAL` count as equal to it: grid
/// directions a whole number of steps apart (20° = four steps of a 5° ring) come out of
/// the unit vectors' arithmetic as 19.99999999999995° at some azimuths and
/// 20.00000000000003° at others, and an id must not depend on which.
pub const ANGLE_TOL_DEG: f64 = 1e-9;

/// Largest `min_id` a tracker takes (ids start at 0 or above).
pub const MAX_MIN_ID: i64 = 1_000_000_000;

/// HARK SourceIntervalExtender parameters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize)]
pub struct IntervalExtenderConfig {
    /// `PREROLL_LENGTH` (50): how many STFT frames before its first appearance a source is
    /// made to start.
    pub preroll_length: usize,
}

impl Default for IntervalExtenderConfig {
    fn default() -> Self {
        IntervalExtenderConfig { preroll_length: 50 }
    }
}

/// Unit direction vector of a source: (x, y, z) normalised, or from azimuth/elevation when
/// the vector is zero or not finite.
pub(crate) fn unit_vector(s: &Source) -> [f64; 3] {
    let n = (s.x * s.x + s.y * s.y + s.z * s.z).sqrt();
    if n.is_finite() && n > 0.0 {
        [s.x / n, s.y / n, s.z / n]
    } else {
        from_az_el(s.azimuth_deg, s.elevation_deg)
    }
}

pub(crate) fn from_az_el(az_deg: f64, el_deg: f64) -> [f64; 3] {
    let (az, el) = (az_deg.to_radians(), el_deg.to_radians());
    [el.cos() * az.cos(), el.cos() * az.sin(), el.sin()]
}

/// Angle between two unit vectors, degrees (NaN-free for finite inputs).
pub(crate) fn angle_deg(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).clamp(-1.0, 1.0);
    d.acos().to_degrees()
}

/// Wraps an angle difference into (−180, 180].
pub(crate) fn wrap_deg(d: f64) -> f64 {
    let w = d.rem_euclid(360.0);
    if w > 180.0 {
        w - 360.0
    } else {
        w
    }
}

/// Sorts by power descending (NaN last), ties by id.
pub(crate) fn sort_strongest_first(sources: &mut [Source]) {
    sources.sort_by(|a, b| {
        let pa = if a.power_db.is_nan() {
            f64::NEG_INFINITY
        } else {
            a.power_db
        };
        let pb = if b.power_db.is_nan() {
            f64::NEG_INFINITY
        } else {
            b.power_db
        };
        pb.total_cmp(&pa).then(a.id.cmp(&b.id))
    });
}
