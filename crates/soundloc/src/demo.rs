//! Built-in scenes with known answers, shared by `soundloc demo` and the test suite.
//!
//! Each [`DemoScene`] is a small simulated recording ([`crate::sim`]): talkers at known
//! directions 2 m from the array and, in the "drone" scenes, four rotor-like noise sources
//! 0.25 m from the array centre (coherent, loud, close: a drone's own rotors), plus weak
//! sensor noise. The first second is noise-only: it gives the noise matrix K. The talkers'
//! SNR at the array is set exactly ([`crate::sim::scale_to_snr`]).
//!
//! Scenes:
//! - [`ring8_drone`]: 8 mics on a 3.65 cm circle (TAMAGO-like), a 5° ring grid in the
//!   array plane.
//! - [`sphere60_drone`]: 60 mics on a 10 cm sphere, a full-sphere grid.
//! - [`ring8_incoherent`]: the 8-mic ring with only incoherent (sensor) noise, where every
//!   algorithm should find the talkers.

use crate::array::freefield::{free_field, DEFAULT_SPEED_OF_SOUND_M_S};
use crate::array::{Geometry, Grid, TransferFunctions};
use crate::audio::Audio;
use crate::config::LocalizeConfig;
use crate::result::LocalizationResult;
use crate::sim::{position_from_az_el, render, scale_to_snr, Scene, SceneSource, Signal};
use crate::Result;

/// A simulated recording with its array, grid and true talker directions.
#[derive(Debug, Clone)]
pub struct DemoScene {
    /// Short name.
    pub name: &'static str,
    /// What it shows.
    pub description: String,
    /// The array.
    pub geometry: Geometry,
    /// The search grid.
    pub grid: Grid,
    /// Grid spacing in degrees (the accuracy one can ask for).
    pub grid_step_deg: f64,
    /// The sources.
    pub scene: Scene,
    /// Talkers' (azimuth, elevation) in degrees.
    pub talkers: Vec<(f64, f64)>,
    /// Noise-only time range in seconds (for K).
    pub noise_range_s: (f64, f64),
    /// When the talkers start, seconds.
    pub talk_start_s: f64,
    /// Length in seconds.
    pub duration_s: f64,
    /// Talkers' SNR at the array, dB.
    pub snr_db: f64,
    /// Sampling rate, Hz.
    pub sample_rate_hz: u32,
    /// Render seed.
    pub seed: u64,
    /// How the array as built differs from its model `geometry` (rendering uses it, the
    /// transfer functions keep the model); `None`: a perfect array.
    pub errors: Option<ArrayErrors>,
}

/// An array as built against its model: where its microphones really are and each
/// channel's gain. Real arrays differ from their model (placement tolerance, capsule
/// sensitivity ±1 dB, measured or geometric TFs that are not exact), and a simulation
/// that renders with the very steering vectors it searches favours methods that lean
/// on those vectors being exact (e.g. MUSIC with very few noise dimensions).
#[derive(Debug, Clone)]
pub struct ArrayErrors {
    /// The microphones' true positions.
    pub geometry: Geometry,
    /// Each channel's linear gain.
    pub gains: Vec<f64>,
}

impl ArrayErrors {
    /// Positions moved by N(0, `position_std_m`) per axis, gains 10^(N(0, `gain_std_db`)/20).
    pub fn random(model: &Geometry, position_std_m: f64, gain_std_db: f64, seed: u64) -> Self {
        let mut g = crate::sim::Gauss::new(seed ^ 0xA77A_E770);
        let mics = model
            .mics
            .iter()
            .map(|p| p.map(|x| x + position_std_m * g.next()))
            .collect();
        let gains = (0..model.num_mics())
            .map(|_| 10f64.powf(gain_std_db * g.next() / 20.0))
            .collect();
        ArrayErrors {
            geometry: Geometry { mics },
            gains,
        }
    }
}

const TALK_START_S: f64 = 1.0;

