//! Source signal generators for the simulator: deterministic from a seed, unit RMS over
//! the rendered interval.
//!
//! - **Speech-like**: a voiced harmonic series, f0 slowly varying within 100–250 Hz
//!   (a drifting base pitch plus 0.7 Hz and 2.3 Hz intonation), harmonics up to 3.8 kHz
//!   with an h^−0.6 source slope (the fundamental softened by f/(f + 250 Hz)) shaped by
//!   three formant resonances per syllable (five vowel patterns), plus band-limited (300–3500 Hz) aspiration and fricative onsets; a
//!   syllable envelope sin^0.7 over 150–350 ms syllables (≈ 4 Hz amplitude modulation) with
//!   occasional 80–300 ms pauses.
//! - **Rotor-like** (a drone): four rotors, each a blade-passing fundamental
//!   f_b ∈ [140, 220] Hz with ±0.5 % random-walk jitter and harmonics up to 4.5 kHz
//!   (amplitude h^−0.8), plus broadband noise (80 Hz high-pass, 1.5 kHz one-pole low-pass)
//!   carrying twice the harmonic power. Stationary.
//! - **White noise**: Gaussian, σ = 1.
//! - **Tone(f)**: √2·sin(2πft + φ), random φ.
//!
//! Every generator fills `total` samples whose sample j is at time (j − `offset`)/fs; the
//! result is scaled to RMS 1 over samples `offset .. offset + n`.

use super::Signal;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::f64::consts::PI;

/// Box–Muller standard normal deviates.
pub(crate) struct Gauss {
    rng: StdRng,
    spare: Option<f64>,
}

impl Gauss {
    pub(crate) fn new(seed: u64) -> Self {
        Gauss {
            rng: StdRng::seed_from_u64(seed),
            spare: None,
        }
    }
    pub(crate) fn next(&mut self) -> f64 {
        if let Some(s) = self.spare.take() {
            return s;
        }
        let u1: f64 = 1.0 - self.rng.gen::<f64>(); // (0, 1]
        let u2: f64 = self.rng.gen();
        let r = (-2.0 * u1.ln()).sqrt();
        self.spare = Some(r * (2.0 * PI * u2).sin());
        r * (2.0 * PI * u2).cos()
    }
    pub(crate) fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.rng.gen::<f64>()
    }
}

/// RBJ-cookbook second-order section (direct form I).
struct Biquad {
    b: [f64; 3],
    a: [f64; 2],
    x: [f64; 2],
    y: [f64; 2],
}

impl Biquad {
    fn new(kind: char, f_hz: f64, fs: f64) -> Self {
        let f = f_hz.clamp(1.0, 0.49 * fs);
        let w0 = 2.0 * PI * f / fs;
        let (cw, sw) = (w0.cos(), w0.sin());
        let alpha = sw / (2.0 * std::f64::consts::FRAC_1_SQRT_2);
        let a0 = 1.0 + alpha;
        let b = if kind == 'h' {
            [(1.0 + cw) / 2.0, -(1.0 + cw), (1.0 + cw) / 2.0]
        } else {
            [(1.0 - cw) / 2.0, 1.0 - cw, (1.0 - cw) / 2.0]
        };
        Biquad {
            b: [b[0] / a0, b[1] / a0, b[2] / a0],
            a: [-2.0 * cw / a0, (1.0 - alpha) / a0],
            x: [0.0; 2],
            y: [0.0; 2],
        }
    }
    fn run(&mut self, x: f64) -> f64 {
        let y = self.b[0] * x + self.b[1] * self.x[0] + self.b[2] * self.x[1]
            - self.a[0] * self.y[0]
            - self.a[1] * self.y[1];
        self.x = [x, self.x[0]];
        self.y = [y, self.y[0]];
        y
    }
}

/// Generate `total` samples of `signal` (see the module docs), unit RMS over
/// `offset .. offset + n`.
pub(crate) fn generate(
    signal: &Signal,
    fs: f64,
    total: usize,
    offset: usize,
    n: usize,
    seed: u64,
) -> Vec<f64> {
    let mut g = Gauss::new(seed);
    let mut x = match *signal {
        Signal::WhiteNoise => (0..total).map(|_| g.next()).collect(),
        Signal::Tone(f) => {
            let phi = g.uniform(0.0, 2.0 * PI);
            if !(f.is_finite() && f > 0.0 && f < fs / 2.0) {
                vec![0.0; total]
            } else {
                (0..total)
                    .map(|j| {
                        let t = (j as f64 - offset as f64) / fs;
                        std::f64::consts::SQRT_2 * (2.0 * PI * f * t + phi).sin()
                    })
                    .collect()
            }
        }
        Signal::Speech => speech(&mut g, fs, total, offset),
        Signal::Rotor => rotor(&mut g, fs, total),
    };
    let end = (offset + n).min(total);
    if end > offset {
        let p = x[offset..end].iter().map(|v| v * v).sum::<f64>() / (end - offset) as f64;
        if p > 0.0 {
            let s = 1.0 / p.sqrt();
            x.iter_mut().for_each(|v| *v *= s);
        }
    }
    x
}

