//! The accuracy study (`soundloc bench --accuracy`): simulated drone scenes in
//! reverberant rooms with several talkers, every algorithm and option side by side, on a
//! tuning split and a held-out split of seeds.
//!
//! ## Scenes
//! A factorial design: RT60 ∈ {anechoic, 0.2, 0.4, 0.6 s} × talkers ∈ {1, 2, 3} × SNR ∈
//! {+20, +10, 0, −5, −10 dB}, `scenes_per_cell` seeds per cell. Per seed: a shoebox room of
//! 5–7 × 4–6 × 2.7–3.2 m (Sabine walls for the RT60, [`crate::sim::Room::with_rt60`]) with
//! the array near its middle; talkers 1.5–2.5 m away at random azimuths at least 30°
//! apart (elevation 0 on the 8-mic ring, −30°…45° on the 60-mic sphere), speaking from 1 s
//! to 3 s; four rotors 0.25 m from the array centre (yaw random), 42 dB above the sensor
//! noise, reverberating like everything else. The first second is noise-only: K comes
//! from it. SNR is the talkers' power over everything else's at the microphones
//! ([`crate::sim::scale_to_snr`]).
//!
//! [`StudyNoise::Room`] keeps the rooms and talkers but replaces the rotors by what a room
//! without a drone has: six broadband noise sources at random places in the room (an
//! air vent, a computer, traffic through a window), reverberating like the talkers, so
//! the noise field at the array is diffuse-like. It studies the default for a user who
//! has no noise recording (no K): the plain MUSIC family and SRP-PHAT.
//!
//! ## Score
//! Every result after the talkers' onset reports as many peaks as there are talkers (the
//! count is given, so variants are compared on direction alone); a talker-window is a hit
//! when a reported direction lies within `tolerance_deg` (5°) of it. Seeds 0… are the
//! tuning split, seeds 1,000,000… the held-out split.

mod scenes;
mod variants;
pub use scenes::{
    conditions, scene, scene_with, Condition, SceneKind, StudyArray, StudyNoise, RT60S, SNRS, TEST_SEED0,
};
pub use variants::{variants, variants_for, variants_without_noise, Variant};

use crate::backend::DeviceChoice;
use crate::demo::localize_scene;
use crate::Result;
use rayon::prelude::*;

/// Hits and talker-windows of one variant in one condition.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Tally {
    /// Talker-windows found within tolerance.
    pub hits: usize,
    /// Talker-windows scored.
    pub pairs: usize,
    /// Sum of the hits' errors, degrees.
    pub err_sum_deg: f64,
    /// Results whose estimated source count (`num_active`) equals the talker count.
    pub count_right: usize,
    /// Results with a source-count estimate.
    pub counted: usize,
}

impl Tally {
    /// hits / pairs.
    pub fn rate(&self) -> f64 {
        if self.pairs == 0 {
            f64::NAN
        } else {
            self.hits as f64 / self.pairs as f64
        }
    }
}

/// The outcome: per condition (in [`conditions`] order), per variant.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Study {
    /// The conditions.
    pub conditions: Vec<Condition>,
    /// Variant names.
    pub variants: Vec<String>,
    /// `tally[condition][variant]`.
    pub tally: Vec<Vec<Tally>>,
    /// Localizations run per variant.
    pub localizations: usize,
    /// CPU seconds of localization per variant (summed over scenes).
    pub seconds: Vec<f64>,
}

