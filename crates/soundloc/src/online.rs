//! Online noise updates (iGEVD- / iGSVD-MUSIC): the noise matrix K follows the recording.
//!
//! GEVD- and GSVD-MUSIC whiten R with K, the correlation of the noise alone. A K measured
//! once goes stale when the noise field changes (rotors change speed, a fan switches on, the
//! robot turns): the new noise is no longer whitened and its directions outshine the
//! talkers. [`localize_online`] re-estimates K while it walks the correlation windows in
//! time order, from frames a [`NoiseUpdate`] rule marks as noise:
//!
//! - [`NoiseUpdate::Fixed`]: K never changes (the engine's K, as [`Engine::localize_spectra`]).
//! - [`NoiseUpdate::Segments`]: time ranges known to hold only noise (a push-to-talk gap,
//!   a voice-activity detector's silences). Segment i covers the STFT frames that lie
//!   entirely inside it: frame f (samples f·hop … f·hop + N − 1) with
//!   f·hop ≥ round(start·fs) and f·hop + N ≤ round(end·fs). Its K, x xᴴ averaged over those
//!   frames, is **causal**: it is used from the first window whose last frame is at or after
//!   the segment's last frame on, and it replaces the K of every earlier segment (each
//!   segment is its own estimate; they are not pooled, since the noise may have changed in
//!   between). Before the first segment completes, the engine's K is used.
//! - [`NoiseUpdate::Preceding`]` { frames: F, gap: G }`: like HARK's delayed correlation
//!   maker, each window whose first frame is s uses K from the F frames s − G − F … s − G − 1
//!   (ending G frames before the window). It suppresses whatever was already sounding a
//!   moment ago, so it finds sources that **start** (a talker after a pause) against a
//!   changing background; a source that sounds through the preceding frames is whitened
//!   away with the noise. A window with fewer than G + F frames before it (s < G + F) keeps
//!   the K in use (the engine's K at the start).
//!
//! Each new K goes through [`Engine::set_noise`], so it is validated (positive definite,
//! diagonal loading as configured) exactly like a K given up front; a failure names the
//! segment or the frames. Windows that share a K are localized in one batch. The engine
//! keeps the last K set when this returns. Online updates need a noise-aware algorithm
//! (`gevd`, `gevd-hark`, `gsvd`; the textbook `gevd` is [`crate::Algorithm::Gevd`]); SEVD
//! ignores K, so a rule other than `Fixed` with SEVD is a configuration error.

use crate::backend::{Spectra, WindowSpec};
use crate::correlation::schedule;
use crate::engine::{Engine, Localization};
use crate::noise::NoiseMatrices;
use crate::real::Real;
use crate::{Error, Result};
use std::ops::Range;

/// How K is updated while localizing (see the [module docs](self)).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum NoiseUpdate {
    /// Keep the engine's K.
    Fixed,
    /// Time ranges (start, end) in seconds that hold only noise; each segment's K is used
    /// once its frames are complete.
    Segments(Vec<(f64, f64)>),
    /// K from the `frames` frames ending `gap` frames before each window's first frame.
    Preceding {
        /// Number of frames averaged (F).
        frames: usize,
        /// Frames skipped between them and the window (G).
        gap: usize,
    },
}

/// Which K a window uses.
#[derive(Debug, Clone, PartialEq)]
enum Source {
    /// The engine's K at the start.
    Initial,
    /// Segment i.
    Segment(usize),
    /// These frames.
    Frames(Range<usize>),
}

