//! Many streams in one group (one backend, windows of all streams in one launch) give each
//! stream exactly the results it gets alone, however the pushes interleave.

use rand::{Rng, SeedableRng};
use soundloc::array::freefield::free_field;
use soundloc::backend::cpu::CpuBackend;
use soundloc::demo::ring8_drone;
use soundloc::engine::{Engine, StreamOptions};
use soundloc::input::ChannelMap;
use soundloc::noise::policy::{InitialNoise, NoiseUpdate};
use soundloc::plan::Plan;
use soundloc::sim::render;
use soundloc::{Algorithm, Block, LocalizeConfig, Output, StreamGroup, TrackingSpec, WindowType};
use std::sync::Arc;

/// Every stream's planar audio in 10 ms ticks: `tick` gets one block per stream.
fn in_ticks(audio: &[Vec<Vec<f32>>], mut tick: impl FnMut(&[Block<'_>])) {
    let len = audio[0][0].len();
    for p0 in (0..len).step_by(160) {
        let parts: Vec<Vec<Vec<f32>>> = audio
            .iter()
            .map(|a| a.iter().map(|c| c[p0..(p0 + 160).min(len)].to_vec()).collect())
            .collect();
        let blocks: Vec<Block<'_>> = parts.iter().map(|p| Block::Planar(p)).collect();
        tick(&blocks);
    }
}

#[test]
fn a_group_gives_every_stream_its_own_results_bit_for_bit() {
    let scenes: Vec<_> = (0..3).map(|s| ring8_drone(0.0, 40 + s).unwrap()).collect();
    let sc = &scenes[0];
    let fs = sc.sample_rate_hz;
    let audio: Vec<Vec<Vec<f32>>> = scenes
        .iter()
        .map(|s| render(&s.scene, &s.geometry, fs, 2.0, s.seed).channels)
        .collect();
    // (window type, PERIOD, tracking, onset weighting's memory in frames)
    for (window_type, period, tracking, onset_frames) in [
        (WindowType::Past, 1, false, 0),
        (WindowType::Future, 50, true, 0),
        (WindowType::Middle, 7, true, 0),
        (WindowType::Past, 1, false, 10),
        (WindowType::Future, 50, true, 10),
    ] {
        let config = LocalizeConfig {
            algorithm: Algorithm::Gevd,
            window_type,
            period,
            window: 30,
            num_sources: 2,
            onset_frames,
            ..LocalizeConfig::default()
        };
        let tf = free_field(&sc.geometry, &sc.grid, config.nfft, fs, config.bin_range(), 343.0).unwrap();
        let k = soundloc::noise::estimate(&config, fs, &audio[0], Some((0.0, 0.5))).unwrap();
        let plan = Arc::new(Plan::<f32>::new(&config, &tf, Some(&k)).unwrap());
        let options = StreamOptions {
            initial_noise: InitialNoise::Given(Some(k.clone())),
            noise_update: NoiseUpdate::Fixed,
            tracking: tracking.then(TrackingSpec::default),
            channels: ChannelMap::identity(8),
            want_spectrum: true,
        };
        // Each stream alone.
        let alone: Vec<Output> = audio
            .iter()
            .map(|ch| {
                let mut e = Engine::new(
                    plan.clone(),
                    Box::new(CpuBackend::new(plan.clone())),
                    options.clone(),
                )
                .unwrap();
                let mut out = Output::default();
                e.push(Block::Planar(ch), &mut out).unwrap();
                e.flush(&mut out).unwrap();
                out
            })
            .collect();
        // Together, pushes of random sizes in random order, `run` now and then.
        let mut g = StreamGroup::with_backend(plan.clone(), Box::new(CpuBackend::new(plan.clone())));
        for _ in 0..3 {
            g.add(options.clone()).unwrap();
        }
        let mut outs = vec![Output::default(); 3];
        let mut pos = [0usize; 3];
        let len = audio[0][0].len();
        let mut rng = rand::rngs::StdRng::seed_from_u64(period as u64);
        while pos.iter().any(|&p| p < len) {
            let i = rng.gen_range(0..3);
            if pos[i] == len {
                continue;
            }
            let n = rng.gen_range(1..3000).min(len - pos[i]);
            let part: Vec<Vec<f32>> = audio[i].iter().map(|c| c[pos[i]..pos[i] + n].to_vec()).collect();
            g.push(i, Block::Planar(&part), &mut outs[i]).unwrap();
            pos[i] += n;
            if rng.gen_bool(0.3) {
                g.run(&mut outs).unwrap();
            }
        }
        for i in 0..3 {
            g.flush(i, &mut outs).unwrap();
        }
        for i in 0..3 {
            let what = format!("{window_type:?} PERIOD {period} onset {onset_frames} stream {i}");
            assert!(alone[i].results.len() >= 3, "{what}");
            assert!(outs[i].results == alone[i].results, "{what}: results differ");
            let (a, b) = (
                outs[i].spectrum.as_ref().unwrap(),
                alone[i].spectrum.as_ref().unwrap(),
            );
            assert!(a.db == b.db && a.frames == b.frames, "{what}: spectra differ");
        }
        // In step: one block per stream per tick (push_all: the STFTs in parallel).
        let mut g = StreamGroup::with_backend(plan.clone(), Box::new(CpuBackend::new(plan.clone())));
        for _ in 0..3 {
            g.add(options.clone()).unwrap();
        }
        let mut outs = vec![Output::default(); 3];
        // A call with one bad block (a NaN in the last stream's) is refused whole, naming
        // that stream: no stream takes its block (the results below would shift).
        let mut bad: Vec<Vec<Vec<f32>>> = audio
            .iter()
            .map(|a| a.iter().map(|c| c[..1000].to_vec()).collect())
            .collect();
        bad[2][5][500] = f32::NAN;
        let blocks: Vec<Block<'_>> = bad.iter().map(|p| Block::Planar(p)).collect();
        let e = g.push_all(&blocks, &mut outs).expect_err("a NaN is refused");
        assert!(
            e.to_string()
                .contains("stream 2: sample 500 of input channel 5 is NaN"),
            "{e}"
        );
        in_ticks(&audio, |blocks| g.push_all(blocks, &mut outs).unwrap());
        for i in 0..3 {
            g.flush(i, &mut outs).unwrap();
            assert!(outs[i].results == alone[i].results, "push_all, stream {i}");
        }
        // The streams differ from each other (the test would pass vacuously otherwise).
        assert!(alone[0].spectrum.as_ref().unwrap().db != alone[1].spectrum.as_ref().unwrap().db);
    }
}

#[test]
fn a_group_refuses_streams_with_their_own_noise_and_bad_indices() {
    let sc = ring8_drone(0.0, 1).unwrap();
    let config = LocalizeConfig::default();
    let tf = free_field(
        &sc.geometry,
        &sc.grid,
        config.nfft,
        16000,
        config.bin_range(),
        343.0,
    )
    .unwrap();
    let plan = Arc::new(Plan::<f32>::new(&config, &tf, None).unwrap());
    let mut g = StreamGroup::with_backend(plan.clone(), Box::new(CpuBackend::new(plan)));
    let online = StreamOptions {
        initial_noise: InitialNoise::Range(0.0, 1.0),
        noise_update: NoiseUpdate::Fixed,
        tracking: None,
        channels: ChannelMap::identity(8),
        want_spectrum: false,
    };
    let e = g.add(online).expect_err("a per-stream K is refused");
    assert!(e.to_string().contains("fixed noise matrix"), "{e}");
    let mut outs = vec![Output::default()];
    assert!(g
        .push(0, Block::Planar(&vec![vec![0.0; 10]; 8]), &mut outs[0])
        .is_err());
    assert!(g.run(&mut outs).is_err(), "one output for no stream");
}

/// The spec-level group (`LocalizerGroup`): built like a `Localizer` from the same spec
/// (here the robust default: a noise recording, no algorithm named, tracking), each stream
/// gives exactly what its own `Localizer` gives.
#[test]
fn a_localizer_group_from_a_spec_equals_one_localizer_per_stream() {
    use soundloc::array::grid::GridSpec;
    use soundloc::{Localizer, LocalizerGroup, LocalizerSpec, NoiseSource};
    let scenes: Vec<_> = (0..2).map(|s| ring8_drone(0.0, 60 + s).unwrap()).collect();
    let fs = scenes[0].sample_rate_hz;
    let audio: Vec<Vec<Vec<f32>>> = scenes
        .iter()
        .map(|s| render(&s.scene, &s.geometry, fs, 1.5, s.seed).channels)
        .collect();
    let dir = std::env::temp_dir().join(format!("soundloc-group-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let noise_path = dir.join("noise.wav");
    let noise = soundloc::audio::Audio {
        sample_rate_hz: fs,
        channels: audio[0].iter().map(|c| c[..8000].to_vec()).collect(),
    };
    noise
        .write_wav(&noise_path, soundloc::audio::SampleFormat::Float32)
        .unwrap();
    let mut spec = LocalizerSpec::free_field(
        scenes[0].geometry.mics.clone(),
        GridSpec::Ring {
            step_deg: 5.0,
            elevation_deg: 0.0,
        },
    );
    spec.noise = NoiseSource::Recording { path: noise_path };
    spec.tracking = Some(TrackingSpec::default());
    spec.analysis.period = 10;
    spec.spectrum = true;
    let mut g = LocalizerGroup::new(&spec, 2).unwrap();
    assert_eq!(g.len(), 2);
    assert_eq!(g.config().algorithm, Algorithm::Gevd, "the robust default");
    let mut outs = vec![Output::default(); 2];
    in_ticks(&audio, |blocks| g.push_all(blocks, &mut outs).unwrap());
    for i in 0..2 {
        g.flush(i, &mut outs).unwrap();
        let alone = Localizer::new(&spec).unwrap().localize(&audio[i]).unwrap();
        assert!(alone.results.len() >= 10, "stream {i}");
        assert!(outs[i].results == alone.results, "stream {i}: results differ");
        assert!(outs[i].spectrum.as_ref().unwrap().db == alone.spectrum.as_ref().unwrap().db);
    }
    assert!(outs[0].results != outs[1].results, "the scenes differ");
    // A silent noise recording gives a zero K: the error names the recording, for a group
    // and for one localizer alike.
    let silent = dir.join("silent.wav");
    soundloc::audio::Audio {
        sample_rate_hz: fs,
        channels: vec![vec![0.0; 8000]; 8],
    }
    .write_wav(&silent, soundloc::audio::SampleFormat::Int16)
    .unwrap();
    spec.noise = NoiseSource::Recording { path: silent.clone() };
    let e = LocalizerGroup::new(&spec, 2).err().expect("zero K refused");
    assert!(
        e.to_string()
            .contains(&format!("{}: the correlation matrix K", silent.display())),
        "{e}"
    );
    let e = Localizer::new(&spec).err().expect("zero K refused");
    assert!(
        e.to_string()
            .contains(&format!("{}: the correlation matrix K", silent.display())),
        "{e}"
    );
    // A noise range of each stream's own input would give each its own K: refused.
    spec.noise = NoiseSource::Range {
        start_s: 0.0,
        end_s: 0.5,
    };
    let e = LocalizerGroup::new(&spec, 2).err().expect("per-stream K refused");
    assert!(e.to_string().contains("one fixed noise matrix"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}
