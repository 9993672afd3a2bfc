//! One window over STFT frames the caller already has — pyroomacoustics'
//! `locate_sources(X)` shape: X is M × F × S (microphones × rfft bins × snapshots), all S
//! snapshots form one correlation window, and the result is the broadband spectrum over
//! the grid and its peaks. The Python drop-in (`soundloc.doa`) calls this; the plan,
//! backends, spectrum and peak rules are the engine's own.
//!
//! With more snapshots than microphones, the window reaches the backend as the M frames
//! of a factor of its correlation ([`factor`]: one pass over X in its own memory order,
//! no copy of every snapshot; for SRP-PHAT of the phase-transformed snapshots' correlation,
//! the frames marked as transformed); short windows get the snapshots themselves.

use crate::array::freefield::free_field;
use crate::array::{Geometry, Grid, TransferFunctions};
use crate::backend::{Backend, BatchOutput, DeviceChoice, Job, Peak, Spectra, WindowSpec};
use crate::config::{LocalizeConfig, Precision};
use crate::engine::make_backend;
use crate::plan::Plan;
use crate::real::{Real, C};
use crate::{Error, Result};
use rayon::prelude::*;
use std::sync::Arc;

mod factor;

/// The spectrum and peaks of one window of given frames.
#[derive(Debug, Clone, PartialEq)]
pub struct FramesResult {
    /// dB spectrum 10·log10(P̄ + 1) per direction.
    pub spectrum_db: Vec<f32>,
    /// Peaks, strongest first (after the azimuth filter and `max_peaks`).
    pub peaks: Vec<Peak>,
}

/// A read-only view of pyroomacoustics' X: M × F × S complex values (microphones × rfft
/// bins × snapshots) at element offsets `i·strides[0] + k·strides[1] + s·strides[2]` of
/// `data` — a C-contiguous array or a slice of one (numpy's `X[:, :, a:b]`), read in
/// place.
#[derive(Debug, Clone, Copy)]
pub struct FramesView<'a> {
    data: &'a [num_complex::Complex<f64>],
    shape: [usize; 3],
    strides: [usize; 3],
}

impl<'a> FramesView<'a> {
    /// A view with the given `shape` and `strides` (in elements); every element must lie
    /// inside `data`.
    pub fn new(
        data: &'a [num_complex::Complex<f64>],
        shape: [usize; 3],
        strides: [usize; 3],
    ) -> Result<Self> {
        let [m, f, s] = shape;
        let last = (0..3).try_fold(0usize, |acc, d| {
            shape[d].checked_sub(1).map_or(Some(acc), |n| {
                n.checked_mul(strides[d]).and_then(|v| v.checked_add(acc))
            })
        });
        let fits = shape.contains(&0) || last.is_some_and(|l| l < data.len());
        if !fits {
            return Err(Error::Config(format!(
                "frames: a {m} × {f} × {s} array with strides {strides:?} does not fit in {} values",
                data.len()
            )));
        }
        Ok(FramesView { data, shape, strides })
    }

    /// A C-contiguous M × F × S array.
    pub fn contiguous(data: &'a [num_complex::Complex<f64>], shape: [usize; 3]) -> Result<Self> {
        let [m, f, s] = shape;
        if m.checked_mul(f).and_then(|v| v.checked_mul(s)) != Some(data.len()) {
            return Err(Error::Config(format!(
                "frames: {} values for a {m} × {f} × {s} array",
                data.len()
            )));
        }
        Self::new(data, shape, [f * s, s, 1])
    }

    /// M × F × S.
    pub fn shape(&self) -> [usize; 3] {
        self.shape
    }
}

/// Checks `x` against `config`: F = nfft/2 + 1 and at least one snapshot.
fn check(config: &LocalizeConfig, x: &FramesView<'_>) -> Result<()> {
    let [_, f, s] = x.shape;
    if f != config.nfft / 2 + 1 {
        return Err(Error::Mismatch(format!(
            "frames hold {f} frequency bins, but an {}-point FFT has {}",
            config.nfft,
            config.nfft / 2 + 1
        )));
    }
    if s == 0 {
        return Err(Error::TooShort("frames: no snapshots".into()));
    }
    Ok(())
}

/// A planned backend for one config.
struct Prepared<T: Real> {
    plan: Arc<Plan<T>>,
    backend: Box<dyn Backend<T>>,
    spectra: Spectra<T>,
    /// Per used bin, its M factor frames (M × M; [`Prepared::factor`]).
    factors: Vec<C<T>>,
    out: BatchOutput,
}

impl<T: Real> Prepared<T> {
    fn new(config: &LocalizeConfig, tf: &TransferFunctions, device: DeviceChoice) -> Result<Self> {
        let plan = Arc::new(Plan::<T>::new(config, tf, None)?);
        let backend = make_backend(
            plan.clone(),
            device,
            crate::engine::device::default_cache().as_deref(),
        )?;
        Ok(Prepared {
            plan,
            backend,
            spectra: Spectra::zeros(0, 0, 0),
            factors: Vec::new(),
            out: BatchOutput::default(),
        })
    }

