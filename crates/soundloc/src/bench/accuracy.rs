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
//! ## Score
//! Every result after the talkers' onset reports as many peaks as there are talkers (the
//! count is given, so variants are compared on direction alone); a talker-window is a hit
//! when a reported direction lies within `tolerance_deg` (5°) of it. Seeds 0… are the
//! tuning split, seeds 1,000,000… the held-out split.

use crate::array::{Geometry, Grid};
use crate::backend::DeviceChoice;
use crate::config::{Algorithm, LocalizeConfig};
use crate::demo::{localize_scene, DemoScene};
use crate::sim::{position_from_az_el, scale_to_snr, Room, Scene, SceneSource, Signal};
use crate::Result;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

/// The arrays of the study.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum StudyArray {
    /// 8 mics on a 3.65 cm circle, 5° ring grid.
    Ring8,
    /// 60 mics on a 10 cm sphere, 2522-point sphere grid.
    Sphere60,
}

/// One cell of the design.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Condition {
    /// Reverberation time in seconds (0 = anechoic).
    pub rt60_s: f64,
    /// Number of talkers.
    pub talkers: usize,
    /// Talkers' SNR, dB.
    pub snr_db: f64,
}

/// RT60 values of the design (0 = anechoic).
pub const RT60S: [f64; 4] = [0.0, 0.2, 0.4, 0.6];
/// SNRs of the design, dB.
pub const SNRS: [f64; 5] = [20.0, 10.0, 0.0, -5.0, -10.0];
/// First seed of the held-out split.
pub const TEST_SEED0: u64 = 1_000_000;

/// Every condition of the design.
pub fn conditions() -> Vec<Condition> {
    let mut v = Vec::new();
    for &rt60_s in &RT60S {
        for talkers in 1..=3 {
            for &snr_db in &SNRS {
                v.push(Condition {
                    rt60_s,
                    talkers,
                    snr_db,
                });
            }
        }
    }
    v
}

/// Build the scene of one condition and seed.
pub fn scene(array: StudyArray, c: Condition, seed: u64) -> Result<DemoScene> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed ^ 0x5EED_AC0C);
    let (geometry, grid, step) = match array {
        StudyArray::Ring8 => (Geometry::circle(8, 0.0365, 0.0), Grid::ring(5.0, 0.0, 1.0), 5.0),
        StudyArray::Sphere60 => {
            let n = 2522;
            let step = (4.0 * std::f64::consts::PI / n as f64).sqrt().to_degrees();
            (Geometry::sphere(60, 0.1), Grid::sphere(n, 1.0), step)
        }
    };
    let size = [
        rng.gen_range(5.0..7.0),
        rng.gen_range(4.0..6.0),
        rng.gen_range(2.7..3.2),
    ];
    // Array position inside the room (from the corner).
    let at = [
        size[0] / 2.0 + rng.gen_range(-0.4..0.4),
        size[1] / 2.0 + rng.gen_range(-0.4..0.4),
        rng.gen_range(1.2..1.5),
    ];
    let origin = [-at[0], -at[1], -at[2]];
    let inside = |p: [f64; 3]| (0..3).all(|a| p[a] > origin[a] + 0.3 && p[a] < origin[a] + size[a] - 0.3);
    let mut talkers: Vec<(f64, f64)> = Vec::new();
    let mut scene = Scene::new();
    let (talk_start, duration) = (1.0, 3.0);
    let mut tries = 0;
    while talkers.len() < c.talkers {
        tries += 1;
        let az: f64 = rng.gen_range(-180.0..180.0);
        let el: f64 = match array {
            StudyArray::Ring8 => 0.0,
            StudyArray::Sphere60 => rng.gen_range(-30.0..45.0),
        };
        let dist = rng.gen_range(1.5..2.5);
        let p = position_from_az_el(az, el, dist);
        let apart = talkers.iter().all(|&(a, e)| {
            crate::demo::angle_deg(
                crate::demo::unit_from_az_el(a, e),
                crate::demo::unit_from_az_el(az, el),
            ) >= 30.0
        });
        if (apart && inside(p)) || tries > 1000 {
            talkers.push((az, el));
            scene =
                scene.with_source(SceneSource::new(p, Signal::Speech).active_between(talk_start, duration));
        }
    }
    let yaw: f64 = rng.gen_range(0.0..90.0);
    for k in 0..4 {
        let mut p = position_from_az_el(yaw + 45.0 + 90.0 * k as f64, 0.0, 0.25);
        p[2] = 0.08;
        scene = scene.with_source(SceneSource::new(p, Signal::Rotor).with_gain(1000.0));
    }
    scene.sensor_noise_std = 30.0;
    if c.rt60_s > 0.0 {
        scene.room = Some(Room::with_rt60(size, origin, c.rt60_s)?);
    }
    let fs = 16000;
    let group: Vec<usize> = (0..talkers.len()).collect();
    scale_to_snr(&mut scene, &group, c.snr_db, &geometry, fs, duration, seed)?;
    Ok(DemoScene {
        name: "study",
        description: format!(
            "{array:?}, RT60 {} s, {} talker(s), SNR {} dB, seed {seed}",
            c.rt60_s, c.talkers, c.snr_db
        ),
        geometry,
        grid,
        grid_step_deg: step,
        scene,
        talkers,
        noise_range_s: (0.0, talk_start),
        talk_start_s: talk_start,
        duration_s: duration,
        snr_db: c.snr_db,
        sample_rate_hz: fs,
        seed,
    })
}

