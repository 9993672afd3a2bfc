//! The stream engine: pushes of any size give the results of the whole recording bit for
//! bit (CPU), for every WINDOW_TYPE, PERIOD 1 and 50, every noise policy and tracking; a
//! whole-file reference computed without the engine (STFT of the whole file, the window
//! schedule, the backend) agrees; online K updates keep talkers after the noise moves.

use soundloc::array::TransferFunctions;
use soundloc::backend::cpu::CpuBackend;
use soundloc::backend::{Backend, BatchOutput, Job, StreamId};
use soundloc::correlation::schedule;
use soundloc::demo::{ring8_drone, DemoScene};
use soundloc::noise::NoiseMatrices;
use soundloc::plan::Plan;
use soundloc::sim::{position_from_az_el, scale_to_snr, Scene, SceneSource, Signal};
use soundloc::stft::Stft;
use soundloc::{
    Algorithm, Block, LocalizationResult, LocalizeConfig, Localizer, NoiseSource, NoiseUpdate, Output,
    Precision, TrackingSpec, WindowType,
};
use std::sync::Arc;

mod common;
use common::{spec_for, stream};

fn assert_same(a: &Output, b: &soundloc::Localization, what: &str) {
    assert!(!b.results.is_empty(), "{what}: no results");
    assert!(a.results == b.results, "{what}: results differ");
    let (sa, sb) = (a.spectrum.as_ref().unwrap(), b.spectrum.as_ref().unwrap());
    assert_eq!(sa.frames, sb.frames, "{what}");
    assert!(sa.db == sb.db, "{what}: spectra differ");
    assert!(sa.bin_weight == sb.bin_weight, "{what}: bin weights differ");
}

#[test]
fn streaming_equals_batch_for_every_window_type_period_and_noise_policy() {
    let scene = ring8_drone(-5.0, 11).unwrap();
    let audio = scene.render();
    let fs = audio.sample_rate_hz as usize;
    let cases: Vec<(WindowType, usize, NoiseSource, NoiseUpdate, bool)> = vec![
        (
            WindowType::Future,
            50,
            NoiseSource::None,
            NoiseUpdate::Fixed,
            false,
        ),
        (WindowType::Past, 1, NoiseSource::None, NoiseUpdate::Fixed, true),
        (
            WindowType::Middle,
            7,
            NoiseSource::Range {
                start_s: 0.0,
                end_s: 1.0,
            },
            NoiseUpdate::Fixed,
            false,
        ),
        (
            WindowType::Future,
            1,
            NoiseSource::Range {
                start_s: 0.3,
                end_s: 0.9,
            },
            NoiseUpdate::Fixed,
            true,
        ),
        (
            WindowType::Past,
            10,
            NoiseSource::Range {
                start_s: 0.0,
                end_s: 0.5,
            },
            NoiseUpdate::Segments(vec![(0.0, 0.8), (1.2, 1.5)]),
            true,
        ),
        (
            WindowType::Middle,
            1,
            NoiseSource::None,
            NoiseUpdate::Preceding { frames: 30, gap: 3 },
            false,
        ),
    ];
    for (i, (wt, period, noise, update, track)) in cases.into_iter().enumerate() {
        let config = LocalizeConfig {
            algorithm: if matches!(noise, NoiseSource::None) && update == NoiseUpdate::Fixed {
                Algorithm::Sevd
            } else {
                Algorithm::Gevd
            },
            window_type: wt,
            period,
            ..LocalizeConfig::default()
        };
        let mut spec = spec_for(&scene, &config);
        spec.noise = noise.clone();
        spec.noise_update = update.clone();
        spec.tracking = track.then(|| TrackingSpec {
            preroll: 20,
            ..TrackingSpec::default()
        });
        let what = format!("case {i}: {wt:?} period {period} {noise:?} {update:?} track {track}");
        let batch = Localizer::new(&spec).unwrap().localize(&audio.channels).unwrap();
        if track {
            assert!(
                batch
                    .results
                    .iter()
                    .any(|r| r.sources.iter().any(|s| s.id.is_some())),
                "{what}"
            );
        }
        let mut loc = Localizer::new(&spec).unwrap();
        for (k, max_block) in [(0u64, 2 * fs), (1, 1600), (2, 37)] {
            let out = stream(&mut loc, &audio.channels, max_block, 100 * i as u64 + k);
            assert_same(&out, &batch, &format!("{what}, blocks ≤ {max_block}"));
            loc.reset().unwrap();
        }
    }
}

