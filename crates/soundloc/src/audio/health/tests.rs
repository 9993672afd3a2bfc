use super::*;
use crate::real::C;
use std::f64::consts::PI;

const FS: f64 = 16000.0;
const SOUND: f64 = 343.0;

/// An 8-microphone circle of radius `r` in the xy plane.
fn ring(r: f64) -> Vec<[f64; 3]> {
    (0..8)
        .map(|i| {
            let a = 2.0 * PI * i as f64 / 8.0;
            [r * a.cos(), r * a.sin(), 0.0]
        })
        .collect()
}

/// Far-field steering vectors at `f` Hz for `dirs` azimuths in the xy plane, `[dir][mic]`.
fn steering(mics: &[[f64; 3]], f: f64, dirs: usize) -> Vec<C<f64>> {
    let mut out = Vec::new();
    for d in 0..dirs {
        let az = 2.0 * PI * d as f64 / dirs as f64;
        let u = [az.cos(), az.sin(), 0.0];
        for p in mics {
            let tau = -(u[0] * p[0] + u[1] * p[1] + u[2] * p[2]) / SOUND;
            let ph = -2.0 * PI * f * tau;
            out.push(C::new(ph.cos(), ph.sin()));
        }
    }
    out
}

/// Uniform numbers in [0, 1) from a linear congruential generator seeded with `seed`.
fn uniform(seed: u64) -> impl FnMut() -> f64 {
    let step = |x: u64| {
        x.wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407)
    };
    let mut rng = step(seed);
    move || {
        rng = step(rng);
        (rng >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// `secs` of a plane-wave field at the microphones: `waves` sources from random
/// azimuths, each a sum of sinusoids 60–3000 Hz, plus white sensor noise of `noise` RMS.
fn field(mics: &[[f64; 3]], waves: usize, secs: f64, noise: f64, seed: u64) -> Vec<Vec<f32>> {
    let mut next = uniform(seed);
    let n = (secs * FS) as usize;
    let mut out = vec![vec![0.0f32; n]; mics.len()];
    for _ in 0..waves {
        let az = 2.0 * PI * next();
        let u = [az.cos(), az.sin(), 0.0];
        let tones: Vec<(f64, f64, f64)> = (0..40)
            .map(|_| (60.0 + 2940.0 * next(), 2.0 * PI * next(), 300.0 * (0.3 + next())))
            .collect();
        for (m, p) in mics.iter().enumerate() {
            let tau = -(u[0] * p[0] + u[1] * p[1] + u[2] * p[2]) / SOUND;
            for (t, v) in out[m].iter_mut().enumerate() {
                let time = t as f64 / FS - tau;
                *v += tones
                    .iter()
                    .map(|&(f, ph, a)| a * (2.0 * PI * f * time + ph).sin())
                    .sum::<f64>() as f32;
            }
        }
    }
    for ch in &mut out {
        for v in ch.iter_mut() {
            // Uniform noise of RMS `noise`.
            *v += (noise * 12f64.sqrt() * (next() - 0.5)) as f32;
        }
    }
    out
}

/// The checks over `chans` pushed `push` samples at a time (no polarity test).
fn check(chans: &[Vec<f32>], push: usize) -> Vec<String> {
    let mut h = ChannelHealth::new((0..chans.len()).collect(), FS, 160, None);
    let n = chans[0].len();
    let mut notes = Vec::new();
    let mut at = 0;
    while at < n {
        let e = (at + push).min(n);
        let part: Vec<&[f32]> = chans.iter().map(|c| &c[at..e]).collect();
        h.observe(&part);
        notes.extend(h.notes(false));
        at = e;
    }
    notes.extend(h.notes(true));
    notes
}

/// Used bins of the tests' frames: 16.. at 31.25 Hz (N = 512 at 16 kHz), 500 Hz up.
const BIN0: usize = 16;
const BIN_HZ: f64 = FS / 512.0;
const NUM_BINS: usize = 73;

/// `frames` STFT frames `[frame][bin][mic]` of `waves` plane waves from random
/// azimuths (complex Gaussian spectra, the array's delays as phases) plus sensor noise
/// of `noise` relative power, with `flip` microphones' signs inverted.
fn frames(
    mics: &[[f64; 3]],
    waves: usize,
    frames: usize,
    noise: f64,
    flip: &[usize],
    seed: u64,
) -> Vec<C<f32>> {
    let mut next = uniform(seed);
    let mut gauss = move || {
        let (u, v) = (next().max(1e-300), next());
        (-2.0 * u.ln()).sqrt() * (2.0 * PI * v).cos()
    };
    let m = mics.len();
    let dirs: Vec<[f64; 3]> = (0..waves)
        .map(|k| {
            let az = 2.0 * PI * (k as f64 + 0.37) / waves.max(1) as f64;
            [az.cos(), az.sin(), 0.0]
        })
        .collect();
    let mut out = Vec::with_capacity(frames * NUM_BINS * m);
    for _ in 0..frames {
        for b in 0..NUM_BINS {
            let f = (BIN0 + b) as f64 * BIN_HZ;
            let mut x = vec![C::new(0.0f64, 0.0); m];
            for u in &dirs {
                let s = C::new(gauss(), gauss());
                for (xm, p) in x.iter_mut().zip(mics) {
                    let tau = -(u[0] * p[0] + u[1] * p[1] + u[2] * p[2]) / SOUND;
                    let ph = -2.0 * PI * f * tau;
                    *xm += s * C::new(ph.cos(), ph.sin());
                }
            }
            for (k, xm) in x.iter().enumerate() {
                let n = C::new(gauss(), gauss()) * noise.sqrt();
                let v = if flip.contains(&k) { -(*xm + n) } else { *xm + n };
                out.push(C::new(v.re as f32, v.im as f32));
            }
        }
    }
    out
}

/// The polarity test over `x` given `push` frames at a time; the notes at the end.
fn polarity(x: &[C<f32>], pairs: Option<ClosePairs>, push: usize) -> Vec<String> {
    let mut h = ChannelHealth::new((0..8).collect(), FS, 160, pairs);
    h.observe(&[&[0.25f32, -0.5][..]; 8]);
    let mut notes = Vec::new();
    for part in x.chunks(push * NUM_BINS * 8) {
        h.observe_frames(part, NUM_BINS);
        notes.extend(h.notes(false));
    }
    notes.extend(h.notes(true));
    notes
}

fn ring_pairs(r: f64) -> Option<ClosePairs> {
    let mics = ring(r);
    close_pairs(&steering(&mics, 500.0, 72), 8, 0, NUM_BINS, 500.0, BIN_HZ)
}

#[test]
fn a_ring_pairs_its_neighbours_in_bins_where_their_phases_stay_below_a_quarter_turn() {
    let p = ring_pairs(0.05).unwrap();
    // Adjacent microphones 2r·sin(π/8) = 3.83 cm apart (0.35 rad at 500 Hz), next but one
    // 7.07 cm (0.65 rad ≤ 2·0.35): 16 pairs; the third, 9.24 cm, is past twice the nearest.
    assert_eq!(p.pairs.len(), 16, "{:?}", p.pairs);
    assert!(p.pairs.contains(&(0, 1)) && p.pairs.contains(&(0, 7)) && p.pairs.contains(&(0, 2)));
    assert!(!p.pairs.contains(&(0, 3)) && !p.pairs.contains(&(0, 4)));
    // π/2 at 500 Hz · (π/2) / 0.65 = 1213 Hz: more than 16 bins, so 16 (500–969 Hz).
    assert_eq!((p.first, p.bins), (0, 16));
    assert!((p.band_hz.1 - (500.0 + 15.0 * BIN_HZ)).abs() < 1e-9);
    // A 20 cm ring: adjacent 15.3 cm (1.40 rad at 500 Hz) is past π/3: no pairs.
    assert!(ring_pairs(0.2).is_none());
    // A 12 cm ring: adjacent 9.2 cm (0.84 rad), next but one past π/3: 8 pairs, and the
    // bins up to 500 · (π/2)/0.84 = 933 Hz.
    let p = ring_pairs(0.12).unwrap();
    assert_eq!(p.pairs.len(), 8, "{:?}", p.pairs);
    assert_eq!(p.bins, 14, "{p:?}");
    // Identical steering (no delays) gives nothing.
    let flat = vec![C::new(1.0f64, 0.0); 72 * 8];
    assert!(close_pairs(&flat, 8, 0, NUM_BINS, 500.0, BIN_HZ).is_none());
}

#[test]
fn a_polarity_inverted_channel_is_named_and_a_clean_field_gives_no_note() {
    let mics = ring(0.05);
    let pairs = ring_pairs(0.05);
    // 3 s of frames (hop 160 at 16 kHz: 100 per second), three waves, sensor noise 10 dB down.
    let n = 300;
    let clean = polarity(&frames(&mics, 3, n, 0.1, &[], 1), pairs.clone(), 7);
    assert!(clean.is_empty(), "{clean:?}");
    let notes = polarity(&frames(&mics, 3, n, 0.1, &[3], 1), pairs.clone(), 7);
    assert_eq!(notes.len(), 1, "{notes:?}");
    assert!(
        notes[0].contains("input channel 3 (0-based) looks polarity-inverted: at 500-969 Hz"),
        "{notes:?}"
    );
    // Two flipped channels, given in one push; the note names each once.
    let notes = polarity(&frames(&mics, 3, n, 0.1, &[3, 6], 2), pairs.clone(), n);
    assert_eq!(notes.len(), 2, "{notes:?}");
    assert!(notes[0].contains("channel 3 ") && notes[1].contains("channel 6 "));
    // Half the array flipped: nothing tells which half is right.
    assert!(polarity(&frames(&mics, 3, n, 0.1, &[0, 1, 2, 3], 3), pairs.clone(), 7).is_empty());
    // Sensor noise alone (no field) says nothing; nor does under a second of frames.
    assert!(polarity(&frames(&mics, 0, n, 1.0, &[3], 4), pairs.clone(), 7).is_empty());
    assert!(polarity(&frames(&mics, 3, 90, 0.1, &[3], 5), pairs, 7).is_empty());
}

#[test]
fn a_dead_or_constant_channel_is_named() {
    let mics = ring(0.05);
    let mut x = field(&mics, 2, 2.0, 10.0, 3);
    for v in &mut x[5] {
        *v *= 1e-3;
    }
    let notes = check(&x, 4000);
    assert_eq!(notes.len(), 1, "{notes:?}");
    assert!(notes[0].contains("input channel 5 (0-based) is 6"), "{notes:?}");
    assert!(notes[0].contains("dB below the median channel"));
    for v in &mut x[5] {
        *v = 7.0;
    }
    let notes = check(&x, 4000);
    assert_eq!(notes.len(), 1, "{notes:?}");
    assert!(
        notes[0].contains("input channel 5 (0-based) is constant"),
        "{notes:?}"
    );
    // The channel names follow the input map.
    let mut h = ChannelHealth::new((10..18).collect(), FS, 160, None);
    h.observe(&x.iter().map(Vec::as_slice).collect::<Vec<_>>());
    let n = h.notes(true);
    assert!(n[0].contains("input channel 15 "), "{n:?}");
    // All channels zero: one note about the input.
    let zero = vec![vec![0.0f32; 1000]; 8];
    let n = check(&zero, 300);
    assert_eq!(n.len(), 1);
    assert!(n[0].contains("the input is silent"));
}

#[test]
fn clipping_at_full_scale_is_named_and_loud_unclipped_audio_is_not() {
    let mics = ring(0.05);
    let x = field(&mics, 2, 2.0, 10.0, 4);
    let peak = x.iter().flatten().fold(0.0f32, |a, &b| a.max(b.abs()));
    // Scaled to peak at 30 000 (int16 units), rounded: no clipping.
    let scaled: Vec<Vec<f32>> = x
        .iter()
        .map(|c| c.iter().map(|&v| (v * 30000.0 / peak).round()).collect())
        .collect();
    assert!(check(&scaled, 1600).is_empty());
    // Three times louder into an int16 converter: flat tops at −32768 and 32767.
    let clipped: Vec<Vec<f32>> = scaled
        .iter()
        .map(|c| c.iter().map(|&v| (3.0 * v).clamp(-32768.0, 32767.0)).collect())
        .collect();
    let notes = check(&clipped, 1600);
    assert_eq!(notes.len(), 1, "{notes:?}");
    assert!(
        notes[0].contains("input channels 0, 1, 2, 3, 4, 5, 6, 7 (0-based) clip")
            && notes[0].contains("(±32767)"),
        "{notes:?}"
    );
    // Float audio clipped at ±1.0 likewise; at ±0.9 (not a full scale) nothing.
    let f: Vec<Vec<f32>> = x
        .iter()
        .map(|c| c.iter().map(|&v| (2.0 * v / peak).clamp(-1.0, 1.0)).collect())
        .collect();
    assert_eq!(check(&f, 1600).len(), 1);
    let g: Vec<Vec<f32>> = x
        .iter()
        .map(|c| c.iter().map(|&v| (2.0 * v / peak).clamp(-0.9, 0.9)).collect())
        .collect();
    assert!(check(&g, 1600).is_empty());
}

#[test]
fn a_channel_that_starts_late_is_not_called_dead_while_the_stream_runs() {
    // Channel 3 gives zeros for its first 2 s, then the field: pushed 0.1 s at a time, no
    // note before DECIDE_SECONDS, and none at the end (it varied and is as loud as the rest
    // over the stream, within DEAD_DB).
    let mics = ring(0.05);
    let mut x = field(&mics, 2, 12.0, 10.0, 6);
    for v in &mut x[3][..(2.0 * FS) as usize] {
        *v = 0.0;
    }
    let mut h = ChannelHealth::new((0..8).collect(), FS, 160, None);
    let mut early = Vec::new();
    for at in (0..x[0].len()).step_by(1600) {
        let part: Vec<&[f32]> = x.iter().map(|c| &c[at..(at + 1600).min(c.len())]).collect();
        h.observe(&part);
        early.extend(h.notes(false));
    }
    assert!(early.is_empty() && h.notes(true).is_empty(), "{early:?}");
    // A channel dead for the whole stream is named once DECIDE_SECONDS are in.
    let mut h = ChannelHealth::new((0..8).collect(), FS, 160, None);
    let mut when = None;
    for (k, at) in (0..x[0].len()).step_by(1600).enumerate() {
        let part: Vec<Vec<f32>> = x
            .iter()
            .enumerate()
            .map(|(c, v)| {
                let s = &v[at..(at + 1600).min(v.len())];
                if c == 5 {
                    vec![0.0; s.len()]
                } else {
                    s.to_vec()
                }
            })
            .collect();
        h.observe(&part.iter().map(Vec::as_slice).collect::<Vec<_>>());
        if !h.notes(false).is_empty() && when.is_none() {
            when = Some(k);
        }
    }
    assert_eq!(when, Some(99), "the note came at push {when:?}");
}

#[test]
fn a_nearly_silent_integer_input_gets_one_note_and_no_dead_microphones() {
    let mics = ring(0.05);
    let x = field(&mics, 2, 2.0, 10.0, 5);
    let rms = |c: &[f32]| (c.iter().map(|&v| (v as f64).powi(2)).sum::<f64>() / c.len() as f64).sqrt();
    let level = rms(&x[0]);
    // Integer samples (a 16-bit file): channel 3 at a quarter of the others' level.
    let quantise = |to: f64| -> Vec<Vec<f32>> {
        x.iter()
            .enumerate()
            .map(|(c, ch)| {
                let g = to / level * if c == 3 { 0.25 } else { 1.0 };
                ch.iter().map(|&v| (v as f64 * g).round() as f32).collect()
            })
            .collect()
    };
    // Median RMS about 0.7 of a step: channel 3 is mostly zeros.
    let quiet = quantise(0.7);
    let r3 = rms(&quiet[3]);
    let r0 = rms(&quiet[0]);
    assert!(r3 < r0 * 10f64.powf(-DEAD_DB / 20.0) || r3 < 0.2, "{r3} {r0}");
    let notes = check(&quiet, 4000);
    assert_eq!(notes.len(), 1, "{notes:?}");
    assert!(notes[0].contains("the input is nearly silent"), "{notes:?}");
    assert!(!notes[0].contains("dead"), "{notes:?}");
    // The same scene at a usable level: no note; a channel of zeros in it is named.
    let mut loud = quantise(300.0);
    assert_eq!(check(&loud, 4000), Vec::<String>::new());
    loud[6].iter_mut().for_each(|v| *v = 0.0);
    let notes = check(&loud, 4000);
    assert_eq!(notes.len(), 1, "{notes:?}");
    assert!(
        notes[0].contains("input channel 6 (0-based) is constant"),
        "{notes:?}"
    );
    // Float samples as quiet are not rounding: the quiet channel is named as before.
    let float: Vec<Vec<f32>> = x
        .iter()
        .enumerate()
        .map(|(c, ch)| {
            ch.iter()
                .map(|&v| v / level as f32 * if c == 3 { 1e-3 } else { 0.7 })
                .collect()
        })
        .collect();
    let notes = check(&float, 4000);
    assert_eq!(notes.len(), 1, "{notes:?}");
    assert!(notes[0].contains("input channel 3 (0-based) is"), "{notes:?}");
}

/// Float audio (±1 full scale) that starts with seconds of digital silence is not taken
/// for integer samples: no "nearly silent" note, and clipping at ±1.0 is still named.
#[test]
fn float_audio_after_digital_silence_is_still_float() {
    let mics = ring(0.05);
    let mut x = field(&mics, 2, 8.0, 10.0, 7);
    let peak = x.iter().flatten().fold(0.0f32, |a, &v| a.max(v.abs()));
    let start = 5 * FS as usize;
    for ch in &mut x {
        for (t, v) in ch.iter_mut().enumerate() {
            *v = if t < start { 0.0 } else { *v / peak * 0.3 };
        }
    }
    assert_eq!(check(&x, 4000), Vec::<String>::new());
    for v in &mut x[2] {
        *v = (*v * 20.0).clamp(-1.0, 1.0);
    }
    let notes = check(&x, 4000);
    assert_eq!(notes.len(), 1, "{notes:?}");
    assert!(notes[0].contains("input channel 2 (0-based) clip"), "{notes:?}");
}
