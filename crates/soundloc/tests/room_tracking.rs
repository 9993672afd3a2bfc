//! The room default's tracking (no algorithm named, no noise source, `--track`): which
//! peaks of each window the tracker sees.

/// The room default with --track: a talker in a reverberant room (RT60 0.4 s) speaking
/// from 1.5 s to 3.0 s, sensor noise only before and after. NormMUSIC's powers do not
/// tell silence from the talker (noise-only windows' peaks reach the talker's), so HARK's
/// tracker, which sees every window, keeps tracks in the silence; the room default feeds
/// it only windows whose `num_active` is not 0: no track before the talker starts, the
/// talker tracked while it speaks, and (with `--no-active-only`, `active_only: Some(false)`)
/// the old behaviour back. A named algorithm keeps HARK's.
#[test]
fn the_room_default_starts_no_tracks_in_silence() {
    use soundloc::array::grid::GridSpec;
    use soundloc::sim::{position_from_az_el, render, Room, Scene, SceneSource, Signal};
    use soundloc::{array::Geometry, Localizer, LocalizerSpec, TrackingSpec};
    let ring = Geometry::circle(8, 0.0365, 0.0);
    let talker = 40.0;
    let scene = Scene {
        sensor_noise_std: 0.02,
        room: Some(Room::with_rt60([6.0, 5.0, 3.0], [-3.0, -2.5, -1.2], 0.4).unwrap()),
        ..Scene::new()
    }
    .with_source(
        SceneSource::new(position_from_az_el(talker, 0.0, 2.0), Signal::Speech).active_between(1.5, 3.0),
    );
    let audio = render(&scene, &ring, 16000, 4.0, 11);
    let mut spec = LocalizerSpec::free_field(
        ring.mics.clone(),
        GridSpec::Ring {
            step_deg: 5.0,
            elevation_deg: 0.0,
        },
    );
    spec.analysis.num_sources = 1;
    spec.analysis.period = 5;
    spec.analysis.window_type = soundloc::config::WindowType::Past;
    let run = |spec: &LocalizerSpec| {
        Localizer::new(spec)
            .unwrap()
            .localize(&audio.channels)
            .unwrap()
            .results
    };
    // Windows wholly before the onset (a PAST window at frame c covers c − 49 … c), and
    // talk windows wholly inside the speech.
    let silent = |r: &soundloc::LocalizationResult| r.time_s < 1.49;
    let talking = |r: &soundloc::LocalizationResult| r.time_s >= 2.0 && r.time_s <= 2.95;
    let near = |s: &soundloc::Source| ((s.azimuth_deg - talker + 540.0) % 360.0 - 180.0).abs() <= 5.0;
    let untracked = run(&spec);
    assert!(untracked
        .iter()
        .filter(|r| silent(r))
        .all(|r| r.num_active == Some(0)));
    spec.tracking = Some(TrackingSpec::default());
    let gated = run(&spec);
    let (quiet, talk): (Vec<_>, Vec<_>) = (
        gated.iter().filter(|r| silent(r)).collect(),
        gated.iter().filter(|r| talking(r)).collect(),
    );
    assert!(
        quiet.len() >= 15 && talk.len() >= 10,
        "{} {}",
        quiet.len(),
        talk.len()
    );
    assert!(quiet.iter().all(|r| r.sources.is_empty()), "{quiet:?}");
    let tracked = talk.iter().filter(|r| r.sources.iter().any(near)).count();
    assert!(
        tracked * 10 >= talk.len() * 8,
        "talker tracked in {tracked} of {}",
        talk.len()
    );
    // HARK's tracker on the same spectra: tracks in the silence.
    for off in [
        Some(TrackingSpec {
            active_only: Some(false),
            ..TrackingSpec::default()
        }),
        None,
    ] {
        let mut s = spec.clone();
        if let Some(t) = off {
            s.tracking = Some(t);
        } else {
            s.algorithm = Some(soundloc::Algorithm::Sevd);
        }
        let all = run(&s);
        let busy = all.iter().filter(|r| silent(r) && !r.sources.is_empty()).count();
        assert!(
            busy * 2 >= quiet.len(),
            "{busy} of {} silent windows tracked",
            quiet.len()
        );
    }
}

