//! The only orchestration: plan once, STFT, schedule windows, feed batches to a backend,
//! turn peaks into results.
//!
//! ```text
//! Audio ─► Stft ─► Spectra ─► correlation::schedule ─► Backend::process (batches)
//!        ─► BatchOutput (peaks, dB spectrum) ─► LocalizationResult per window
//! ```

use crate::array::TransferFunctions;
use crate::backend::{cpu::CpuBackend, Backend, BatchOutput, DeviceChoice, Spectra, StageTimes, WindowSpec};
use crate::config::LocalizeConfig;
use crate::correlation::schedule;
use crate::noise::NoiseMatrices;
use crate::plan::Plan;
use crate::real::Real;
use crate::result::{LocalizationResult, Source};
use crate::stft::Stft;
use crate::{Error, Result};
use std::sync::Arc;

/// The broadband spectrum of every result, dB, `[result][dir]`.
#[derive(Debug, Clone, PartialEq)]
pub struct SpectrumTable {
    /// Result frame c of each row.
    pub frames: Vec<usize>,
    /// Time of each row in seconds.
    pub times_s: Vec<f64>,
    /// Number of directions (columns).
    pub num_dirs: usize,
    /// 10·log10(P̄ + 1), `[result][dir]`.
    pub db: Vec<f32>,
    /// Number of used bins.
    pub num_bins: usize,
    /// g_k (eigenvalue weight, or 1) per result and used bin, `[result][bin]`.
    pub bin_weight: Vec<f32>,
}

/// Everything one localization run produces.
#[derive(Debug, Clone)]
pub struct Localization {
    /// One result per correlation window, in time order.
    pub results: Vec<LocalizationResult>,
    /// The spectrum, when asked for.
    pub spectrum: Option<SpectrumTable>,
    /// The device that computed it.
    pub device: String,
    /// Time per stage in ms.
    pub stage_times: StageTimes,
}

/// Build the backend for a device choice. `Auto` uses CUDA when a usable GPU and the
/// libraries are present, else the CPU.
pub fn make_backend<T: Real>(plan: Arc<Plan<T>>, device: DeviceChoice) -> Result<Box<dyn Backend<T>>> {
    match device {
        DeviceChoice::Cpu => Ok(Box::new(CpuBackend::new(plan))),
        DeviceChoice::Cuda => crate::backend::cuda::new_backend(plan, 0),
        DeviceChoice::Auto => match crate::backend::cuda::new_backend(plan.clone(), 0) {
            Ok(b) => Ok(b),
            Err(e) => {
                tracing::info!("CUDA not used ({e}); running on the CPU");
                Ok(Box::new(CpuBackend::new(plan)))
            }
        },
    }
}

/// A localization engine: a plan, its STFT, and a backend.
pub struct Engine<T: Real> {
    plan: Arc<Plan<T>>,
    stft: Stft<T>,
    backend: Box<dyn Backend<T>>,
}

impl<T: Real> Engine<T> {
    /// Plan and pick a device.
    pub fn new(
        config: &LocalizeConfig,
        tf: &TransferFunctions,
        noise: Option<&NoiseMatrices>,
        device: DeviceChoice,
    ) -> Result<Self> {
        let plan = Arc::new(Plan::<T>::new(config, tf, noise)?);
        let backend = make_backend(plan.clone(), device)?;
        Self::with_backend(plan, backend)
    }

    /// Use a given plan and backend.
    pub fn with_backend(plan: Arc<Plan<T>>, backend: Box<dyn Backend<T>>) -> Result<Self> {
        let c = &plan.config;
        let stft = Stft::new(c.nfft, c.hop, c.window_function, plan.bins.clone())?;
        Ok(Engine { plan, stft, backend })
    }

    /// The plan.
    pub fn plan(&self) -> &Plan<T> {
        &self.plan
    }

    /// The backend's device description.
    pub fn device_name(&self) -> String {
        self.backend.device_name()
    }

    /// The backend (for benchmarks).
    pub fn backend_mut(&mut self) -> &mut dyn Backend<T> {
        &mut *self.backend
    }

    /// Replace the noise matrix K (online updates, iGSVD / iGEVD).
    pub fn set_noise(&mut self, noise: &NoiseMatrices) -> Result<()> {
        let plan = Arc::new(self.plan.with_noise(noise)?);
        self.backend.set_plan(plan.clone())?;
        self.plan = plan;
        Ok(())
    }

    /// STFT of planar samples after checking them against the plan.
    pub fn spectra(&self, sample_rate_hz: u32, channels: &[Vec<f32>]) -> Result<Spectra<T>> {
        self.check_samples(sample_rate_hz, channels)?;
        self.stft.process(channels)
    }