#[test]
fn one_sample_pushes_and_f64_equal_batch() {
    let scene = ring8_drone(0.0, 5).unwrap();
    let audio = scene.render();
    let short: Vec<Vec<f32>> = audio.channels.iter().map(|c| c[..24000].to_vec()).collect();
    let config = LocalizeConfig {
        algorithm: Algorithm::Gsvd,
        period: 5,
        window_type: WindowType::Past,
        ..LocalizeConfig::default()
    };
    let mut spec = spec_for(&scene, &config);
    spec.precision = Precision::F64;
    spec.noise = NoiseSource::Range {
        start_s: 0.0,
        end_s: 0.6,
    };
    let batch = Localizer::new(&spec).unwrap().localize(&short).unwrap();
    let mut loc = Localizer::new(&spec).unwrap();
    let mut out = Output::default();
    let mut inter = Vec::new();
    for i in 0..short[0].len() {
        inter.clear();
        inter.extend(short.iter().map(|c| c[i]));
        loc.push(
            Block::Interleaved {
                data: &inter,
                channels: 8,
            },
            &mut out,
        )
        .unwrap();
    }
    loc.flush(&mut out).unwrap();
    assert_same(&out, &batch, "one-sample pushes");

    // The stream is closed now: a push is refused as a state error (not a configuration
    // one) and changes nothing; after reset the same pushes give the same results.
    let e = loc.push(Block::Planar(&short), &mut out).unwrap_err();
    assert!(matches!(e, soundloc::Error::State(_)), "{e:?}");
    assert_eq!(
        e.to_string(),
        "push after flush: call reset to start a new stream"
    );
    assert_same(&out, &batch, "after a refused push");
    let e = loc.skip(160, &mut out).unwrap_err();
    assert!(matches!(e, soundloc::Error::State(_)), "{e:?}");
    loc.reset().unwrap();
    let mut again = Output::default();
    loc.push(Block::Planar(&short), &mut again).unwrap();
    loc.flush(&mut again).unwrap();
    assert_same(&again, &batch, "after reset");
}

/// The whole-file path without the engine: STFT of everything, the window schedule, one
/// backend call per batch.
fn whole_file_reference(
    config: &LocalizeConfig,
    tf: &TransferFunctions,
    k: Option<&NoiseMatrices>,
    channels: &[Vec<f32>],
) -> Vec<LocalizationResult> {
    let plan = Arc::new(Plan::<f32>::new(config, tf, k).unwrap());
    let stft = Stft::<f32>::new(config.nfft, config.hop, config.window_function, plan.bins.clone()).unwrap();
    let spectra = stft.process(channels).unwrap();
    let windows = schedule(
        spectra.num_frames,
        config.window,
        config.period,
        config.window_type,
    );
    let mut backend = CpuBackend::new(plan.clone());
    let mut out = BatchOutput::default();
    let mut results = Vec::new();
    let stream = StreamId::fresh();
    for chunk in windows.chunks(7) {
        let job = Job {
            stream,
            first: 0,
            spectra: &spectra,
            windows: chunk,
        };
        backend.process(&[job], false, &mut out).unwrap();
        for (i, (w, peaks)) in chunk.iter().zip(&out.peaks).enumerate() {
            results.push(LocalizationResult {
                num_active: out.source_count.get(i).map(|&c| c as usize),
                frame: w.frame,
                time_s: w.frame as f64 * config.hop as f64 / config.sample_rate_hz as f64,
                sources: peaks
                    .iter()
                    .map(|p| soundloc::engine::source(&plan.grid, p.dir, p.power_db))
                    .collect(),
            });
        }
    }
    results
}

#[test]
fn the_engine_equals_the_whole_file_reference() {
    let scene = ring8_drone(-5.0, 2).unwrap();
    let audio = scene.render();
    for (wt, period) in [
        (WindowType::Future, 50),
        (WindowType::Middle, 3),
        (WindowType::Past, 1),
    ] {
        let config = LocalizeConfig {
            algorithm: Algorithm::Gevd,
            window_type: wt,
            period,
            ..LocalizeConfig::default()
        };
        let tf = scene.transfer_functions(&config).unwrap();
        let k = soundloc::noise::estimate(&config, 16000, &audio.channels, Some((0.0, 1.0))).unwrap();
        let reference = whole_file_reference(&config, &tf, Some(&k), &audio.channels);
        let mut spec = spec_for(&scene, &config);
        spec.noise = NoiseSource::Range {
            start_s: 0.0,
            end_s: 1.0,
        };
        let mut loc = Localizer::new(&spec).unwrap();
        let out = stream(&mut loc, &audio.channels, 3000, 9);
        assert_eq!(out.results.len(), reference.len(), "{wt:?}");
        assert!(
            out.results == reference,
            "{wt:?} {period}: engine differs from the whole-file path"
        );
        // The latency is what the window type says.
        let want = match wt {
            WindowType::Future => 49,
            WindowType::Middle => 25,
            WindowType::Past => 0,
        };
        assert_eq!(loc.latency_frames(), want);
    }
}

