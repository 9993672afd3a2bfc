use super::*;
use num_complex::Complex;

fn config(algorithm: crate::Algorithm) -> LocalizeConfig {
    LocalizeConfig {
        algorithm,
        nfft: 64,
        sample_rate_hz: 16000,
        num_sources: 1,
        max_peaks: 1,
        lower_freq_hz: 1000.0,
        upper_freq_hz: 6000.0,
        ..Default::default()
    }
}

/// A plane wave from azimuth 60° on a 6-mic circle (far field, ring grid), S frames of
/// F bins laid out M × F × S, with a little noise.
fn plane_wave(s: usize) -> (Geometry, Vec<Complex<f64>>, [usize; 3]) {
    let geo = Geometry::circle(6, 0.05, 0.0);
    let (m, f) = (6, 33);
    let az = 60f64.to_radians();
    let dir = [az.cos(), az.sin(), 0.0];
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    let mut rnd = || rng.gen_range(-0.5..0.5);
    let mut x = vec![Complex::new(0.0, 0.0); m * f * s];
    let src: Vec<Complex<f64>> = (0..f * s).map(|_| Complex::new(rnd(), rnd())).collect();
    for (i, p) in geo.mics.iter().enumerate() {
        let delay_s = (p[0] * dir[0] + p[1] * dir[1]) / 343.0;
        for k in 0..f {
            let w = 2.0 * std::f64::consts::PI * k as f64 * 16000.0 / 64.0;
            let steer = Complex::from_polar(1.0, w * delay_s);
            for t in 0..s {
                x[(i * f + k) * s + t] = src[k * s + t] * steer + Complex::new(0.01 * rnd(), 0.01 * rnd());
            }
        }
    }
    (geo, x, [m, f, s])
}

/// A slice of a larger array (numpy's `X[:, :, a:b]`), read in place through its
/// strides, gives the bits of the same frames copied out contiguously; the source is
/// found; a non-finite value outside the used bins is not read, inside them it is
/// named.
#[test]
fn strided_view_equals_the_contiguous_copy() {
    let (geo, x, [m, f, s]) = plane_wave(40);
    let (a, b) = (7, 27);
    let copy: Vec<Complex<f64>> = (0..m * f)
        .flat_map(|row| x[row * s + a..row * s + b].iter().copied())
        .collect();
    for alg in [crate::Algorithm::Sevd, crate::Algorithm::SrpPhat] {
        let mut fl = FramesLocalizer::new(
            geo.clone(),
            Grid::ring(5.0, 0.0, 1e4),
            343.0,
            DeviceChoice::Cpu,
            Precision::F64,
        );
        let c = config(alg);
        let strided = FramesView::new(&x[a..], [m, f, b - a], [f * s, s, 1]).unwrap();
        let got = fl.process(&c, &strided).unwrap();
        let want = fl
            .process(&c, &FramesView::contiguous(&copy, [m, f, b - a]).unwrap())
            .unwrap();
        assert_eq!(got, want, "{alg:?}");
        // The microphones closest together in memory (an (S, F, M) array): read in
        // the other order, the same bits; a bad value is named the same way.
        let (n, mut t) = (b - a, vec![Complex::new(0.0, 0.0); m * f * (b - a)]);
        for (i, v) in copy.iter().enumerate() {
            let (mic, k, snap) = (i / (f * n), i / n % f, i % n);
            t[(snap * f + k) * m + mic] = *v;
        }
        let view = FramesView::new(&t, [m, f, n], [1, m, f * m]).unwrap();
        assert_eq!(fl.process(&c, &view).unwrap(), want, "{alg:?} (S, F, M)");
        t[(4 * f + 11) * m + 5] = Complex::new(f64::NAN, 1.0);
        let view = FramesView::new(&t, [m, f, n], [1, m, f * m]).unwrap();
        let e = fl.process(&c, &view).unwrap_err().to_string();
        assert!(
            e.contains("microphone 5, bin 11, snapshot 4 is not finite"),
            "{e}"
        );
        let az = fl.grid.azimuth_deg(got.peaks[0].dir);
        assert!((az - 60.0).abs() < 2.6, "{alg:?}: peak at {az}°");
        // Bin 1 (250 Hz) is below the band: never read. Bin 10 (2.5 kHz) is used.
        let mut bad = copy.clone();
        bad[(2 * f + 1) * (b - a) + 3] = Complex::new(f64::NAN, 0.0);
        let view = FramesView::contiguous(&bad, [m, f, b - a]).unwrap();
        assert_eq!(fl.process(&c, &view).unwrap(), want, "{alg:?}");
        bad[(2 * f + 10) * (b - a) + 3] = Complex::new(0.0, f64::INFINITY);
        let view = FramesView::contiguous(&bad, [m, f, b - a]).unwrap();
        let e = fl.process(&c, &view).unwrap_err().to_string();
        assert!(
            e.contains("microphone 2, bin 10, snapshot 3 is not finite"),
            "{e}"
        );
    }
}

