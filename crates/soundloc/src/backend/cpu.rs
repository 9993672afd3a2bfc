//! The CPU backend: one rayon pass over groups of used bins runs the per-bin stages back
//! to back — the correlation (each stream's running sums between calls,
//! [`crate::correlation::running`]: at PERIOD 1 a window costs two outer products per bin
//! instead of W), the decompositions (in f64, [`crate::subspace::decompose_group`]: eight
//! problems at once in vector lanes), the spectrum's contributions (fixed blocks of directions, every window of
//! the batch through each block; [`crate::lanes`] for arrays up to 16 mics, faer products
//! above) and the source count — then one pass over the windows sums the bins, converts to
//! dB and finds the peaks. Never parallel inside faer (`Par::Seq`), so small problems do
//! not pay for nested threading; a small array's window costs tens of µs, about what each
//! hand-off between the pool's threads costs, hence one pass.
//!
//! Parallelism is per group of bins that fills the eigensolvers' eight lanes for MUSIC
//! (one bin per task from eight windows on, eight bins for a lone window;
//! [`bins_per_task`]), otherwise (SRP-PHAT, the approximate mode) per pair of bins while
//! that gives four or more tasks per thread, per bin on larger pools. Where the tasks are
//! still few for the pool (about eight parts per thread), each task's decompositions run
//! in parts of windows that still fill a lane group ([`pass`]), and its spectrum bin by
//! bin in parallel (a lone window's call). Results are the same bits for any pool size
//! (`music::tests`).

mod linger;
mod pass;

use super::{Backend, BatchOutput, Job, StageTimes, StreamId};
use crate::correlation::running::{RunningCorrelation, Step};
use crate::music::{bin_gain, to_db, vectors_needed, SpectrumScratch};
use crate::peaks::find_peaks;
use crate::plan::Plan;
use crate::real::{Real, C};
use crate::srp::SrpScratch;
use crate::subspace::tracking::{BinTrack, Tracker};
use crate::subspace::{count, Decomposition, Workspace};
use crate::Result;
use pass::{BinTask, Ctx, StageNanos};
use rayon::prelude::*;
use std::collections::HashMap;
use std::sync::atomic::Ordering;
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
    /// When the last call ended ([`linger`]).
    pass_end: Option<Instant>,
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
            pass_end: None,
            scratch: scratch_slots(rayon::current_num_threads()),
        }
    }
}

/// Used bins per task. The exact decompositions run eight problems at once in vector
/// lanes ([`crate::subspace::decompose_group`]), and a group costs the same however few of
/// its lanes are used: a task holds enough bins for full groups when the call has few
/// windows (eight bins for one window), whatever the pool — on 16 threads, ten full
/// groups beat 37 quarter-full ones (8-mic ring, 2026-11-27). Otherwise (SRP-PHAT, the
/// approximate mode) pairs of bins while they keep the pool busy (four or more per
/// thread), single bins on larger pools, where twice the tasks for the correlation and
/// the spectrum are worth more.
fn bins_per_task<T: Real>(plan: &Plan<T>, nb: usize, nw: usize, threads: usize) -> usize {
    if lane_groups(plan) {
        LANES.div_ceil(nw.max(1))
    } else if nb.div_ceil(2) >= 4 * threads {
        2
    } else {
        1
    }
}

/// Whether the call's decompositions run in lane groups ([`LANES`] problems at once,
/// [`crate::subspace::decompose_group`]): the exact MUSIC path, any array.
fn lane_groups<T: Real>(plan: &Plan<T>) -> bool {
    plan.config.algorithm.is_music() && !plan.config.subspace_tracking
}

/// Problems per lane group (both lane solvers).
const LANES: usize = crate::subspace::tridiag_lanes::LANES;
const _: () = assert!(LANES == crate::subspace::eigh_lanes::LANES);

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
    ///
    /// One parallel pass over groups of bins runs the per-bin stages back to back —
    /// correlation (each stream's running sums), decomposition (exact, in groups:
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
        // The approximate mode's states, per stream (kept or fresh).
        let mut states: Vec<Vec<BinTrack>> = streams
            .iter()
            .map(|&id| {
                let kept = (tracking && id.is_kept())
                    .then(|| self.tracks.remove(&id))
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

        // The tasks.
        let per_task = bins_per_task(plan, nb, nw, threads);
        let mut decs = self.decs.chunks_mut(per_task * nw);
        let mut tracks = tracks_by_bin.chunks_mut(per_task);
        let tasks: Vec<BinTask<'_, T>> = sums_by_bin
            .chunks_mut(per_task)
            .zip(self.r.chunks_mut(per_task * nw * mm))
            .zip(self.contrib.chunks_mut(per_task * nw * d))
            .zip(counts.chunks_mut(per_task * nw))
            .enumerate()
            .map(|(i, (((sums, r), contrib), counts))| BinTask {
                b0: per_task * i,
                sums,
                r,
                decs: decs.next().unwrap_or_default(),
                contrib,
                counts,
                tracks: tracks.next().unwrap_or_default(),
            })
            .collect();
        let ntasks = tasks.len();
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
            // Decompositions in parts of windows when the call's tasks are few for the
            // pool: about eight parts per thread (one part, all windows, on small pools),
            // each with enough problems to fill a lane group.
            part_windows: nw
                .div_ceil((8 * threads).div_ceil(ntasks).max(1))
                .max(if lane_groups(plan) {
                    LANES.div_ceil(per_task)
                } else {
                    1
                }),
            spread_bins: ntasks < 8 * threads,
        };
        linger::pass_starts();
        tasks
            .into_par_iter()
            .try_for_each(|task| ctx.run(task, slots, &nanos))?;
        let pass_ms = ms(t_pass);
        let linger_after = linger::wanted(self.pass_end, t_pass);
        let cpu: Vec<f64> = nanos.0.iter().map(|n| n.load(Ordering::Relaxed) as f64).collect();
        let total: f64 = cpu.iter().sum::<f64>().max(1.0);
        self.times.correlation_ms += pass_ms * cpu[0] / total;
        self.times.decomposition_ms += pass_ms * cpu[1] / total;
        self.times.spectrum_ms += pass_ms * cpu[2] / total;
        self.times.peaks_ms += pass_ms * cpu[3] / total;

        // Keep the streams' running sums and tracking states; drop the least recently
        // used streams' sums beyond the budget.
        for (&id, rc) in streams.iter().zip(rcs) {
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
            for (&id, st) in streams.iter().zip(states) {
                if id.is_kept() && self.running.contains_key(&id) {
                    self.tracks.insert(id, st);
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
        // weight; where estimated: `LocalizeConfig::counts_sources`).
        let t = Instant::now();
        out.source_count.clear();
        if c.counts_sources() {
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
        // Helpers stay awake for the next call when calls come close together.
        if linger_after {
            linger::keep_awake(threads.min(ntasks).saturating_sub(1));
        }
        self.pass_end = Some(Instant::now());
        Ok(())
    }
}
