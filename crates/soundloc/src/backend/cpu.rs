//! The CPU backend: rayon across (window, bin) pairs for the correlation and the
//! decompositions (which run in f64: [`crate::subspace`]), across bins for the spectrum
//! (faer products over fixed blocks of directions, every window of the batch through each
//! block) — never inside faer (`Par::Seq`), so small problems do not pay for nested
//! threading.
//!
//! Each batch runs the stages one after another, which keeps every core busy even for a
//! single window (73 bins) and gives exact stage times. The
//! correlation keeps each stream's running sums between calls
//! ([`crate::correlation::running`]): at PERIOD 1 a window costs two outer products per
//! bin instead of W.

use super::{Backend, BatchOutput, Job, StageTimes, StreamId};
use crate::correlation::running::{run_bin, RunningCorrelation, Step};
use crate::music::{
    accumulate_bin, bin_gain, normalize_bin, to_db, vectors_needed, SpectrumScratch, DIR_BLOCK,
};
use crate::peaks::find_peaks;
use crate::plan::Plan;
use crate::real::{Real, C};
use crate::srp::{self, SrpScratch};
use crate::subspace::tracking::{self, BinTrack, Tracker};
use crate::subspace::{count, decompose, decompose_many, Decomposition, Workspace};
use crate::Result;
use rayon::prelude::*;
use std::collections::HashMap;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Instant;

/// Bytes of running sums kept for streams between calls; the least recently used stream's
/// are dropped beyond it (it restarts with a direct sum).
const KEEP_BYTES: usize = 256 << 20;

/// Runs the pipeline's numeric stages on the CPU.
pub struct CpuBackend<T: Real> {
    plan: Arc<Plan<T>>,
    times: StageTimes,
    /// R of every window of a call in f64, `[bin][window][M×M]` (bins run in parallel).
    r: Vec<C<f64>>,
    decs: Vec<Decomposition<T>>,
    contrib: Vec<T>,
    /// Running sums per stream, with the call count of their last use.
    running: HashMap<StreamId, (RunningCorrelation, u64)>,
    /// Subspace-tracking state per kept stream, `[bin]` (the approximate mode only); dropped
    /// with the stream's running sums (which then restart exact).
    tracks: HashMap<StreamId, Vec<BinTrack>>,
    calls: u64,
    /// Scratch per pool thread, kept between calls (a small array's window costs tens of
    /// µs: building the scratch anew for each call weighed as much as a stage).
    scratch: Vec<Mutex<ThreadScratch<T>>>,
}

/// One pool thread's scratch, built on first use, dropped with a new plan.
struct ThreadScratch<T: Real> {
    decompose: Option<Workspace>,
    spectrum: Option<SpectrumScratch<T>>,
    srp: Option<SrpScratch<T>>,
}

/// The scratch of the pool thread running this (any slot outside the pool: the lock
/// keeps it safe). Work done while holding it must not enter rayon: a job stolen by the
/// same thread would wait on the lock (the stages' per-bin work runs faer with
/// `Par::Seq`).
fn thread_scratch<T: Real>(slots: &[Mutex<ThreadScratch<T>>]) -> MutexGuard<'_, ThreadScratch<T>> {
    let i = rayon::current_thread_index().unwrap_or(0) % slots.len();
    slots[i].lock().unwrap_or_else(|e| e.into_inner())
}

/// `n` empty slots.
fn scratch_slots<T: Real>(n: usize) -> Vec<Mutex<ThreadScratch<T>>> {
    (0..n.max(1))
        .map(|_| {
            Mutex::new(ThreadScratch {
                decompose: None,
                spectrum: None,
                srp: None,
            })
        })
        .collect()
}

impl<T: Real> CpuBackend<T> {
    /// A CPU backend for `plan`, using rayon's global pool.
    pub fn new(plan: Arc<Plan<T>>) -> Self {
        CpuBackend {
            plan,
            times: StageTimes::default(),
            r: Vec::new(),
            decs: Vec::new(),
            contrib: Vec::new(),
            running: HashMap::new(),
            tracks: HashMap::new(),
            calls: 0,
            scratch: scratch_slots(rayon::current_num_threads()),
        }
    }