/// Run the study on `array` with scenes of `kind` for the seeds `seed0 .. seed0 + scenes_per_cell` of every
/// condition, scoring within `tolerance_deg`. `progress` is called after each scene.
#[allow(clippy::too_many_arguments)]
pub fn run(
    array: StudyArray,
    kind: SceneKind,
    variants: &[Variant],
    seed0: u64,
    scenes_per_cell: usize,
    tolerance_deg: f64,
    only: &dyn Fn(&Condition) -> bool,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Study> {
    let conds: Vec<Condition> = conditions().into_iter().filter(only).collect();
    let jobs: Vec<(usize, u64)> = (0..conds.len())
        .flat_map(|ci| (0..scenes_per_cell as u64).map(move |s| (ci, s)))
        .collect();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let per_job: Vec<(usize, Vec<Tally>, Vec<f64>, usize)> = jobs
        .par_iter()
        .map(|&(ci, s)| -> Result<_> {
            let c = conds[ci];
            // Seed: split offset + cell + index, so every cell has its own scenes.
            let seed = seed0 + (ci as u64) * 1000 + s;
            let sc = scene_with(array, kind, c, seed)?;
            let audio = sc.render();
            let mut tallies = Vec::with_capacity(variants.len());
            let mut secs = Vec::with_capacity(variants.len());
            let mut count = 0;
            for v in variants {
                let mut cfg = v.config.clone();
                cfg.max_peaks = c.talkers as i64;
                let t = std::time::Instant::now();
                let run = localize_scene::<f32>(&sc, &audio, &cfg, DeviceChoice::Cpu)?;
                secs.push(t.elapsed().as_secs_f64());
                count = run.results.len();
                let score = sc.score(&run.results, tolerance_deg);
                let est: Vec<usize> = run
                    .results
                    .iter()
                    .filter(|r| r.time_s >= sc.talk_start_s)
                    .filter_map(|r| r.num_active)
                    .collect();
                let pairs = score.windows * c.talkers;
                let hits = (score.hit_rate * pairs as f64).round() as usize;
                tallies.push(Tally {
                    hits,
                    pairs,
                    err_sum_deg: if hits > 0 {
                        score.mean_error_deg * hits as f64
                    } else {
                        0.0
                    },
                    count_right: est.iter().filter(|&&n| n == c.talkers).count(),
                    counted: est.len(),
                });
            }
            let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(n, jobs.len());
            Ok((ci, tallies, secs, count))
        })
        .collect::<Result<_>>()?;
    let mut tally = vec![vec![Tally::default(); variants.len()]; conds.len()];
    let mut seconds = vec![0.0; variants.len()];
    let mut localizations = 0;
    for (ci, t, s, n) in per_job {
        for (vi, x) in t.into_iter().enumerate() {
            let y = &mut tally[ci][vi];
            y.hits += x.hits;
            y.pairs += x.pairs;
            y.err_sum_deg += x.err_sum_deg;
            y.count_right += x.count_right;
            y.counted += x.counted;
            seconds[vi] += s[vi];
        }
        localizations += n;
    }
    Ok(Study {
        conditions: conds,
        variants: variants.iter().map(|v| v.name.clone()).collect(),
        tally,
        localizations,
        seconds,
    })
}

/// A group of conditions for the summary table.
pub struct Group {
    /// Column heading.
    pub name: &'static str,
    /// Which conditions it pools.
    pub filter: fn(&Condition) -> bool,
}

/// The summary columns: the goal groups first.
pub fn groups() -> Vec<Group> {
    vec![
        Group {
            name: "reverb 2 talkers SNR<=0",
            filter: |c| c.rt60_s > 0.0 && c.talkers == 2 && c.snr_db <= 0.0,
        },
        Group {
            name: "anechoic 2 talkers SNR<=0",
            filter: |c| c.rt60_s == 0.0 && c.talkers == 2 && c.snr_db <= 0.0,
        },
        Group {
            name: "anechoic all",
            filter: |c| c.rt60_s == 0.0,
        },
        Group {
            name: "reverb all",
            filter: |c| c.rt60_s > 0.0,
        },
        Group {
            name: "reverb 3 talkers",
            filter: |c| c.rt60_s > 0.0 && c.talkers == 3,
        },
        Group {
            name: "RT60 0.6 SNR<=0",
            filter: |c| c.rt60_s >= 0.6 && c.snr_db <= 0.0,
        },
        Group {
            name: "reverb SNR>=10",
            filter: |c| c.rt60_s > 0.0 && c.snr_db >= 10.0,
        },
        Group {
            name: "anechoic SNR>=10",
            filter: |c| c.rt60_s == 0.0 && c.snr_db >= 10.0,
        },
    ]
}

impl Study {
    /// Pooled tally of variant `vi` over the conditions `filter` accepts.
    pub fn pooled(&self, vi: usize, filter: fn(&Condition) -> bool) -> Tally {
        let mut t = Tally::default();
        for (ci, c) in self.conditions.iter().enumerate() {
            if filter(c) {
                let x = self.tally[ci][vi];
                t.hits += x.hits;
                t.pairs += x.pairs;
                t.err_sum_deg += x.err_sum_deg;
                t.count_right += x.count_right;
                t.counted += x.counted;
            }
        }
        t
    }

    /// The summary as a Markdown table: hit rate per group, mean error of the hits, and
    /// the cost relative to the first variant.
    pub fn markdown(&self) -> String {
        let gs = groups();
        let mut s = String::from("| variant |");
        for g in &gs {
            s += &format!(" {} |", g.name);
        }
        s += " mean err (hits) | source count right (all) | cost vs first |\n|---|";
        for _ in &gs {
            s += "---:|";
        }
        s += "---:|---:|---:|\n";
        for (vi, name) in self.variants.iter().enumerate() {
            s += &format!("| {name} |");
            for g in &gs {
                let t = self.pooled(vi, g.filter);
                if t.pairs == 0 {
                    s += " – |";
                } else {
                    s += &format!(" {:.1}% |", 100.0 * t.rate());
                }
            }
            let all = self.pooled(vi, |_| true);
            let count = if all.counted == 0 {
                "–".to_string()
            } else {
                format!("{:.1}%", 100.0 * all.count_right as f64 / all.counted as f64)
            };
            s += &format!(
                " {:.2}° | {count} | {:.2}× |\n",
                all.err_sum_deg / all.hits.max(1) as f64,
                self.seconds[vi] / self.seconds[0].max(1e-12)
            );
        }
        s
    }
}