/// The spectrum and peaks of `view` as its snapshots and as its factor frames, and the
/// largest difference of the two spectra (dB); checks that `run` takes the factor.
fn both_paths<T: Real>(
    c: &LocalizeConfig,
    tf: &TransferFunctions,
    view: &FramesView<'_>,
) -> (Vec<usize>, Vec<usize>, f32) {
    let mut p = Prepared::<T>::new(c, tf, DeviceChoice::Cpu).unwrap();
    let [m, _, s] = view.shape();
    let nb = p.plan.num_bins();
    p.spectra = Spectra::zeros(s, nb, m);
    assert!(p.copy(view));
    let snapshots = p.localize().unwrap();
    p.spectra = Spectra::zeros(m, nb, m);
    assert_eq!(p.factor(view).unwrap(), Some(true));
    let factored = p.localize().unwrap();
    let worst = factored
        .spectrum_db
        .iter()
        .zip(&snapshots.spectrum_db)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    // What process() does with more snapshots than microphones.
    assert_eq!(p.run(view).unwrap(), factored);
    assert_eq!(p.spectra.num_frames, m);
    let dirs = |r: &FramesResult| r.peaks.iter().map(|p| p.dir).collect::<Vec<_>>();
    (dirs(&factored), dirs(&snapshots), worst)
}