#[allow(clippy::too_many_arguments)] // a private builder with one caller per scene
fn build(
    name: &'static str,
    description: String,
    geometry: Geometry,
    grid: Grid,
    grid_step_deg: f64,
    talkers: Vec<(f64, f64)>,
    rotors: bool,
    snr_db: f64,
    duration_s: f64,
    seed: u64,
) -> Result<DemoScene> {
    let fs = 16000;
    let mut scene = Scene::new();
    for &(az, el) in &talkers {
        scene = scene.with_source(
            SceneSource::new(position_from_az_el(az, el, 2.0), Signal::Speech)
                .active_between(TALK_START_S, duration_s),
        );
    }
    if rotors {
        for k in 0..4 {
            let az = 45.0 + 90.0 * k as f64;
            let mut p = position_from_az_el(az, 0.0, 0.25);
            p[2] = 0.08;
            scene = scene.with_source(SceneSource::new(p, Signal::Rotor).with_gain(1000.0));
        }
        // Rotors reach the mics at ~4000 RMS each; microphone self-noise ~42 dB below
        // (a realistic floor; it also keeps K within what single precision resolves).
        scene.sensor_noise_std = 30.0;
    } else {
        scene.sensor_noise_std = 100.0;
    }
    let group: Vec<usize> = (0..talkers.len()).collect();
    scale_to_snr(&mut scene, &group, snr_db, &geometry, fs, duration_s, seed)?;
    Ok(DemoScene {
        name,
        description,
        geometry,
        grid,
        grid_step_deg,
        scene,
        talkers,
        noise_range_s: (0.0, TALK_START_S),
        talk_start_s: TALK_START_S,
        duration_s,
        snr_db,
        sample_rate_hz: fs,
        seed,
        errors: None,
    })
}

/// 8-mic circle (r = 3.65 cm), 5° ring grid, two talkers (30°, −120°), four rotors at
/// 0.25 m, talkers at `snr_db`.
pub fn ring8_drone(snr_db: f64, seed: u64) -> Result<DemoScene> {
    build(
        "ring8-drone",
        format!("8-mic circle, 2 talkers at 2 m, 4 rotors at 0.25 m, SNR {snr_db} dB"),
        Geometry::circle(8, 0.0365, 0.0),
        Grid::ring(5.0, 0.0, 1.0),
        5.0,
        vec![(30.0, 0.0), (-120.0, 0.0)],
        true,
        snr_db,
        3.0,
        seed,
    )
}

/// 8-mic circle, 5° ring grid, `talkers` azimuths (degrees), incoherent sensor noise only.
pub fn ring8_incoherent(talker_az_deg: &[f64], snr_db: f64, seed: u64) -> Result<DemoScene> {
    build(
        "ring8-incoherent",
        format!(
            "8-mic circle, {} talker(s) at 2 m, white sensor noise, SNR {snr_db} dB",
            talker_az_deg.len()
        ),
        Geometry::circle(8, 0.0365, 0.0),
        Grid::ring(5.0, 0.0, 1.0),
        5.0,
        talker_az_deg.iter().map(|&a| (a, 0.0)).collect(),
        false,
        snr_db,
        3.0,
        seed,
    )
}

/// 60-mic sphere (r = 10 cm), full-sphere grid of `grid_points`, two talkers
/// (az 40°/el 20°, az −100°/el −10°), four rotors at 0.25 m, talkers at `snr_db`.
pub fn sphere60_drone(snr_db: f64, grid_points: usize, seed: u64) -> Result<DemoScene> {
    // Mean spacing of a Fibonacci sphere of n points: √(4π/n) rad.
    let step = (4.0 * std::f64::consts::PI / grid_points as f64)
        .sqrt()
        .to_degrees();
    build(
        "sphere60-drone",
        format!(
            "60-mic sphere, 2 talkers at 2 m, 4 rotors at 0.25 m, SNR {snr_db} dB, {grid_points}-point grid"
        ),
        Geometry::sphere(60, 0.1),
        Grid::sphere(grid_points, 1.0),
        step,
        vec![(40.0, 20.0), (-100.0, -10.0)],
        true,
        snr_db,
        2.5,
        seed,
    )
}