/// One syllable (or pause) of the speech generator.
struct Syllable {
    start: f64,
    dur: f64,
    voiced: bool,
    formants: [f64; 3],
    fricative_s: f64,
    pitch_factor: f64,
}

const VOWELS: [[f64; 3]; 5] = [
    [730.0, 1090.0, 2440.0], // a
    [270.0, 2290.0, 3010.0], // i
    [300.0, 870.0, 2240.0],  // u
    [530.0, 1840.0, 2480.0], // e
    [570.0, 840.0, 2410.0],  // o
];
const BANDWIDTHS: [f64; 3] = [90.0, 110.0, 170.0];

fn formant_gain(f: f64, formants: &[f64; 3]) -> f64 {
    let mut g = 0.0;
    for (i, &fc) in formants.iter().enumerate() {
        let b = BANDWIDTHS[i];
        // Magnitude of a two-pole resonance, normalised to 1 at its peak.
        let r = (f / fc).powi(2);
        let h = 1.0 / ((1.0 - r).powi(2) + (f * b / (fc * fc)).powi(2)).sqrt();
        g += h * (b / fc) / [1.0, 1.4, 2.0][i];
    }
    g + 0.05
}

fn speech(g: &mut Gauss, fs: f64, total: usize, offset: usize) -> Vec<f64> {
    let t0 = -(offset as f64) / fs;
    let t_end = t0 + total as f64 / fs;
    // Syllable plan.
    let mut syl = Vec::new();
    let mut t = t0 - g.uniform(0.0, 0.3);
    while t < t_end {
        if g.uniform(0.0, 1.0) < 0.18 {
            let dur = g.uniform(0.08, 0.3);
            syl.push(Syllable {
                start: t,
                dur,
                voiced: false,
                formants: VOWELS[0],
                fricative_s: 0.0,
                pitch_factor: 1.0,
            });
            t += dur;
        }
        let dur = g.uniform(0.15, 0.35);
        let v = (g.uniform(0.0, 5.0) as usize).min(4);
        let jitter = |g: &mut Gauss| g.uniform(0.9, 1.1);
        syl.push(Syllable {
            start: t,
            dur,
            voiced: true,
            formants: [
                VOWELS[v][0] * jitter(g),
                VOWELS[v][1] * jitter(g),
                VOWELS[v][2] * jitter(g),
            ],
            fricative_s: if g.uniform(0.0, 1.0) < 0.5 {
                g.uniform(0.03, 0.08)
            } else {
                0.0
            },
            pitch_factor: g.uniform(0.88, 1.12),
        });
        t += dur;
    }
    let f0_base = g.uniform(120.0, 180.0);
    let (ph1, ph2) = (g.uniform(0.0, 2.0 * PI), g.uniform(0.0, 2.0 * PI));
    let f_top = 3800.0f64.min(0.45 * fs);
    let nh = (f_top / 100.0).floor().max(1.0) as usize;
    let mut phases: Vec<f64> = (0..nh).map(|_| g.uniform(0.0, 2.0 * PI)).collect();
    let block = ((0.005 * fs).round() as usize).max(1);
    let mut amps = vec![0.0; nh];
    let mut hp = Biquad::new('h', 300.0, fs);
    let mut lp = Biquad::new('l', 3500.0, fs);
    let mut hp2 = Biquad::new('h', 300.0, fs);
    let mut lp2 = Biquad::new('l', 3500.0, fs);
    let mut fric_hp = Biquad::new('h', 2000.0, fs);
    let mut out = vec![0.0; total];
    let mut si = 0usize;
    let mut f0 = f0_base;
    for (j, o) in out.iter_mut().enumerate() {
        let t = t0 + j as f64 / fs;
        while si + 1 < syl.len() && t >= syl[si].start + syl[si].dur {
            si += 1;
        }
        let s = &syl[si];
        let tau = ((t - s.start) / s.dur).clamp(0.0, 1.0);
        let env = if s.voiced {
            (PI * tau).sin().max(0.0).powf(0.7)
        } else {
            0.0
        };
        if j % block == 0 {
            let drift =
                1.0 + 0.12 * (2.0 * PI * 0.7 * t + ph1).sin() + 0.06 * (2.0 * PI * 2.3 * t + ph2).sin();
            f0 = (f0_base * s.pitch_factor * drift).clamp(100.0, 250.0);
            for (h, a) in amps.iter_mut().enumerate() {
                let f = (h + 1) as f64 * f0;
                *a = if f < f_top {
                    formant_gain(f, &s.formants) * ((h + 1) as f64).powf(-0.6) * (f / (f + 250.0))
                        / (1.0 + (f / 3500.0).powi(8))
                } else {
                    0.0
                };
            }
        }
        let mut v = 0.0;
        if env > 0.0 {
            for (h, (p, a)) in phases.iter_mut().zip(&amps).enumerate() {
                if *a > 0.0 {
                    v += a * p.sin();
                }
                *p += 2.0 * PI * (h + 1) as f64 * f0 / fs;
                if *p > 2.0 * PI {
                    *p -= 2.0 * PI;
                }
            }
        } else {
            for (h, p) in phases.iter_mut().enumerate() {
                *p = (*p + 2.0 * PI * (h + 1) as f64 * f0 / fs) % (2.0 * PI);
            }
        }
        // Aspiration (follows the voiced envelope) and fricative onsets.
        let noise = lp.run(hp.run(g.next()));
        let fric = fric_hp.run(lp2.run(hp2.run(g.next())));
        let t_in = t - s.start;
        let fric_env = if s.voiced && t_in < s.fricative_s {
            (PI * t_in / s.fricative_s).sin()
        } else {
            0.0
        };
        *o = env * (v + 0.15 * noise) + 0.6 * fric_env * fric;
    }
    out
}