/// The window as the M frames of its correlation's factor gives the spectrum and
/// peaks of its S snapshots: in f64 to rounding, in f32 within the f32 path's own
/// rounding (the snapshots are rounded to f32 on one path, the factor frames on the
/// other), for plain and normalised MUSIC and SRP-PHAT.
#[test]
fn factor_frames_localize_as_the_snapshots() {
    let (geo, x, shape) = plane_wave(40);
    let view = FramesView::contiguous(&x, shape).unwrap();
    let tf = free_field(
        &geo,
        &Grid::ring(5.0, 0.0, 1e4),
        64,
        16000,
        config(crate::Algorithm::Sevd).bin_range(),
        343.0,
    )
    .unwrap();
    for (alg, normalize_bins) in [
        (crate::Algorithm::Sevd, false),
        (crate::Algorithm::Sevd, true),
        (crate::Algorithm::SrpPhat, false),
        (crate::Algorithm::SrpPhat, true),
    ] {
        let c = LocalizeConfig {
            normalize_bins,
            subspace_dim: alg.is_music().then_some(2),
            ..config(alg)
        };
        let (factored, snapshots, worst) = both_paths::<f64>(&c, &tf, &view);
        assert_eq!(factored.len(), 1);
        assert_eq!(factored, snapshots);
        assert!(
            worst < 1e-5,
            "f64, {alg:?}, normalize_bins {normalize_bins}: {worst} dB"
        );
        let (factored, snapshots, worst) = both_paths::<f32>(&c, &tf, &view);
        assert_eq!(factored, snapshots);
        assert!(
            worst < 2e-4,
            "f32, {alg:?}, normalize_bins {normalize_bins}: {worst} dB"
        );
    }
    // Values whose sums overflow f64 take the snapshots' path, and its error, instead
    // of a silent all-zero factor; large values that the sums hold are factored.
    let mut fl = FramesLocalizer::new(
        geo,
        Grid::ring(5.0, 0.0, 1e4),
        343.0,
        DeviceChoice::Cpu,
        Precision::F32,
    );
    let c = config(crate::Algorithm::Sevd);
    let want = fl.process(&c, &view).unwrap();
    let big: Vec<Complex<f64>> = x.iter().map(|v| v * 1e30).collect();
    let got = fl
        .process(&c, &FramesView::contiguous(&big, shape).unwrap())
        .unwrap();
    assert!(matches!(&fl.cached, Some((_, Cached::F32(p))) if p.spectra.num_frames == shape[0]));
    assert_eq!(
        got.peaks.iter().map(|p| p.dir).collect::<Vec<_>>(),
        want.peaks.iter().map(|p| p.dir).collect::<Vec<_>>()
    );
    let huge: Vec<Complex<f64>> = x.iter().map(|v| v * 1e200).collect();
    let e = fl.process(&c, &FramesView::contiguous(&huge, shape).unwrap());
    let e = e.unwrap_err().to_string();
    assert!(e.contains("beyond f32") && e.contains("precision f64"), "{e}");
    // In f64 the sums' overflow is named where it happens.
    let mut fl64 = FramesLocalizer::new(
        fl.geometry.clone(),
        fl.grid.clone(),
        343.0,
        DeviceChoice::Cpu,
        Precision::F64,
    );
    let e = fl64.process(&c, &FramesView::contiguous(&huge, shape).unwrap());
    assert!(e.unwrap_err().to_string().contains("overflows double precision"));
    // SRP-PHAT (the snapshots' path) said nothing and found no peak before.
    let srp = config(crate::Algorithm::SrpPhat);
    let e = fl.process(&srp, &FramesView::contiguous(&huge, shape).unwrap());
    assert!(e.unwrap_err().to_string().contains("beyond f32"));
}

/// Shapes and strides that reach past the data are refused, not read.
#[test]
fn views_past_the_data_are_refused() {
    let x = vec![Complex::new(1.0, 0.0); 100];
    assert!(FramesView::new(&x, [2, 5, 10], [50, 10, 1]).is_ok());
    assert!(FramesView::new(&x, [2, 5, 11], [50, 10, 1]).is_err());
    assert!(FramesView::new(&x, [2, 5, 10], [usize::MAX / 2, 10, 1]).is_err());
    assert!(FramesView::new(&x, [3, 5, 10], [usize::MAX / 2, 10, 1]).is_err()); // overflows
    assert!(FramesView::new(&x, [0, 5, 10], [usize::MAX, 10, 1]).is_ok());
    assert!(FramesView::contiguous(&x, [2, 5, 9]).is_err());
}

/// Frames given whole are localized unweighted, so onset weighting is refused there
/// instead of shrinking the source count's snapshots without weighting.
#[test]
fn onset_weighting_is_refused_for_frames_given_whole() {
    let (geo, x, shape) = plane_wave(40);
    let mut fl = FramesLocalizer::new(
        geo,
        Grid::ring(5.0, 0.0, 1e4),
        343.0,
        DeviceChoice::Cpu,
        Precision::F64,
    );
    let mut c = config(crate::Algorithm::Sevd);
    let view = FramesView::contiguous(&x, shape).unwrap();
    assert!(fl.process(&c, &view).is_ok());
    c.onset_frames = 10;
    let e = fl.process(&c, &view).unwrap_err().to_string();
    assert!(e.contains("onset"), "{e}");
}
