//! How well the tracker's ids follow the talkers (`soundloc bench --tracks`): long
//! simulated scenes in which each talker speaks for one stretch of 4–7 s, run through
//! the library's defaults with `--track`, and the ids scored against the truth.
//!
//! The scenes are the accuracy study's ([`super::accuracy::scene_with`]: an 8-mic 3.65 cm
//! ring in a shoebox room, talkers 1.5–2.5 m away ≥ 30° apart) made 12 s long: talker i
//! speaks from a random start in 1–5 s for 4–7 s. With rotors 25 cm from the array
//! (the drone scenes) K comes from the first second and the robust default runs; with
//! broadband sources spread over the room no noise source is given and the room default
//! runs. PERIOD as asked, `--num-sources` 2, CPU f32.
//!
//! Scores, over the scenes of a variant:
//! - an id is **true** when the median angle between its observed (not held) directions
//!   and one talker's is ≤ 10° (that talker is its talker), **false** otherwise;
//! - **ids per talker**: true ids over talkers that got one (1 is ideal: every
//!   interruption of a talker's track gives it another id), and the talkers that got none;
//! - **false ids per minute** of audio: ids near no talker and, by azimuth, near none of
//!   the other point sources (rotors, the room's noise sources: tracking those is right),
//!   whose ids are counted apart;
//! - **coverage**: the share of (result, talker) pairs whose window lies inside the
//!   talker's speech where an output source with an id (held or not) lies within 10° of
//!   the talker.

use super::accuracy::{scene_with, Condition, SceneKind, StudyArray, StudyNoise};
use crate::array::grid::GridSpec;
use crate::demo::{angle_deg, unit_from_az_el};
use crate::localizer::{Localizer, LocalizerSpec, NoiseSource};
use crate::result::LocalizationResult;
use crate::sim::scale_to_snr;
use crate::tracking::TrackerConfig;
use crate::{Result, TrackingSpec};
use rand::{Rng, SeedableRng};
use std::collections::BTreeMap;

/// Length of a scene, seconds.
pub const SCENE_S: f64 = 12.0;
/// Angle within which an id belongs to a talker, degrees.
pub const MATCH_DEG: f64 = 10.0;

/// One variant's scores.
#[derive(Debug, Clone, serde::Serialize)]
pub struct TrackScores {
    /// Name of the variant.
    pub variant: String,
    /// Scenes run.
    pub scenes: usize,
    /// Talkers over those scenes.
    pub talkers: usize,
    /// Talkers that got no true id.
    pub talkers_missed: usize,
    /// True ids over the talkers that got one.
    pub ids_per_talker: f64,
    /// False ids per minute of audio: near no talker and no other point source.
    pub false_ids_per_min: f64,
    /// Ids of the other point sources (rotors, the room's noise sources) per minute.
    pub other_ids_per_min: f64,
    /// Share of (result, talker) pairs inside the talker's speech with a tracked source
    /// within 10° of it.
    pub coverage: f64,
}

/// A scene of the study made long: its talkers' directions and speech intervals.
struct LongScene {
    audio: crate::audio::Audio,
    mics: Vec<[f64; 3]>,
    talkers: Vec<((f64, f64), (f64, f64))>,
    /// Azimuths of the other point sources (rotors, the room's noise sources), degrees.
    others: Vec<f64>,
}

fn long_scene(noise: StudyNoise, c: Condition, seed: u64) -> Result<LongScene> {
    let kind = SceneKind {
        noise,
        ..SceneKind::DRONE
    };
    let mut d = scene_with(StudyArray::Ring8, kind, c, seed)?;
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed ^ 0x07EA_C1D5);
    let mut talkers = Vec::new();
    for (i, &dir) in d.talkers.iter().enumerate() {
        let start: f64 = rng.gen_range(1.0..5.0);
        let end = (start + rng.gen_range(4.0..7.0f64)).min(SCENE_S - 0.5);
        d.scene.sources[i].active = Some((start, end));
        talkers.push((dir, (start, end)));
    }
    d.duration_s = SCENE_S;
    let group: Vec<usize> = (0..talkers.len()).collect();
    scale_to_snr(
        &mut d.scene,
        &group,
        c.snr_db,
        &d.geometry,
        d.sample_rate_hz,
        SCENE_S,
        d.seed,
    )?;
    let others = d.scene.sources[talkers.len()..]
        .iter()
        .map(|s| s.position_m[1].atan2(s.position_m[0]).to_degrees())
        .collect();
    Ok(LongScene {
        audio: d.render(),
        mics: d.geometry.mics.clone(),
        talkers,
        others,
    })
}

/// One way of tracking.
#[derive(Debug, Clone)]
pub struct TrackVariant {
    /// Its name in the table.
    pub name: String,
    /// The tracker's `confirm_frames` (None: the default's).
    pub confirm_frames: Option<usize>,
    /// SourceIntervalExtender's PREROLL_LENGTH (0: off).
    pub preroll: usize,
}

