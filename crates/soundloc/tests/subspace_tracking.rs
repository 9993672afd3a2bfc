//! The approximate mode (`subspace_tracking`): a stream gives the same bits however its
//! input is cut, its spectra and peaks stay next to the exact path's on a drone scene,
//! and the combinations it cannot serve are clear errors.

use soundloc::backend::DeviceChoice;
mod common;
use common::stream;
use soundloc::config::Denominator;
use soundloc::demo::{ring8_drone, DemoScene};
use soundloc::{Algorithm, LocalizeConfig, Localizer, LocalizerSpec, NoiseSource, NoiseUpdate, WindowType};

/// The common ring spec with K from the first second.
fn spec_for(scene: &DemoScene, config: &LocalizeConfig) -> LocalizerSpec {
    let mut s = common::spec_for(scene, config);
    s.noise = NoiseSource::Range {
        start_s: 0.0,
        end_s: 1.0,
    };
    s
}

fn tracked(config: &LocalizeConfig) -> LocalizeConfig {
    LocalizeConfig {
        subspace_tracking: true,
        ..config.clone()
    }
}

#[test]
fn tracked_streams_equal_tracked_batch_bit_for_bit() {
    let scene = ring8_drone(-5.0, 11).unwrap();
    let audio = scene.render();
    let cases = [
        (Algorithm::Gevd, WindowType::Past, 1, NoiseUpdate::Fixed),
        (Algorithm::Gsvd, WindowType::Middle, 3, NoiseUpdate::Fixed),
        // 2·PERIOD ≥ W: the frames that left are not kept, and must not be looked for.
        (Algorithm::GevdHark, WindowType::Past, 30, NoiseUpdate::Fixed),
        (
            Algorithm::Gevd,
            WindowType::Past,
            2,
            NoiseUpdate::Segments(vec![(0.0, 0.8), (1.2, 1.5)]),
        ),
    ];
    for (i, (alg, wt, period, update)) in cases.into_iter().enumerate() {
        let config = tracked(&LocalizeConfig {
            algorithm: alg,
            window_type: wt,
            period,
            ..LocalizeConfig::default()
        });
        let mut spec = spec_for(&scene, &config);
        spec.noise_update = update.clone();
        let what = format!("{alg:?} {wt:?} period {period} {update:?}");
        let batch = Localizer::new(&spec).unwrap().localize(&audio.channels).unwrap();
        assert!(
            batch.results.len() >= 8,
            "{what}: {} results",
            batch.results.len()
        );
        // The mode really ran: its spectra are not the exact path's.
        let mut exact_spec = spec.clone();
        exact_spec.analysis.subspace_tracking = false;
        let exact = Localizer::new(&exact_spec)
            .unwrap()
            .localize(&audio.channels)
            .unwrap();
        assert!(
            exact.spectrum.as_ref().unwrap().db != batch.spectrum.as_ref().unwrap().db,
            "{what}: tracked spectra equal the exact ones"
        );
        assert!(
            batch.results.iter().all(|r| r.num_active.is_none()),
            "{what}: the approximate mode estimates no source count"
        );
        let mut loc = Localizer::new(&spec).unwrap();
        for (k, max_block) in [(0u64, 16000), (1, 37)] {
            let out = stream(&mut loc, &audio.channels, max_block, 10 * i as u64 + k);
            assert!(
                out.results == batch.results,
                "{what}, blocks ≤ {max_block}: results differ"
            );
            let (a, b) = (out.spectrum.as_ref().unwrap(), batch.spectrum.as_ref().unwrap());
            assert!(a.db == b.db, "{what}, blocks ≤ {max_block}: spectra differ");
            loc.reset().unwrap();
        }
    }
}

#[test]
fn tracked_spectra_and_peaks_stay_next_to_the_exact_ones() {
    let scene = ring8_drone(0.0, 5).unwrap();
    let audio = scene.render();
    for alg in [
        Algorithm::Gevd,
        Algorithm::Gsvd,
        Algorithm::GevdHark,
        Algorithm::Sevd,
    ] {
        let exact_cfg = LocalizeConfig {
            algorithm: alg,
            window_type: WindowType::Past,
            period: 1,
            ..LocalizeConfig::default()
        };
        let exact = Localizer::new(&spec_for(&scene, &exact_cfg))
            .unwrap()
            .localize(&audio.channels)
            .unwrap();
        let approx = Localizer::new(&spec_for(&scene, &tracked(&exact_cfg)))
            .unwrap()
            .localize(&audio.channels)
            .unwrap();
        assert_eq!(exact.results.len(), approx.results.len());
        let (se, sa) = (exact.spectrum.unwrap(), approx.spectrum.unwrap());
        let n = se.db.len() as f64;
        let rms = (se
            .db
            .iter()
            .zip(&sa.db)
            .map(|(a, b)| ((a - b) as f64).powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        // Exact vs tracked differ (the mode is approximate), but little.
        assert!(rms > 0.0 && rms < 0.01, "{alg:?}: spectra differ by {rms} dB RMS");
        let same = exact
            .results
            .iter()
            .zip(&approx.results)
            .filter(|(a, b)| {
                a.sources.first().map(|s| s.grid_index) == b.sources.first().map(|s| s.grid_index)
            })
            .count();
        let share = same as f64 / exact.results.len() as f64;
        assert!(
            share >= 0.98,
            "{alg:?}: same strongest peak in {share} of windows"
        );
    }
}

#[test]
fn what_the_mode_cannot_serve_is_a_clear_error() {
    let scene = ring8_drone(0.0, 5).unwrap();
    let base = tracked(&LocalizeConfig {
        algorithm: Algorithm::Gevd,
        period: 1,
        ..LocalizeConfig::default()
    });
    let err = |spec: &LocalizerSpec| {
        Localizer::new(spec)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default()
    };
    let srp = spec_for(
        &scene,
        &LocalizeConfig {
            algorithm: Algorithm::SrpPhat,
            ..base.clone()
        },
    );
    let mut srp = srp;
    srp.noise = NoiseSource::None;
    assert!(
        err(&srp).contains("subspace tracking needs a MUSIC algorithm"),
        "{}",
        err(&srp)
    );
    let unsq = spec_for(
        &scene,
        &LocalizeConfig {
            denominator: Denominator::Unsquared,
            ..base.clone()
        },
    );
    assert!(err(&unsq).contains("squared denominator"), "{}", err(&unsq));
    let mut cuda = spec_for(&scene, &base);
    cuda.device = DeviceChoice::Cuda;
    assert!(err(&cuda).contains("runs on the CPU only"), "{}", err(&cuda));
    // auto picks the CPU.
    let mut auto = spec_for(&scene, &base);
    auto.device = DeviceChoice::Auto;
    let loc = Localizer::new(&auto).unwrap();
    assert!(loc.device_name().starts_with("cpu"), "{}", loc.device_name());
}