#[test]
fn results_come_out_as_soon_as_their_window_is_complete() {
    let scene = ring8_drone(0.0, 1).unwrap();
    let audio = scene.render();
    let config = LocalizeConfig {
        window_type: WindowType::Past,
        period: 10,
        ..LocalizeConfig::default()
    };
    let spec = spec_for(&scene, &config);
    let mut loc = Localizer::new(&spec).unwrap();
    let mut out = Output::default();
    let mut pos = 0;
    let mut seen = 0;
    while seen < 5 {
        let need = loc.samples_needed_next();
        // One sample short: nothing new.
        let part: Vec<Vec<f32>> = audio
            .channels
            .iter()
            .map(|c| c[pos..pos + need - 1].to_vec())
            .collect();
        loc.push(Block::Planar(&part), &mut out).unwrap();
        assert_eq!(out.results.len(), seen);
        pos += need - 1;
        let part: Vec<Vec<f32>> = audio.channels.iter().map(|c| c[pos..pos + 1].to_vec()).collect();
        loc.push(Block::Planar(&part), &mut out).unwrap();
        pos += 1;
        assert_eq!(
            out.results.len(),
            seen + 1,
            "the window completed by the last sample is out"
        );
        let r = &out.results[seen];
        // PAST: the result frame is the window's last frame, complete at this sample.
        assert_eq!(r.frame * 160 + 512, pos);
        seen += 1;
    }
}

#[test]
fn bad_blocks_and_misuse_are_clear_errors() {
    let scene = ring8_drone(0.0, 1).unwrap();
    let spec = spec_for(&scene, &LocalizeConfig::default());
    let mut loc = Localizer::new(&spec).unwrap();
    let mut out = Output::default();
    let e = loc
        .push(
            Block::Interleaved {
                data: &[0.0; 12],
                channels: 4,
            },
            &mut out,
        )
        .unwrap_err();
    assert!(
        e.to_string().contains("4 channels") && e.to_string().contains("8 microphones"),
        "{e}"
    );
    let mut x = vec![0.5f32; 8 * 100];
    x[8 * 57 + 3] = f32::NAN;
    let e = loc
        .push(
            Block::Interleaved {
                data: &x,
                channels: 8,
            },
            &mut out,
        )
        .unwrap_err();
    assert!(
        e.to_string().contains("sample 57 of input channel 3 is NaN"),
        "{e}"
    );
    loc.reset().unwrap();
    let e = loc
        .push(
            Block::Interleaved {
                data: &x[..7],
                channels: 8,
            },
            &mut out,
        )
        .unwrap_err();
    assert!(e.to_string().contains("whole number"), "{e}");
    // Silent and DC-only input: results, and a warning saying they mean nothing.
    for (v, want) in [(0.0f32, "silent"), (250.0, "DC only")] {
        loc.reset().unwrap();
        let mut o = Output::default();
        loc.push(
            Block::Interleaved {
                data: &vec![v; 8 * 20000],
                channels: 8,
            },
            &mut o,
        )
        .unwrap();
        loc.flush(&mut o).unwrap();
        assert!(o.notes.iter().any(|n| n.contains(want)), "{:?}", o.notes);
    }
    loc.reset().unwrap();
    let run = loc.localize(&scene.render().channels).unwrap();
    assert!(
        !run.notes.iter().any(|n| n.contains("warning")),
        "{:?}",
        run.notes
    );
    loc.reset().unwrap();
    // Too short for one window: flush says so.
    loc.push(
        Block::Interleaved {
            data: &[1.0; 8 * 1000],
            channels: 8,
        },
        &mut out,
    )
    .unwrap();
    let e = loc.flush(&mut out).unwrap_err();
    assert!(e.to_string().contains("needs at least"), "{e}");
    let e = loc
        .push(
            Block::Interleaved {
                data: &[1.0; 8],
                channels: 8,
            },
            &mut out,
        )
        .unwrap_err();
    assert!(e.to_string().contains("reset"), "{e}");
}

