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
//! mean of the azimuths, the mean of the elevations), maximum power, number of results.

use std::collections::{BTreeMap, HashSet, VecDeque};

use serde::Serialize;

use crate::error::{Error, Result};
use crate::result::{LocalizationResult, Source};

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
}

impl Default for TrackerConfig {
    fn default() -> Self {
        TrackerConfig {
            thresh_db: 0.0,
            pause_length: 800.0,
            min_src_interval_deg: 20.0,
            min_id: 0,
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
fn unit_vector(s: &Source) -> [f64; 3] {
    let n = (s.x * s.x + s.y * s.y + s.z * s.z).sqrt();
    if n.is_finite() && n > 0.0 {
        [s.x / n, s.y / n, s.z / n]
    } else {
        from_az_el(s.azimuth_deg, s.elevation_deg)
    }
}

fn from_az_el(az_deg: f64, el_deg: f64) -> [f64; 3] {
    let (az, el) = (az_deg.to_radians(), el_deg.to_radians());
    [el.cos() * az.cos(), el.cos() * az.sin(), el.sin()]
}

/// Angle between two unit vectors, degrees (NaN-free for finite inputs).
fn angle_deg(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).clamp(-1.0, 1.0);
    d.acos().to_degrees()
}

/// Wraps an angle difference into (−180, 180].
fn wrap_deg(d: f64) -> f64 {
    let w = d.rem_euclid(360.0);
    if w > 180.0 {
        w - 360.0
    } else {
        w
    }
}

#[derive(Debug, Clone)]
struct Track {
    id: i64,
    /// Last claimed peak (position and power), with `id` set.
    source: Source,
    remaining: f64,
    last_match_frame: usize,
    /// Azimuth and elevation velocity, degrees per frame (motion prediction only).
    velocity: (f64, f64),
}

impl Track {
    /// Direction to match against at `frame`.
    fn match_direction(&self, frame: usize, predict: bool) -> [f64; 3] {
        if !predict || self.velocity == (0.0, 0.0) {
            return unit_vector(&self.source);
        }
        let dt = frame.saturating_sub(self.last_match_frame) as f64;
        let az = self.source.azimuth_deg + self.velocity.0 * dt;
        let el = (self.source.elevation_deg + self.velocity.1 * dt).clamp(-90.0, 90.0);
        from_az_el(az, el)
    }
}

/// HARK's SourceTracker: assigns ids to peaks over time. See the [module docs](self).
#[derive(Debug, Clone)]
pub struct SourceTracker {
    cfg: TrackerConfig,
    tracks: Vec<Track>,
    next_id: i64,
    last_frame: Option<usize>,
    predict_motion: bool,
}

impl SourceTracker {
    /// A tracker with no sources; the first new source gets id `cfg.min_id`.
    pub fn new(cfg: TrackerConfig) -> Self {
        SourceTracker {
            cfg,
            tracks: Vec::new(),
            next_id: cfg.min_id,
            last_frame: None,
            predict_motion: false,
        }
    }

    /// Enables (or disables) constant-velocity motion prediction (not in HARK; off by
    /// default): a source is matched against its last position moved by its last
    /// azimuth/elevation velocity × frames elapsed. Its reported position when carried is
    /// still its last claimed one.
    pub fn with_motion_prediction(mut self, on: bool) -> Self {
        self.predict_motion = on;
        self
    }

    /// The configuration.
    pub fn config(&self) -> &TrackerConfig {
        &self.cfg
    }

    /// Forgets every source; ids restart at `MIN_ID`.
    pub fn reset(&mut self) {
        self.tracks.clear();
        self.next_id = self.cfg.min_id;
        self.last_frame = None;
    }

    /// Number of sources currently alive.
    pub fn num_alive(&self) -> usize {
        self.tracks.len()
    }

    /// Tracks one result: returns it with the alive sources (claimed, new and carried),
    /// each with `id: Some(..)`, strongest first.
    pub fn update(&mut self, result: &LocalizationResult) -> LocalizationResult {
        let frame = result.frame;
        let decrement = match self.last_frame {
            Some(p) if frame > p => 10.0 * (frame - p) as f64,
            _ => 10.0,
        };
        self.last_frame = Some(frame);

        // Eligible peaks: power ≥ THRESH (NaN power fails the comparison).
        let peaks: Vec<(usize, [f64; 3])> = result
            .sources
            .iter()
            .enumerate()
            .filter(|(_, s)| s.power_db >= self.cfg.thresh_db)
            .map(|(i, s)| (i, unit_vector(s)))
            .filter(|(_, v)| v.iter().all(|c| c.is_finite()))
            .collect();

        // Step 1: candidate pairs closer than MIN_SRC_INTERVAL, closest first.
        self.tracks.sort_by_key(|t| t.id);
        let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
        for (ti, t) in self.tracks.iter().enumerate() {
            let d = t.match_direction(frame, self.predict_motion);
            for (pi, (_, v)) in peaks.iter().enumerate() {
                let a = angle_deg(d, *v);
                if a < self.cfg.min_src_interval_deg - ANGLE_TOL_DEG {
                    pairs.push((a, ti, pi));
                }
            }
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        let mut track_claim: Vec<Option<usize>> = vec![None; self.tracks.len()];
        let mut peak_claimed = vec![false; peaks.len()];
        for &(_, ti, pi) in &pairs {
            if track_claim[ti].is_none() && !peak_claimed[pi] {
                track_claim[ti] = Some(pi);
                peak_claimed[pi] = true;
            }
        }

        // Steps 1-2: update claimed sources, carry or end the others.
        let mut alive = Vec::with_capacity(self.tracks.len());
        for (t, claim) in std::mem::take(&mut self.tracks).into_iter().zip(track_claim) {
            let mut t = t;
            match claim {
                Some(pi) => {
                    let mut s = result.sources[peaks[pi].0].clone();
                    s.id = Some(t.id);
                    if self.predict_motion && frame > t.last_match_frame {
                        let dt = (frame - t.last_match_frame) as f64;
                        t.velocity = (
                            wrap_deg(s.azimuth_deg - t.source.azimuth_deg) / dt,
                            (s.elevation_deg - t.source.elevation_deg) / dt,
                        );
                    }
                    t.source = s;
                    t.remaining = self.cfg.pause_length;
                    t.last_match_frame = frame;
                    alive.push(t);
                }
                None => {
                    t.remaining -= decrement;
                    if t.remaining >= 0.0 {
                        alive.push(t);
                    }
                }
            }
        }
        self.tracks = alive;

        // Step 3: unclaimed peaks far from every alive source start new sources.
        let mut unclaimed: Vec<usize> = (0..peaks.len()).filter(|&pi| !peak_claimed[pi]).collect();
        unclaimed.sort_by(|&a, &b| {
            result.sources[peaks[b].0]
                .power_db
                .total_cmp(&result.sources[peaks[a].0].power_db)
                .then(a.cmp(&b))
        });
        for pi in unclaimed {
            let v = peaks[pi].1;
            let far = self.tracks.iter().all(|t| {
                angle_deg(unit_vector(&t.source), v) >= self.cfg.min_src_interval_deg - ANGLE_TOL_DEG
            });
            if far {
                let id = self.next_id;
                self.next_id = self.next_id.saturating_add(1);
                let mut s = result.sources[peaks[pi].0].clone();
                s.id = Some(id);
                self.tracks.push(Track {
                    id,
                    source: s,
                    remaining: self.cfg.pause_length,
                    last_match_frame: frame,
                    velocity: (0.0, 0.0),
                });
            }
        }

        let mut sources: Vec<Source> = self
            .tracks
            .iter()
            .map(|t| Source {
                held: t.last_match_frame != frame,
                ..t.source.clone()
            })
            .collect();
        sort_strongest_first(&mut sources);
        LocalizationResult {
            num_active: result.num_active,
            frame,
            time_s: result.time_s,
            sources,
        }
    }

    /// Tracks a whole run (starting from the current state).
    pub fn track_all(&mut self, results: &[LocalizationResult]) -> Vec<LocalizationResult> {
        results.iter().map(|r| self.update(r)).collect()
    }
}

/// Sorts by power descending (NaN last), ties by id.
fn sort_strongest_first(sources: &mut [Source]) {
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

/// Streaming SourceIntervalExtender: [`push`](Self::push) results in increasing frame
/// order; a result is released once a result more than `PREROLL_LENGTH` frames later has
/// arrived (or at [`finish`](Self::finish)). Sources without an id pass through unchanged
/// and are never extended.
#[derive(Debug, Clone)]
pub struct IntervalExtender {
    cfg: IntervalExtenderConfig,
    pending: VecDeque<LocalizationResult>,
    seen: HashSet<i64>,
}

impl IntervalExtender {
    /// An empty extender.
    pub fn new(cfg: IntervalExtenderConfig) -> Self {
        IntervalExtender {
            cfg,
            pending: VecDeque::new(),
            seen: HashSet::new(),
        }
    }

    /// Adds one result; returns the results that are now final (possibly none).
    pub fn push(&mut self, result: LocalizationResult) -> Vec<LocalizationResult> {
        let f = result.frame;
        let p = self.cfg.preroll_length;
        for s in &result.sources {
            let Some(id) = s.id else { continue };
            if !self.seen.insert(id) {
                continue;
            }
            // First appearance at frame f: emit in pending results with frame in [f-P, f).
            for r in self.pending.iter_mut() {
                if r.frame < f
                    && r.frame.saturating_add(p) >= f
                    && !r.sources.iter().any(|x| x.id == Some(id))
                {
                    // Not observed there: marked held, as a carried source is.
                    r.sources.push(Source {
                        held: true,
                        ..s.clone()
                    });
                    sort_strongest_first(&mut r.sources);
                }
            }
        }
        self.pending.push_back(result);
        let mut out = Vec::new();
        while let Some(front) = self.pending.front() {
            // No later result (frame > f) can reach back to it: r.frame + P ≤ f.
            if front.frame.saturating_add(p) <= f {
                if let Some(r) = self.pending.pop_front() {
                    out.push(r);
                }
            } else {
                break;
            }
        }
        out
    }

    /// Releases every pending result.
    pub fn finish(&mut self) -> Vec<LocalizationResult> {
        self.pending.drain(..).collect()
    }

    /// Forgets pending results and seen ids.
    pub fn reset(&mut self) {
        self.pending.clear();
        self.seen.clear();
    }
}

/// SourceIntervalExtender on a whole run (results in increasing frame order): each source
/// first seen at frame f also appears in the results with frame in [f − PREROLL_LENGTH, f).
pub fn extend(results: &[LocalizationResult], cfg: IntervalExtenderConfig) -> Vec<LocalizationResult> {
    let mut ex = IntervalExtender::new(cfg);
    let mut out = Vec::with_capacity(results.len());
    for r in results {
        out.extend(ex.push(r.clone()));
    }
    out.extend(ex.finish());
    out
}

/// Summary of one tracked source over a run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SourceSummary {
    /// Track id.
    pub id: i64,
    /// Frame of the first result observing the id (not [`Source::held`]: `--preroll`'s
    /// copies before the first observation are not counted).
    pub start_frame: usize,
    /// Frame of the last result observing the id (not [`Source::held`]: the pause a
    /// tracker carries a source through after it falls silent is not counted).
    pub end_frame: usize,
    /// `time_s` of the first result observing the id, seconds.
    pub start_s: f64,
    /// `time_s` of the last result observing the id, seconds.
    pub end_s: f64,
    /// Circular mean of the observed azimuths (the azimuth of the mean horizontal unit
    /// vector, so 170° and −170° average to 180°), degrees.
    pub mean_azimuth_deg: f64,
    /// Mean of the elevations, degrees: always within the elevations seen (the elevation
    /// of the mean 3-D unit vector would rise toward the pole as the azimuths spread).
    pub mean_elevation_deg: f64,
    /// Largest power over the source's results, dB.
    pub max_power_db: f64,
    /// Number of results observing the id (held ones not counted).
    pub num_results: usize,
}

/// One summary per id (sorted by id) over the results that observe it; sources without an
/// id, and [`Source::held`] ones, are ignored.
pub fn summarize(results: &[LocalizationResult]) -> Vec<SourceSummary> {
    let mut s = Summarizer::default();
    results.iter().for_each(|r| s.add(r));
    s.finish()
}

/// [`summarize`] one result at a time (a live run's summary, without keeping its results).
#[derive(Debug, Clone, Default)]
pub struct Summarizer {
    acc: BTreeMap<i64, SummaryAcc>,
}

#[derive(Debug, Clone)]
struct SummaryAcc {
    s: SourceSummary,
    /// Σ cos az, Σ sin az, Σ el (radians), and how many directions.
    sum: [f64; 3],
    n: usize,
}

impl Summarizer {
    /// Takes in one result's tracked, observed sources.
    pub fn add(&mut self, r: &LocalizationResult) {
        for s in r.sources.iter().filter(|s| !s.held) {
            let Some(id) = s.id else { continue };
            let v = unit_vector(s);
            let a = self.acc.entry(id).or_insert_with(|| SummaryAcc {
                s: SourceSummary {
                    id,
                    start_frame: r.frame,
                    end_frame: r.frame,
                    start_s: r.time_s,
                    end_s: r.time_s,
                    mean_azimuth_deg: 0.0,
                    mean_elevation_deg: 0.0,
                    max_power_db: f64::NEG_INFINITY,
                    num_results: 0,
                },
                sum: [0.0; 3],
                n: 0,
            });
            if r.frame < a.s.start_frame {
                a.s.start_frame = r.frame;
                a.s.start_s = r.time_s;
            }
            if r.frame >= a.s.end_frame {
                a.s.end_frame = r.frame;
                a.s.end_s = r.time_s;
            }
            if s.power_db > a.s.max_power_db {
                a.s.max_power_db = s.power_db;
            }
            a.s.num_results += 1;
            if v.iter().all(|c| c.is_finite()) {
                let [x, y, z] = v;
                let h = x.hypot(y);
                if h > 0.0 {
                    a.sum[0] += x / h;
                    a.sum[1] += y / h;
                }
                a.sum[2] += z.atan2(h);
                a.n += 1;
            }
        }
    }

    /// One summary per id, sorted by id.
    pub fn finish(self) -> Vec<SourceSummary> {
        self.acc
            .into_values()
            .map(|mut a| {
                let [c, s, el] = a.sum;
                let az = s.atan2(c).to_degrees();
                a.s.mean_azimuth_deg = if az <= -180.0 { az + 360.0 } else { az };
                a.s.mean_elevation_deg = (el / a.n.max(1) as f64).to_degrees();
                a.s
            })
            .collect()
    }
}
