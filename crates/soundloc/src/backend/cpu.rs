//! The CPU backend: one rayon pass over pairs of used bins runs the per-bin stages back to
//! back — the correlation (each stream's running sums between calls,
//! [`crate::correlation::running`]: at PERIOD 1 a window costs two outer products per bin
//! instead of W), the decompositions (in f64, [`crate::subspace`]; the pair's two problems
//! side by side), the spectrum's contributions (fixed blocks of directions, every window of
//! the batch through each block; [`crate::lanes`] for arrays up to 16 mics, faer products
//! above) and the source count — then one pass over the windows sums the bins, converts to
//! dB and finds the peaks. Never parallel inside faer (`Par::Seq`), so small problems do
//! not pay for nested threading; a small array's window costs tens of µs, about what each
//! hand-off between the pool's threads costs, hence one pass.
//!
//! Parallelism is per pair of bins (37 tasks at the 73 bins of HARK's defaults), each task
//! running every window of the batch: enough for a few dozen cores; more cores than that
//! (or very narrow bands) would need the tasks split by windows as well.

use super::{Backend, BatchOutput, Job, StageTimes, StreamId, WindowSpec};
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
use std::sync::atomic::{AtomicU64, Ordering};
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
    /// Frames gathered for the correlation.
    y: Vec<C<f64>>,
    decompose: Option<Workspace>,
    tracker: Option<Tracker>,
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
                y: Vec::new(),
                decompose: None,
                tracker: None,
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

/// One task of a call: a pair of used bins (the last may be one), with every window of
/// every job at those bins.
struct BinTask<'a, T: Real> {
    /// The first bin.
    b0: usize,
    /// Per bin of the task, per stream of the call: the running sums.
    sums: &'a mut [Vec<&'a mut [C<f64>]>],
    /// R, `[bin][window][M×M]` (the task's bins).
    r: &'a mut [C<f64>],
    /// Decompositions, `[bin][window]` (empty for SRP-PHAT).
    decs: &'a mut [Decomposition<T>],
    /// w_k g_k P_k(d), `[bin][window][dir]`.
    contrib: &'a mut [T],
    /// Source count per bin and window, `[bin][window]`.
    counts: &'a mut [usize],
    /// The approximate mode: per bin, per job, the tracking state.
    tracks: &'a mut [Vec<&'a mut BinTrack>],
}

/// CPU time per stage summed over a call's tasks, ns.
#[derive(Default)]
struct StageNanos([AtomicU64; 4]);

impl StageNanos {
    fn add(&self, stage: usize, t: Instant) -> Instant {
        let now = Instant::now();
        self.0[stage].fetch_add((now - t).as_nanos() as u64, Ordering::Relaxed);
        now
    }
}

impl<T: Real> CpuBackend<T> {
    /// [`Backend::process`], run on a rayon thread.
    ///
    /// One parallel pass over pairs of bins runs the per-bin stages back to back —
    /// correlation (each stream's running sums), decomposition (exact, the pair's two
    /// problems side by side, or tracked), the spectrum's contributions and the source
    /// count — then one pass over the windows sums the bins (in bin order: the result
    /// depends neither on how rayon splits the work nor on the batch), converts to dB and
    /// finds the peaks. A small array's window is tens of µs of work, about what each
    /// extra hand-off between the pool's threads costs. The stage times split the
    /// pass's wall time by the CPU time each stage took in it.
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
        let mm = m * m;
        let c = &plan.config;
        let alg = c.algorithm;
        let srp = !alg.is_music();
        let tracking = !srp && c.subspace_tracking;
        if nw == 0 {
            out.source_count.clear();
            out.peaks.clear();
            out.spectrum_db.clear();
            out.bin_weight.clear();
            return Ok(());
        }
        let t_pass = Instant::now();

