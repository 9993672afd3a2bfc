//! Simulator tests: geometric delays, 1/r, SNR, determinism, rooms, signal character.

use super::*;
use realfft::RealFftPlanner;

const FS: u32 = 16000;

fn rms(x: &[f32]) -> f64 {
    (x.iter().map(|&v| (v as f64).powi(2)).sum::<f64>() / x.len() as f64).sqrt()
}

fn spectrum(x: &[f64]) -> Vec<Complex<f64>> {
    let n = x.len();
    let mut p = RealFftPlanner::<f64>::new();
    let f = p.plan_fft_forward(n);
    let mut inp: Vec<f64> = x
        .iter()
        .enumerate()
        .map(|(i, v)| v * (0.5 - 0.5 * (2.0 * PI * i as f64 / n as f64).cos()))
        .collect();
    let mut out = f.make_output_vec();
    f.process(&mut inp, &mut out).unwrap();
    out
}

/// Delay of `b` relative to `a` in samples (positive: b is later), by the integer
/// cross-correlation peak refined with a weighted phase-slope fit of the cross-spectrum.
fn delay_samples(a: &[f32], b: &[f32]) -> f64 {
    let n = a.len();
    let mut best = (0i64, f64::MIN);
    for lag in -40i64..=40 {
        let mut s = 0.0;
        for i in 40..n - 40 {
            s += a[i] as f64 * b[(i as i64 + lag) as usize] as f64;
        }
        if s > best.1 {
            best = (lag, s);
        }
    }
    let d_int = best.0 as f64;
    let fa = spectrum(&a.iter().map(|&v| v as f64).collect::<Vec<_>>());
    let fb = spectrum(&b.iter().map(|&v| v as f64).collect::<Vec<_>>());
    let (mut num, mut den) = (0.0, 0.0);
    for k in 1..(0.8 * (n / 2) as f64) as usize {
        let w0 = 2.0 * PI * k as f64 / n as f64;
        let c = fb[k] * fa[k].conj() * Complex::from_polar(1.0, w0 * d_int);
        let wgt = c.norm();
        num += wgt * w0 * c.arg();
        den += wgt * w0 * w0;
    }
    d_int - num / den
}

fn two_mics() -> Geometry {
    Geometry {
        mics: vec![[0.0, 0.0, 0.0], [0.15, 0.02, -0.01]],
    }
}

#[test]
fn position_from_az_el_convention() {
    let p = position_from_az_el(90.0, 0.0, 2.0);
    assert!(p[0].abs() < 1e-12 && (p[1] - 2.0).abs() < 1e-12 && p[2].abs() < 1e-12);
    let p = position_from_az_el(-135.0, 30.0, 1.0);
    let az = p[1].atan2(p[0]).to_degrees();
    let el = p[2].atan2(p[0].hypot(p[1])).to_degrees();
    assert!((az + 135.0).abs() < 1e-9 && (el - 30.0).abs() < 1e-9);
}

#[test]
fn delay_between_mics_matches_geometry() {
    let geo = two_mics();
    let mut worst: f64 = 0.0;
    for (signal, az) in [
        (Signal::WhiteNoise, 37.0),
        (Signal::WhiteNoise, -151.3),
        (Signal::Speech, 12.7),
    ] {
        let pos = position_from_az_el(az, 10.0, 2.0);
        let scene = Scene::new().with_source(SceneSource::new(pos, signal));
        let a = render(&scene, &geo, FS, 2.0, 11);
        let expected =
            (distance(&pos, &geo.mics[1]) - distance(&pos, &geo.mics[0])) / SPEED_OF_SOUND_M_S * FS as f64;
        let got = delay_samples(&a.channels[0], &a.channels[1]);
        let err = (got - expected).abs();
        eprintln!("{signal:?} az {az}: expected {expected:.4} samples, got {got:.4}, error {err:.2e}");
        assert!(err < 0.05, "{signal:?}: expected {expected}, got {got}");
        worst = worst.max(err);
    }
    assert!(worst < 0.01, "worst fractional delay error {worst}");
}