    /// R of every window of `job` into `self.r` as windows `w0 …` of `nw` in all.
    fn correlate_job(&mut self, job: &Job<'_, T>, w0: usize, nw: usize, phat: bool) {
        let (m, nb) = (self.plan.num_mics, self.plan.num_bins());
        let mm = m * m;
        let mut rc = match self.running.remove(&job.stream) {
            Some((rc, _)) => rc,
            None => RunningCorrelation::new(m, nb),
        };
        let steps: Vec<Step> = job.windows.iter().map(|w| rc.step(w, job.first)).collect();
        let bins: Vec<&mut [C<f64>]> = rc.bins_mut().collect();
        bins.into_par_iter()
            .zip(self.r.par_chunks_mut(nw * mm))
            .enumerate()
            .for_each_init(Vec::new, |y, (b, (sum, rb))| {
                for (wi, (w, st)) in job.windows.iter().zip(&steps).enumerate() {
                    let o = (w0 + wi) * mm;
                    run_bin(sum, *st, job, w, b, phat, y, &mut rb[o..o + mm]);
                }
            });
        if job.stream.is_kept() {
            self.running.insert(job.stream, (rc, self.calls));
            // Drop the least recently used streams' sums beyond the budget.
            let per = self.running.values().next().map_or(0, |(rc, _)| rc.bytes());
            while self.running.len() * per > KEEP_BYTES {
                let Some(oldest) = self.running.iter().min_by_key(|(_, (_, t))| *t).map(|(k, _)| *k) else {
                    break;
                };
                self.running.remove(&oldest);
            }
            let running = &self.running;
            self.tracks.retain(|id, _| running.contains_key(id));
        }
    }

