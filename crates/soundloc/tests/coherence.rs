//! Coherence normalisation (`LocalizeConfig::coherence`, on in the room default): a
//! microphone's gain cancels, so an array whose channels are louder or quieter than its
//! transfer functions say gives the results of a matched one.

mod ring;

use ring::{drone_spec, ring_spec, two_talker_drone};
use soundloc::demo::ring8_incoherent;
use soundloc::localizer::{Localizer, LocalizerSpec};
use soundloc::{LocalizationResult, Precision};

/// `channels` with channel m multiplied by `gains[m]`.
fn with_gains(channels: &[Vec<f32>], gains: &[f32]) -> Vec<Vec<f32>> {
    channels
        .iter()
        .zip(gains)
        .map(|(ch, g)| ch.iter().map(|x| x * g).collect())
        .collect()
}

fn run(spec: &LocalizerSpec, channels: &[Vec<f32>]) -> Vec<LocalizationResult> {
    Localizer::new(spec).unwrap().localize(channels).unwrap().results
}

/// The largest difference between two runs' peaks: (degrees of azimuth, dB), and whether
/// they have the same number of results and peaks.
fn difference(a: &[LocalizationResult], b: &[LocalizationResult]) -> (bool, f64, f64) {
    let mut same = a.len() == b.len();
    let (mut deg, mut db) = (0.0f64, 0.0f64);
    for (x, y) in a.iter().zip(b) {
        same &= x.sources.len() == y.sources.len();
        for (s, t) in x.sources.iter().zip(&y.sources) {
            deg = deg.max((s.azimuth_deg - t.azimuth_deg).abs());
            db = db.max((s.power_db - t.power_db).abs());
        }
    }
    (same, deg, db)
}

/// Channels scaled by 2, ½, 4, ¼ (6–12 dB, far beyond any real mismatch): with coherence
/// normalisation the room default's results are those of the unscaled recording, to f64
/// rounding; without it they change.
#[test]
fn a_channel_gain_cancels_with_coherence() {
    let sc = ring8_incoherent(&[30.0, -120.0], 15.0, 5).unwrap();
    let audio = sc.render();
    let scaled = with_gains(&audio.channels, &[1.0f32, 2.0, 0.5, 1.0, 4.0, 1.0, 0.25, 2.0]);
    let mut spec = ring_spec(&sc);
    spec.precision = Precision::F64;
    let room = Localizer::new(&spec).unwrap();
    assert!(room.config().coherence, "the room default normalises");
    let (a, b) = (run(&spec, &audio.channels), run(&spec, &scaled));
    assert!(!a.is_empty());
    let (same, deg, db) = difference(&a, &b);
    assert!(
        same && deg < 1e-6 && db < 1e-7,
        "with coherence: {deg}° / {db} dB apart"
    );
    // The same analysis without it sees the gains.
    spec.coherence = Some(false);
    let (a, b) = (run(&spec, &audio.channels), run(&spec, &scaled));
    let (same, deg, db) = difference(&a, &b);
    assert!(
        !same || deg > 1.0 || db > 0.1,
        "without coherence: {deg}° / {db} dB apart"
    );
}

/// The textbook GEVD with coherence takes the gains from K: on a drone scene (four rotors
/// 25 cm away, K from the first second) whose channels are 1–2 dB off, it finds what it
/// finds on the matched array, and the GEVD without it does not. (Exact invariance is not
/// expected here: HARK's scaling of R adds 1 to its divisor.)
#[test]
fn the_gevd_takes_the_gains_from_k() {
    use soundloc::Algorithm;
    let sc = two_talker_drone(0.0, GEVD_SEED);
    let audio = sc.render();
    let scaled = with_gains(
        &audio.channels,
        &[1.0f32, 1.26, 0.79, 1.0, 1.12, 0.89, 1.26, 0.84],
    );
    let mut spec = drone_spec(&sc);
    spec.algorithm = Some(Algorithm::Gevd);
    spec.analysis.subspace_dim = Some(4);
    let hits = |spec: &LocalizerSpec, ch: &[Vec<f32>]| sc.score(&run(spec, ch), 5.0);
    let matched = hits(&spec, &audio.channels);
    let off = hits(&spec, &scaled);
    spec.coherence = Some(true);
    let with = hits(&spec, &scaled);
    let windows = with.windows;
    let all = |h: &[usize]| h.iter().all(|&n| 4 * n >= 3 * windows);
    assert!(
        all(&matched.per_talker_hits),
        "matched array: {:?} of {windows}",
        matched.per_talker_hits
    );
    assert!(
        all(&with.per_talker_hits),
        "with coherence: {:?} of {windows}",
        with.per_talker_hits
    );
    assert!(
        off.per_talker_hits.iter().any(|&n| 2 * n <= windows),
        "without coherence: {:?} of {windows}",
        off.per_talker_hits
    );
}

/// An anechoic drone scene of the study's (`soundloc::bench::accuracy::scene`). Over seeds
/// 1–8 of this condition and these gains the GEVD without coherence found a talker in at
/// most 3 of 6 windows (mostly none), with it in at least 4; here 0 against 6 of 6.
const GEVD_SEED: u64 = 5;

/// The robust default says when the channels' levels depart from the transfer functions'
/// (it loses talkers at 1–3 dB of gain mismatch, docs/accuracy.md): far talkers in
/// sensor noise, K from the noise-only first second. Matched channels: no warning;
/// channels ±2 dB: a warning naming them; with coherence (gains cancel): none. Until
/// 2026-12-02 nothing was said (a user sweep's room lost a talker at ±3 dB, silently).
#[test]
fn the_robust_default_warns_of_channel_gains_its_transfer_functions_lack() {
    let sc = ring8_incoherent(&[30.0, -120.0], 10.0, 3).unwrap();
    let audio = sc.render();
    let gains: Vec<f32> = (0..8).map(|m| if m % 2 == 0 { 1.26 } else { 0.79 }).collect();
    let scaled = with_gains(&audio.channels, &gains);
    let mut spec = drone_spec(&sc);
    let notes = |spec: &LocalizerSpec, ch: &[Vec<f32>]| -> Vec<String> {
        let out = Localizer::new(spec).unwrap().localize(ch).unwrap();
        out.notes
            .into_iter()
            .filter(|n| n.contains("what the transfer functions expect"))
            .collect()
    };
    assert_eq!(notes(&spec, &audio.channels), Vec::<String>::new());
    let warned = notes(&spec, &scaled);
    assert_eq!(warned.len(), 1, "{warned:?}");
    assert!(
        warned[0].starts_with("warning: input channel levels differ") && warned[0].contains("--coherence"),
        "{warned:?}"
    );
    // "excess): 0 +2.1 dB, 1 -1.9 dB, …": every channel, ±2 dB by the parity of its index.
    let list = warned[0]
        .split("excess): ")
        .nth(1)
        .unwrap()
        .split(". ")
        .next()
        .unwrap();
    let excess: Vec<(usize, f64)> = list
        .split(", ")
        .map(|e| {
            let v: Vec<&str> = e.split(' ').collect();
            (v[0].parse().unwrap(), v[1].parse().unwrap())
        })
        .collect();
    assert_eq!(excess.len(), 8, "{list}");
    for (m, g) in excess {
        let want = if m % 2 == 0 { 2.0 } else { -2.0 };
        assert!((g - want).abs() < 0.3, "channel {m}: {g} dB ({list})");
    }
    spec.coherence = Some(true);
    assert_eq!(notes(&spec, &scaled), Vec::<String>::new());
}