#[test]
fn amplitude_falls_as_one_over_r() {
    let geo = Geometry {
        mics: vec![[1.0, 0.0, 0.0], [0.0, 3.0, 0.0], [0.0, 0.0, -0.5]],
    };
    let scene = Scene::new().with_source(SceneSource::new([0.0; 3], Signal::WhiteNoise).with_gain(100.0));
    let a = render(&scene, &geo, FS, 2.0, 5);
    let r: Vec<f64> = a.channels.iter().map(|c| rms(c)).collect();
    eprintln!("RMS at 1 m, 3 m, 0.5 m: {r:?} (expected 100, 33.3, 200)");
    assert!((r[0] / 100.0 - 1.0).abs() < 0.02, "{r:?}");
    assert!((r[0] / r[1] / 3.0 - 1.0).abs() < 0.005, "{r:?}");
    assert!((r[2] / r[0] / 2.0 - 1.0).abs() < 0.005, "{r:?}");
}

fn talkers_and_drone() -> (Scene, Geometry) {
    let geo = Geometry {
        mics: (0..8)
            .map(|i| {
                let a = i as f64 * PI / 4.0;
                [0.1 * a.cos(), 0.1 * a.sin(), 0.0]
            })
            .collect(),
    };
    let scene = Scene {
        sources: vec![
            SceneSource::new(position_from_az_el(30.0, 0.0, 2.0), Signal::Speech).active_between(1.0, 4.0),
            SceneSource::new(position_from_az_el(-100.0, 10.0, 1.5), Signal::Speech).active_between(1.2, 4.0),
            SceneSource::new([0.0, 0.0, 0.35], Signal::Rotor).with_gain(3.0),
        ],
        sensor_noise_std: 0.05,
        ..Scene::default()
    };
    (scene, geo)
}

#[test]
fn scale_to_snr_gives_requested_ratio() {
    let (mut scene, geo) = talkers_and_drone();
    let group = [0, 1];
    for target in [-5.0, 0.0, 10.0] {
        let factor = scale_to_snr(&mut scene, &group, target, &geo, FS, 3.0, 7).unwrap();
        // Independent check: powers over t ≥ 1 s (the talkers' active time).
        let sig = render_parts(&scene, &geo, FS, 3.0, 7, &group, false);
        let noise = render_parts(&scene, &geo, FS, 3.0, 7, &[2], true);
        let p = |a: &Audio| {
            a.channels
                .iter()
                .map(|c| c[FS as usize..].iter().map(|&v| (v as f64).powi(2)).sum::<f64>())
                .sum::<f64>()
        };
        let snr = 10.0 * (p(&sig) / p(&noise)).log10();
        eprintln!("target {target} dB: got {snr:.4} dB (gain factor {factor:.4})");
        assert!((snr - target).abs() < 0.1, "target {target}, got {snr}");
    }
    // The full render is the sum of its parts.
    let full = render(&scene, &geo, FS, 3.0, 7);
    let sig = render_parts(&scene, &geo, FS, 3.0, 7, &group, false);
    let noise = render_parts(&scene, &geo, FS, 3.0, 7, &[2], true);
    for m in 0..8 {
        for i in (0..full.num_samples()).step_by(97) {
            let d = full.channels[m][i] - sig.channels[m][i] - noise.channels[m][i];
            assert!(d.abs() < 1e-4 * (1.0 + full.channels[m][i].abs()), "{d}");
        }
    }
    // Errors.
    assert!(scale_to_snr(&mut scene, &[], 0.0, &geo, FS, 3.0, 7).is_err());
    assert!(scale_to_snr(&mut scene, &[9], 0.0, &geo, FS, 3.0, 7).is_err());
    let mut quiet = scene.clone();
    quiet.sources.truncate(2);
    quiet.sensor_noise_std = 0.0;
    assert!(scale_to_snr(&mut quiet, &group, 0.0, &geo, FS, 3.0, 7).is_err());
}