#[test]
fn a_rejected_block_leaves_the_stream_as_it_was() {
    let scene = ring8_drone(0.0, 1).unwrap();
    let audio = scene.render();
    let spec = spec_for(&scene, &LocalizeConfig::default());
    let reference = Localizer::new(&spec).unwrap().localize(&audio.channels).unwrap();
    let mut loc = Localizer::new(&spec).unwrap();
    let mut out = Output::default();
    let split = 10_000;
    let part = |r: std::ops::Range<usize>| -> Vec<Vec<f32>> {
        audio.channels.iter().map(|c| c[r.clone()].to_vec()).collect()
    };
    loc.push(Block::Planar(&part(0..split)), &mut out).unwrap();
    // The next 4000 samples with one NaN near the end of each layout: refused whole.
    let mut bad = part(split..split + 4000);
    bad[5][3900] = f32::NAN;
    let e = loc.push(Block::Planar(&bad), &mut out).unwrap_err();
    assert!(
        e.to_string()
            .contains(&format!("sample {} of input channel 5 is NaN", split + 3900)),
        "{e}"
    );
    let inter: Vec<f32> = (0..4000).flat_map(|i| bad.iter().map(move |c| c[i])).collect();
    let e = loc
        .push(
            Block::Interleaved {
                data: &inter,
                channels: 8,
            },
            &mut out,
        )
        .unwrap_err();
    assert!(e.to_string().contains("is NaN"), "{e}");
    let n = audio.channels[0].len();
    loc.push(Block::Planar(&part(split..n)), &mut out).unwrap();
    loc.flush(&mut out).unwrap();
    assert_same(&out, &reference, "rejected blocks in the middle");
}

const FS: u32 = 16000;
const CHANGE_S: f64 = 2.0;
/// Talk bursts (seconds); the noise field changes at 2 s.
const BURSTS: [(f64, f64); 4] = [(1.0, 1.5), (3.0, 3.5), (4.0, 4.5), (5.0, 5.5)];

