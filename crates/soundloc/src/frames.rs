//! One window over STFT frames the caller already has — pyroomacoustics'
//! `locate_sources(X)` shape: X is M × F × S (microphones × rfft bins × snapshots), all S
//! snapshots form one correlation window, and the result is the broadband spectrum over
//! the grid and its peaks. The Python drop-in (`soundloc.doa`) calls this; the plan,
//! backends, spectrum and peak rules are the engine's own.

use crate::array::freefield::free_field;
use crate::array::{Geometry, Grid, TransferFunctions};
use crate::backend::{Backend, BatchOutput, DeviceChoice, Job, Peak, Spectra, WindowSpec};
use crate::config::{LocalizeConfig, Precision};
use crate::engine::make_backend;
use crate::plan::Plan;
use crate::real::{Real, C};
use crate::{Error, Result};
use std::sync::Arc;

/// The spectrum and peaks of one window of given frames.
#[derive(Debug, Clone, PartialEq)]
pub struct FramesResult {
    /// dB spectrum 10·log10(P̄ + 1) per direction.
    pub spectrum_db: Vec<f32>,
    /// Peaks, strongest first (after the azimuth filter and `max_peaks`).
    pub peaks: Vec<Peak>,
}

/// Checks `x` against `shape` and `config`: sizes, F = nfft/2 + 1, finite values.
fn check(config: &LocalizeConfig, x: &[num_complex::Complex<f64>], shape: [usize; 3]) -> Result<()> {
    let [m, f, s] = shape;
    if m.checked_mul(f).and_then(|v| v.checked_mul(s)) != Some(x.len()) {
        return Err(Error::Config(format!(
            "frames: {} values for a {m} × {f} × {s} array",
            x.len()
        )));
    }
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
    if let Some(i) = x.iter().position(|v| !(v.re.is_finite() && v.im.is_finite())) {
        return Err(Error::Numerical {
            stage: "input",
            message: format!("frames: value {i} is not finite"),
        });
    }
    Ok(())
}

/// A planned backend for one config.
struct Prepared<T: Real> {
    plan: Arc<Plan<T>>,
    backend: Box<dyn Backend<T>>,
    spectra: Spectra<T>,
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
            out: BatchOutput::default(),
        })
    }

    fn run(&mut self, x: &[num_complex::Complex<f64>], shape: [usize; 3]) -> Result<FramesResult> {
        let [m, f, s] = shape;
        if self.plan.num_mics != m {
            return Err(Error::Mismatch(format!(
                "frames have {m} microphones, the array {}",
                self.plan.num_mics
            )));
        }
        let bins = self.plan.bins.clone();
        let nb = bins.len();
        if self.spectra.num_frames != s || self.spectra.num_bins != nb || self.spectra.num_mics != m {
            self.spectra = Spectra::zeros(s, nb, m);
        }
        for (mic, per_mic) in x.chunks_exact(f * s).enumerate() {
            for (b, k) in bins.clone().enumerate() {
                for (snap, v) in per_mic[k * s..(k + 1) * s].iter().enumerate() {
                    self.spectra.data[(snap * nb + b) * m + mic] = C::new(T::of_f64(v.re), T::of_f64(v.im));
                }
            }
        }
        let window = WindowSpec {
            frame: 0,
            start: 0,
            len: s,
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

    /// Localize `x`, laid out `[mic][bin][snapshot]` row-major (M × F × S with
    /// F = nfft/2 + 1, pyroomacoustics' X), as one window over the bins `config` uses.
    pub fn process(
        &mut self,
        config: &LocalizeConfig,
        x: &[num_complex::Complex<f64>],
        shape: [usize; 3],
    ) -> Result<FramesResult> {
        check(config, x, shape)?;
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
            Some(Cached::F32(p)) => p.run(x, shape),
            Some(Cached::F64(p)) => p.run(x, shape),
            None => Err(Error::Config("frames: no plan".into())),
        }
    }
}
