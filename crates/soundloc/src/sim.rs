//! A scene simulator for tests, benchmarks and `soundloc demo`: point sources in free
//! field or in a shoebox room, recorded by a microphone array.
//!
//! ## Model
//! Microphone m records
//!
//! x_m(t) = Σ_s Σ_i g_s β^{o_i} / r_{s,i,m} · s_s(t − r_{s,i,m}/c) + n_m(t)
//!
//! where s_s is source s's signal (unit RMS, see [`Signal`]), g_s its `gain` (so g_s/r
//! is the RMS amplitude at distance r metres; raw sample units, as [`crate::audio`]),
//! i runs over the direct path and, with a [`Room`], the image sources up to
//! `max_order` reflections (o_i reflections, each scaling by the reflection coefficient
//! β), r_{s,i,m} is the distance in metres from image i to microphone m (clamped to
//! ≥ 1 cm), c the speed of sound (343 m/s by default), and n_m white Gaussian sensor
//! noise with standard deviation `sensor_noise_std`, independent per microphone.
//!
//! ## Fractional delays
//! Delays are applied exactly in the frequency domain: each source signal (with a
//! pre-roll long enough to cover the largest delay, and tapered edges) is transformed
//! once with a zero-padded real FFT of length L; microphone m's spectrum is
//! Y_m(k) = Σ_s S_s(k) Σ_i a_i e^{−j2πk d_i/L}, with d_i = r/c·fs in samples (not rounded),
//! and one inverse FFT per microphone gives its signal. This is band-limited
//! interpolation, accurate to far better than 0.01 sample below 0.9·fs/2 (the Nyquist
//! bin is dropped).
//!
//! ## Image sources (Allen & Berkley)
//! A room is an axis-aligned box of size `size_m` with its corner at `origin_m`. Along
//! each axis of length L a source at coordinate u (from the corner) has images
//! (1 − 2q)·u + 2nL, q ∈ {0, 1}, n ∈ ℤ, after |2n − q| reflections; images whose total
//! reflection count is ≤ `max_order` are kept (7 images up to order 1, 25 up to order 2),
//! all walls with the same coefficient β.
//!
//! ## Determinism
//! Everything is a function of the seed: source s uses a generator seeded from
//! (seed, s) and microphone m's noise one seeded from (seed, m), so rendering a subset of
//! the sources ([`render_parts`]) gives exactly the same components as the full render.
//!
//! ## Noise-only segments and SNR
//! A source with `active: Some((start_s, end_s))` is silent outside that window (10 ms
//! raised-cosine edges; times are emission times, so the array hears it r/c later).
//! Talkers that start at 1 s leave the first second noise-only ([`Scene::first_onset_s`]).
//! [`scale_to_snr`] sets the gains of a group of sources so that, over the time the group
//! is active, the mean power per microphone of the group's signal divided by that of
//! everything else (other sources and sensor noise) is the requested SNR in dB.

mod room;
mod signals;
#[cfg(test)]
mod tests;

pub use room::{image_sources, Room, MAX_REFLECTION_ORDER};
use room::{reflections_response, EXACT_IMAGES_MAX};
pub(crate) use signals::Gauss;

use crate::array::Geometry;
use crate::audio::Audio;
use crate::{Error, Result};
use rayon::prelude::*;
use realfft::num_complex::Complex;
use realfft::RealFftPlanner;
use std::f64::consts::PI;

/// Speed of sound in m/s used by default.
pub const SPEED_OF_SOUND_M_S: f64 = 343.0;

/// Minimum source–microphone distance in metres (closer distances are clamped).
pub const MIN_DISTANCE_M: f64 = 0.01;

/// Edge length of the `active` window ramps in seconds.
const RAMP_S: f64 = 0.01;

/// What a source emits. All signals have unit RMS over the rendered duration (before the
/// `active` window), deterministic from the seed; see the generator details in the
/// private `signals` module docs, summarised here.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Signal {
    /// Speech-like: voiced harmonics with f0 slowly varying in 100–250 Hz, formant
    /// shaping, ≈ 4 Hz syllable amplitude modulation with pauses, broadband energy
    /// 300–3500 Hz.
    Speech,
    /// Rotor/drone-like: four rotors' blade-passing harmonics (140–220 Hz fundamentals,
    /// slight jitter) plus strong broadband noise; stationary.
    Rotor,
    /// White Gaussian noise.
    WhiteNoise,
    /// A sine at the given frequency in Hz (random phase).
    Tone(f64),
}