fn rotor(g: &mut Gauss, fs: f64, total: usize) -> Vec<f64> {
    let f_top = 4500.0f64.min(0.45 * fs);
    struct R {
        f: f64,
        dev: f64,
        phases: Vec<f64>,
    }
    let mut rotors: Vec<R> = (0..4)
        .map(|_| {
            let f = g.uniform(140.0, 220.0);
            let nh = (f_top / f).floor().max(1.0) as usize;
            R {
                f,
                dev: 0.0,
                phases: (0..nh).map(|_| g.uniform(0.0, 2.0 * PI)).collect(),
            }
        })
        .collect();
    let amps: Vec<f64> = (1..=40).map(|h| (h as f64).powf(-0.8)).collect();
    // Harmonic power per rotor: Σ a_h²/2; the noise gets twice the total.
    let harm_power: f64 = rotors
        .iter()
        .map(|r| {
            amps[..r.phases.len().min(40)]
                .iter()
                .map(|a| a * a / 2.0)
                .sum::<f64>()
        })
        .sum();
    let mut hp = Biquad::new('h', 80.0, fs);
    let a_lp = (-2.0 * PI * 1500.0 / fs).exp();
    let mut lp_state = 0.0;
    let mut noise: Vec<f64> = (0..total)
        .map(|_| {
            lp_state = a_lp * lp_state + (1.0 - a_lp) * g.next();
            hp.run(lp_state)
        })
        .collect();
    let np = noise.iter().map(|v| v * v).sum::<f64>() / total.max(1) as f64;
    if np > 0.0 {
        let s = (2.0 * harm_power / np).sqrt();
        noise.iter_mut().for_each(|v| *v *= s);
    }
    // Jitter: AR(1) deviation, σ 0.5 %, time constant 0.2 s, updated every 1 ms.
    let step = ((0.001 * fs).round() as usize).max(1);
    let rho = (-0.001 / 0.2f64).exp();
    let innov = 0.005 * (1.0 - rho * rho).sqrt();
    let mut out = noise;
    for (j, o) in out.iter_mut().enumerate() {
        if j % step == 0 {
            for r in rotors.iter_mut() {
                r.dev = rho * r.dev + innov * g.next();
            }
        }
        let mut v = 0.0;
        for r in rotors.iter_mut() {
            let f = r.f * (1.0 + r.dev);
            for (h, p) in r.phases.iter_mut().enumerate() {
                v += amps[h.min(39)] * p.sin();
                *p += 2.0 * PI * (h + 1) as f64 * f / fs;
                if *p > 2.0 * PI {
                    *p -= 2.0 * PI;
                }
            }
        }
        *o += v;
    }
    out
}
