//! The stream engine: pushes of any size give the results of the whole recording bit for
//! bit (CPU), for every WINDOW_TYPE, PERIOD 1 and 50, every noise policy and tracking; a
//! whole-file reference computed without the engine (STFT of the whole file, the window
//! schedule, the backend) agrees. (Online K updates: `online_noise.rs`.)

use soundloc::array::TransferFunctions;
use soundloc::backend::cpu::CpuBackend;
use soundloc::backend::{Backend, BatchOutput, Job, StreamId};
use soundloc::correlation::schedule;
use soundloc::demo::ring8_drone;
use soundloc::noise::NoiseMatrices;
use soundloc::plan::Plan;
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
        "push after the end of the stream (flush, or localize of a whole recording): call reset to start a new stream"
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

/// Audio too short for any result says how much the first result needs for the window
/// type and PERIOD in use (a result frame c is a multiple of PERIOD whose window starts
/// at frame 0 or later: PAST's first is c = PERIOD, MIDDLE's ends ⌊W/2⌋ after c), and exactly that much gives a result. Until 2026-12-07 the message
/// gave one window's length, which PAST and MIDDLE runs longer than that still failed.
#[test]
fn too_short_audio_names_what_the_first_result_needs() {
    let scene = ring8_drone(0.0, 5).unwrap();
    let audio = scene.render();
    let (nfft, hop) = (512, 160);
    for (window_type, period, last) in [
        (WindowType::Future, 50, 49),
        (WindowType::Past, 200, 200),
        (WindowType::Past, 1, 49),
        (WindowType::Middle, 50, 75),
        (WindowType::Middle, 1, 49),
    ] {
        let config = LocalizeConfig {
            algorithm: Algorithm::Sevd,
            period,
            window_type,
            ..LocalizeConfig::default()
        };
        let spec = spec_for(&scene, &config);
        let need = nfft + last * hop;
        let part = |n: usize| -> Vec<Vec<f32>> { audio.channels.iter().map(|c| c[..n].to_vec()).collect() };
        let mut loc = Localizer::new(&spec).unwrap();
        let e = loc.localize(&part(need - 1)).unwrap_err();
        assert!(
            matches!(e, soundloc::Error::NoWindow(_))
                && e.to_string().contains(&format!("needs at least {need} ")),
            "{window_type:?} PERIOD {period}: {e}"
        );
        loc.reset().unwrap();
        let run = loc.localize(&part(need)).unwrap();
        assert_eq!(run.results.len(), 1, "{window_type:?} PERIOD {period}");
    }
}
