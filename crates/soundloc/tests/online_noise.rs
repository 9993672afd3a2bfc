//! Online noise updates in the stream engine: K updated from marked noise-only segments
//! or from the frames before each window keeps the talkers after the noise field moves;
//! SEVD refuses updates and bad rules are clear errors.

use soundloc::correlation::schedule;
use soundloc::demo::DemoScene;
use soundloc::sim::{position_from_az_el, scale_to_snr, Scene, SceneSource, Signal};
use soundloc::{Algorithm, LocalizationResult, LocalizeConfig, Localizer, NoiseSource, NoiseUpdate};

mod common;
use common::{spec_for, stream};

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

/// Online updates with no K to start from: the windows before the first update are not
/// whitened, and the localizer says until when; with a K to start from it says nothing.
#[test]
fn online_updates_without_a_starting_k_say_which_windows_are_unwhitened() {
    let scene = changing_drone(0.0, 1);
    let mut spec = spec_for(&scene, &LocalizeConfig::default());
    spec.algorithm = Some(Algorithm::Gevd);
    let unwhitened = |spec: &soundloc::LocalizerSpec| -> Vec<String> {
        let loc = Localizer::new(spec).unwrap();
        loc.notes()
            .iter()
            .filter(|n| n.contains("K = I"))
            .cloned()
            .collect()
    };
    spec.noise_update = NoiseUpdate::Segments(vec![(1.2, 1.5), (0.1, 0.5)]);
    let n = unwhitened(&spec);
    assert!(
        n.len() == 1 && n[0].contains("until the first noise segment ends (0.5 s)"),
        "{n:?}"
    );
    spec.noise_update = NoiseUpdate::Preceding { frames: 20, gap: 5 };
    let n = unwhitened(&spec);
    assert!(
        n.len() == 1 && n[0].contains("in the first 0.25 s (windows with fewer than 25 frames"),
        "{n:?}"
    );
    spec.noise = NoiseSource::Range {
        start_s: 0.0,
        end_s: 1.0,
    };
    assert!(unwhitened(&spec).is_empty());
    spec.noise = NoiseSource::None;
    spec.noise_update = NoiseUpdate::Fixed;
    assert!(unwhitened(&spec).is_empty());
}