        // Each stream's running sums (jobs of one stream share them, in job order) and
        // the step that carries them to each window.
        let mut streams: Vec<StreamId> = Vec::new();
        let mut rcs: Vec<RunningCorrelation> = Vec::new();
        let mut rc_of = Vec::with_capacity(jobs.len());
        for job in jobs {
            let i = match streams.iter().position(|&s| s == job.stream && s.is_kept()) {
                Some(i) => i,
                None => {
                    streams.push(job.stream);
                    rcs.push(match self.running.remove(&job.stream) {
                        Some((rc, _)) => rc,
                        None => RunningCorrelation::new(m, nb),
                    });
                    rcs.len() - 1
                }
            };
            rc_of.push(i);
        }
        let steps: Vec<Vec<Step>> = jobs
            .iter()
            .zip(&rc_of)
            .map(|(job, &i)| job.windows.iter().map(|w| rcs[i].step(w, job.first)).collect())
            .collect();
        // The approximate mode's states, per job (kept or fresh).
        let mut states: Vec<Vec<BinTrack>> = jobs
            .iter()
            .map(|j| {
                let kept = (tracking && j.stream.is_kept())
                    .then(|| self.tracks.remove(&j.stream))
                    .flatten();
                kept.unwrap_or_else(|| {
                    if tracking {
                        vec![BinTrack::default(); nb]
                    } else {
                        Vec::new()
                    }
                })
            })
            .collect();
        let mut sums_by_bin: Vec<Vec<&mut [C<f64>]>> = (0..nb).map(|_| Vec::new()).collect();
        for rc in rcs.iter_mut() {
            for (b, sum) in rc.bins_mut().enumerate() {
                sums_by_bin[b].push(sum);
            }
        }
        let mut tracks_by_bin: Vec<Vec<&mut BinTrack>> = (0..nb).map(|_| Vec::new()).collect();
        for st in states.iter_mut() {
            for (b, t) in st.iter_mut().enumerate() {
                tracks_by_bin[b].push(t);
            }
        }
        self.r.resize(nw * nb * mm, C::new(0.0, 0.0));
        if srp {
            self.decs.clear();
        } else {
            let k = vectors_needed(plan);
            if self.decs.first().is_some_and(|d| d.dim != k) {
                self.decs.clear();
            }
            self.decs.resize_with(nw * nb, || Decomposition::new(m, k));
        }
        self.contrib.clear();
        self.contrib.resize(nw * nb * d, T::zero());
        let mut counts = vec![0usize; nw * nb];

        // The tasks: pairs of bins.
        const PAIR: usize = 2;
        let mut decs = self.decs.chunks_mut(PAIR * nw);
        let mut tracks = tracks_by_bin.chunks_mut(PAIR);
        let tasks: Vec<BinTask<'_, T>> = sums_by_bin
            .chunks_mut(PAIR)
            .zip(self.r.chunks_mut(PAIR * nw * mm))
            .zip(self.contrib.chunks_mut(PAIR * nw * d))
            .zip(counts.chunks_mut(PAIR * nw))
            .enumerate()
            .map(|(i, (((sums, r), contrib), counts))| BinTask {
                b0: PAIR * i,
                sums,
                r,
                decs: decs.next().unwrap_or_default(),
                contrib,
                counts,
                tracks: tracks.next().unwrap_or_default(),
            })
            .collect();
        let nanos = StageNanos::default();
        let slots = &self.scratch;
        let lens: Vec<usize> = jobs
            .iter()
            .flat_map(|j| j.windows.iter().map(|w| w.len))
            .collect();
        let ctx = Ctx {
            plan,
            jobs,
            steps: &steps,
            rc_of: &rc_of,
            lens: &lens,
            nw,
        };
        tasks.into_par_iter().try_for_each(|task| -> Result<()> {
            let mut slot = thread_scratch(slots);
            ctx.run(task, &mut slot, &nanos)
        })?;
        let pass_ms = ms(t_pass);
        let cpu: Vec<f64> = nanos.0.iter().map(|n| n.load(Ordering::Relaxed) as f64).collect();
        let total: f64 = cpu.iter().sum::<f64>().max(1.0);
        self.times.correlation_ms += pass_ms * cpu[0] / total;
        self.times.decomposition_ms += pass_ms * cpu[1] / total;
        self.times.spectrum_ms += pass_ms * cpu[2] / total;
        self.times.peaks_ms += pass_ms * cpu[3] / total;