    /// The approximate mode's decompositions ([`tracking`]): each job's windows in order
    /// per bin, (job, bin) pairs in parallel, every stream's state carried between calls.
    fn track_jobs(&mut self, jobs: &[Job<'_, T>], nw: usize) -> Result<()> {
        let plan = &*self.plan;
        let (m, nb) = (plan.num_mics, plan.num_bins());
        let mm = m * m;
        let alg = plan.config.algorithm;
        let c = &plan.config;
        let refresh = c.window.div_ceil(c.period).max(1);
        let mut states: Vec<Vec<BinTrack>> = jobs
            .iter()
            .map(|j| {
                let kept = j
                    .stream
                    .is_kept()
                    .then(|| self.tracks.remove(&j.stream))
                    .flatten();
                kept.unwrap_or_else(|| vec![BinTrack::default(); nb])
            })
            .collect();
        // (job, bin) → that bin's decompositions of the job's windows, in window order.
        let mut job_of = Vec::with_capacity(nw);
        let mut first_window = Vec::with_capacity(jobs.len());
        for (j, job) in jobs.iter().enumerate() {
            first_window.push(job_of.len());
            job_of.extend(std::iter::repeat_n(j, job.windows.len()));
        }
        let mut tasks: Vec<Vec<&mut Decomposition<T>>> = (0..jobs.len() * nb).map(|_| Vec::new()).collect();
        for (i, dec) in self.decs.iter_mut().enumerate() {
            tasks[job_of[i / nb] * nb + i % nb].push(dec);
        }
        let bins: Vec<&mut BinTrack> = states.iter_mut().flat_map(|s| s.iter_mut()).collect();
        let r = &self.r;
        tasks.into_par_iter().zip(bins).enumerate().try_for_each_init(
            || (Workspace::new(m), Tracker::new(m)),
            |(ws, tr), (t, (decs, state))| -> Result<()> {
                let (j, b) = (t / nb, t % nb);
                let job = &jobs[j];
                for (wi, dec) in decs.into_iter().enumerate() {
                    let w = &job.windows[wi];
                    let g = first_window[j] + wi;
                    // Frames that entered and left since the previous window (PERIOD of
                    // each, at most CHANGED_FRAMES). The engine keeps the frames that left
                    // only while 2·PERIOD < W: decided from the config alone, so the search
                    // space never depends on how the input was cut (the clip at `first`
                    // matters only at a stream's start, which is decomposed exactly).
                    let n = c.period.min(w.len).min(tracking::CHANGED_FRAMES);
                    let n_left = if 2 * c.period < c.window { n } else { 0 };
                    let end = w.start + w.len;
                    let left = w.start.saturating_sub(n_left).max(job.first)..w.start;
                    let changed: Vec<&[C<T>]> = (end - n..end)
                        .chain(left)
                        .map(|f| job.spectra.frame_bin(job.local(f), b))
                        .collect();
                    let win = tracking::Window {
                        algorithm: alg,
                        r: r_at(r, mm, nw, g, b),
                        w: plan.whitening_matrix64(b),
                        changed: &changed,
                        refresh,
                    };
                    tracking::decompose_tracked(&win, state, ws, tr, dec)?;
                }
                Ok(())
            },
        )?;
        for (job, st) in jobs.iter().zip(states) {
            if job.stream.is_kept() && self.running.contains_key(&job.stream) {
                self.tracks.insert(job.stream, st);
            }
        }
        Ok(())
    }
}

/// R of window `w`, bin `b` in the backend's `[bin][window][M×M]` layout of `nw` windows.
fn r_at(r: &[C<f64>], mm: usize, nw: usize, w: usize, b: usize) -> &[C<f64>] {
    &r[(b * nw + w) * mm..(b * nw + w + 1) * mm]
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

impl<T: Real> Backend<T> for CpuBackend<T> {
    fn device_name(&self) -> String {
        format!("cpu ({} threads, {})", rayon::current_num_threads(), T::NAME)
    }

    fn max_windows_per_batch(&self) -> usize {
        16
    }

    fn process(&mut self, jobs: &[Job<'_, T>], want_spectrum: bool, out: &mut BatchOutput) -> Result<()> {
        // The whole call on a pool thread: its parallel stages then start from inside the
        // pool, and the caller blocks once per call instead of once per stage (what a
        // PERIOD-1 stream of a small array pays most for).
        rayon::scope(|_| self.process_on_pool(jobs, want_spectrum, out))
    }

    fn set_plan(&mut self, plan: Arc<Plan<T>>) -> Result<()> {
        super::check_replacement_plan("cpu backend", &self.plan, &plan)?;
        self.plan = plan;
        // New whitening: the tracked blocks restart from exact decompositions.
        self.tracks.clear();
        self.scratch = scratch_slots(rayon::current_num_threads());
        Ok(())
    }

    fn stage_times(&self) -> StageTimes {
        self.times
    }

    fn reset_stage_times(&mut self) {
        self.times = StageTimes::default();
    }

    fn forget(&mut self, stream: StreamId) {
        self.running.remove(&stream);
        self.tracks.remove(&stream);
    }

    fn runs_on_pool(&self) -> bool {
        true
    }
}

impl<T: Real> CpuBackend<T> {
    /// [`Backend::process`], run on a rayon thread.
    fn process_on_pool(
        &mut self,
        jobs: &[Job<'_, T>],
        want_spectrum: bool,
        out: &mut BatchOutput,
    ) -> Result<()> {
        super::check_jobs("cpu backend", &self.plan, jobs)?;
        self.calls += 1;
        // One slot per thread of the pool this call runs in (it may be larger than the
        // one the backend was built in).
        let threads = rayon::current_num_threads();
        if self.scratch.len() < threads {
            let more = threads - self.scratch.len();
            self.scratch.extend(scratch_slots(more));
        }
        let plan = self.plan.clone();
        let plan = &*plan;
        let (m, nb, d) = (plan.num_mics, plan.num_bins(), plan.num_dirs);
        let nw = super::count_windows(jobs);
        let lens: Vec<usize> = jobs
            .iter()
            .flat_map(|j| j.windows.iter().map(|w| w.len))
            .collect();
        let mm = m * m;
        let alg = plan.config.algorithm;
        let srp = !alg.is_music();
        // 1. Correlation matrices, [window][bin] (phase-transformed for SRP-PHAT), from
        // each stream's running sums.
        let t = Instant::now();
        self.r.resize(nw * nb * mm, C::new(0.0, 0.0));
        let mut w0 = 0;
        for job in jobs {
            self.correlate_job(job, w0, nw, srp);
            w0 += job.windows.len();
        }
        self.times.correlation_ms += ms(t);

        // 2. Decompositions, [window][bin] (none for SRP-PHAT): the leading vectors the
        // spectrum needs, in f64.
        let t = Instant::now();
        if srp {
            self.decs.clear();
        } else {
            let k = vectors_needed(plan);
            if self.decs.first().is_some_and(|d| d.dim != k) {
                self.decs.clear();
            }
            self.decs.resize_with(nw * nb, || Decomposition::new(m, k));
        }
        if !srp && plan.config.subspace_tracking {
            self.track_jobs(jobs, nw)?;
        }
        let r = &self.r;
        let r_of = |w: usize, b: usize| r_at(r, mm, nw, w, b);
        if !srp && !plan.config.subspace_tracking {
            // In pairs: two problems' eigenvalue iterations run side by side (same
            // results as one at a time).
            let w_of = |i: usize| plan.whitening_matrix64(i % nb);
            let slots = &self.scratch;
            self.decs
                .par_chunks_mut(2)
                .enumerate()
                .try_for_each(|(c, pair)| {
                    let mut slot = thread_scratch(slots);
                    let ws = slot.decompose.get_or_insert_with(|| Workspace::new(m));
                    let (i0, i1) = (2 * c, 2 * c + 1);
                    let r = |i: usize| r_of(i / nb, i % nb);
                    match pair {
                        [d0, d1] => decompose_many(alg, [r(i0), r(i1)], [w_of(i0), w_of(i1)], ws, [d0, d1]),
                        [d0] => decompose(alg, r(i0), w_of(i0), ws, d0),
                        _ => Ok(()),
                    }
                })?;
        }
        self.times.decomposition_ms += ms(t);

        // 3. Broadband spectrum per window: Σ_k w_k g_k P_k(d), then dB. Per-bin
        // contributions `[bin][window][dir]` with the bins in parallel; within a bin the
        // directions run in fixed blocks and every window passes through each block (its
        // steering vectors stay in cache). The sum over bins runs in bin order: the result
        // depends neither on how rayon splits the work nor on the batch (bit-reproducible).
        let t = Instant::now();
        let decs = &self.decs;
        self.contrib.clear();
        self.contrib.resize(nw * nb * d, T::zero());
        let normalize = plan.config.normalize_bins;
        let blocks = || {
            (0..d)
                .step_by(DIR_BLOCK)
                .map(move |d0| d0..(d0 + DIR_BLOCK).min(d))
        };
        let slots = &self.scratch;
        self.contrib
            .par_chunks_mut(nw * d)
            .enumerate()
            .for_each(|(b, cb)| {
                let mut slot = thread_scratch(slots);
                if srp {
                    let sc = slot.srp.get_or_insert_with(|| SrpScratch::new(plan));
                    for (w, acc) in cb.chunks_mut(d).enumerate() {
                        srp::accumulate_bin(plan, b, r_of(w, b), sc, acc);
                    }
                    return;
                }
                let sc = slot.spectrum.get_or_insert_with(|| SpectrumScratch::new(plan));
                let bin_decs: Vec<&Decomposition<T>> = (0..nw).map(|w| &decs[w * nb + b]).collect();
                for dirs in blocks() {
                    let mut accs: Vec<&mut [T]> =
                        cb.chunks_mut(d).map(|acc| &mut acc[dirs.clone()]).collect();
                    accumulate_bin(plan, b, dirs.clone(), &bin_decs, sc, &mut accs);
                }
            });
        if normalize {
            self.contrib.par_chunks_mut(d).enumerate().for_each(|(i, acc)| {
                normalize_bin(acc, plan.weights[i / nw]);
            });
        }
        let contrib = &self.contrib;
        let spectra_lin: Vec<Vec<T>> = (0..nw)
            .into_par_iter()
            .map(|w| {
                let mut acc = vec![T::zero(); d];
                for b in 0..nb {
                    for (x, y) in acc
                        .iter_mut()
                        .zip(&contrib[(b * nw + w) * d..(b * nw + w + 1) * d])
                    {
                        *x += *y;
                    }
                }
                acc
            })
            .collect();
        let db: Vec<Vec<f64>> = spectra_lin
            .par_iter()
            .map(|p| p.iter().map(|&v| to_db(v)).collect())
            .collect();
        self.times.spectrum_ms += ms(t);

        // 4. Peaks, and the number of active sources (MDL per bin, median over bins).
        let t = Instant::now();
        out.source_count.clear();
        // (The approximate mode keeps only the tracked values: no count.)
        if !srp && !plan.config.subspace_tracking {
            // Overlapping frames are not independent snapshots: N = W·hop/N_fft of them.
            // k̂ per (window, bin) in parallel (a few µs each, ≈ 10³ per batch), then the
            // median per window over the bins that carry weight.
            let c = &plan.config;
            let overlap = c.hop.min(c.nfft) as f64 / c.nfft as f64;
            let snapshots = |w: usize| ((lens[w] as f64 * overlap).round() as usize).max(1);
            let per_bin: Vec<usize> = (0..nw * nb)
                .into_par_iter()
                .map(|i| {
                    if plan.weights[i % nb] == T::zero() {
                        0 // not used: the median skips bins without weight
                    } else {
                        count::mdl(&decs[i].values, snapshots(i / nb))
                    }
                })
                .collect();
            for w in 0..nw {
                let used = (0..nb)
                    .filter(|&b| plan.weights[b] != T::zero())
                    .map(|b| per_bin[w * nb + b]);
                out.source_count.push(count::median(used.collect()) as u32);
            }
        }
        out.peaks = db.par_iter().map(|s| find_peaks(s, &plan.peak_table)).collect();
        out.spectrum_db.clear();
        out.bin_weight.clear();
        if want_spectrum {
            for s in &db {
                out.spectrum_db.extend(s.iter().map(|&v| v as f32));
            }
            if srp {
                out.bin_weight.resize(nw * nb, 1.0);
            } else {
                for dec in decs.iter().take(nw * nb) {
                    out.bin_weight.push(bin_gain(plan, dec).to_f64() as f32);
                }
            }
        }
        self.times.peaks_ms += ms(t);
        Ok(())
    }
}
