//! Coherence normalisation (`LocalizeConfig::coherence`, on in the room default): a
//! microphone's gain cancels, so an array whose channels are louder or quieter than its
//! transfer functions say gives the results of a matched one.

use soundloc::array::grid::GridSpec;
use soundloc::backend::DeviceChoice;
use soundloc::demo::{ring8_incoherent, DemoScene};
use soundloc::localizer::{Localizer, LocalizerSpec};
use soundloc::{LocalizationResult, Precision};

fn ring_spec(sc: &DemoScene) -> LocalizerSpec {
    let mut spec = LocalizerSpec::free_field(
        sc.geometry.mics.clone(),
        GridSpec::Ring {
            step_deg: 5.0,
            elevation_deg: 0.0,
        },
    );
    spec.analysis.period = 25;
    spec.device = DeviceChoice::Cpu;
    spec
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
    let gains = [1.0f32, 2.0, 0.5, 1.0, 4.0, 1.0, 0.25, 2.0];
    let scaled: Vec<Vec<f32>> = audio
        .channels
        .iter()
        .zip(gains)
        .map(|(ch, g)| ch.iter().map(|x| x * g).collect())
        .collect();
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
