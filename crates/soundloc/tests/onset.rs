//! Onset weighting of the correlation (`LocalizeConfig::onset_frames`, on in the
//! defaults): more talker-windows in reverberant rooms on held-out seeds, the same results
//! whatever blocks a stream arrives in, named algorithms untouched, and refusals where
//! the weights cannot apply.

#[allow(dead_code)] // spec_for is for the other suites
mod common;
mod ring;

use ring::{drone_spec, ring_spec, two_talker_drone};
use soundloc::bench::accuracy::{
    run, variants_for, variants_without_noise, Condition, SceneKind, StudyArray, StudyNoise, Variant,
    TEST_SEED0,
};
use soundloc::localizer::{Localizer, ONSET_FRAMES};
use soundloc::noise::policy::NoiseUpdate;
use soundloc::Algorithm;

/// The study's hit rate of each of `names` (variants whose name starts so) over the
/// reverberant conditions with at least 0 dB SNR and 2–3 talkers, one held-out seed per
/// condition.
fn reverberant_rates(noise: StudyNoise, all: Vec<Variant>, names: &[&str]) -> Vec<f64> {
    let picked: Vec<Variant> = names
        .iter()
        .map(|n| all.iter().find(|v| v.name.starts_with(n)).cloned().unwrap())
        .collect();
    let kind = SceneKind {
        noise,
        ..SceneKind::DRONE
    };
    let only = |c: &Condition| c.rt60_s > 0.0 && c.snr_db >= 0.0 && c.talkers >= 2;
    let study = run(
        StudyArray::Ring8,
        kind,
        &picked,
        TEST_SEED0,
        1,
        5.0,
        &only,
        &|_, _| {},
    )
    .unwrap();
    (0..picked.len())
        .map(|v| {
            let (hits, pairs) = study
                .tally
                .iter()
                .fold((0, 0), |(h, p), row| (h + row[v].hits, p + row[v].pairs));
            hits as f64 / pairs as f64
        })
        .collect()
}

#[test]
fn onset_weighting_finds_more_talkers_in_reverberant_rooms() {
    // Room noise, the room default with and without its onset weighting.
    let room = reverberant_rates(
        StudyNoise::Room,
        variants_without_noise(StudyArray::Ring8, 25),
        &["room default coherence", "room default no onset"],
    );
    eprintln!("room default with / without onset weighting: {room:?}");
    assert!(room[0] >= room[1] + 0.04, "room default with / without: {room:?}");
    // Rotors, the robust default with and without.
    let drone = reverberant_rates(
        StudyNoise::Rotors,
        variants_for(StudyArray::Ring8, 25),
        &["robust default", "robust no onset"],
    );
    eprintln!("robust default with / without onset weighting: {drone:?}");
    assert!(
        drone[0] >= drone[1] + 0.04,
        "robust default with / without: {drone:?}"
    );
}

#[test]
fn the_defaults_weigh_onsets_and_named_algorithms_do_not() {
    let sc = two_talker_drone(0.4, 3);
    let mut spec = drone_spec(&sc);
    assert_eq!(Localizer::new(&spec).unwrap().config().onset_frames, ONSET_FRAMES);
    spec.onset_frames = Some(0);
    assert_eq!(Localizer::new(&spec).unwrap().config().onset_frames, 0);
    spec.onset_frames = Some(25);
    assert_eq!(Localizer::new(&spec).unwrap().config().onset_frames, 25);
    spec.onset_frames = None;
    spec.algorithm = Some(Algorithm::Gevd);
    assert_eq!(Localizer::new(&spec).unwrap().config().onset_frames, 0);
    // The room default too; K from the frames before each window turns it off.
    let mut room = ring_spec(&sc);
    assert_eq!(Localizer::new(&room).unwrap().config().onset_frames, ONSET_FRAMES);
    room.noise_update = NoiseUpdate::Preceding { frames: 50, gap: 0 };
    assert_eq!(Localizer::new(&room).unwrap().config().onset_frames, 0);
    // Asked for there, or with SRP-PHAT: refused, naming the way out.
    room.onset_frames = Some(10);
    let e = Localizer::new(&room).err().unwrap().to_string();
    assert!(e.contains("onset") && e.contains("--noise-preceding"), "{e}");
    let mut srp = ring_spec(&sc);
    srp.algorithm = Some(Algorithm::SrpPhat);
    srp.onset_frames = Some(10);
    let e = Localizer::new(&srp).err().unwrap().to_string();
    assert!(e.contains("onset") && e.contains("srp-phat"), "{e}");
}

#[test]
fn onset_weighting_changes_the_results_and_streams_like_the_whole_run() {
    let sc = two_talker_drone(0.4, 5);
    let audio = sc.render();
    for (period, window) in [(25, 50), (70, 50)] {
        let mut spec = drone_spec(&sc);
        spec.analysis.period = period;
        spec.analysis.window = window;
        spec.spectrum = true;
        let whole = Localizer::new(&spec).unwrap().localize(&audio.channels).unwrap();
        for seed in 0..3 {
            let mut loc = Localizer::new(&spec).unwrap();
            let out = common::stream(&mut loc, &audio.channels, 4000, seed);
            assert_eq!(out.results, whole.results, "PERIOD {period}, seed {seed}");
            assert_eq!(out.spectrum, whole.spectrum, "PERIOD {period}, seed {seed}");
        }
        // And the weighting does something: without it the spectra differ.
        spec.onset_frames = Some(0);
        let off = Localizer::new(&spec).unwrap().localize(&audio.channels).unwrap();
        assert_eq!(off.results.len(), whole.results.len());
        assert_ne!(off.spectrum, whole.spectrum, "PERIOD {period}");
    }
}

/// Without a noise matrix (the room default) each microphone is weighed against its own
/// past: that path streams like the whole run too, and changes the results.
#[test]
fn the_room_defaults_weighting_streams_like_the_whole_run() {
    let sc = two_talker_drone(0.4, 6);
    let audio = sc.render();
    let mut spec = ring_spec(&sc);
    spec.analysis.period = 10;
    spec.spectrum = true;
    let loc = Localizer::new(&spec).unwrap();
    assert_eq!(loc.config().onset_frames, ONSET_FRAMES);
    let whole = Localizer::new(&spec).unwrap().localize(&audio.channels).unwrap();
    assert!(whole.results.len() >= 10);
    for seed in 0..3 {
        let mut loc = Localizer::new(&spec).unwrap();
        let out = common::stream(&mut loc, &audio.channels, 3000, seed);
        assert_eq!(out.results, whole.results, "seed {seed}");
        assert_eq!(out.spectrum, whole.spectrum, "seed {seed}");
    }
    spec.onset_frames = Some(0);
    let off = Localizer::new(&spec).unwrap().localize(&audio.channels).unwrap();
    assert_ne!(off.spectrum, whole.spectrum);
}