/// A named configuration to compare.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Variant {
    /// Short name for the table.
    pub name: String,
    /// The configuration (its `max_peaks` is set per scene to the talker count).
    pub config: LocalizeConfig,
}

/// The variants of the study: the textbook GEVD and HARK's algorithms as they are, then
/// one change at a time and the promising combinations.
pub fn variants(period: usize) -> Vec<Variant> {
    let base = LocalizeConfig {
        algorithm: Algorithm::Gevd,
        period,
        ..Default::default()
    };
    let v = |name: &str, f: &dyn Fn(&mut LocalizeConfig)| {
        let mut c = base.clone();
        f(&mut c);
        Variant {
            name: name.into(),
            config: c,
        }
    };
    vec![
        v("gevd (textbook, Ns=2)", &|_| {}),
        v("sevd", &|c| c.algorithm = Algorithm::Sevd),
        v("gsvd (HARK)", &|c| c.algorithm = Algorithm::Gsvd),
        v("gevd-hark", &|c| c.algorithm = Algorithm::GevdHark),
        v("srp-phat", &|c| c.algorithm = Algorithm::SrpPhat),
        v("normmusic (sevd)", &|c| {
            c.algorithm = Algorithm::Sevd;
            c.normalize_bins = true
        }),
        v("gevd Ns=1", &|c| c.num_sources = 1),
        v("gevd Ns=3", &|c| c.num_sources = 3),
        v("gevd Ns=4", &|c| c.num_sources = 4),
        v("gevd no eigen weight", &|c| c.eigenvalue_weight = false),
        v("gevd normalized bins", &|c| c.normalize_bins = true),
        v("gevd 300-4000 Hz", &|c| {
            c.lower_freq_hz = 300.0;
            c.upper_freq_hz = 4000.0
        }),
        v("gevd 1000-4000 Hz", &|c| {
            c.lower_freq_hz = 1000.0;
            c.upper_freq_hz = 4000.0
        }),
        v("gevd Ns=3 normalized", &|c| {
            c.num_sources = 3;
            c.normalize_bins = true
        }),
        v("gevd Ns=3 normalized 300-4000", &|c| {
            c.num_sources = 3;
            c.normalize_bins = true;
            c.lower_freq_hz = 300.0;
            c.upper_freq_hz = 4000.0
        }),
        v("gevd Ns=3 W=25", &|c| {
            c.num_sources = 3;
            c.window = 25
        }),
        v("gevd Ns=3 W=100", &|c| {
            c.num_sources = 3;
            c.window = 100
        }),
        v("gevd Ns=3 no eigen weight", &|c| {
            c.num_sources = 3;
            c.eigenvalue_weight = false
        }),
        v("gevd Ns=3 loading 1e-2", &|c| {
            c.num_sources = 3;
            c.diagonal_loading = 1e-2
        }),
        v("gevd subspace 4 refined", &|c| {
            c.subspace_dim = Some(4);
            c.refine = true
        }),
        v("gevd normalized refined", &|c| {
            c.normalize_bins = true;
            c.refine = true
        }),
    ]
}

/// [`variants`], plus the robust default (its signal subspace depends on the array:
/// [`crate::localizer::robust_subspace_dim`]), other subspace sizes (the ring's 8
/// microphones allow at most 7), and the robust default with longer windows, another
/// band, no eigenvalue weight.
pub fn variants_for(array: StudyArray, period: usize) -> Vec<Variant> {
    let mut vs = variants(period);
    let base = vs[0].config.clone();
    let dims: &[usize] = match array {
        StudyArray::Ring8 => &[5, 6],
        StudyArray::Sphere60 => &[6, 8, 12, 16, 20, 24, 30],
    };
    let mut push = |name: String, f: &dyn Fn(&mut LocalizeConfig)| {
        let mut c = base.clone();
        c.refine = true;
        f(&mut c);
        vs.push(Variant { name, config: c });
    };
    let mics = match array {
        StudyArray::Ring8 => 8,
        StudyArray::Sphere60 => 60,
    };
    let robust = crate::localizer::robust_subspace_dim(base.num_sources, mics);
    push(format!("robust default (subspace {robust} refined)"), &|c| {
        c.subspace_dim = Some(robust)
    });
    for &dim in dims {
        push(format!("gevd subspace {dim} refined"), &|c| {
            c.subspace_dim = Some(dim)
        });
    }
    push("robust W=100".into(), &|c| {
        c.subspace_dim = Some(robust);
        c.window = 100
    });
    push("robust W=150".into(), &|c| {
        c.subspace_dim = Some(robust);
        c.window = 150
    });
    push("robust W=100 400-3500 Hz".into(), &|c| {
        c.subspace_dim = Some(robust);
        c.window = 100;
        c.lower_freq_hz = 400.0;
        c.upper_freq_hz = 3500.0
    });
    push("robust no eigen weight".into(), &|c| {
        c.subspace_dim = Some(robust);
        c.eigenvalue_weight = false
    });
    vs
}

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

/// Run the study on `array` for the seeds `seed0 .. seed0 + scenes_per_cell` of every
/// condition, scoring within `tolerance_deg`. `progress` is called after each scene.
pub fn run(
    array: StudyArray,
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
            let sc = scene(array, c, seed)?;
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
