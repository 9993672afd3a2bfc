//! Compute backends: the CPU (faer + rayon) and CUDA behind one batch interface.
//!
//! The engine ([`crate::engine`]) owns stage order, batching, peaks-to-results, tracking
//! and outputs; a backend owns *where* the numeric stages run. Every call covers a batch of
//! correlation windows, never one bin or one direction:
//!
//! ```text
//! Spectra [frame][bin][mic] ──► correlate R_k per window ──► decompose (SEVD/GEVD/GSVD)
//!      ──► MUSIC spectrum P̄(d) ──► dB ──► local maxima ──► BatchOutput (peaks, dB spectrum)
//! ```
//!
//! Only plain data crosses this seam: [`Spectra`], [`WindowSpec`], [`BatchOutput`]. A
//! backend is built from an `Arc<Plan<T>>` (everything precomputed once: steering vectors,
//! their norms, whitening matrices, weights, the peak table) and keeps its own scratch or
//! device buffers.

pub mod cpu;
pub mod cuda;
pub mod multi;

use crate::plan::Plan;
use crate::real::{Real, C};
use crate::Result;
use std::sync::Arc;

/// Which compute device to use. Written (CLI, Python, serde) as `auto`, `cpu`, `cuda`
/// (= `cuda:0`), `cuda:all` or a list `cuda:0,1,…`; several GPUs share every batch of
/// windows ([`multi::MultiBackend`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum DeviceChoice {
    /// CUDA when a usable GPU and the CUDA libraries are present, else the CPU.
    #[default]
    Auto,
    /// The CPU (faer + rayon).
    Cpu,
    /// CUDA device 0 (an error when unavailable).
    Cuda,
    /// Every GPU present.
    CudaAll,
    /// These GPUs: bit i set = `cuda:i` (ordinals 0–63).
    CudaSet(u64),
}

impl DeviceChoice {
    /// The GPU ordinals a CUDA choice names (`None` for `auto`/`cpu`/`cuda:all`).
    pub fn ordinals(self) -> Option<Vec<usize>> {
        match self {
            DeviceChoice::Cuda => Some(vec![0]),
            DeviceChoice::CudaSet(m) => Some((0..64).filter(|i| m >> i & 1 == 1).collect()),
            _ => None,
        }
    }
}

impl std::str::FromStr for DeviceChoice {
    type Err = crate::Error;
    fn from_str(s: &str) -> Result<Self> {
        let bad = || {
            crate::Error::Config(format!(
                "device {s:?}: expected auto, cpu, cuda, cuda:all or cuda:N[,M...] (GPU ordinals 0-63)"
            ))
        };
        Ok(match s.trim() {
            "auto" => DeviceChoice::Auto,
            "cpu" => DeviceChoice::Cpu,
            "cuda" => DeviceChoice::Cuda,
            "cuda:all" => DeviceChoice::CudaAll,
            t => {
                let list = t.strip_prefix("cuda:").ok_or_else(bad)?;
                let mut mask = 0u64;
                for n in list.split(',') {
                    let i: u32 = n.trim().parse().map_err(|_| bad())?;
                    if i >= 64 {
                        return Err(bad());
                    }
                    if mask >> i & 1 == 1 {
                        return Err(crate::Error::Config(format!(
                            "device {s:?}: GPU {i} is named twice (each GPU once: cuda:0,1)"
                        )));
                    }
                    mask |= 1 << i;
                }
                if mask == 1 {
                    DeviceChoice::Cuda
                } else {
                    DeviceChoice::CudaSet(mask)
                }
            }
        })
    }
}

impl std::fmt::Display for DeviceChoice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DeviceChoice::Auto => f.write_str("auto"),
            DeviceChoice::Cpu => f.write_str("cpu"),
            DeviceChoice::Cuda => f.write_str("cuda"),
            DeviceChoice::CudaAll => f.write_str("cuda:all"),
            DeviceChoice::CudaSet(_) => {
                let l: Vec<String> = self
                    .ordinals()
                    .unwrap_or_default()
                    .iter()
                    .map(|i| i.to_string())
                    .collect();
                write!(f, "cuda:{}", l.join(","))
            }
        }
    }
}