impl DemoScene {
    /// Render the recording.
    pub fn render(&self) -> Audio {
        let geometry = self.errors.as_ref().map_or(&self.geometry, |e| &e.geometry);
        let mut audio = render(
            &self.scene,
            geometry,
            self.sample_rate_hz,
            self.duration_s,
            self.seed,
        );
        if let Some(e) = &self.errors {
            for (ch, &g) in audio.channels.iter_mut().zip(&e.gains) {
                ch.iter_mut().for_each(|x| *x = (*x as f64 * g) as f32);
            }
        }
        audio
    }

    /// Free-field transfer functions for the bins `config` uses.
    pub fn transfer_functions(&self, config: &LocalizeConfig) -> Result<TransferFunctions> {
        free_field(
            &self.geometry,
            &self.grid,
            config.nfft,
            config.sample_rate_hz,
            config.bin_range(),
            DEFAULT_SPEED_OF_SOUND_M_S,
        )
    }

    /// How well `results` found the talkers: over the results whose window lies after the
    /// talkers' onset (`first_frame_s` ≥ talk start), the share of (result, talker) pairs
    /// with a reported source within `tolerance_deg` of the talker.
    pub fn score(&self, results: &[LocalizationResult], tolerance_deg: f64) -> Score {
        let mut pairs = 0usize;
        let mut hits = 0usize;
        let mut err_sum = 0.0;
        let mut per_talker = vec![0usize; self.talkers.len()];
        let mut windows = 0usize;
        for r in results.iter().filter(|r| r.time_s >= self.talk_start_s) {
            windows += 1;
            for (t, &(az, el)) in self.talkers.iter().enumerate() {
                let truth = unit_from_az_el(az, el);
                let best = r
                    .sources
                    .iter()
                    .map(|s| angle_deg(truth, [s.x, s.y, s.z]))
                    .fold(f64::INFINITY, f64::min);
                pairs += 1;
                if best <= tolerance_deg {
                    hits += 1;
                    per_talker[t] += 1;
                    err_sum += best;
                }
            }
        }
        Score {
            windows,
            hit_rate: if pairs > 0 {
                hits as f64 / pairs as f64
            } else {
                0.0
            },
            per_talker_hits: per_talker,
            mean_error_deg: if hits > 0 { err_sum / hits as f64 } else { f64::NAN },
        }
    }
}

/// How a run did on a scene.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Score {
    /// Results scored (those after the talkers' onset).
    pub windows: usize,
    /// Share of (result, talker) pairs found within tolerance.
    pub hit_rate: f64,
    /// Results in which each talker was found.
    pub per_talker_hits: Vec<usize>,
    /// Mean angular error of the hits, degrees.
    pub mean_error_deg: f64,
}

/// Unit vector for azimuth/elevation in degrees.
pub fn unit_from_az_el(az_deg: f64, el_deg: f64) -> [f64; 3] {
    let (a, e) = (az_deg.to_radians(), el_deg.to_radians());
    [e.cos() * a.cos(), e.cos() * a.sin(), e.sin()]
}

/// Angle between two direction vectors, degrees.
pub fn angle_deg(a: [f64; 3], b: [f64; 3]) -> f64 {
    let na = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    let nb = (b[0] * b[0] + b[1] * b[1] + b[2] * b[2]).sqrt();
    let c = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / (na * nb);
    c.clamp(-1.0, 1.0).acos().to_degrees()
}

/// Localize a rendered scene with `config` on `device`: K from the scene's noise-only
/// range for the noise-aware algorithms. Returns the run.
pub fn localize_scene<T: crate::Real>(
    scene: &DemoScene,
    audio: &Audio,
    config: &LocalizeConfig,
    device: crate::backend::DeviceChoice,
) -> Result<crate::engine::Localization> {
    let tf = scene.transfer_functions(config)?;
    let noise = if config.algorithm.uses_noise() {
        Some(crate::noise::estimate(
            config,
            audio.sample_rate_hz,
            &audio.channels,
            Some(scene.noise_range_s),
        )?)
    } else {
        None
    };
    let mut engine = crate::engine::Engine::<T>::with_fixed_noise(config, &tf, noise.as_ref(), device, true)?;
    engine.check_input(audio.sample_rate_hz, audio.num_channels())?;
    engine.localize(&audio.channels)
}
