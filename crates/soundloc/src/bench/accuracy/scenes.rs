//! The study's scenes: the design's conditions and one scene per condition and seed
//! (see the [module docs](super)).

use crate::array::{Geometry, Grid};
use crate::demo::DemoScene;
use crate::sim::{position_from_az_el, scale_to_snr, Room, Scene, SceneSource, Signal};
use crate::Result;
use rand::{Rng, SeedableRng};

/// The arrays of the study.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum StudyArray {
    /// 8 mics on a 3.65 cm circle, 5° ring grid.
    Ring8,
    /// 60 mics on a 10 cm sphere, 2522-point sphere grid.
    Sphere60,
    /// 4 mics on a 3.2 cm circle (a ReSpeaker 4-mic array's), 5° ring grid.
    Ring4,
}

impl StudyArray {
    /// Its number of microphones.
    pub fn num_mics(self) -> usize {
        match self {
            StudyArray::Ring8 => 8,
            StudyArray::Sphere60 => 60,
            StudyArray::Ring4 => 4,
        }
    }

    /// A source's elevation, degrees: 0 for the rings (their grid is the plane), −30…45°
    /// for the sphere.
    fn elevation(self, rng: &mut impl Rng) -> f64 {
        match self {
            StudyArray::Ring8 | StudyArray::Ring4 => 0.0,
            StudyArray::Sphere60 => rng.gen_range(-30.0..45.0),
        }
    }
}

/// What else sounds in the scenes besides the talkers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum StudyNoise {
    /// Four drone rotors 0.25 m from the array centre (the drone scenes).
    Rotors,
    /// Six broadband sources spread over the room (no drone).
    Room,
    /// One point source in the room 1–3 m away, sounding throughout (a machine, a fan, a
    /// television): white noise, a rotor-like hum or speech, chosen per seed.
    Interferer,
}

/// The scenes of a study: what else sounds besides the talkers, and how the array as
/// built differs from its model ([`crate::demo::ArrayErrors`]; standard deviations, 0 =
/// a perfect array).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SceneKind {
    /// What else sounds.
    pub noise: StudyNoise,
    /// A microphone's position error per axis, metres.
    pub position_error_m: f64,
    /// A channel's gain error, dB.
    pub gain_error_db: f64,
}

impl SceneKind {
    /// The drone scenes with a perfect array (the study as first run).
    pub const DRONE: SceneKind = SceneKind {
        noise: StudyNoise::Rotors,
        position_error_m: 0.0,
        gain_error_db: 0.0,
    };

    fn has_errors(&self) -> bool {
        self.position_error_m > 0.0 || self.gain_error_db > 0.0
    }
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

/// Build the drone scene of one condition and seed.
pub fn scene(array: StudyArray, c: Condition, seed: u64) -> Result<DemoScene> {
    scene_with(array, SceneKind::DRONE, c, seed)
}

/// Build the scene of one condition and seed of the given kind.
pub fn scene_with(array: StudyArray, kind: SceneKind, c: Condition, seed: u64) -> Result<DemoScene> {
    let noise = kind.noise;
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed ^ 0x5EED_AC0C);
    let (geometry, grid, step) = match array {
        StudyArray::Ring8 => (Geometry::circle(8, 0.0365, 0.0), Grid::ring(5.0, 0.0, 1.0), 5.0),
        StudyArray::Ring4 => (Geometry::circle(4, 0.032, 0.0), Grid::ring(5.0, 0.0, 1.0), 5.0),
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
        let el = array.elevation(&mut rng);
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
    match noise {
        StudyNoise::Rotors => {
            let yaw: f64 = rng.gen_range(0.0..90.0);
            for k in 0..4 {
                let mut p = position_from_az_el(yaw + 45.0 + 90.0 * k as f64, 0.0, 0.25);
                p[2] = 0.08;
                scene = scene.with_source(SceneSource::new(p, Signal::Rotor).with_gain(1000.0));
            }
        }
        StudyNoise::Room => {
            // Anywhere in the room at least 1 m from the array, levels within 10 dB of
            // each other (the SNR scaling sets their sum against the talkers).
            let mut placed = 0;
            while placed < 6 {
                let p = [
                    origin[0] + rng.gen_range(0.3..size[0] - 0.3),
                    origin[1] + rng.gen_range(0.3..size[1] - 0.3),
                    origin[2] + rng.gen_range(0.3..size[2] - 0.3),
                ];
                if p.iter().map(|x| x * x).sum::<f64>() >= 1.0 {
                    let gain = 100.0 * 10f64.powf(rng.gen_range(-0.25..0.25));
                    scene = scene.with_source(SceneSource::new(p, Signal::WhiteNoise).with_gain(gain));
                    placed += 1;
                }
            }
        }
        StudyNoise::Interferer => {
            let mut tries = 0;
            loop {
                tries += 1;
                let az: f64 = rng.gen_range(-180.0..180.0);
                let el = array.elevation(&mut rng);
                let p = position_from_az_el(az, el, rng.gen_range(1.0..3.0));
                let apart = talkers.iter().all(|&(a, e)| {
                    crate::demo::angle_deg(
                        crate::demo::unit_from_az_el(a, e),
                        crate::demo::unit_from_az_el(az, el),
                    ) >= 30.0
                });
                if (apart && inside(p)) || tries > 1000 {
                    let signal = match rng.gen_range(0..3) {
                        0 => Signal::WhiteNoise,
                        1 => Signal::Rotor,
                        _ => Signal::Speech,
                    };
                    scene = scene.with_source(SceneSource::new(p, signal).with_gain(100.0));
                    break;
                }
            }
        }
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
            "{array:?}, {noise:?} noise{}, RT60 {} s, {} talker(s), SNR {} dB, seed {seed}",
            if kind.has_errors() {
                format!(
                    ", array errors {} mm / {} dB",
                    kind.position_error_m * 1e3,
                    kind.gain_error_db
                )
            } else {
                String::new()
            },
            c.rt60_s,
            c.talkers,
            c.snr_db
        ),
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
        errors: kind.has_errors().then(|| {
            crate::demo::ArrayErrors::random(&geometry, kind.position_error_m, kind.gain_error_db, seed)
        }),
        geometry,
    })
}
