//! Unit tests of the engine's frame bookkeeping.

use super::*;
use crate::array::freefield::free_field;
use crate::backend::cpu::CpuBackend;
use crate::input::ChannelMap;
use crate::noise::policy::{InitialNoise, NoiseUpdate};
use crate::{Algorithm, Block, LocalizeConfig};

/// With PERIOD far longer than W, frames no window reads pass through the onset average
/// as they are released (one K for the stream), so the ring holds about a window, not a
/// PERIOD; and the results equal those of a stream whose frames waited for the next
/// window's batch (the same K either way).
#[test]
fn frames_between_windows_are_weighed_and_dropped() {
    let sc = crate::demo::ring8_drone(0.0, 3).unwrap();
    let fs = sc.sample_rate_hz;
    let audio = crate::sim::render(&sc.scene, &sc.geometry, fs, 4.0, sc.seed).channels;
    let config = LocalizeConfig {
        algorithm: Algorithm::Gevd,
        period: 150,
        window: 20,
        onset_frames: 10,
        ..LocalizeConfig::default()
    };
    let tf = free_field(&sc.geometry, &sc.grid, config.nfft, fs, config.bin_range(), 343.0).unwrap();
    let k = crate::noise::estimate(&config, fs, &audio, Some((0.0, 0.5))).unwrap();
    let plan = Arc::new(Plan::<f32>::new(&config, &tf, Some(&k)).unwrap());
    let options = StreamOptions {
        initial_noise: InitialNoise::Given(Some(k.clone())),
        noise_update: NoiseUpdate::Fixed,
        tracking: None,
        channels: ChannelMap::identity(8),
        want_spectrum: true,
    };
    let engine = || {
        Engine::new(
            plan.clone(),
            Box::new(CpuBackend::new(plan.clone())),
            options.clone(),
        )
        .unwrap()
    };
    let mut whole = engine();
    let mut expect = Output::default();
    whole.push(Block::Planar(&audio), &mut expect).unwrap();
    whole.flush(&mut expect).unwrap();
    assert!(expect.results.len() >= 3);
    let mut e = engine();
    let mut out = Output::default();
    let mut most = 0;
    for p0 in (0..audio[0].len()).step_by(160) {
        let part: Vec<Vec<f32>> = audio
            .iter()
            .map(|c| c[p0..(p0 + 160).min(c.len())].to_vec())
            .collect();
        e.push(Block::Planar(&part), &mut out).unwrap();
        most = most.max(e.ring.end() - e.ring.first());
    }
    e.flush(&mut out).unwrap();
    assert!(
        most <= 2 * config.window,
        "the ring held {most} frames at PERIOD {}",
        config.period
    );
    assert_eq!(out.results, expect.results);
    assert_eq!(out.spectrum, expect.spectrum);
}