/// One point source of a [`Scene`].
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SceneSource {
    /// Position in metres, in the array's coordinates.
    pub position_m: [f64; 3],
    /// What it emits.
    pub signal: Signal,
    /// RMS amplitude at 1 m (raw sample units).
    pub gain: f64,
    /// Emission window (start, end) in seconds; `None` = the whole duration.
    pub active: Option<(f64, f64)>,
}

impl SceneSource {
    /// A source at `position_m` emitting `signal`, gain 1, always active.
    pub fn new(position_m: [f64; 3], signal: Signal) -> Self {
        SceneSource {
            position_m,
            signal,
            gain: 1.0,
            active: None,
        }
    }
    /// Set the RMS amplitude at 1 m.
    pub fn with_gain(mut self, gain: f64) -> Self {
        self.gain = gain;
        self
    }
    /// Emit only between `start_s` and `end_s` seconds.
    pub fn active_between(mut self, start_s: f64, end_s: f64) -> Self {
        self.active = Some((start_s, end_s));
        self
    }
}

/// Everything to render: sources, sensor noise, an optional room.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Scene {
    /// The point sources.
    pub sources: Vec<SceneSource>,
    /// Standard deviation of the white sensor noise per microphone (raw sample units).
    pub sensor_noise_std: f64,
    /// Image-source room; `None` = free field.
    pub room: Option<Room>,
    /// Speed of sound in m/s.
    pub speed_of_sound_m_s: f64,
}

impl Default for Scene {
    fn default() -> Self {
        Scene {
            sources: Vec::new(),
            sensor_noise_std: 0.0,
            room: None,
            speed_of_sound_m_s: SPEED_OF_SOUND_M_S,
        }
    }
}

impl Scene {
    /// An empty free-field scene (c = 343 m/s, no sensor noise).
    pub fn new() -> Self {
        Self::default()
    }

    /// Add a source.
    pub fn with_source(mut self, source: SceneSource) -> Self {
        self.sources.push(source);
        self
    }

    /// The earliest emission start among `group` (0 for an always-active source): the
    /// audio before it holds only the other sources and sensor noise (the group is heard
    /// from `first_onset_s + min distance / c` on).
    /// An empty or unknown group gives 0.
    pub fn first_onset_s(&self, group: &[usize]) -> f64 {
        let t = group
            .iter()
            .filter_map(|&i| self.sources.get(i))
            .map(|s| s.active.map_or(0.0, |(a, _)| a.max(0.0)))
            .fold(f64::INFINITY, f64::min);
        if t.is_finite() {
            t
        } else {
            0.0
        }
    }

    /// Check the scene against `geometry` and a sample rate: finite positions, gains ≥ 0,
    /// ordered active windows, tone frequencies below fs/2, a sensible room that contains
    /// every source and microphone.
    pub fn validate(&self, geometry: &Geometry, sample_rate_hz: u32) -> Result<()> {
        let bad = |m: String| Err(Error::Config(format!("scene: {m}")));
        if sample_rate_hz == 0 {
            return bad("sample rate must be positive".into());
        }
        if !(self.speed_of_sound_m_s.is_finite() && self.speed_of_sound_m_s > 0.0) {
            return bad(format!("speed of sound {} m/s", self.speed_of_sound_m_s));
        }
        if !(self.sensor_noise_std.is_finite() && self.sensor_noise_std >= 0.0) {
            return bad(format!("sensor noise std {}", self.sensor_noise_std));
        }
        if geometry.mics.iter().flatten().any(|v| !v.is_finite()) {
            return bad("microphone position is not finite".into());
        }
        for (i, s) in self.sources.iter().enumerate() {
            if s.position_m.iter().any(|v| !v.is_finite()) {
                return bad(format!("source {i}: position is not finite"));
            }
            if !(s.gain.is_finite() && s.gain >= 0.0) {
                return bad(format!("source {i}: gain {} must be finite and ≥ 0", s.gain));
            }
            if let Some((a, b)) = s.active {
                if !(a.is_finite() && b.is_finite() && a < b) {
                    return bad(format!("source {i}: active window {a} s .. {b} s"));
                }
            }
            if let Signal::Tone(f) = s.signal {
                let nyq = sample_rate_hz as f64 / 2.0;
                if !(f.is_finite() && f > 0.0 && f < nyq) {
                    return bad(format!("source {i}: tone {f} Hz must be in (0, {nyq}) Hz"));
                }
            }
        }
        if let Some(room) = &self.room {
            if room.size_m.iter().any(|v| !(v.is_finite() && *v > 0.0))
                || room.origin_m.iter().any(|v| !v.is_finite())
            {
                return bad(format!("room size {:?} m at {:?}", room.size_m, room.origin_m));
            }
            if !(0.0..=1.0).contains(&room.reflection) {
                return bad(format!(
                    "reflection coefficient {} not in [0, 1]",
                    room.reflection
                ));
            }
            if room.max_order > MAX_REFLECTION_ORDER {
                return bad(format!(
                    "reflection order {} > {MAX_REFLECTION_ORDER}",
                    room.max_order
                ));
            }
            let inside = |p: &[f64; 3]| {
                (0..3).all(|a| p[a] >= room.origin_m[a] && p[a] <= room.origin_m[a] + room.size_m[a])
            };
            for (i, s) in self.sources.iter().enumerate() {
                if !inside(&s.position_m) {
                    return bad(format!("source {i} at {:?} m is outside the room", s.position_m));
                }
            }
            for (m, p) in geometry.mics.iter().enumerate() {
                if !inside(p) {
                    return bad(format!("microphone {m} at {p:?} m is outside the room"));
                }
            }
        }
        Ok(())
    }
}