        // Keep the streams' running sums and tracking states; drop the least recently
        // used streams' sums beyond the budget.
        for (id, rc) in streams.into_iter().zip(rcs) {
            if id.is_kept() {
                self.running.insert(id, (rc, self.calls));
            }
        }
        let per = self.running.values().next().map_or(0, |(rc, _)| rc.bytes());
        while self.running.len() * per > KEEP_BYTES {
            let Some(oldest) = self.running.iter().min_by_key(|(_, (_, t))| *t).map(|(k, _)| *k) else {
                break;
            };
            self.running.remove(&oldest);
        }
        if tracking {
            for (job, st) in jobs.iter().zip(states) {
                if job.stream.is_kept() && self.running.contains_key(&job.stream) {
                    self.tracks.insert(job.stream, st);
                }
            }
        }
        let running = &self.running;
        self.tracks.retain(|id, _| running.contains_key(id));

        // Per window: Σ_k over the bins in bin order, dB.
        let t = Instant::now();
        let contrib = &self.contrib;
        let db: Vec<Vec<f64>> = (0..nw)
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
                acc.iter().map(|&v| to_db(v)).collect()
            })
            .collect();
        self.times.spectrum_ms += ms(t);

        // Peaks, and the number of active sources (median over the bins that carry
        // weight; none in the approximate mode, which keeps only the tracked values).
        let t = Instant::now();
        out.source_count.clear();
        if !srp && !tracking {
            for w in 0..nw {
                let used = (0..nb)
                    .filter(|&b| plan.weights[b] != T::zero())
                    .map(|b| counts[b * nw + w]);
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
                for w in 0..nw {
                    for b in 0..nb {
                        out.bin_weight
                            .push(bin_gain(plan, &self.decs[b * nw + w]).to_f64() as f32);
                    }
                }
            }
        }
        self.times.peaks_ms += ms(t);
        Ok(())
    }
}

/// What every task of a call reads.
struct Ctx<'a, 'j, T: Real> {
    plan: &'a Plan<T>,
    jobs: &'a [Job<'j, T>],
    /// Per job, per window: the running sums' step.
    steps: &'a [Vec<Step>],
    /// Per job: its stream's index among the task's sums.
    rc_of: &'a [usize],
    /// Per window of the call: its length in frames.
    lens: &'a [usize],
    nw: usize,
}

