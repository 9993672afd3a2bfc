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

/// `secs` of a plane-wave field at the microphones: `waves` sources from random
/// azimuths, each a sum of sinusoids 60–3000 Hz, plus white sensor noise of `noise` RMS.
fn field(mics: &[[f64; 3]], waves: usize, secs: f64, noise: f64, seed: u64) -> Vec<Vec<f32>> {
    let mut rng = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    let mut next = move || {
        rng = rng
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (rng >> 11) as f64 / (1u64 << 53) as f64
    };
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

fn check(chans: &[Vec<f32>], pairs: Option<ClosePairsT>, push: usize) -> Vec<String> {
    let mut h = ChannelHealth::new((0..chans.len()).collect(), FS, pairs);
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

type ClosePairsT = (Vec<(usize, usize)>, f64);

fn ring_pairs(r: f64) -> Option<ClosePairsT> {
    let mics = ring(r);
    close_pairs(&steering(&mics, 500.0, 72), 8, 500.0, FS)
}

#[test]
fn a_ring_pairs_its_neighbours_below_a_band_edge_from_their_spacing() {
    let (pairs, fc) = ring_pairs(0.05).unwrap();
    // Adjacent microphones 2r·sin(π/8) = 3.83 cm apart (τ 112 µs), next but one 7.07 cm
    // (206 µs ≤ 2τ_c): 16 pairs, f_c = 1/(16·112 µs).
    assert_eq!(pairs.len(), 16, "{pairs:?}");
    assert!(pairs.contains(&(0, 1)) && pairs.contains(&(0, 7)) && pairs.contains(&(0, 2)));
    assert!(!pairs.contains(&(0, 3)) && !pairs.contains(&(0, 4)));
    let tc = 2.0 * 0.05 * (PI / 8.0).sin() / SOUND;
    assert!((fc - 1.0 / (16.0 * tc)).abs() < 5.0, "{fc}");
    // Identical steering (no delays) and an array too wide for the band give nothing.
    let flat = vec![C::new(1.0f64, 0.0); 72 * 8];
    assert!(close_pairs(&flat, 8, 500.0, FS).is_none());
    let wide = ring(1.0);
    assert!(close_pairs(&steering(&wide, 500.0, 72), 8, 500.0, FS).is_none());
}

#[test]
fn a_polarity_inverted_channel_is_named_and_a_clean_field_gives_no_note() {
    let mics = ring(0.05);
    let pairs = ring_pairs(0.05);
    let clean = field(&mics, 3, 4.0, 30.0, 1);
    let notes = check(&clean, pairs.clone(), 1600);
    assert!(notes.is_empty(), "{notes:?}");
    let mut flipped = clean.clone();
    for v in &mut flipped[3] {
        *v = -*v;
    }
    let notes = check(&flipped, pairs.clone(), 1600);
    assert_eq!(notes.len(), 1, "{notes:?}");
    assert!(
        notes[0].contains("input channel 3 (0-based) looks polarity-inverted"),
        "{notes:?}"
    );
    // Two flipped channels, given in one push; the note names each once.
    for v in &mut flipped[6] {
        *v = -*v;
    }
    let notes = check(&flipped, pairs.clone(), usize::MAX);
    assert_eq!(notes.len(), 2, "{notes:?}");
    assert!(notes[0].contains("channel 3 ") && notes[1].contains("channel 6 "));
    // Sensor noise alone (no field in the band) says nothing.
    let quiet = field(&mics, 0, 4.0, 30.0, 2);
    let mut q = quiet.clone();
    for v in &mut q[3] {
        *v = -*v;
    }
    assert!(check(&q, pairs, 1600).is_empty());
}

#[test]
fn a_dead_or_constant_channel_is_named() {
    let mics = ring(0.05);
    let mut x = field(&mics, 2, 2.0, 10.0, 3);
    for v in &mut x[5] {
        *v *= 1e-3;
    }
    let notes = check(&x, ring_pairs(0.05), 4000);
    assert_eq!(notes.len(), 1, "{notes:?}");
    assert!(notes[0].contains("input channel 5 (0-based) is 6"), "{notes:?}");
    assert!(notes[0].contains("dB below the median channel"));
    for v in &mut x[5] {
        *v = 7.0;
    }
    let notes = check(&x, None, 4000);
    assert_eq!(notes.len(), 1, "{notes:?}");
    assert!(
        notes[0].contains("input channel 5 (0-based) is constant"),
        "{notes:?}"
    );
    // The channel names follow the input map.
    let mut h = ChannelHealth::new((10..18).collect(), FS, None);
    h.observe(&x.iter().map(Vec::as_slice).collect::<Vec<_>>());
    let n = h.notes(true);
    assert!(n[0].contains("input channel 15 "), "{n:?}");
    // All channels zero: one note about the input.
    let zero = vec![vec![0.0f32; 1000]; 8];
    let n = check(&zero, None, 300);
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
    assert!(check(&scaled, None, 1600).is_empty());
    // Three times louder into an int16 converter: flat tops at −32768 and 32767.
    let clipped: Vec<Vec<f32>> = scaled
        .iter()
        .map(|c| c.iter().map(|&v| (3.0 * v).clamp(-32768.0, 32767.0)).collect())
        .collect();
    let notes = check(&clipped, None, 1600);
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
    assert_eq!(check(&f, None, 1600).len(), 1);
    let g: Vec<Vec<f32>> = x
        .iter()
        .map(|c| c.iter().map(|&v| (2.0 * v / peak).clamp(-0.9, 0.9)).collect())
        .collect();
    assert!(check(&g, None, 1600).is_empty());
}