/// A position `dist_m` metres away in direction (azimuth, elevation) in degrees:
/// dist·(cos el·cos az, cos el·sin az, sin el).
pub fn position_from_az_el(az_deg: f64, el_deg: f64, dist_m: f64) -> [f64; 3] {
    let (az, el) = (az_deg.to_radians(), el_deg.to_radians());
    [
        dist_m * el.cos() * az.cos(),
        dist_m * el.cos() * az.sin(),
        dist_m * el.sin(),
    ]
}

fn mix_seed(seed: u64, tag: u64, index: u64) -> u64 {
    // SplitMix64 finaliser over the combined words.
    let mut z = seed ^ tag.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ index.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn next_fast_len(n: usize) -> usize {
    let mut best = n.next_power_of_two();
    let mut p2 = 1usize;
    while p2 < best {
        let mut p3 = p2;
        while p3 < best {
            let mut p5 = p3;
            while p5 < best {
                if p5 >= n && p5 & 1 == 0 {
                    best = p5;
                }
                p5 *= 5;
            }
            p3 *= 3;
        }
        p2 *= 2;
    }
    best.max(2)
}

fn distance(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2))
        .sqrt()
        .max(MIN_DISTANCE_M)
}

fn gate(t: f64, window: Option<(f64, f64)>) -> f64 {
    let Some((a, b)) = window else { return 1.0 };
    if !(t > a && t < b) {
        return 0.0;
    }
    let ramp = RAMP_S.min((b - a) / 2.0);
    let edge = ((t - a).min(b - t) / ramp).min(1.0);
    0.5 - 0.5 * (PI * edge).cos()
}

/// Render the whole scene: every source plus sensor noise. `duration_s` is rounded to
/// whole samples. Invalid values do not panic (distances are clamped to 1 cm, non-finite
/// gains count as 0); call [`Scene::validate`] first for clear errors.
pub fn render(scene: &Scene, geometry: &Geometry, sample_rate_hz: u32, duration_s: f64, seed: u64) -> Audio {
    let all: Vec<usize> = (0..scene.sources.len()).collect();
    render_parts(scene, geometry, sample_rate_hz, duration_s, seed, &all, true)
}