    /// Check channel count, sample rate and length against the plan.
    fn check_samples(&self, sample_rate_hz: u32, channels: &[Vec<f32>]) -> Result<()> {
        let c = &self.plan.config;
        if channels.len() != self.plan.num_mics {
            return Err(Error::Mismatch(format!(
                "the audio has {} channels but the transfer functions have {} microphones \
                 (select channels with --channels)",
                channels.len(),
                self.plan.num_mics
            )));
        }
        if sample_rate_hz != c.sample_rate_hz {
            return Err(Error::Mismatch(format!(
                "the audio is sampled at {} Hz but the analysis (and transfer functions) at {} Hz",
                sample_rate_hz, c.sample_rate_hz
            )));
        }
        let len = channels.first().map_or(0, |c| c.len());
        let need = c.nfft + (c.window.max(1) - 1) * c.hop;
        if len < need {
            return Err(Error::TooShort(format!(
                "the audio has {} samples ({:.3} s); one correlation window of {} frames needs at least {} ({:.3} s)",
                len,
                len as f64 / sample_rate_hz as f64,
                c.window,
                need,
                need as f64 / sample_rate_hz as f64
            )));
        }
        Ok(())
    }

    /// Localize planar samples: one result per correlation window. The STFT is computed
    /// per group of windows (only the frames they cover), so memory stays bounded on long
    /// recordings.
    pub fn localize_samples(
        &mut self,
        sample_rate_hz: u32,
        channels: &[Vec<f32>],
        want_spectrum: bool,
        progress: &mut dyn FnMut(usize, usize),
    ) -> Result<Localization> {
        self.check_samples(sample_rate_hz, channels)?;
        let c = self.plan.config.clone();
        let len = channels.first().map_or(0, |c| c.len());
        let windows = schedule(self.stft.num_frames(len), c.window, c.period, c.window_type);
        // Groups of windows spanning about GROUP_FRAMES frames (at least one batch).
        const GROUP_FRAMES: usize = 4096;
        let per_group = (GROUP_FRAMES / c.period.max(1))
            .max(self.backend.max_windows_per_batch())
            .max(1);
        self.backend.reset_stage_times();
        let mut all: Option<Localization> = None;
        let total = windows.len();
        for (g, group) in windows.chunks(per_group).enumerate() {
            let f0 = group.iter().map(|w| w.start).min().unwrap_or(0);
            let f1 = group.iter().map(|w| w.start + w.len).max().unwrap_or(0);
            let spectra = self.stft.process_frames(channels, f0..f1)?;
            let local: Vec<WindowSpec> = group
                .iter()
                .map(|w| WindowSpec {
                    start: w.start - f0,
                    ..*w
                })
                .collect();
            let done = g * per_group;
            let part = self.localize_windows(&spectra, &local, want_spectrum, &mut |d, _| {
                progress(done + d, total)
            })?;
            match all.as_mut() {
                None => all = Some(part),
                Some(a) => {
                    a.results.extend(part.results);
                    if let (Some(t), Some(p)) = (a.spectrum.as_mut(), part.spectrum) {
                        t.frames.extend(p.frames);
                        t.times_s.extend(p.times_s);
                        t.db.extend(p.db);
                        t.bin_weight.extend(p.bin_weight);
                    }
                    a.stage_times = part.stage_times;
                }
            }
        }
        all.ok_or_else(|| {
            Error::TooShort(format!(
                "{len} samples give no complete correlation window of {} frames",
                c.window
            ))
        })
    }

    /// Localize precomputed spectra (frame 0 of `spectra` is STFT frame 0).
    pub fn localize_spectra(
        &mut self,
        spectra: &Spectra<T>,
        want_spectrum: bool,
        progress: &mut dyn FnMut(usize, usize),
    ) -> Result<Localization> {
        let c = self.plan.config.clone();
        let windows = schedule(spectra.num_frames, c.window, c.period, c.window_type);
        if windows.is_empty() {
            return Err(Error::TooShort(format!(
                "{} frames give no complete correlation window of {} frames",
                spectra.num_frames, c.window
            )));
        }
        self.backend.reset_stage_times();
        self.localize_windows(spectra, &windows, want_spectrum, progress)
    }

    /// Localize an explicit list of windows over `spectra` (e.g. one at a time between
    /// online noise updates). Stage times accumulate across calls.
    pub fn localize_windows(
        &mut self,
        spectra: &Spectra<T>,
        windows: &[WindowSpec],
        want_spectrum: bool,
        progress: &mut dyn FnMut(usize, usize),
    ) -> Result<Localization> {
        let batch = self.backend.max_windows_per_batch().max(1);
        let mut results = Vec::with_capacity(windows.len());
        let mut table = want_spectrum.then(|| SpectrumTable {
            frames: Vec::new(),
            times_s: Vec::new(),
            num_dirs: self.plan.num_dirs,
            db: Vec::new(),
            num_bins: self.plan.num_bins(),
            bin_weight: Vec::new(),
        });
        let mut out = BatchOutput::default();
        for (i, chunk) in windows.chunks(batch).enumerate() {
            self.backend.process(spectra, chunk, want_spectrum, &mut out)?;
            for (w, peaks) in chunk.iter().zip(&out.peaks) {
                results.push(self.result(w, peaks));
            }
            if let Some(t) = table.as_mut() {
                t.db.extend_from_slice(&out.spectrum_db);
                t.bin_weight.extend_from_slice(&out.bin_weight);
                for w in chunk {
                    t.frames.push(w.frame);
                    t.times_s.push(self.frame_time(w.frame));
                }
            }
            progress((i * batch + chunk.len()).min(windows.len()), windows.len());
        }
        Ok(Localization {
            results,
            spectrum: table,
            device: self.backend.device_name(),
            stage_times: self.backend.stage_times(),
        })
    }