/// Runs each variant on `seeds` scenes per condition (RT60 0–0.6 s × 1–2 talkers × the
/// SNRs given) and scores it.
pub fn run(
    noise: StudyNoise,
    snrs: &[f64],
    period: usize,
    seed0: u64,
    seeds: usize,
    variants: &[TrackVariant],
) -> Result<Vec<TrackScores>> {
    let mut scenes = Vec::new();
    for (ci, &rt60_s) in super::accuracy::RT60S.iter().enumerate() {
        for talkers in 1..=2 {
            for (si, &snr_db) in snrs.iter().enumerate() {
                for s in 0..seeds as u64 {
                    let c = Condition {
                        rt60_s,
                        talkers,
                        snr_db,
                    };
                    let seed = seed0 + (ci * 100 + talkers * 10 + si) as u64 * 1000 + s;
                    scenes.push(long_scene(noise, c, seed)?);
                }
            }
        }
    }
    variants
        .iter()
        .map(|v| {
            let mut t = Tally::default();
            for sc in &scenes {
                let mut spec = LocalizerSpec::free_field(
                    sc.mics.clone(),
                    GridSpec::Ring {
                        step_deg: 5.0,
                        elevation_deg: 0.0,
                    },
                );
                spec.analysis.period = period;
                spec.device = crate::backend::DeviceChoice::Cpu;
                if noise == StudyNoise::Rotors {
                    spec.noise = NoiseSource::Range {
                        start_s: 0.0,
                        end_s: 1.0,
                    };
                }
                spec.tracking = Some(TrackingSpec {
                    tracker: TrackerConfig {
                        confirm_frames: v.confirm_frames,
                        ..TrackerConfig::default()
                    },
                    preroll: v.preroll,
                    ..TrackingSpec::default()
                });
                let mut loc = Localizer::new(&spec)?;
                let window_s =
                    (loc.config().window * loc.config().hop) as f64 / loc.config().sample_rate_hz as f64;
                let out = loc.localize(&sc.audio.channels)?;
                t.add(&out.results, sc, window_s);
            }
            Ok(t.scores(&v.name, scenes.len()))
        })
        .collect()
}

#[derive(Default)]
struct Tally {
    talkers: usize,
    missed: usize,
    true_ids: usize,
    false_ids: usize,
    other_ids: usize,
    covered: usize,
    pairs: usize,
}

impl Tally {
    fn add(&mut self, results: &[LocalizationResult], sc: &LongScene, window_s: f64) {
        let talkers = &sc.talkers;
        let units: Vec<[f64; 3]> = talkers.iter().map(|&((a, e), _)| unit_from_az_el(a, e)).collect();
        // Observed directions per id.
        let mut seen: BTreeMap<i64, Vec<[f64; 3]>> = BTreeMap::new();
        for r in results {
            for s in r.sources.iter().filter(|s| !s.held) {
                if let Some(id) = s.id {
                    seen.entry(id)
                        .or_default()
                        .push(unit_from_az_el(s.azimuth_deg, s.elevation_deg));
                }
            }
        }
        let mut per_talker = vec![0usize; talkers.len()];
        for dirs in seen.values() {
            let best = units
                .iter()
                .enumerate()
                .map(|(i, u)| {
                    let mut a: Vec<f64> = dirs.iter().map(|d| angle_deg(*d, *u)).collect();
                    a.sort_by(f64::total_cmp);
                    (a[a.len() / 2], i)
                })
                .min_by(|x, y| x.0.total_cmp(&y.0));
            match best {
                Some((m, i)) if m <= MATCH_DEG => per_talker[i] += 1,
                _ => {
                    // Another point source's (a rotor's, a noise source's): azimuths
                    // only (the ring's grid is its plane; rotors sit above it).
                    let mut az: Vec<f64> = dirs.iter().map(|d| d[1].atan2(d[0]).to_degrees()).collect();
                    az.sort_by(f64::total_cmp);
                    let near_other = sc.others.iter().any(|&o| {
                        let mut a: Vec<f64> = az
                            .iter()
                            .map(|x| ((x - o + 540.0).rem_euclid(360.0) - 180.0).abs())
                            .collect();
                        a.sort_by(f64::total_cmp);
                        a[a.len() / 2] <= MATCH_DEG
                    });
                    if near_other {
                        self.other_ids += 1;
                    } else {
                        self.false_ids += 1;
                    }
                }
            }
        }
        self.talkers += talkers.len();
        self.missed += per_talker.iter().filter(|&&n| n == 0).count();
        self.true_ids += per_talker.iter().sum::<usize>();
        for r in results {
            for (i, &(_, (start, end))) in talkers.iter().enumerate() {
                if r.time_s >= start && r.time_s + window_s <= end {
                    self.pairs += 1;
                    let hit = r.sources.iter().any(|s| {
                        s.id.is_some()
                            && angle_deg(unit_from_az_el(s.azimuth_deg, s.elevation_deg), units[i])
                                <= MATCH_DEG
                    });
                    self.covered += hit as usize;
                }
            }
        }
    }

    fn scores(&self, name: &str, scenes: usize) -> TrackScores {
        let got = self.talkers - self.missed;
        TrackScores {
            variant: name.to_string(),
            scenes,
            talkers: self.talkers,
            talkers_missed: self.missed,
            ids_per_talker: self.true_ids as f64 / got.max(1) as f64,
            false_ids_per_min: self.false_ids as f64 / (scenes as f64 * SCENE_S / 60.0),
            other_ids_per_min: self.other_ids as f64 / (scenes as f64 * SCENE_S / 60.0),
            coverage: self.covered as f64 / self.pairs.max(1) as f64,
        }
    }
}

/// The scores as a Markdown table.
pub fn markdown(scores: &[TrackScores]) -> String {
    let mut s = String::from(
        "| variant | scenes | talkers (missed) | ids per talker | false ids per minute | other sources' ids per minute | coverage |\n|---|---:|---:|---:|---:|---:|---:|\n",
    );
    for v in scores {
        s.push_str(&format!(
            "| {} | {} | {} ({}) | {:.2} | {:.1} | {:.1} | {:.1}% |\n",
            v.variant,
            v.scenes,
            v.talkers,
            v.talkers_missed,
            v.ids_per_talker,
            v.false_ids_per_min,
            v.other_ids_per_min,
            100.0 * v.coverage
        ));
    }
    s
}