#[test]
fn talkers_silent_before_onset() {
    let (scene, geo) = talkers_and_drone();
    assert_eq!(scene.first_onset_s(&[0, 1]), 1.0);
    assert_eq!(scene.first_onset_s(&[2]), 0.0);
    let talk = render_parts(&scene, &geo, FS, 3.0, 3, &[0, 1], false);
    let before: f64 = talk
        .channels
        .iter()
        .map(|c| rms(&c[..(0.99 * FS as f64) as usize]))
        .sum();
    let after: f64 = talk
        .channels
        .iter()
        .map(|c| rms(&c[(1.3 * FS as f64) as usize..]))
        .sum();
    eprintln!("talker RMS before onset {before:.3e}, after {after:.3e}");
    assert!(before < 1e-4 * after, "{before} vs {after}");
}

#[test]
fn deterministic_with_seed() {
    let (scene, geo) = talkers_and_drone();
    let a = render(&scene, &geo, FS, 1.5, 42);
    let b = render(&scene, &geo, FS, 1.5, 42);
    assert_eq!(a, b);
    let c = render(&scene, &geo, FS, 1.5, 43);
    assert_ne!(a, c);
    assert_eq!(a.num_channels(), 8);
    assert_eq!(a.num_samples(), 24000);
    assert!(a.channels.iter().flatten().all(|v| v.is_finite()));
}

#[test]
fn image_sources_of_a_shoebox() {
    let room = Room {
        size_m: [5.0, 4.0, 3.0],
        origin_m: [-2.0, -2.0, -1.0],
        reflection: 0.5,
        max_order: 1,
    };
    let src = [1.0, 0.5, 0.2];
    let im = image_sources(src, Some(&room));
    assert_eq!(im.len(), 7);
    assert_eq!(im[0], (src, 1.0));
    let has = |p: [f64; 3], b: f64| {
        im.iter()
            .any(|(q, g)| (0..3).all(|i| (q[i] - p[i]).abs() < 1e-12) && (g - b).abs() < 1e-12)
    };
    // Walls at x = -2 and x = 3, z = -1 and z = 2.
    assert!(has([-5.0, 0.5, 0.2], 0.5));
    assert!(has([5.0, 0.5, 0.2], 0.5));
    assert!(has([1.0, 0.5, -2.2], 0.5));
    assert!(has([1.0, 0.5, 3.8], 0.5));
    let room2 = Room {
        max_order: 2,
        ..room.clone()
    };
    let im2 = image_sources(src, Some(&room2));
    assert_eq!(im2.len(), 25);
    assert_eq!(im2.iter().filter(|(_, g)| (g - 0.25).abs() < 1e-12).count(), 18);
    assert!(has_in(&im2, [-5.0, -4.5, 0.2], 0.25)); // x = -2 and y = -2 walls
    assert_eq!(image_sources(src, None), vec![(src, 1.0)]);

    // A room adds the reflections' energy.
    let geo = two_mics();
    let mut scene = Scene::new().with_source(SceneSource::new(src, Signal::WhiteNoise));
    let free = render(&scene, &geo, FS, 1.0, 1);
    scene.room = Some(room2);
    scene.validate(&geo, FS).unwrap();
    let echo = render(&scene, &geo, FS, 1.0, 1);
    assert!(rms(&echo.channels[0]) > 1.1 * rms(&free.channels[0]));
}

fn has_in(im: &[([f64; 3], f64)], p: [f64; 3], b: f64) -> bool {
    im.iter()
        .any(|(q, g)| (0..3).all(|i| (q[i] - p[i]).abs() < 1e-12) && (g - b).abs() < 1e-12)
}

#[test]
fn validate_reports_bad_scenes() {
    let geo = two_mics();
    let ok = Scene::new().with_source(SceneSource::new([1.0, 0.0, 0.0], Signal::Tone(1000.0)));
    ok.validate(&geo, FS).unwrap();
    let mut s = ok.clone();
    s.sources[0].signal = Signal::Tone(9000.0);
    assert!(s.validate(&geo, FS).unwrap_err().to_string().contains("tone"));
    let mut s = ok.clone();
    s.sources[0].active = Some((2.0, 1.0));
    assert!(s.validate(&geo, FS).is_err());
    let mut s = ok.clone();
    s.sources[0].gain = f64::NAN;
    assert!(s.validate(&geo, FS).is_err());
    let mut s = ok.clone();
    s.room = Some(Room {
        size_m: [0.5, 0.5, 0.5],
        origin_m: [-0.25, -0.25, -0.25],
        reflection: 0.3,
        max_order: 1,
    });
    assert!(s
        .validate(&geo, FS)
        .unwrap_err()
        .to_string()
        .contains("outside the room"));
    // Degenerate inputs do not panic.
    assert_eq!(render(&ok, &geo, FS, 0.0, 1).num_samples(), 0);
    let at_mic = Scene::new().with_source(SceneSource::new([0.0; 3], Signal::WhiteNoise));
    assert!(render(&at_mic, &geo, FS, 0.1, 1).channels[0]
        .iter()
        .all(|v| v.is_finite()));
}