/// The room default with --track and the default two peaks per window: one talker
/// (anechoic, sensor noise only) gives one track. Each window feeds the tracker only its
/// strongest `num_active` peaks; fed both, the second peak (noise or a sidelobe) starts
/// tracks of its own.
#[test]
fn the_room_default_tracks_one_talker_as_one_source() {
    use soundloc::array::grid::GridSpec;
    use soundloc::sim::{position_from_az_el, render, Scene, SceneSource, Signal};
    use soundloc::tracking::summarize;
    use soundloc::{array::Geometry, Localizer, LocalizerSpec, TrackingSpec};
    let ring = Geometry::circle(8, 0.1, 0.0);
    let talker = 120.0;
    let scene = Scene {
        sensor_noise_std: 0.02,
        ..Scene::new()
    }
    .with_source(SceneSource::new(position_from_az_el(talker, 0.0, 2.0), Signal::WhiteNoise).with_gain(0.3));
    let audio = render(&scene, &ring, 16000, 6.0, 5);
    let mut spec = LocalizerSpec::free_field(
        ring.mics.clone(),
        GridSpec::Ring {
            step_deg: 5.0,
            elevation_deg: 0.0,
        },
    );
    spec.analysis.period = 10;
    spec.tracking = Some(TrackingSpec::default());
    let tracks = |spec: &LocalizerSpec| {
        let r = Localizer::new(spec).unwrap().localize(&audio.channels).unwrap();
        assert!(r.results.len() >= 50);
        assert!(r.results.iter().all(|r| r.num_active.is_some()));
        summarize(&r.results)
    };
    let one = tracks(&spec);
    assert_eq!(one.len(), 1, "{one:?}");
    assert!(
        ((one[0].mean_azimuth_deg - talker + 540.0) % 360.0 - 180.0).abs() < 2.0,
        "{one:?}"
    );
    spec.tracking = Some(TrackingSpec {
        active_only: Some(false),
        ..TrackingSpec::default()
    });
    let all = tracks(&spec);
    assert!(all.len() > 1, "{all:?}");
    // The approximate mode estimates no source count: the gate cannot work, so asking
    // for it is an error and the room default says it is off (the tracker sees every peak).
    spec.analysis.subspace_tracking = true;
    spec.tracking = Some(TrackingSpec {
        active_only: Some(true),
        ..TrackingSpec::default()
    });
    let e = Localizer::new(&spec).err().unwrap().to_string();
    assert!(e.contains("subspace-tracking") && e.contains("num_active"), "{e}");
    spec.tracking = Some(TrackingSpec::default());
    let mut l = Localizer::new(&spec).unwrap();
    assert!(
        l.notes()
            .iter()
            .any(|n| n.contains("the tracker sees every peak")),
        "{:?}",
        l.notes()
    );
    let approx = summarize(&l.localize(&audio.channels).unwrap().results);
    assert!(approx.len() > 1, "{approx:?}");
    spec.analysis.subspace_tracking = false;
    spec.algorithm = Some(soundloc::Algorithm::SrpPhat);
    spec.tracking = Some(TrackingSpec {
        active_only: Some(true),
        ..TrackingSpec::default()
    });
    let e = Localizer::new(&spec).err().unwrap().to_string();
    assert!(e.contains("srp-phat estimates no source count"), "{e}");
    // Outside the room default the tracker takes every peak: at THRESH 0 a note says what
    // to set (the gate where the algorithm counts sources), and it is right: the second
    // peaks start tracks; with the gate, one talker is one track. A threshold silences it.
    let says = |spec: &LocalizerSpec, what: &str| {
        Localizer::new(spec)
            .unwrap()
            .notes()
            .iter()
            .any(|n| n.contains("takes every peak at THRESH 0 dB") && n.contains(what))
    };
    spec.algorithm = Some(soundloc::Algorithm::Sevd);
    spec.tracking = Some(TrackingSpec::default());
    assert!(says(&spec, "--active-only"));
    assert!(tracks(&spec).len() > 1);
    spec.algorithm = Some(soundloc::Algorithm::SrpPhat);
    assert!(says(&spec, "--thresh") && !says(&spec, "--active-only"));
    spec.algorithm = Some(soundloc::Algorithm::Sevd);
    spec.tracking = Some(TrackingSpec {
        active_only: Some(true),
        ..TrackingSpec::default()
    });
    assert!(!says(&spec, ""));
    assert_eq!(tracks(&spec).len(), 1);
    spec.tracking = Some(TrackingSpec {
        tracker: soundloc::tracking::TrackerConfig::with_thresh(10.0),
        ..TrackingSpec::default()
    });
    assert!(!says(&spec, ""));
}