    /// The window's M factor frames into `self.spectra` (factor.rs; for SRP-PHAT those
    /// of the phase-transformed snapshots, marked `phased`); false if a value of a used
    /// bin is not finite; `None` if a sum or a factor frame overflows and T is f32, or a
    /// value is beyond T for SRP-PHAT, and nothing is written: the caller then copies the
    /// snapshots, whose path names the value beyond f32. In f64 an overflowing sum is an
    /// error here (the snapshots' path would only fail later, in the decomposition).
    fn factor(&mut self, x: &FramesView<'_>) -> Result<Option<bool>> {
        let [m, _, s] = x.shape;
        let phat = !self.plan.config.algorithm.is_music();
        let bins = self.plan.bins.clone();
        let nb = bins.len();
        let mut per_bin = std::mem::take(&mut self.factors);
        per_bin.resize(nb * m * m, C::new(T::zero(), T::zero()));
        let ok = |v: &C<T>| v.re.to_f64().is_finite() & v.im.to_f64().is_finite();
        // (finite input, sums held in f64, frames held in T)
        let (finite, sums_held, held) = per_bin
            .par_chunks_mut(m * m)
            .zip(bins.into_par_iter())
            .map_init(factor::Scratch::default, |ws, (out, k)| {
                let read = factor::bin_sum::<T>(x, k, phat, ws);
                if !read.finite {
                    return (false, true, true);
                }
                factor::factor_frames(ws, m, s, out, m);
                let sums_held = ws.sum.iter().all(|z| z.re.is_finite() & z.im.is_finite());
                (true, sums_held, read.held && sums_held && out.iter().all(ok))
            })
            .reduce(|| (true, true, true), |a, b| (a.0 & b.0, a.1 & b.1, a.2 & b.2));
        self.factors = per_bin;
        if finite && !sums_held && std::mem::size_of::<T>() == 8 {
            return Err(Error::Numerical {
                stage: "input",
                message: format!(
                    "frames: Σ|x|² over the {s} snapshots overflows double precision (values \
                     beyond about 1e150); scale the input"
                ),
            });
        }
        if !held {
            return Ok(None);
        }
        let per_bin = &self.factors;
        // Frame c of bin b at (c · nb + b) · M.
        for (b, fb) in per_bin.chunks_exact(m * m).enumerate() {
            for (c, y) in fb.chunks_exact(m).enumerate() {
                let o = (c * nb + b) * m;
                self.spectra.data[o..o + m].copy_from_slice(y);
            }
        }
        self.spectra.phased = phat;
        Ok(Some(finite))
    }

    /// The snapshots of the used bins into `self.spectra` (converted to T); false if one
    /// is not finite.
    fn copy(&mut self, x: &FramesView<'_>) -> bool {
        let [m, _, s] = x.shape;
        self.spectra.phased = false;
        let bins = self.plan.bins.clone();
        let nb = bins.len();
        // Only the used bins are read (and must be finite), in the order of the source's
        // memory where the snapshots lie closer together than the microphones (numpy's
        // (M, F, S) layout: each bin's snapshots are a contiguous run), else microphone
        // by microphone within each snapshot.
        let [st_mic, st_bin, st_snap] = x.strides;
        let conv = |v: num_complex::Complex<f64>| C::new(T::of_f64(v.re), T::of_f64(v.im));
        // Parts of snapshots in parallel (each part's destination is contiguous): a
        // window's frames are read once, from memory, at the pool's combined bandwidth.
        let part = s.div_ceil(rayon::current_num_threads().max(1)).max(8);
        self.spectra
            .data
            .par_chunks_mut(part * nb * m)
            .enumerate()
            .map(|(p, data)| {
                let snaps = p * part..(p * part + data.len() / (nb * m)).min(s);
                let mut finite = true;
                if st_snap <= st_mic {
                    for mic in 0..m {
                        for (b, k) in bins.clone().enumerate() {
                            let src = &x.data[mic * st_mic + k * st_bin..];
                            for (i, snap) in snaps.clone().enumerate() {
                                let v = src[snap * st_snap];
                                let y = conv(v);
                                finite &= y.re.to_f64().is_finite() & y.im.to_f64().is_finite();
                                data[(i * nb + b) * m + mic] = y;
                            }
                        }
                    }
                } else {
                    for (b, k) in bins.clone().enumerate() {
                        for (i, snap) in snaps.clone().enumerate() {
                            let src = &x.data[k * st_bin + snap * st_snap..];
                            let dst = &mut data[(i * nb + b) * m..(i * nb + b + 1) * m];
                            for (mic, out) in dst.iter_mut().enumerate() {
                                let v = src[mic * st_mic];
                                *out = conv(v);
                                finite &= out.re.to_f64().is_finite() & out.im.to_f64().is_finite();
                            }
                        }
                    }
                }
                finite
            })
            .reduce(|| true, |a, b| a & b)
    }