/// Localize `spectra` window by window, updating K per `update` (see the [module
/// docs](self)). Results, spectrum rows and progress are in time order, as
/// [`Engine::localize_spectra`] gives them; stage times cover the whole run.
pub fn localize_online<T: Real>(
    engine: &mut Engine<T>,
    spectra: &Spectra<T>,
    update: &NoiseUpdate,
    want_spectrum: bool,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Localization> {
    let c = engine.plan().config.clone();
    if !matches!(update, NoiseUpdate::Fixed) && !c.algorithm.uses_noise() {
        return Err(Error::Config(format!(
            "online noise updates need a noise-aware algorithm (gevd, gevd-hark or gsvd); {} ignores K",
            c.algorithm.name()
        )));
    }
    let windows = schedule(spectra.num_frames, c.window, c.period, c.window_type);
    if windows.is_empty() {
        return Err(Error::TooShort(format!(
            "{} frames give no complete correlation window of {} frames",
            spectra.num_frames, c.window
        )));
    }
    let segments = match update {
        NoiseUpdate::Segments(s) => segment_frames(s, spectra.num_frames, c.nfft, c.hop, c.sample_rate_hz)?,
        _ => Vec::new(),
    };
    if let NoiseUpdate::Preceding { frames: 0, .. } = update {
        return Err(Error::Config(
            "preceding-frames noise update: needs at least one frame".into(),
        ));
    }
    let sources = window_sources(update, &windows, &segments);

    engine.backend_mut().reset_stage_times();
    let total = windows.len();
    let first_bin = engine.plan().bins.start;
    let mut current = Source::Initial;
    let mut out: Option<Localization> = None;
    let mut done = 0usize;
    let mut i = 0;
    while i < total {
        let src = sources[i].clone();
        let mut j = i + 1;
        while j < total && sources[j] == src {
            j += 1;
        }
        if src != current {
            // Sources only move forward (Initial → segments or frames), so `src` is never
            // Initial here.
            let (frames, what) = match (&src, update) {
                (Source::Segment(s), NoiseUpdate::Segments(v)) => {
                    let f = segments[*s].clone();
                    let what = format!(
                        "noise segment {s} ({}–{} s, frames {}..{})",
                        v[*s].0, v[*s].1, f.start, f.end
                    );
                    (f, what)
                }
                (Source::Frames(f), _) => {
                    let what = format!(
                        "noise from frames {}..{} (before the window at frame {})",
                        f.start, f.end, windows[i].frame
                    );
                    (f.clone(), what)
                }
                _ => return Err(Error::Config("online noise update: no K for a window".into())),
            };
            NoiseMatrices::from_spectra(spectra, first_bin, frames)
                .and_then(|k| engine.set_noise(&k))
                .map_err(|e| Error::Mismatch(format!("{what}: {e}")))?;
            current = src;
        }
        let base = done;
        let part = engine.localize_windows(spectra, &windows[i..j], want_spectrum, &mut |d, _| {
            progress(base + d, total)
        })?;
        done += j - i;
        out = Some(match out {
            None => part,
            Some(mut acc) => {
                acc.results.extend(part.results);
                if let (Some(t), Some(p)) = (acc.spectrum.as_mut(), part.spectrum) {
                    t.frames.extend(p.frames);
                    t.times_s.extend(p.times_s);
                    t.db.extend(p.db);
                    t.bin_weight.extend(p.bin_weight);
                }
                acc.device = part.device;
                acc.stage_times = part.stage_times;
                acc
            }
        });
        i = j;
    }
    // `windows` is non-empty, so at least one group ran.
    out.ok_or_else(|| Error::TooShort("no correlation window".into()))
}

/// The K source of each window (see the module docs).
fn window_sources(update: &NoiseUpdate, windows: &[WindowSpec], segments: &[Range<usize>]) -> Vec<Source> {
    let mut prev = Source::Initial;
    windows
        .iter()
        .map(|w| {
            let s = match update {
                NoiseUpdate::Fixed => Source::Initial,
                NoiseUpdate::Segments(_) => {
                    let last = w.start + w.len - 1;
                    // The latest-ending segment complete by the window's last frame.
                    segments
                        .iter()
                        .enumerate()
                        .filter(|(_, f)| f.end - 1 <= last)
                        .max_by_key(|(_, f)| f.end)
                        .map_or(Source::Initial, |(i, _)| Source::Segment(i))
                }
                &NoiseUpdate::Preceding { frames, gap } => match w.start.checked_sub(gap + frames) {
                    Some(s0) => Source::Frames(s0..s0 + frames),
                    None => prev.clone(),
                },
            };
            prev = s.clone();
            s
        })
        .collect()
}

/// The frames each segment covers (see the module docs); an error names a segment that is
/// not a valid range or holds no complete frame.
fn segment_frames(
    segments: &[(f64, f64)],
    num_frames: usize,
    nfft: usize,
    hop: usize,
    sample_rate_hz: u32,
) -> Result<Vec<Range<usize>>> {
    let fs = sample_rate_hz as f64;
    segments
        .iter()
        .enumerate()
        .map(|(i, &(a, b))| {
            if !(a.is_finite() && b.is_finite() && a >= 0.0 && b > a) {
                return Err(Error::Config(format!(
                    "noise segment {i} ({a}–{b} s): need 0 <= start < end"
                )));
            }
            let s0 = (a * fs).round() as usize;
            let s1 = (b * fs).round() as usize;
            let first = s0.div_ceil(hop);
            let end = if s1 >= nfft { ((s1 - nfft) / hop + 1).min(num_frames) } else { 0 };
            if first >= end {
                return Err(Error::TooShort(format!(
                    "noise segment {i} ({a}–{b} s) holds no complete {nfft}-sample frame of the {} s recording",
                    ((num_frames.max(1) - 1) * hop + nfft) as f64 / fs
                )));
            }
            Ok(first..end)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::array::{Geometry, Grid};
    use crate::backend::DeviceChoice;
    use crate::config::{Algorithm, LocalizeConfig};
    use crate::demo::DemoScene;
    use crate::engine::estimate_noise;
    use crate::result::LocalizationResult;
    use crate::sim::{position_from_az_el, scale_to_snr, Scene, SceneSource, Signal};

    #[test]
    fn segments_cover_complete_frames_only() {
        // N = 512, hop 160, 16 kHz: frame f is samples 160f .. 160f + 511.
        let f = segment_frames(&[(0.0, 1.0), (2.0, 2.5)], 1000, 512, 160, 16000).unwrap();
        assert_eq!(f[0], 0..97); // 160·96 + 512 = 15872 ≤ 16000 < 160·97 + 512
        assert_eq!(f[1], 200..247); // 32000 / 160 = 200; (40000 − 512)/160 = 246.8
        let e = segment_frames(&[(0.0, 1.0), (1.0, 1.02)], 1000, 512, 160, 16000).unwrap_err();
        assert!(e.to_string().contains("noise segment 1 (1–1.02 s)"), "{e}");
        assert!(segment_frames(&[(2.0, 1.0)], 1000, 512, 160, 16000).is_err());
        // Past the end of the recording.
        assert!(segment_frames(&[(20.0, 21.0)], 1000, 512, 160, 16000).is_err());
    }

    #[test]
    fn sources_are_causal() {
        let w = |start: usize| WindowSpec {
            frame: start,
            start,
            len: 50,
        };
        let windows: Vec<WindowSpec> = (0..6).map(|i| w(i * 50)).collect();
        let segs = vec![0..90, 120..180];
        let s = window_sources(&NoiseUpdate::Segments(vec![]), &windows, &segs);
        // Window [0, 49]: nothing complete; [50, 99]: segment 0 (ends at 89); [150, 199]:
        // segment 1 (ends at 179).
        assert_eq!(
            s,
            vec![
                Source::Initial,
                Source::Segment(0),
                Source::Segment(0),
                Source::Segment(1),
                Source::Segment(1),
                Source::Segment(1)
            ]
        );
        let p = window_sources(&NoiseUpdate::Preceding { frames: 40, gap: 20 }, &windows, &[]);
        assert_eq!(p[0], Source::Initial);
        assert_eq!(p[1], Source::Initial); // 50 < 60: keeps the previous K
        assert_eq!(p[2], Source::Frames(40..80));
        assert_eq!(p[5], Source::Frames(190..230));
        assert!(window_sources(&NoiseUpdate::Fixed, &windows, &[])
            .iter()
            .all(|s| *s == Source::Initial));
    }

    const FS: u32 = 16000;
    const CHANGE_S: f64 = 2.0;
    /// Talk bursts (seconds); the noise field changes at 2 s.
    const BURSTS: [(f64, f64); 4] = [(1.0, 1.5), (3.0, 3.5), (4.0, 4.5), (5.0, 5.5)];

    /// The 8-mic ring with two talkers (30°, −120°) talking in bursts, and four rotors at
    /// 0.25 m that move at 2 s: azimuths 45° + 90°k before, 90°k (and below the array
    /// plane instead of above) after.
    fn changing_drone(snr_db: f64, seed: u64) -> DemoScene {
        let geometry = Geometry::circle(8, 0.0365, 0.0);
        let talkers = vec![(30.0, 0.0), (-120.0, 0.0)];
        let duration_s = 6.0;
        let mut scene = Scene::new();
        for &(a, b) in &BURSTS {
            for &(az, el) in &talkers {
                scene = scene.with_source(
                    SceneSource::new(position_from_az_el(az, el, 2.0), Signal::Speech).active_between(a, b),
                );
            }
        }
        let group: Vec<usize> = (0..scene.sources.len()).collect();
        for (offset, z, span) in [
            (45.0, 0.08, (0.0, CHANGE_S)),
            (0.0, -0.08, (CHANGE_S, duration_s)),
        ] {
            for k in 0..4 {
                let mut p = position_from_az_el(offset + 90.0 * k as f64, 0.0, 0.25);
                p[2] = z;
                scene = scene.with_source(
                    SceneSource::new(p, Signal::Rotor)
                        .with_gain(1000.0)
                        .active_between(span.0, span.1),
                );
            }
        }
        scene.sensor_noise_std = 1.0;
        scale_to_snr(&mut scene, &group, snr_db, &geometry, FS, duration_s, seed).unwrap();
        DemoScene {
            name: "ring8-changing-drone",
            description: "8-mic circle, 2 talkers in bursts, 4 rotors that move at 2 s".into(),
            geometry,
            grid: Grid::ring(5.0, 0.0, 1.0),
            grid_step_deg: 5.0,
            scene,
            talkers,
            noise_range_s: (0.0, 1.0),
            talk_start_s: 0.0,
            duration_s,
            snr_db,
            sample_rate_hz: FS,
            seed,
        }
    }

    /// Results of the windows that lie inside a talk burst starting at or after `from_s`.
    fn in_bursts(results: &[LocalizationResult], from_s: f64) -> Vec<LocalizationResult> {
        results
            .iter()
            .filter(|r| {
                let (a, b) = (r.time_s, r.time_s + 0.5);
                BURSTS
                    .iter()
                    .any(|&(s, e)| s >= from_s && a >= s - 1e-9 && b <= e + 0.05)
            })
            .cloned()
            .collect()
    }

    #[test]
    fn online_k_keeps_the_talkers_after_the_noise_moves() {
        let scene = changing_drone(-5.0, 3);
        let audio = scene.render();
        let config = LocalizeConfig {
            algorithm: Algorithm::Gevd,
            ..LocalizeConfig::default()
        };
        let tf = scene.transfer_functions(&config).unwrap();
        let k0 = estimate_noise(&config, FS, &audio.channels, Some(scene.noise_range_s)).unwrap();
        let rules = [
            ("fixed", NoiseUpdate::Fixed),
            ("segments", NoiseUpdate::Segments(vec![(0.0, 1.0), (2.1, 2.95)])),
            ("preceding", NoiseUpdate::Preceding { frames: 40, gap: 2 }),
        ];
        let mut rates = Vec::new();
        for (name, rule) in &rules {
            let mut engine = Engine::<f32>::new(&config, &tf, Some(&k0), DeviceChoice::Cpu).unwrap();
            let spectra = engine.spectra(FS, &audio.channels).unwrap();
            let mut calls = 0;
            let run = localize_online(&mut engine, &spectra, rule, true, &mut |d, t| {
                calls += 1;
                assert!(d <= t);
            })
            .unwrap();
            assert!(calls > 0);
            // Same windows, in order, as a plain run; the spectrum table matches.
            let frames: Vec<usize> = run.results.iter().map(|r| r.frame).collect();
            let sched: Vec<usize> = schedule(spectra.num_frames, 50, 50, config.window_type)
                .iter()
                .map(|w| w.frame)
                .collect();
            assert_eq!(frames, sched, "{name}");
            let table = run.spectrum.as_ref().unwrap();
            assert_eq!(table.frames, frames);
            assert_eq!(table.db.len(), frames.len() * table.num_dirs);
            let before = scene.score(&in_bursts(&run.results, 0.0)[..1], 5.0);
            let after = scene.score(&in_bursts(&run.results, CHANGE_S), 5.0);
            let dets: Vec<String> = run
                .results
                .iter()
                .map(|r| {
                    let s: Vec<String> = r
                        .sources
                        .iter()
                        .map(|s| format!("{:.0}", s.azimuth_deg))
                        .collect();
                    format!("{:.1}s:{}", r.time_s, s.join("/"))
                })
                .collect();
            let mut err = std::io::stderr();
            let _ = std::io::Write::write_fmt(
                &mut err,
                format_args!(
                    "{name}: before {before:?} after {after:?}\n  {}\n",
                    dets.join(" ")
                ),
            );
            assert_eq!(after.windows, 3, "{name}");
            rates.push((before.hit_rate, after.hit_rate));
        }
        let (fixed, segments, preceding) = (rates[0], rates[1], rates[2]);
        // Before the change every rule uses (an estimate of) the right K.
        assert!(fixed.0 >= 0.99 && segments.0 >= 0.99, "{rates:?}");
        // After it the fixed K loses the talkers; the online ones keep them.
        assert!(fixed.1 <= 0.5, "{rates:?}");
        assert!(segments.1 >= 0.99, "{rates:?}");
        assert!(preceding.1 >= 0.99, "{rates:?}");
    }

    #[test]
    fn sevd_rejects_online_updates_and_bad_rules_are_errors() {
        let scene = changing_drone(0.0, 1);
        let config = LocalizeConfig::default();
        let tf = scene.transfer_functions(&config).unwrap();
        let mut engine = Engine::<f64>::new(&config, &tf, None, DeviceChoice::Cpu).unwrap();
        let spectra = Spectra::<f64>::zeros(200, config.bin_range().len(), 8);
        let e = localize_online(
            &mut engine,
            &spectra,
            &NoiseUpdate::Preceding { frames: 10, gap: 0 },
            false,
            &mut |_, _| {},
        )
        .unwrap_err();
        assert!(e.to_string().contains("noise-aware"), "{e}");
        let config = LocalizeConfig {
            algorithm: Algorithm::Gsvd,
            ..config
        };
        let mut engine = Engine::<f64>::new(&config, &tf, None, DeviceChoice::Cpu).unwrap();
        let e = localize_online(
            &mut engine,
            &spectra,
            &NoiseUpdate::Preceding { frames: 0, gap: 0 },
            false,
            &mut |_, _| {},
        )
        .unwrap_err();
        assert!(e.to_string().contains("at least one frame"), "{e}");
        // Silent frames: K is zero; the error names the frames.
        let e = localize_online(
            &mut engine,
            &spectra,
            &NoiseUpdate::Preceding { frames: 20, gap: 0 },
            false,
            &mut |_, _| {},
        )
        .unwrap_err();
        assert!(
            e.to_string()
                .contains("noise from frames 30..50 (before the window at frame 50)"),
            "{e}"
        );
        let e = localize_online(
            &mut engine,
            &spectra,
            &NoiseUpdate::Segments(vec![(0.1, 0.5)]),
            false,
            &mut |_, _| {},
        )
        .unwrap_err();
        assert!(e.to_string().contains("noise segment 0"), "{e}");
    }
}