impl TryFrom<String> for DeviceChoice {
    type Error = crate::Error;
    fn try_from(s: String) -> Result<Self> {
        s.parse()
    }
}

impl From<DeviceChoice> for String {
    fn from(d: DeviceChoice) -> String {
        d.to_string()
    }
}

/// STFT frames of the used bins, laid out `[frame][bin][mic]` (row-major): frame f, used
/// bin index b (absolute bin = `plan.bins.start + b`), microphone m at
/// `data[(f * num_bins + b) * num_mics + m]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Spectra<T: Real> {
    /// Number of frames.
    pub num_frames: usize,
    /// Number of used bins.
    pub num_bins: usize,
    /// Number of microphones.
    pub num_mics: usize,
    /// The frames.
    pub data: Vec<C<T>>,
    /// The frames are already reduced to their phase (SRP-PHAT's x̃ = x/|x|, or frames
    /// whose correlation is that of such frames: `frames`' factor of a long window), so
    /// SRP-PHAT's correlation sums them as they are. Every job of one `process` call
    /// agrees on it.
    pub phased: bool,
}

impl<T: Real> Spectra<T> {
    /// Zeroed spectra of the given shape.
    pub fn zeros(num_frames: usize, num_bins: usize, num_mics: usize) -> Self {
        Spectra {
            num_frames,
            num_bins,
            num_mics,
            data: vec![C::new(T::zero(), T::zero()); num_frames * num_bins * num_mics],
            phased: false,
        }
    }
    /// x_{f,b} (length `num_mics`).
    #[inline]
    pub fn frame_bin(&self, frame: usize, bin: usize) -> &[C<T>] {
        let o = (frame * self.num_bins + bin) * self.num_mics;
        &self.data[o..o + self.num_mics]
    }
}

/// Names one stream's frames across `process` calls, so that a backend may keep what it
/// already has of them (a device-resident frame ring, a running correlation): frame `f` of
/// stream `s` is the same data in every call. A stream takes a fresh id when it starts,
/// after a reset and after a gap; [`StreamId::ONCE`] marks frames nobody will hand in again.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct StreamId(u64);

impl StreamId {
    /// Frames of a one-off call: nothing is kept for them.
    pub const ONCE: StreamId = StreamId(0);

    /// A new id, never handed out before in this process.
    pub fn fresh() -> StreamId {
        static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);
        StreamId(NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed))
    }

    /// Whether a backend may keep this stream's frames for later calls.
    pub fn is_kept(self) -> bool {
        self != StreamId::ONCE
    }
}

/// The windows of one stream in a batch: `spectra` frame 0 is the stream's frame `first`,
/// window starts are stream frames (absolute), and `spectra` holds every frame the windows
/// read (plus, when present, the frames just before them: a backend with a running
/// correlation subtracts those that leave).
#[derive(Debug, Clone, Copy)]
pub struct Job<'a, T: Real> {
    /// Whose frames these are.
    pub stream: StreamId,
    /// Stream frame of `spectra` frame 0.
    pub first: usize,
    /// The frames.
    pub spectra: &'a Spectra<T>,
    /// The windows, in result order; `start` is a stream frame ≥ `first`.
    pub windows: &'a [WindowSpec],
}

impl<'a, T: Real> Job<'a, T> {
    /// Windows over `spectra` alone (starts are `spectra` frames), kept by no backend.
    pub fn once(spectra: &'a Spectra<T>, windows: &'a [WindowSpec]) -> Self {
        Job {
            stream: StreamId::ONCE,
            first: 0,
            spectra,
            windows,
        }
    }

    /// `spectra`'s frame index of stream frame `f`.
    #[inline]
    pub fn local(&self, f: usize) -> usize {
        f - self.first
    }
}

/// One correlation window: frames `start .. start + len` of a stream, producing the
/// result for frame `frame` (the result frame c of [`crate::correlation`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct WindowSpec {
    /// Result frame c (absolute STFT frame index).
    pub frame: usize,
    /// First frame of the window, as an index into the `Spectra` passed with it.
    pub start: usize,
    /// Number of frames W.
    pub len: usize,
}