    fn run(&mut self, x: &FramesView<'_>) -> Result<FramesResult> {
        let [m, _, s] = x.shape;
        if self.plan.num_mics != m {
            return Err(Error::Mismatch(format!(
                "frames have {m} microphones, the array {}",
                self.plan.num_mics
            )));
        }
        let bins = self.plan.bins.clone();
        // More snapshots than microphones: the window goes to the backend as the M frames
        // of its correlation's factor (factor.rs), else as the snapshots.
        let factored = s > m;
        let mut finite = None;
        if factored {
            self.reshape(m);
            finite = self.factor(x)?;
        }
        // `copied`: the snapshots went in as values of T, which must hold them.
        let (finite, copied) = match finite {
            Some(f) => (f, false),
            None => {
                self.reshape(s);
                (self.copy(x), true)
            }
        };
        if !finite {
            let [st_mic, st_bin, st_snap] = x.strides;
            for (k, snap, mic) in
                bins.flat_map(|k| (0..s).flat_map(move |snap| (0..m).map(move |mic| (k, snap, mic))))
            {
                let v = x.data[k * st_bin + snap * st_snap + mic * st_mic];
                let what = if !v.is_finite() {
                    "is not finite".to_string()
                } else if copied
                    && !(T::of_f64(v.re).to_f64().is_finite() && T::of_f64(v.im).to_f64().is_finite())
                {
                    format!(
                        "is {:e}, beyond {} (|x| <= {:e}; use precision f64 or scale the input)",
                        v.norm(),
                        T::NAME,
                        f32::MAX
                    )
                } else {
                    continue;
                };
                return Err(Error::Numerical {
                    stage: "input",
                    message: format!("frames: microphone {mic}, bin {k}, snapshot {snap} {what}"),
                });
            }
        }
        self.localize()
    }

    /// `self.spectra` for `frames` frames of the plan's bins and microphones.
    fn reshape(&mut self, frames: usize) {
        let (nb, m) = (self.plan.num_bins(), self.plan.num_mics);
        if self.spectra.num_frames != frames || self.spectra.num_bins != nb || self.spectra.num_mics != m {
            self.spectra = Spectra::zeros(frames, nb, m);
        }
    }

    /// The backend's result for the frames in `self.spectra`, all of them one window.
    fn localize(&mut self) -> Result<FramesResult> {
        let window = WindowSpec {
            frame: 0,
            start: 0,
            len: self.spectra.num_frames,
        };
        self.backend
            .process(&[Job::once(&self.spectra, &[window])], true, &mut self.out)?;
        Ok(FramesResult {
            spectrum_db: self.out.spectrum_db.clone(),
            peaks: self.out.peaks.first().cloned().unwrap_or_default(),
        })
    }
}

enum Cached {
    F32(Prepared<f32>),
    F64(Prepared<f64>),
}

/// Localizes windows of given STFT frames for one array and grid: free-field TFs, plan
/// and backend are built on the first call and kept while the analysis config stays the
/// same (plan once, call cheap).
pub struct FramesLocalizer {
    geometry: Geometry,
    grid: Grid,
    speed_of_sound_m_s: f64,
    device: DeviceChoice,
    precision: Precision,
    cached: Option<(LocalizeConfig, Cached)>,
}

impl FramesLocalizer {
    /// For `geometry` (metres) and `grid` (points; far field = far away), with free-field
    /// TFs at `speed_of_sound_m_s`.
    pub fn new(
        geometry: Geometry,
        grid: Grid,
        speed_of_sound_m_s: f64,
        device: DeviceChoice,
        precision: Precision,
    ) -> Self {
        FramesLocalizer {
            geometry,
            grid,
            speed_of_sound_m_s,
            device,
            precision,
            cached: None,
        }
    }

    /// Localize `x` (pyroomacoustics' X, F = nfft/2 + 1) as one window over the bins
    /// `config` uses; only those bins are read, and they must be finite.
    pub fn process(&mut self, config: &LocalizeConfig, x: &FramesView<'_>) -> Result<FramesResult> {
        check(config, x)?;
        if self.cached.as_ref().map(|(c, _)| c) != Some(config) {
            self.cached = None;
            let tf = free_field(
                &self.geometry,
                &self.grid,
                config.nfft,
                config.sample_rate_hz,
                config.bin_range(),
                self.speed_of_sound_m_s,
            )?;
            let prepared = match self.precision {
                Precision::F32 => Cached::F32(Prepared::new(config, &tf, self.device)?),
                Precision::F64 => Cached::F64(Prepared::new(config, &tf, self.device)?),
            };
            self.cached = Some((config.clone(), prepared));
        }
        match self.cached.as_mut().map(|(_, p)| p) {
            Some(Cached::F32(p)) => p.run(x),
            Some(Cached::F64(p)) => p.run(x),
            None => Err(Error::Config("frames: no plan".into())),
        }
    }
}

#[cfg(test)]
mod tests {
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
                    x[(i * f + k) * s + t] =
                        src[k * s + t] * steer + Complex::new(0.01 * rnd(), 0.01 * rnd());
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
                subspace_dim: Some(2),
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
}
