//! One summary per tracked source (see the [module docs](super)).

use std::collections::BTreeMap;

use serde::Serialize;

use super::{unit_vector, TrackStart};
use crate::result::LocalizationResult;

/// Summary of one tracked source over a run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SourceSummary {
    /// Track id.
    pub id: i64,
    /// Frame of the first result observing the id (not [`Source::held`](crate::result::Source::held): `--preroll`'s
    /// copies before the first observation are not counted).
    pub start_frame: usize,
    /// Frame of the last result observing the id (not [`Source::held`](crate::result::Source::held): the pause a
    /// tracker carries a source through after it falls silent is not counted).
    pub end_frame: usize,
    /// `time_s` of the first result observing the id, seconds.
    pub start_s: f64,
    /// `time_s` of the last result observing the id, seconds.
    pub end_s: f64,
    /// Frame of the result where the tracker first saw the source. With confirmation
    /// (`--confirm` C, the defaults' C = W) a source gets its id, and is output, only once
    /// seen again C frames or more later, so this is `start_frame` − C or earlier: when
    /// the source began. `start_frame` where the tracker's [`TrackStart`]s were not given
    /// ([`summarize`] of bare results) and without confirmation.
    pub first_seen_frame: usize,
    /// `time_s` of that result, seconds.
    pub first_seen_s: f64,
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
/// id, and [`Source::held`](crate::result::Source::held) ones, are ignored.
pub fn summarize(results: &[LocalizationResult]) -> Vec<SourceSummary> {
    summarize_with_starts(results, &[])
}

/// [`summarize`], with the tracker's first sightings ([`SourceSummary::first_seen_frame`];
/// [`crate::engine::Output::track_starts`], [`super::SourceTracker::take_started`]).
pub fn summarize_with_starts(results: &[LocalizationResult], starts: &[TrackStart]) -> Vec<SourceSummary> {
    let mut s = Summarizer::default();
    starts.iter().for_each(|t| s.started(t));
    results.iter().for_each(|r| s.add(r));
    s.finish()
}

/// [`summarize`] one result at a time (a live run's summary, without keeping its results).
#[derive(Debug, Clone, Default)]
pub struct Summarizer {
    acc: BTreeMap<i64, SummaryAcc>,
    /// First sightings by id ([`Summarizer::started`]).
    seen: BTreeMap<i64, (usize, f64)>,
}

#[derive(Debug, Clone)]
struct SummaryAcc {
    s: SourceSummary,
    /// Σ cos az, Σ sin az, Σ el (radians), and how many directions.
    sum: [f64; 3],
    n: usize,
}

impl Summarizer {
    /// Takes in the tracker's first sighting of a source (before or after its results).
    pub fn started(&mut self, t: &TrackStart) {
        let e = self.seen.entry(t.id).or_insert((t.frame, t.time_s));
        if t.frame < e.0 {
            *e = (t.frame, t.time_s);
        }
    }

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
                    first_seen_frame: r.frame,
                    first_seen_s: r.time_s,
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
        let seen = self.seen;
        self.acc
            .into_values()
            .map(|mut a| {
                (a.s.first_seen_frame, a.s.first_seen_s) = (a.s.start_frame, a.s.start_s);
                if let Some(&(f, t)) = seen.get(&a.s.id).filter(|s| s.0 < a.s.start_frame) {
                    (a.s.first_seen_frame, a.s.first_seen_s) = (f, t);
                }
                let [c, s, el] = a.sum;
                let az = s.atan2(c).to_degrees();
                a.s.mean_azimuth_deg = if az <= -180.0 { az + 360.0 } else { az };
                a.s.mean_elevation_deg = (el / a.n.max(1) as f64).to_degrees();
                a.s
            })
            .collect()
    }
}