/// Render only the sources listed in `sources` (indices into `scene.sources`), with or
/// without the sensor noise. Each component is identical to its share of [`render`] with
/// the same seed, so `render = render_parts(group) + render_parts(rest, noise)` exactly
/// (up to f32 rounding).
pub fn render_parts(
    scene: &Scene,
    geometry: &Geometry,
    sample_rate_hz: u32,
    duration_s: f64,
    seed: u64,
    sources: &[usize],
    sensor_noise: bool,
) -> Audio {
    let fs = sample_rate_hz as f64;
    let n = if duration_s.is_finite() && duration_s > 0.0 && sample_rate_hz > 0 {
        (duration_s * fs).round() as usize
    } else {
        0
    };
    let num_mics = geometry.mics.len();
    let mut channels = vec![vec![0.0f32; n]; num_mics];
    if n == 0 || num_mics == 0 {
        return Audio {
            sample_rate_hz,
            channels,
        };
    }
    let c = if scene.speed_of_sound_m_s.is_finite() && scene.speed_of_sound_m_s > 0.0 {
        scene.speed_of_sound_m_s
    } else {
        SPEED_OF_SOUND_M_S
    };
    // Paths (delay in samples, amplitude) per source and microphone, for every source of
    // the scene: the pre-roll must not depend on which subset is rendered.
    let paths: Vec<Vec<Vec<(f64, f64)>>> = scene
        .sources
        .iter()
        .map(|s| {
            let gain = if s.gain.is_finite() { s.gain } else { 0.0 };
            let images = image_sources(s.position_m, scene.room.as_ref());
            geometry
                .mics
                .iter()
                .map(|m| {
                    images
                        .iter()
                        .map(|(p, beta)| {
                            let r = distance(p, m);
                            (r / c * fs, gain * beta / r)
                        })
                        .collect()
                })
                .collect()
        })
        .collect();
    let max_delay = paths
        .iter()
        .flatten()
        .flatten()
        .map(|p| p.0)
        .fold(0.0f64, f64::max);
    const PAD: usize = 256;
    let pre = max_delay.ceil() as usize + PAD;
    let total = pre + n + PAD;
    let len = next_fast_len(total + PAD);
    let mut planner = RealFftPlanner::<f64>::new();
    let fwd = planner.plan_fft_forward(len);
    let inv = planner.plan_fft_inverse(len);

    let selected: Vec<usize> = {
        let mut v: Vec<usize> = sources
            .iter()
            .copied()
            .filter(|&i| i < scene.sources.len())
            .collect();
        v.sort_unstable();
        v.dedup();
        v
    };
    // Source spectra.
    let spectra: Vec<(usize, Vec<Complex<f64>>)> = selected
        .par_iter()
        .map(|&si| {
            let s = &scene.sources[si];
            let mut x = signals::generate(&s.signal, fs, total, pre, n, mix_seed(seed, 1, si as u64));
            let half = PAD / 2;
            for (j, v) in x.iter_mut().enumerate() {
                let t = (j as f64 - pre as f64) / fs;
                let mut w = gate(t, s.active);
                // Taper the outer half of the pre- and post-roll.
                let edge = j.min(total - 1 - j);
                if edge < half {
                    w *= 0.5 - 0.5 * (PI * edge as f64 / half as f64).cos();
                }
                *v *= w;
            }
            x.resize(len, 0.0);
            let mut spec = fwd.make_output_vec();
            // Lengths come from the plan, so the transform cannot fail.
            let _ = fwd.process(&mut x, &mut spec);
            (si, spec)
        })
        .collect();

    let noise_std = if sensor_noise && scene.sensor_noise_std.is_finite() {
        scene.sensor_noise_std.max(0.0)
    } else {
        0.0
    };
    let nbins = len / 2 + 1;
    channels.par_iter_mut().enumerate().for_each(|(m, out)| {
        if !spectra.is_empty() {
            let mut y = vec![Complex::new(0.0, 0.0); nbins];
            for (si, spec) in &spectra {
                let all = &paths[*si][m];
                // Many images: the reflections go through a windowed-sinc impulse response.
                let exact = if all.len() > EXACT_IMAGES_MAX + 1 {
                    let mut h = reflections_response(&all[1..], len);
                    let mut hs = fwd.make_output_vec();
                    let _ = fwd.process(&mut h, &mut hs);
                    for ((yk, sk), hk) in y.iter_mut().zip(spec).zip(&hs) {
                        *yk += sk * hk;
                    }
                    &all[..1]
                } else {
                    &all[..]
                };
                for &(d, a) in exact {
                    if a == 0.0 {
                        continue;
                    }
                    // e^{-j2πkd/len}, by recurrence, re-anchored every 512 bins.
                    let step = -2.0 * PI * d / len as f64;
                    let w = Complex::from_polar(1.0, step);
                    let mut z = Complex::new(a, 0.0);
                    for (k, (yk, sk)) in y.iter_mut().zip(spec).enumerate() {
                        if k % 512 == 0 {
                            z = Complex::from_polar(a, step * k as f64);
                        }
                        *yk += sk * z;
                        z *= w;
                    }
                }
            }
            y[0].im = 0.0;
            if len & 1 == 0 {
                y[nbins - 1] = Complex::new(0.0, 0.0);
            }
            let mut buf = inv.make_output_vec();
            let _ = inv.process(&mut y, &mut buf);
            let scale = 1.0 / len as f64;
            for (o, v) in out.iter_mut().zip(&buf[pre..pre + n]) {
                *o = (v * scale) as f32;
            }
        }
        if noise_std > 0.0 {
            let mut g = signals::Gauss::new(mix_seed(seed, 2, m as u64));
            for o in out.iter_mut() {
                *o += (noise_std * g.next()) as f32;
            }
        }
    });
    Audio {
        sample_rate_hz,
        channels,
    }
}