/// Check that a batch fits a plan: each job's spectra have the plan's mics and bins and
/// hold every frame of its windows, and the jobs agree on [`Spectra::phased`]. `who`
/// names the backend in the message.
pub fn check_jobs<T: Real>(who: &str, plan: &Plan<T>, jobs: &[Job<'_, T>]) -> Result<()> {
    check_phased(who, jobs)?;
    for j in jobs {
        if let Some(w) = j.windows.iter().find(|w| w.start < j.first) {
            return Err(crate::Error::Mismatch(format!(
                "{who}: window at frame {} starts before the first frame given ({})",
                w.start, j.first
            )));
        }
        let local: Vec<WindowSpec> = j
            .windows
            .iter()
            .map(|w| WindowSpec {
                start: w.start - j.first,
                ..*w
            })
            .collect();
        check_batch(who, plan, j.spectra, &local)?;
    }
    Ok(())
}

/// Every job of one call agrees on [`Spectra::phased`].
pub fn check_phased<T: Real>(who: &str, jobs: &[Job<'_, T>]) -> Result<()> {
    if jobs
        .windows(2)
        .any(|p| p[0].spectra.phased != p[1].spectra.phased)
    {
        return Err(crate::Error::Mismatch(format!(
            "{who}: one call mixes phase-transformed frames with plain ones"
        )));
    }
    Ok(())
}

/// Total number of windows of `jobs`.
pub fn count_windows<T: Real>(jobs: &[Job<'_, T>]) -> usize {
    jobs.iter().map(|j| j.windows.len()).sum()
}

/// Check that one spectra block fits a plan and holds every frame of `windows` (starts
/// are `spectra` frames). `who` names the backend in the message.
fn check_batch<T: Real>(
    who: &str,
    plan: &Plan<T>,
    spectra: &Spectra<T>,
    windows: &[WindowSpec],
) -> Result<()> {
    let (m, nb) = (plan.num_mics, plan.num_bins());
    if spectra.num_mics != m || spectra.num_bins != nb {
        return Err(crate::Error::Mismatch(format!(
            "{who}: spectra have {} mics × {} bins, plan expects {m} × {nb}",
            spectra.num_mics, spectra.num_bins
        )));
    }
    if spectra.data.len() < spectra.num_frames * nb * m {
        return Err(crate::Error::Mismatch(format!(
            "{who}: spectra hold {} values, {} frames × {nb} bins × {m} mics need {}",
            spectra.data.len(),
            spectra.num_frames,
            spectra.num_frames * nb * m
        )));
    }
    if let Some(w) = windows
        .iter()
        .find(|w| w.start + w.len > spectra.num_frames || w.len == 0)
    {
        return Err(crate::Error::Mismatch(format!(
            "{who}: window {}..{} outside the {} frames given",
            w.start,
            w.start + w.len,
            spectra.num_frames
        )));
    }
    Ok(())
}

/// Check that a replacement plan keeps the shapes a backend was built for (mics, bins,
/// directions): only its contents (K, weights) may change.
pub fn check_replacement_plan<T: Real>(who: &str, old: &Plan<T>, new: &Plan<T>) -> Result<()> {
    if new.num_mics != old.num_mics || new.num_bins() != old.num_bins() || new.num_dirs != old.num_dirs {
        return Err(crate::Error::Mismatch(format!(
            "{who}: a new plan must keep mics, bins and directions ({} × {} × {}, got {} × {} × {})",
            old.num_mics,
            old.num_bins(),
            old.num_dirs,
            new.num_mics,
            new.num_bins(),
            new.num_dirs
        )));
    }
    Ok(())
}

/// A local maximum of the broadband spectrum.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Peak {
    /// Grid index of the direction.
    pub dir: usize,
    /// 10·log10(P̄ + 1) in dB.
    pub power_db: f64,
}

/// What a batch produces.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BatchOutput {
    /// Peaks per window, strongest first, after the azimuth filter and the top-N cut.
    pub peaks: Vec<Vec<Peak>>,
    /// dB spectrum `[window][dir]`, filled only when asked for (else empty).
    pub spectrum_db: Vec<f32>,
    /// √(largest eigen/singular value) per window and used bin `[window][bin]` (the
    /// eigenvalue weight g_k), filled only with the spectrum.
    pub bin_weight: Vec<f32>,
    /// Estimated number of active sources per window ([`crate::subspace::count`]); empty
    /// when the backend does not estimate it.
    pub source_count: Vec<u32>,
}

/// Wall time spent per stage, in milliseconds, summed over calls since the last reset.
/// (The CPU backend runs the per-bin stages in one parallel pass and splits that pass's
/// wall time by the CPU time each stage took in it.)
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct StageTimes {
    /// Correlation matrices and scaling.
    pub correlation_ms: f64,
    /// Whitening and decomposition.
    pub decomposition_ms: f64,
    /// MUSIC spectrum, bin sum, dB.
    pub spectrum_ms: f64,
    /// Peak search and transfer of results.
    pub peaks_ms: f64,
}

/// A compute device that runs the numeric stages on batches of windows.
pub trait Backend<T: Real>: Send {
    /// Human-readable device description, e.g. `cpu (2 threads)` or `cuda:0 NVIDIA H200`.
    fn device_name(&self) -> String;
    /// Largest number of windows one `process` call accepts.
    fn max_windows_per_batch(&self) -> usize;
    /// Run correlation → decomposition → spectrum → peaks for every window of `jobs` (one
    /// job per stream; several streams sharing the plan go in one call). `out` is
    /// overwritten with one entry per window, jobs in order, windows in order. What a
    /// backend keeps of a stream between calls (frames on the device, a running
    /// correlation) changes where the work runs, never the results beyond rounding.
    fn process(&mut self, jobs: &[Job<'_, T>], want_spectrum: bool, out: &mut BatchOutput) -> Result<()>;
    /// Replace the plan (e.g. after the noise matrix K changed online); the shapes (mics,
    /// bins, directions) must be unchanged.
    fn set_plan(&mut self, plan: Arc<Plan<T>>) -> Result<()>;
    /// Stage times accumulated since the last `reset_stage_times`.
    fn stage_times(&self) -> StageTimes;
    /// Zero the stage times.
    fn reset_stage_times(&mut self);
    /// `stream` will not come again (it ended, was reset, or had a gap): drop what is kept
    /// for it. Nothing is kept by default.
    fn forget(&mut self, stream: StreamId) {
        let _ = stream;
    }
    /// Whether a stream's whole push should run on rayon's pool (one hand-off per push
    /// instead of one per parallel stage): true for a backend whose stages are rayon
    /// loops. Not for device backends: a push on the pool could then run inside another
    /// push's wait on the pool and change the thread's current device context.
    fn runs_on_pool(&self) -> bool {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every job of a call agrees on [`Spectra::phased`] (the GPU tells its correlation
    /// kernel once per call); a call that mixes them is refused, one that agrees runs.
    #[test]
    fn a_call_mixing_phased_and_plain_frames_is_refused() {
        use crate::bench::{inputs, BenchConfig};
        let cfg = BenchConfig {
            algorithm: crate::config::Algorithm::SrpPhat,
            num_mics: 8,
            num_dirs: 72,
            batch: 2,
            ..Default::default()
        };
        let inp = inputs::<f64>(&cfg).unwrap();
        let mut phased = inp.spectra.clone();
        phased.phased = true;
        let mut be = cpu::CpuBackend::new(inp.plan.clone());
        let mut out = BatchOutput::default();
        let (w0, w1) = (&inp.windows[..1], &inp.windows[1..]);
        let mixed = [Job::once(&inp.spectra, w0), Job::once(&phased, w1)];
        let e = be.process(&mixed, false, &mut out).unwrap_err().to_string();
        assert!(
            e.contains("mixes phase-transformed frames with plain ones"),
            "{e}"
        );
        let agreed = [Job::once(&phased, w0), Job::once(&phased, w1)];
        be.process(&agreed, false, &mut out).unwrap();
        assert_eq!(out.peaks.len(), 2);
    }
}