impl<T: Real> Ctx<'_, '_, T> {
    /// Run one task's stages: correlation, decomposition, spectrum, source count.
    fn run(&self, task: BinTask<'_, T>, slot: &mut ThreadScratch<T>, nanos: &StageNanos) -> Result<()> {
        let plan = self.plan;
        let (m, nb, d, nw) = (plan.num_mics, plan.num_bins(), plan.num_dirs, self.nw);
        let mm = m * m;
        let c = &plan.config;
        let alg = c.algorithm;
        let srp = !alg.is_music();
        let bins = task.b0..(task.b0 + task.sums.len()).min(nb);
        let mut t = Instant::now();

        // 1. R of every window at the task's bins (phase-transformed for SRP-PHAT).
        let y = &mut slot.y;
        for (i, b) in bins.clone().enumerate() {
            let mut wi = 0;
            for (j, job) in self.jobs.iter().enumerate() {
                let sum = &mut *task.sums[i][self.rc_of[j]];
                for (w, st) in job.windows.iter().zip(&self.steps[j]) {
                    let o = (i * nw + wi) * mm;
                    run_bin(sum, *st, job, w, b, srp, y, &mut task.r[o..o + mm]);
                    wi += 1;
                }
            }
        }
        t = nanos.add(0, t);

        // 2. Decompositions (none for SRP-PHAT): the leading vectors the spectrum needs.
        let r = &*task.r;
        let r_of = |i: usize, w: usize| &r[(i * nw + w) * mm..(i * nw + w + 1) * mm];
        if !srp {
            let ws = slot.decompose.get_or_insert_with(|| Workspace::new(m));
            if c.subspace_tracking {
                let tr = slot.tracker.get_or_insert_with(|| Tracker::new(m));
                let refresh = c.window.div_ceil(c.period).max(1);
                for (i, b) in bins.clone().enumerate() {
                    let mut wi = 0;
                    for (j, job) in self.jobs.iter().enumerate() {
                        for w in job.windows {
                            let changed = changed_frames(c, job, w, b);
                            let win = tracking::Window {
                                algorithm: alg,
                                r: r_of(i, wi),
                                w: plan.whitening_matrix64(b),
                                changed: &changed,
                                refresh,
                            };
                            let dec = &mut task.decs[i * nw + wi];
                            tracking::decompose_tracked(&win, &mut *task.tracks[i][j], ws, tr, dec)?;
                            wi += 1;
                        }
                    }
                }
            } else {
                // The pair's two bins side by side (same results as one at a time).
                let wm = |b: usize| plan.whitening_matrix64(b);
                let (d0, d1) = task.decs.split_at_mut(nw.min(task.decs.len()));
                for (w, e0) in d0.iter_mut().enumerate() {
                    match d1.get_mut(w) {
                        Some(e1) => decompose_many(
                            alg,
                            [r_of(0, w), r_of(1, w)],
                            [wm(bins.start), wm(bins.start + 1)],
                            ws,
                            [e0, e1],
                        )?,
                        None => decompose(alg, r_of(0, w), wm(bins.start), ws, e0)?,
                    }
                }
            }
        }
        t = nanos.add(1, t);

        // 3. w_k g_k P_k(d) per window; within a bin the directions run in fixed blocks
        // and every window passes through each block (its steering stays in cache).
        for (i, b) in bins.clone().enumerate() {
            let cb = &mut task.contrib[i * nw * d..(i + 1) * nw * d];
            if srp {
                let sc = slot.srp.get_or_insert_with(|| SrpScratch::new(plan));
                for (w, acc) in cb.chunks_mut(d).enumerate() {
                    srp::accumulate_bin(plan, b, r_of(i, w), sc, acc);
                }
            } else {
                let sc = slot.spectrum.get_or_insert_with(|| SpectrumScratch::new(plan));
                let bin_decs: Vec<&Decomposition<T>> = task.decs[i * nw..(i + 1) * nw].iter().collect();
                for d0 in (0..d).step_by(DIR_BLOCK) {
                    let dirs = d0..(d0 + DIR_BLOCK).min(d);
                    let mut accs: Vec<&mut [T]> =
                        cb.chunks_mut(d).map(|acc| &mut acc[dirs.clone()]).collect();
                    accumulate_bin(plan, b, dirs, &bin_decs, sc, &mut accs);
                }
            }
            if c.normalize_bins {
                for acc in cb.chunks_mut(d) {
                    normalize_bin(acc, plan.weights[b]);
                }
            }
        }
        t = nanos.add(2, t);

        // 4. k̂ per window and bin (MDL; overlapping frames are not independent
        // snapshots: N = W·hop/N_fft of them).
        if !srp && !c.subspace_tracking {
            let overlap = c.hop.min(c.nfft) as f64 / c.nfft as f64;
            for (i, b) in bins.enumerate() {
                if plan.weights[b] == T::zero() {
                    continue; // not used: the median skips bins without weight
                }
                for w in 0..nw {
                    let snapshots = ((self.lens[w] as f64 * overlap).round() as usize).max(1);
                    task.counts[i * nw + w] = count::mdl(&task.decs[i * nw + w].values, snapshots);
                }
            }
        }
        nanos.add(3, t);
        Ok(())
    }
}

/// The frames at bin `b` that entered and left since the stream's previous window (PERIOD
/// of each, at most [`tracking::CHANGED_FRAMES`]). The engine keeps the frames that left
/// only while 2·PERIOD < W: decided from the config alone, so the search space never
/// depends on how the input was cut (the clip at `first` matters only at a stream's start,
/// which is decomposed exactly).
fn changed_frames<'a, T: Real>(
    c: &crate::config::LocalizeConfig,
    job: &'a Job<'_, T>,
    w: &WindowSpec,
    b: usize,
) -> Vec<&'a [C<T>]> {
    let n = c.period.min(w.len).min(tracking::CHANGED_FRAMES);
    let n_left = if 2 * c.period < c.window { n } else { 0 };
    let end = w.start + w.len;
    let left = w.start.saturating_sub(n_left).max(job.first)..w.start;
    (end - n..end)
        .chain(left)
        .map(|f| job.spectra.frame_bin(job.local(f), b))
        .collect()
}