/// Sample range over which the group is active, clamped to `0..n`.
fn group_mask(scene: &Scene, group: &[usize], fs: f64, n: usize) -> Vec<bool> {
    let mut mask = vec![false; n];
    for &i in group {
        match scene.sources.get(i).and_then(|s| s.active) {
            None => mask.iter_mut().for_each(|v| *v = true),
            Some((a, b)) => {
                let a = ((a * fs).floor().max(0.0) as usize).min(n);
                let b = ((b * fs).ceil().max(0.0) as usize).min(n);
                mask[a..b.max(a)].iter_mut().for_each(|v| *v = true);
            }
        }
    }
    mask
}

fn mean_power(a: &Audio, mask: &[bool]) -> f64 {
    let count = mask.iter().filter(|&&m| m).count() * a.channels.len();
    if count == 0 {
        return 0.0;
    }
    let sum: f64 = a
        .channels
        .iter()
        .map(|ch| {
            ch.iter()
                .zip(mask)
                .filter(|(_, &m)| m)
                .map(|(&v, _)| (v as f64) * (v as f64))
                .sum::<f64>()
        })
        .sum();
    sum / count as f64
}

fn check_group(scene: &Scene, group: &[usize]) -> Result<()> {
    if group.is_empty() {
        return Err(Error::Config("SNR: the signal group is empty".into()));
    }
    if let Some(&i) = group.iter().find(|&&i| i >= scene.sources.len()) {
        return Err(Error::Config(format!(
            "SNR: source {i} does not exist (the scene has {})",
            scene.sources.len()
        )));
    }
    Ok(())
}

/// The SNR in dB at the array: mean power per microphone of the `group` sources over
/// the samples where any of them is active, over that of everything else (other sources
/// and sensor noise) over the same samples.
pub fn measure_snr_db(
    scene: &Scene,
    group: &[usize],
    geometry: &Geometry,
    sample_rate_hz: u32,
    duration_s: f64,
    seed: u64,
) -> Result<f64> {
    check_group(scene, group)?;
    let rest: Vec<usize> = (0..scene.sources.len()).filter(|i| !group.contains(i)).collect();
    let sig = render_parts(scene, geometry, sample_rate_hz, duration_s, seed, group, false);
    let noise = render_parts(scene, geometry, sample_rate_hz, duration_s, seed, &rest, true);
    let mask = group_mask(scene, group, sample_rate_hz as f64, sig.num_samples());
    let (ps, pn) = (mean_power(&sig, &mask), mean_power(&noise, &mask));
    if ps.is_nan() || ps <= 0.0 {
        return Err(Error::Config(
            "SNR: the signal group is silent at the array (zero gain or no active samples)".into(),
        ));
    }
    if pn.is_nan() || pn <= 0.0 {
        return Err(Error::Config(
            "SNR: there is no noise (no other source and no sensor noise)".into(),
        ));
    }
    Ok(10.0 * (ps / pn).log10())
}

/// Scale the gains of the `group` sources so that [`measure_snr_db`] gives `snr_db`;
/// returns the amplitude factor applied. The rendering must later use the same geometry,
/// sample rate, duration and seed for the figure to hold exactly.
pub fn scale_to_snr(
    scene: &mut Scene,
    group: &[usize],
    snr_db: f64,
    geometry: &Geometry,
    sample_rate_hz: u32,
    duration_s: f64,
    seed: u64,
) -> Result<f64> {
    if !snr_db.is_finite() {
        return Err(Error::Config(format!("SNR {snr_db} dB is not finite")));
    }
    let now = measure_snr_db(scene, group, geometry, sample_rate_hz, duration_s, seed)?;
    let factor = 10f64.powf((snr_db - now) / 20.0);
    for &i in group {
        scene.sources[i].gain *= factor;
    }
    Ok(factor)
}
