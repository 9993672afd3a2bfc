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
    if config.onset_frames > 0 {
        return Err(Error::Config(
            "onset weighting (onset_frames) runs in the stream engine over an STFT it made; \
             frames given whole are localized unweighted: set onset_frames to 0"
                .into(),
        ));
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
mod tests;
