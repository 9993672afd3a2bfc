//! Unit tests of the localizer facade.
use super::*;

/// With `resample`, a TF zip made at 16 kHz is read for the bins the analysis uses at
/// 16 kHz even when the input (and so the spec's analysis) is at 48 kHz; without it the
/// mismatch keeps every bin (so the plan can say why).
#[test]
fn resampling_reads_the_bins_of_the_files_own_rate() {
    let geo = crate::array::Geometry::circle(8, 0.0365, 0.0);
    let grid = crate::array::Grid::ring(30.0, 0.0, 1.0);
    let tf = crate::array::freefield::free_field(&geo, &grid, 512, 16000, 0..257, 343.0).unwrap();
    let dir = crate::audio::tests::temp_dir("resample-tf");
    let path = dir.join("tf16k.zip");
    crate::formats::hark_zip::write_tf_zip(&tf, &path).unwrap();
    let mut spec = LocalizerSpec::from_tf(&path);
    spec.tf_cache = TfCache::Off;
    let config = LocalizeConfig {
        sample_rate_hz: 48000,
        ..LocalizeConfig::default()
    };
    let at16 = LocalizeConfig {
        sample_rate_hz: 16000,
        ..config.clone()
    }
    .bin_range();
    assert_eq!(spec.load_array(&config).unwrap().bins(), 0..257);
    spec.resample = true;
    let got = spec.load_array(&config).unwrap();
    assert_eq!((got.bins(), got.sample_rate_hz), (at16.clone(), 16000));
    assert_eq!(at16, 16..89);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A tracker threshold above the highest power a normalised spectrum reaches (the room
/// default's NormMUSIC: 10·log10(73 + 1) = 18.7 dB with the default bins) is refused
/// with a message, not run to an empty output; below it, or with HARK's SEVD named, it
/// runs.
#[test]
fn a_threshold_no_normmusic_peak_can_reach_is_refused() {
    let geo = crate::array::Geometry::circle(8, 0.0365, 0.0);
    let mut spec = LocalizerSpec::free_field(
        geo.mics,
        GridSpec::Ring {
            step_deg: 5.0,
            elevation_deg: 0.0,
        },
    );
    spec.device = DeviceChoice::Cpu;
    let track = |thresh_db: f64| {
        Some(TrackingSpec {
            tracker: crate::tracking::TrackerConfig::with_thresh(thresh_db),
            preroll: 0,
            active_only: None,
        })
    };
    spec.tracking = track(25.0);
    let err = Localizer::new(&spec).err().expect("refused").to_string();
    assert!(err.contains("never exceeds 18.7 dB"), "{err}");
    assert!(err.contains("--algorithm sevd"), "{err}");
    spec.tracking = track(18.0);
    assert!(Localizer::new(&spec).is_ok());
    spec.tracking = track(25.0);
    spec.algorithm = Some(Algorithm::Sevd);
    assert!(Localizer::new(&spec).is_ok(), "HARK's scale has no ceiling");
}

/// Settings that would run without a word but do not do what they say: a grid inside
/// the array and a band past Nyquist get notes; a band of only DC and all-zero
/// manual weights are refused (the spectrum would be flat).
#[test]
fn settings_that_would_silently_do_nothing_are_noted_or_refused() {
    let geo = crate::array::Geometry::circle(8, 0.0365, 0.0);
    let ring = GridSpec::Ring {
        step_deg: 30.0,
        elevation_deg: 0.0,
    };
    let mut spec = LocalizerSpec::free_field(geo.mics.clone(), ring);
    spec.device = DeviceChoice::Cpu;
    let plain = Localizer::new(&spec).unwrap();
    assert!(plain.notes().iter().all(|n| !n.contains("inside the array")
        && !n.contains("Nyquist")
        && !n.contains("diagonal loading")
        && !n.contains("rank")));
    // Diagonal loading without a K, and a window shorter than the array.
    let mut odd = spec.clone();
    odd.analysis.diagonal_loading = 0.5;
    odd.analysis.window = 5;
    let notes = Localizer::new(&odd).unwrap().notes().join("\n");
    assert!(
        notes.contains("the diagonal loading (0.5) acts on the noise matrix K, and this run has none"),
        "{notes}"
    );
    assert!(
        notes.contains("warning: a window of 5 frames gives R of rank 5 at most, below the 8 microphones"),
        "{notes}"
    );
    if let ArraySpec::FreeField { radius_m, .. } = &mut spec.array {
        *radius_m = 0.01;
    }
    spec.analysis.upper_freq_hz = 12000.0;
    let l = Localizer::new(&spec).unwrap();
    let notes = l.notes().join("\n");
    assert!(
        notes.contains("grid radius 0.01 m is inside the array"),
        "{notes}"
    );
    assert!(
        notes.contains("upper edge 12000 Hz is above the Nyquist frequency (8000 Hz"),
        "{notes}"
    );
    // A frame past the largest FFT (32 ms of a mistyped rate) is refused before the
    // free-field TFs of its bins are built (it took 1.7 GB and 6.6 s at 4.3 GHz).
    let mut huge = LocalizerSpec::free_field(geo.mics.clone(), ring);
    huge.analysis.nfft = 1 << 27;
    huge.analysis.sample_rate_hz = 4_000_000_000;
    let e = Localizer::new(&huge).err().expect("too long a frame").to_string();
    assert!(
        e.contains("exceeds the largest supported FFT length, 65536"),
        "{e}"
    );
    // 1000..3000 Hz at N = 8: bins 0..1, DC only.
    let mut dc = LocalizerSpec::free_field(geo.mics.clone(), ring);
    dc.device = DeviceChoice::Cpu;
    dc.analysis.nfft = 8;
    dc.analysis.hop = 4;
    dc.analysis.lower_freq_hz = 1000.0;
    dc.analysis.upper_freq_hz = 3000.0;
    let e = Localizer::new(&dc).err().expect("DC only").to_string();
    assert!(e.contains("only bin 0 (0 Hz, which carries no direction)"), "{e}");
    let mut zero = LocalizerSpec::free_field(geo.mics.clone(), ring);
    zero.device = DeviceChoice::Cpu;
    let nb = zero.analysis.bin_range().len();
    zero.analysis.spectrum_weight = crate::config::SpectrumWeight::Manual(vec![0.0; nb]);
    let e = Localizer::new(&zero).err().expect("all zero").to_string();
    assert!(e.contains("manual spectrum weights are all zero"), "{e}");
    zero.analysis.spectrum_weight =
        crate::config::SpectrumWeight::Manual((0..nb).map(|i| (i % 2) as f64).collect());
    Localizer::new(&zero).unwrap();
}

/// Where the spectrum is kept, every output of a stream has a table, with zero rows
/// where no window ran (a short push, a flush with nothing left), so that the outputs
/// join as they are; without it none has one.
#[test]
fn every_output_of_a_stream_keeping_the_spectrum_has_a_table() {
    let geo = crate::array::Geometry::circle(8, 0.0365, 0.0);
    let mut spec = LocalizerSpec::free_field(
        geo.mics,
        GridSpec::Ring {
            step_deg: 5.0,
            elevation_deg: 0.0,
        },
    );
    spec.device = DeviceChoice::Cpu;
    spec.analysis.sample_rate_hz = 16000;
    let short: Vec<Vec<f32>> = (0..8)
        .map(|c| (0..100).map(|i| ((i * (c + 3)) % 17) as f32).collect())
        .collect();
    for keep in [true, false] {
        spec.spectrum = keep;
        let mut loc = Localizer::new(&spec).unwrap();
        let mut out = crate::engine::Output::default();
        loc.push(crate::input::Block::Planar(&short), &mut out).unwrap();
        assert!(out.results.is_empty());
        match &out.spectrum {
            Some(t) if keep => assert_eq!((t.frames.len(), t.db.len(), t.num_dirs), (0, 0, 72)),
            None if !keep => {}
            t => panic!("keep {keep}: {t:?}"),
        }
        let mut end = crate::engine::Output::default();
        let _ = loc.flush(&mut end); // too short for a window: an error, the table all the same
        assert_eq!(end.spectrum.is_some(), keep);
    }
}
