//! HARK's SourceTracker (see the [module docs](super)).

use super::{
    angle_deg, from_az_el, sort_strongest_first, unit_vector, wrap_deg, TrackerConfig, ANGLE_TOL_DEG,
};
use crate::result::{LocalizationResult, Source};

#[derive(Debug, Clone)]
struct Track {
    /// None while the track is tentative (confirmation, not yet seen over
    /// `confirm_frames`): it claims peaks but is not output.
    id: Option<i64>,
    /// Frame of the first claimed peak.
    first_frame: usize,
    /// `time_s` of that result.
    first_time_s: f64,
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

/// HARK's SourceTracker: assigns ids to peaks over time. See the [module docs](super).
#[derive(Debug, Clone)]
pub struct SourceTracker {
    cfg: TrackerConfig,
    tracks: Vec<Track>,
    next_id: i64,
    last_frame: Option<usize>,
    predict_motion: bool,
    /// Tentative sources started since the last reset (confirmation).
    tentative_started: usize,
    /// Ids given since the last [`take_started`](Self::take_started), with their first
    /// sightings.
    started: Vec<super::TrackStart>,
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
            tentative_started: 0,
            started: Vec::new(),
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
        self.tentative_started = 0;
        self.started.clear();
    }

    /// The ids given since the last call, each with the result of its first sighting
    /// (the tentative one, with confirmation), in the order given.
    pub fn take_started(&mut self) -> Vec<super::TrackStart> {
        std::mem::take(&mut self.started)
    }

    /// With confirmation, where sources were seen but none was ever confirmed (no id was
    /// given, so a tracked run output no source at all): how many tentative sources there
    /// were. None otherwise.
    pub fn none_confirmed(&self) -> Option<usize> {
        let confirming = self.cfg.confirm_frames.unwrap_or(0) > 0;
        (confirming && self.tentative_started > 0 && self.next_id == self.cfg.min_id)
            .then_some(self.tentative_started)
    }

    /// Forgets the tentative sources (confirmation), keeping the confirmed ones: at a gap
    /// in the input, a source seen before it must be seen anew over the confirmation
    /// after it (the frames between were never analysed).
    pub fn drop_tentative(&mut self) {
        self.tracks.retain(|t| t.id.is_some());
    }

    /// Number of sources currently alive (tentative ones not counted).
    pub fn num_alive(&self) -> usize {
        self.tracks.iter().filter(|t| t.id.is_some()).count()
    }

    /// Tracks one result: returns it with the alive sources (claimed, new and carried),
    /// each with `id: Some(..)`, strongest first. Tentative sources (confirmation) are
    /// not in it.
    pub fn update(&mut self, result: &LocalizationResult) -> LocalizationResult {
        let frame = result.frame;
        let step = match self.last_frame {
            Some(p) if frame > p => frame - p,
            _ => 1,
        };
        let decrement = 10.0 * step as f64;
        self.last_frame = Some(frame);
        let confirm = self.cfg.confirm_frames.unwrap_or(0);
        // A tentative source must be seen again within `confirm` frames, or at the next
        // result when results are further apart than that.
        let allowed = confirm.max(step);
        self.tracks
            .retain(|t| t.id.is_some() || frame.saturating_sub(t.last_match_frame) <= allowed);

        // Eligible peaks: power ≥ THRESH (NaN power fails the comparison).
        let peaks: Vec<(usize, [f64; 3])> = result
            .sources
            .iter()
            .enumerate()
            .filter(|(_, s)| s.power_db >= self.cfg.thresh_db)
            .map(|(i, s)| (i, unit_vector(s)))
            .filter(|(_, v)| v.iter().all(|c| c.is_finite()))
            .collect();

        // Step 1: candidate pairs closer than MIN_SRC_INTERVAL, closest first (ties:
        // sources by id, then tentative ones by age).
        self.tracks.sort_by_key(|t| (t.id.is_none(), t.id, t.first_frame));
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
        // Confirmed sources claim first (with confirmation a source being confirmed never
        // takes the peak of one already reported); without it every source is confirmed
        // and the closest pair wins, as in HARK.
        let tentative = |ti: usize| self.tracks[ti].id.is_none();
        pairs.sort_by(|a, b| {
            (tentative(a.1).cmp(&tentative(b.1)))
                .then(a.0.total_cmp(&b.0))
                .then(a.1.cmp(&b.1))
                .then(a.2.cmp(&b.2))
        });
        let mut track_claim: Vec<Option<usize>> = vec![None; self.tracks.len()];
        let mut peak_claimed = vec![false; peaks.len()];
        for &(_, ti, pi) in &pairs {
            if track_claim[ti].is_none() && !peak_claimed[pi] {
                track_claim[ti] = Some(pi);
                peak_claimed[pi] = true;
            }
        }

        // Steps 1-2: update claimed sources (a tentative one seen over `confirm` frames
        // gets its id), carry or end the others.
        let mut alive = Vec::with_capacity(self.tracks.len());
        for (t, claim) in std::mem::take(&mut self.tracks).into_iter().zip(track_claim) {
            let mut t = t;
            match claim {
                Some(pi) => {
                    if t.id.is_none() && frame.saturating_sub(t.first_frame) >= confirm {
                        let id = self.take_id();
                        t.id = Some(id);
                        self.started.push(super::TrackStart {
                            id,
                            frame: t.first_frame,
                            time_s: t.first_time_s,
                        });
                    }
                    let mut s = result.sources[peaks[pi].0].clone();
                    s.id = t.id;
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
                None if t.id.is_none() => {
                    // Tentative: it must be seen again within `confirm` frames.
                    if frame.saturating_sub(t.last_match_frame) < confirm {
                        alive.push(t);
                    }
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

        // Step 3: unclaimed peaks far from every alive source start new sources
        // (tentative ones while `confirm` > 0).
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
                let id = (confirm == 0).then(|| self.take_id());
                match id {
                    Some(id) => self.started.push(super::TrackStart {
                        id,
                        frame,
                        time_s: result.time_s,
                    }),
                    None => self.tentative_started += 1,
                }
                let mut s = result.sources[peaks[pi].0].clone();
                s.id = id;
                self.tracks.push(Track {
                    id,
                    first_frame: frame,
                    first_time_s: result.time_s,
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
            .filter(|t| t.id.is_some())
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

    /// The next id.
    fn take_id(&mut self) -> i64 {
        let id = self.next_id;
        self.next_id = self.next_id.saturating_add(1);
        id
    }

    /// Tracks a whole run (starting from the current state).
    pub fn track_all(&mut self, results: &[LocalizationResult]) -> Vec<LocalizationResult> {
        results.iter().map(|r| self.update(r)).collect()
    }
}