fn band_fraction(x: &[f64], fs: f64, lo: f64, hi: f64) -> f64 {
    let s = spectrum(x);
    let n = x.len() as f64;
    let (mut inb, mut all) = (0.0, 0.0);
    for (k, c) in s.iter().enumerate() {
        let f = k as f64 * fs / n;
        let p = c.norm_sqr();
        all += p;
        if f >= lo && f <= hi {
            inb += p;
        }
    }
    inb / all
}

#[test]
fn speech_is_speech_like() {
    let fs = FS as f64;
    let n = 6 * FS as usize;
    let x = signals::generate(&Signal::Speech, fs, n, 0, n, 9);
    let r = (x.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
    assert!((r - 1.0).abs() < 1e-9);
    let band = band_fraction(&x, fs, 90.0, 3600.0);
    let upper = band_fraction(&x, fs, 300.0, 3500.0);
    eprintln!("speech: energy in 90-3600 Hz {band:.3}, in 300-3500 Hz {upper:.3}");
    assert!(band > 0.97 && upper > 0.6, "{band} {upper}");
    // Syllable-rate modulation: the envelope spectrum peaks between 2 and 8 Hz.
    let hop = 160;
    let env: Vec<f64> = x
        .chunks(hop)
        .map(|c| (c.iter().map(|v| v * v).sum::<f64>() / c.len() as f64).sqrt())
        .collect();
    let mean = env.iter().sum::<f64>() / env.len() as f64;
    let e: Vec<f64> = env.iter().map(|v| v - mean).collect();
    let es = spectrum(&e);
    let fr = fs / hop as f64 / e.len() as f64;
    let (kmax, _) = es
        .iter()
        .enumerate()
        .skip(1)
        .take_while(|(k, _)| (*k as f64) * fr < 30.0)
        .max_by(|a, b| a.1.norm().total_cmp(&b.1.norm()))
        .unwrap();
    let f_mod = kmax as f64 * fr;
    eprintln!("speech: envelope modulation peak {f_mod:.2} Hz");
    assert!((1.5..8.0).contains(&f_mod), "{f_mod}");
    // Pitch: autocorrelation of a voiced stretch peaks at a lag within 100-250 Hz.
    let loudest = env
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .map(|(i, _)| i * hop)
        .unwrap();
    let seg = &x[loudest.saturating_sub(400)..(loudest + 400).min(n)];
    let ac = |lag: usize| seg.iter().zip(&seg[lag..]).map(|(a, b)| a * b).sum::<f64>();
    let lag = (64..=160).max_by(|&a, &b| ac(a).total_cmp(&ac(b))).unwrap();
    let f0 = fs / lag as f64;
    eprintln!("speech: f0 at the loudest syllable {f0:.1} Hz");
    assert!((95.0..=255.0).contains(&f0), "{f0}");
}

#[test]
fn rotor_is_stationary_and_harmonic() {
    let fs = FS as f64;
    let n = 4 * FS as usize;
    let x = signals::generate(&Signal::Rotor, fs, n, 0, n, 4);
    let blocks: Vec<f64> = x
        .chunks(FS as usize / 4)
        .map(|c| (c.iter().map(|v| v * v).sum::<f64>() / c.len() as f64).sqrt())
        .collect();
    let (lo, hi) = blocks
        .iter()
        .fold((f64::MAX, 0.0f64), |(l, h), &v| (l.min(v), h.max(v)));
    eprintln!("rotor: 0.25 s block RMS range {lo:.3} .. {hi:.3}");
    assert!(lo > 0.85 && hi < 1.15, "{lo} {hi}");
    // Blade-passing lines stand well above the broadband floor in 130-230 Hz.
    let s = spectrum(&x);
    let bin = |f: f64| (f * n as f64 / fs) as usize;
    let mut band: Vec<f64> = s[bin(130.0)..bin(230.0)].iter().map(|c| c.norm_sqr()).collect();
    band.sort_by(f64::total_cmp);
    let ratio = band[band.len() - 1] / band[band.len() / 2];
    eprintln!("rotor: strongest line / median in 130-230 Hz = {ratio:.0}");
    assert!(ratio > 100.0, "{ratio}");
    // Strong broadband part: much energy away from 140-220 Hz harmonics' lines.
    assert!(band_fraction(&x, fs, 1000.0, 8000.0) > 0.2);
}

#[test]
fn tone_and_white_noise() {
    let fs = FS as f64;
    let n = FS as usize;
    let t = signals::generate(&Signal::Tone(1000.0), fs, n, 0, n, 1);
    assert!(band_fraction(&t, fs, 990.0, 1010.0) > 0.99);
    let w = signals::generate(&Signal::WhiteNoise, fs, n, 0, n, 1);
    let f = band_fraction(&w, fs, 0.0, 4000.0);
    assert!((f - 0.5).abs() < 0.03, "{f}");
}

#[test]
fn rt60_room_follows_sabine() {
    let room = Room::with_rt60([6.0, 5.0, 3.0], [-3.0, -2.0, -1.2], 0.4).unwrap();
    // V = 90 m³, S = 126 m²: α = 0.161·90/(126·0.4) = 0.2875, β = √(1 − α).
    assert!((room.reflection - (1.0f64 - 0.2875).sqrt()).abs() < 1e-4);
    // Images up to ≈ RT60/2 after the direct sound: ⌈0.2·343/4.667⌉ = 15.
    assert_eq!(room.max_order, 15);
    assert!(Room::with_rt60([2.0, 2.0, 2.0], [0.0; 3], 0.01).is_err());
    assert!(Room::with_rt60([2.0, 2.0, 2.0], [0.0; 3], -1.0).is_err());
}

#[test]
fn windowed_sinc_reflections_match_exact_delays_in_band() {
    // One path of fractional delay: its response's spectrum equals a·e^{−j2πkd/L} to
    // well under 1 % below 0.8·Nyquist, where the rendered bands live.
    let len = 4096;
    let (d, a) = (123.37, 0.8);
    let mut h = reflections_response(&[(d, a)], len);
    let mut planner = RealFftPlanner::<f64>::new();
    let fwd = planner.plan_fft_forward(len);
    let mut spec = fwd.make_output_vec();
    fwd.process(&mut h, &mut spec).unwrap();
    let mut worst = 0.0f64;
    for (k, v) in spec.iter().enumerate().take(len / 2 * 8 / 10) {
        let exact = Complex::from_polar(a, -2.0 * PI * k as f64 * d / len as f64);
        worst = worst.max((v - exact).norm() / a);
    }
    assert!(worst < 1e-2, "worst relative error {worst}");
}

#[test]
fn reverberant_room_renders_and_adds_a_tail() {
    // A high-order room takes the impulse-response path; the reflections add energy and
    // the direct sound still arrives first.
    let g = Geometry::circle(4, 0.05, 0.0);
    let room = Room::with_rt60([5.0, 4.0, 3.0], [-2.5, -2.0, -1.5], 0.3).unwrap();
    assert!(image_sources([1.0, 0.0, 0.0], Some(&room)).len() > EXACT_IMAGES_MAX + 1);
    let mut s =
        Scene::new().with_source(SceneSource::new([1.0, 0.0, 0.0], Signal::WhiteNoise).with_gain(100.0));
    let dry = render(&s, &g, 16000, 1.0, 3);
    s.room = Some(room);
    s.validate(&g, 16000).unwrap();
    let wet = render(&s, &g, 16000, 1.0, 3);
    let p = |a: &Audio| a.channels[0].iter().map(|v| (*v as f64).powi(2)).sum::<f64>();
    assert!(p(&wet) > 1.3 * p(&dry), "wet {} dry {}", p(&wet), p(&dry));
}