    /// Time of STFT frame `frame` in seconds (its first sample).
    pub fn frame_time(&self, frame: usize) -> f64 {
        frame as f64 * self.plan.config.hop as f64 / self.plan.config.sample_rate_hz as f64
    }

    fn result(&self, w: &WindowSpec, peaks: &[crate::backend::Peak]) -> LocalizationResult {
        LocalizationResult {
            frame: w.frame,
            time_s: self.frame_time(w.frame),
            sources: peaks
                .iter()
                .map(|p| source(&self.plan.grid, p.dir, p.power_db))
                .collect(),
        }
    }
}

/// A result source for grid direction `dir`: unit direction vector, azimuth, elevation.
pub fn source(grid: &crate::array::Grid, dir: usize, power_db: f64) -> Source {
    let [x, y, z] = grid.unit(dir);
    Source {
        id: None,
        grid_index: dir,
        azimuth_deg: grid.azimuth_deg(dir),
        elevation_deg: grid.elevation_deg(dir),
        x,
        y,
        z,
        power_db,
    }
}

/// Estimate K from planar samples: x xᴴ averaged over the complete STFT frames that start
/// inside `range_s` (seconds; None = all), for the config's used bins, in f64.
pub fn estimate_noise(
    config: &LocalizeConfig,
    sample_rate_hz: u32,
    channels: &[Vec<f32>],
    range_s: Option<(f64, f64)>,
) -> Result<NoiseMatrices> {
    if sample_rate_hz != config.sample_rate_hz {
        return Err(Error::Mismatch(format!(
            "the noise audio is sampled at {} Hz but the analysis runs at {} Hz",
            sample_rate_hz, config.sample_rate_hz
        )));
    }
    let bins = config.bin_range();
    let stft = Stft::<f64>::new(config.nfft, config.hop, config.window_function, bins.clone())?;
    let len = channels.first().map_or(0, |c| c.len());
    let (s0, s1) = match range_s {
        None => (0usize, len),
        Some((a, b)) => {
            if !(a.is_finite() && b.is_finite()) || a < 0.0 || b <= a {
                return Err(Error::Config(format!(
                    "noise range {a}:{b} s: need 0 <= start < end"
                )));
            }
            let fs = sample_rate_hz as f64;
            let s0 = (a * fs).round() as usize;
            let s1 = ((b * fs).round() as usize).min(len);
            if s0 >= len {
                return Err(Error::TooShort(format!(
                    "noise range {a}:{b} s starts after the end of the audio ({:.3} s)",
                    len as f64 / fs
                )));
            }
            (s0, s1)
        }
    };
    let part: Vec<Vec<f32>> = channels.iter().map(|c| c[s0..s1].to_vec()).collect();
    let nf = stft.num_frames(s1 - s0);
    if nf == 0 {
        return Err(Error::TooShort(format!(
            "the noise segment has {} samples, fewer than one {}-sample frame",
            s1 - s0,
            config.nfft
        )));
    }
    let spectra = stft.process(&part)?;
    NoiseMatrices::from_spectra(&spectra, bins.start, 0..nf)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::array::{freefield::free_field, Geometry, Grid};
    use rand::{Rng, SeedableRng};

    #[test]
    fn chunked_stft_equals_whole_file_stft_on_a_long_recording() {
        // 45 s of 8-channel noise: > 4096 frames, so several STFT groups.
        let config = LocalizeConfig::default();
        let tf = free_field(
            &Geometry::circle(8, 0.0365, 0.0),
            &Grid::ring(5.0, 0.0, 1.0),
            512,
            16000,
            config.bin_range(),
            343.0,
        )
        .unwrap();
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let n = 45 * 16000;
        let channels: Vec<Vec<f32>> = (0..8)
            .map(|_| (0..n).map(|_| rng.gen_range(-1000.0..1000.0)).collect())
            .collect();
        let mut e = Engine::<f32>::new(&config, &tf, None, DeviceChoice::Cpu).unwrap();
        let chunked = e
            .localize_samples(16000, &channels, true, &mut |_, _| {})
            .unwrap();
        let whole_spectra = e.spectra(16000, &channels).unwrap();
        assert!(whole_spectra.num_frames > 4096);
        let whole = e.localize_spectra(&whole_spectra, true, &mut |_, _| {}).unwrap();
        assert!(chunked.results == whole.results, "results differ");
        // Bit-identical: the CPU backend sums bins in a fixed order.
        assert!(chunked.spectrum.unwrap().db == whole.spectrum.unwrap().db);
        assert_eq!(whole.results.len(), (whole_spectra.num_frames - 50) / 50 + 1);
    }
}