/// The 8-mic ring with two talkers (30°, −120°) talking in bursts, and four rotors at
/// 0.25 m that move at 2 s: azimuths 45° + 90°k before, 90°k (and below the array plane
/// instead of above) after.
fn changing_drone(snr_db: f64, seed: u64) -> DemoScene {
    let geometry = soundloc::array::Geometry::circle(8, 0.0365, 0.0);
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
        grid: soundloc::array::Grid::ring(5.0, 0.0, 1.0),
        grid_step_deg: 5.0,
        scene,
        talkers,
        noise_range_s: (0.0, 1.0),
        talk_start_s: 0.0,
        duration_s,
        snr_db,
        sample_rate_hz: FS,
        seed,
        errors: None,
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
    let rules = [
        ("fixed", NoiseUpdate::Fixed),
        ("segments", NoiseUpdate::Segments(vec![(0.0, 1.0), (2.1, 2.95)])),
        ("preceding", NoiseUpdate::Preceding { frames: 40, gap: 2 }),
    ];
    let mut rates = Vec::new();
    for (name, rule) in &rules {
        let mut spec = spec_for(&scene, &config);
        spec.noise = NoiseSource::Range {
            start_s: 0.0,
            end_s: 1.0,
        };
        spec.noise_update = rule.clone();
        let mut loc = Localizer::new(&spec).unwrap();
        let run = stream(&mut loc, &audio.channels, 4000, 1);
        // Same windows, in order, as a plain run; the spectrum table matches.
        let frames: Vec<usize> = run.results.iter().map(|r| r.frame).collect();
        let nf = (audio.num_samples() - 512) / 160 + 1;
        let sched: Vec<usize> = schedule(nf, 50, 50, config.window_type)
            .iter()
            .map(|w| w.frame)
            .collect();
        assert_eq!(frames, sched, "{name}");
        let table = run.spectrum.as_ref().unwrap();
        assert_eq!(table.frames, frames);
        let before = scene.score(&in_bursts(&run.results, 0.0)[..1], 5.0);
        let after = scene.score(&in_bursts(&run.results, CHANGE_S), 5.0);
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
    let mut spec = spec_for(&scene, &LocalizeConfig::default());
    spec.algorithm = Some(Algorithm::Sevd);
    spec.noise_update = NoiseUpdate::Preceding { frames: 10, gap: 0 };
    let e = Localizer::new(&spec).err().unwrap();
    assert!(e.to_string().contains("noise-aware"), "{e}");
    spec.algorithm = Some(Algorithm::Gsvd);
    spec.noise_update = NoiseUpdate::Preceding { frames: 0, gap: 0 };
    let e = Localizer::new(&spec).err().unwrap();
    assert!(e.to_string().contains("at least one frame"), "{e}");
    // Silent frames: K is zero; the error names the frames.
    let silent = vec![vec![0.0f32; 160 * 249 + 512]; 8];
    spec.noise_update = NoiseUpdate::Preceding { frames: 20, gap: 0 };
    let e = Localizer::new(&spec).unwrap().localize(&silent).unwrap_err();
    assert!(
        e.to_string()
            .contains("noise from frames 30..50 (before the window at frame 50)"),
        "{e}"
    );
    spec.noise_update = NoiseUpdate::Segments(vec![(0.1, 0.5)]);
    let e = Localizer::new(&spec).unwrap().localize(&silent).unwrap_err();
    assert!(e.to_string().contains("noise segment 0"), "{e}");
    // A segment the input ends inside of is not used, with a note.
    spec.noise_update = NoiseUpdate::Segments(vec![(2.0, 3.0)]);
    // Periodic sequences plus a little independent noise per channel: without it, K of
    // these line spectra is singular to rounding at bins between the lines (a
    // combination of channels), which the plan refuses.
    let loud: Vec<Vec<f32>> = (0..8u64)
        .map(|c| {
            let mut seed = 17 + c;
            (0..40000u64)
                .map(|i| {
                    seed = seed
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    ((i * (c + 3)) % 17) as f32 - 8.0
                        + ((seed >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 0.1
                })
                .collect()
        })
        .collect();
    let run = Localizer::new(&spec).unwrap().localize(&loud).unwrap();
    assert!(
        run.notes
            .iter()
            .any(|n| n.contains("noise segment 0") && n.contains("not used")),
        "{:?}",
        run.notes
    );
    // Preceding frames longer than the input: K is never updated, and the notes say so.
    spec.noise_update = NoiseUpdate::Preceding { frames: 1000, gap: 0 };
    let run = Localizer::new(&spec).unwrap().localize(&loud).unwrap();
    assert!(!run.results.is_empty());
    assert!(
        run.notes.iter().any(|n| n.contains("never updated")),
        "{:?}",
        run.notes
    );
    spec.noise_update = NoiseUpdate::Preceding { frames: 20, gap: 0 };
    let run = Localizer::new(&spec).unwrap().localize(&loud).unwrap();
    assert!(
        !run.notes.iter().any(|n| n.contains("never updated")),
        "{:?}",
        run.notes
    );
}

#[test]
fn a_gap_skips_the_windows_across_it_and_keeps_times_true() {
    let scene = ring8_drone(0.0, 8).unwrap();
    let audio = scene.render();
    let config = LocalizeConfig {
        window_type: WindowType::Future,
        period: 10,
        ..LocalizeConfig::default()
    };
    let spec = spec_for(&scene, &config);
    let batch = Localizer::new(&spec).unwrap().localize(&audio.channels).unwrap();
    // Lose samples [a, b) (b a multiple of hop × PERIOD, so results after the gap fall on
    // the whole file's result grid).
    let (a, b) = (19_200 - 160 * 37, 19_200usize);
    let mut loc = Localizer::new(&spec).unwrap();
    let mut out = Output::default();
    let part = |r: std::ops::Range<usize>| -> Vec<Vec<f32>> {
        audio.channels.iter().map(|c| c[r.clone()].to_vec()).collect()
    };
    loc.push(Block::Planar(&part(0..a)), &mut out).unwrap();
    loc.skip((b - a) as u64, &mut out).unwrap();
    assert!(
        out.notes
            .iter()
            .any(|n| n.contains("input gap") && n.contains("0.370 s")),
        "{:?}",
        out.notes
    );
    loc.push(Block::Planar(&part(b..audio.num_samples())), &mut out)
        .unwrap();
    loc.flush(&mut out).unwrap();
    // Before the gap: the whole file's windows that end before it.
    let before: Vec<&LocalizationResult> = batch
        .results
        .iter()
        .filter(|r| r.frame * 160 + 49 * 160 + 512 <= a)
        .collect();
    assert_eq!(
        &out.results[..before.len()],
        before.iter().map(|r| (*r).clone()).collect::<Vec<_>>().as_slice()
    );
    // After it: windows starting at the gap's end on, same times and values as the whole
    // file's windows with the same frames.
    let after: Vec<&LocalizationResult> = out.results[before.len()..].iter().collect();
    assert!(!after.is_empty());
    for r in &after {
        assert!(r.time_s * 16000.0 >= b as f64 - 1e-6, "{}", r.time_s);
        // After the gap result frames start afresh at b, which lies on the whole file's
        // grid of results (every PERIOD frames from 0).
        let x = batch
            .results
            .iter()
            .find(|x| (x.time_s - r.time_s).abs() < 1e-9)
            .expect("a whole-file result at the same time");
        assert_eq!(x.sources, r.sources, "at {} s", r.time_s);
        assert_eq!(x.frame, r.frame);
    }
    assert!(after.len() >= 5);
}
