//! One task of the CPU backend's pass ([`super::CpuBackend`]): a few used bins
//! ([`super::bins_per_task`]), every window of the call — the correlation, the decompositions (in parts of windows where the
//! pool has more threads than the call has tasks), then the spectrum contributions and
//! source counts.

use super::{thread_scratch, ThreadScratch};
use crate::backend::{Job, WindowSpec};
use crate::correlation::normalize_coherence;
use crate::correlation::running::{run_bin, Step};
use crate::music::{accumulate_bin, dir_block, normalize_bin, SpectrumScratch};
use crate::plan::Plan;
use crate::real::{Real, C};
use crate::srp::{self, SrpScratch};
use crate::subspace::tracking::{self, BinTrack, Tracker};
use crate::subspace::{count, decompose_group, Decomposition, Item, Workspace};
use crate::Result;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::Instant;

/// One task of a call: a few consecutive used bins, with every window of every job at
/// those bins.
pub(super) struct BinTask<'a, T: Real> {
    /// The first bin.
    pub(super) b0: usize,
    /// Per bin of the task, per stream of the call: the running sums.
    pub(super) sums: &'a mut [Vec<&'a mut [C<f64>]>],
    /// R, `[bin][window][M×M]` (the task's bins).
    pub(super) r: &'a mut [C<f64>],
    /// Decompositions, `[bin][window]` (empty for SRP-PHAT).
    pub(super) decs: &'a mut [Decomposition<T>],
    /// w_k g_k P_k(d), `[bin][window][dir]`.
    pub(super) contrib: &'a mut [T],
    /// Source count per bin and window, `[bin][window]`.
    pub(super) counts: &'a mut [usize],
    /// The approximate mode: per bin, per stream of the call, the tracking state.
    pub(super) tracks: &'a mut [Vec<&'a mut BinTrack>],
}

/// CPU time per stage summed over a call's tasks, ns.
#[derive(Default)]
pub(super) struct StageNanos(pub(super) [AtomicU64; 4]);

impl StageNanos {
    pub(super) fn add(&self, stage: usize, t: Instant) -> Instant {
        let now = Instant::now();
        self.0[stage].fetch_add((now - t).as_nanos() as u64, Ordering::Relaxed);
        now
    }
}

/// What every task of a call reads.
pub(super) struct Ctx<'a, 'j, T: Real> {
    pub(super) plan: &'a Plan<T>,
    pub(super) jobs: &'a [Job<'j, T>],
    /// Per job, per window: the running sums' step.
    pub(super) steps: &'a [Vec<Step>],
    /// Per job: its stream's index among the task's sums (and tracking states).
    pub(super) rc_of: &'a [usize],
    /// Per window of the call: its length in frames.
    pub(super) lens: &'a [usize],
    pub(super) nw: usize,
    /// Windows per part of a task after its correlation (see [`Ctx::run`]).
    pub(super) part_windows: usize,
    /// The spectrum stage of a task runs its bins in parallel (see [`Ctx::run`]).
    pub(super) spread_bins: bool,
}

/// A task's windows `w0 …`: per bin of the task, their decompositions.
struct Part<'a, T: Real> {
    w0: usize,
    decs: Vec<&'a mut [Decomposition<T>]>,
}

impl<T: Real> Ctx<'_, '_, T> {
    /// Run one task: the correlation of every window (each stream's windows in order);
    /// the decompositions — all at once, or, when the call has few tasks for the pool's
    /// threads, in parts of `part_windows` windows run in parallel (a window's
    /// decomposition does not depend on its part; the approximate mode carries state from
    /// window to window: one part); then the spectrum contributions and source counts of
    /// all its windows (each bin's steering read once per call).
    pub(super) fn run(
        &self,
        task: BinTask<'_, T>,
        slots: &[Mutex<ThreadScratch<T>>],
        nanos: &StageNanos,
    ) -> Result<()> {
        let plan = self.plan;
        let (m, nb, nw) = (plan.num_mics, plan.num_bins(), self.nw);
        let mm = m * m;
        let srp = !plan.config.algorithm.is_music();
        let coherence = plan.config.normalizes_r();
        let bins = task.b0..(task.b0 + task.sums.len()).min(nb);
        let BinTask {
            sums,
            r,
            decs,
            contrib,
            counts,
            tracks,
            ..
        } = task;

        // 1. R of every window at the task's bins (phase-transformed for SRP-PHAT).
        let t = Instant::now();
        {
            let mut slot = thread_scratch(slots);
            let y = &mut slot.y;
            for (i, b) in bins.clone().enumerate() {
                let mut wi = 0;
                for (j, job) in self.jobs.iter().enumerate() {
                    let sum = &mut *sums[i][self.rc_of[j]];
                    for (w, st) in job.windows.iter().zip(&self.steps[j]) {
                        let o = (i * nw + wi) * mm;
                        run_bin(sum, *st, job, w, b, srp, y, &mut r[o..o + mm]);
                        if coherence {
                            normalize_coherence(&mut r[o..o + mm], m);
                        }
                        wi += 1;
                    }
                }
            }
        }
        nanos.add(0, t);

        // 2. Decompositions (none for SRP-PHAT).
        let r = &*r;
        if !srp {
            let pw = if plan.config.subspace_tracking {
                nw
            } else {
                self.part_windows.clamp(1, nw)
            };
            let mut parts: Vec<Part<'_, T>> = (0..nw.div_ceil(pw))
                .map(|k| Part {
                    w0: k * pw,
                    decs: Vec::new(),
                })
                .collect();
            for db in decs.chunks_mut(nw) {
                for (p, chunk) in parts.iter_mut().zip(db.chunks_mut(pw)) {
                    p.decs.push(chunk);
                }
            }
            if parts.len() == 1 {
                let part = parts.pop().expect("one part");
                self.decompose(&bins, r, part, tracks, &mut thread_scratch(slots), nanos)?;
            } else {
                parts.into_par_iter().try_for_each(|part| {
                    self.decompose(&bins, r, part, &mut [], &mut thread_scratch(slots), nanos)
                })?;
            }
        }

        // 3–4 over all the task's windows; bin by bin in parallel when the call's tasks
        // are few for the pool (a lone window's call, where the spectrum is most of the
        // time). Each bin's contributions are its own, so the split changes no result.
        if self.spread_bins && bins.len() > 1 {
            let d = plan.num_dirs;
            let decs = &*decs;
            // (SRP-PHAT has no decompositions: `decs` is empty.)
            let per_bin: Vec<_> = contrib
                .chunks_mut(nw * d)
                .zip(counts.chunks_mut(nw))
                .zip(r.chunks(nw * mm))
                .take(bins.len())
                .enumerate()
                .collect();
            per_bin.into_par_iter().for_each(|(i, ((cb, cn), rb))| {
                let b = bins.start + i;
                let dc = decs.get(i * nw..(i + 1) * nw).unwrap_or_default();
                self.spectrum_and_count(&(b..b + 1), rb, dc, cb, cn, &mut thread_scratch(slots), nanos);
            });
        } else {
            self.spectrum_and_count(&bins, r, decs, contrib, counts, &mut thread_scratch(slots), nanos);
        }
        Ok(())
    }

    /// The decompositions of one part of a task (`r`: the task's R, `[bin][window][M×M]`;
    /// `tracks`: per bin, per stream, the approximate mode's states).
    fn decompose(
        &self,
        bins: &std::ops::Range<usize>,
        r: &[C<f64>],
        mut part: Part<'_, T>,
        tracks: &mut [Vec<&mut BinTrack>],
        slot: &mut ThreadScratch<T>,
        nanos: &StageNanos,
    ) -> Result<()> {
        let plan = self.plan;
        let (m, nw) = (plan.num_mics, self.nw);
        let mm = m * m;
        let c = &plan.config;
        let alg = c.algorithm;
        let w0 = part.w0;
        let r_of = |i: usize, w: usize| &r[(i * nw + w) * mm..(i * nw + w + 1) * mm];
        let t = Instant::now();
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
                        let state = &mut *tracks[i][self.rc_of[j]];
                        tracking::decompose_tracked(&win, state, ws, tr, &mut part.decs[i][wi])?;
                        wi += 1;
                    }
                }
            }
        } else {
            // The task's problems, window by window (a window's bins together): in
            // groups ([`decompose_group`]; each result is the same in any group).
            let wm = |b: usize| plan.whitening_matrix64(b);
            let mut per_bin: Vec<std::slice::IterMut<'_, Decomposition<T>>> =
                part.decs.iter_mut().map(|d| d.iter_mut()).collect();
            let mut items = Vec::with_capacity(per_bin.len() * per_bin.first().map_or(0, |d| d.len()));
            for k in 0.. {
                let before = items.len();
                for (i, it) in per_bin.iter_mut().enumerate() {
                    if let Some(out) = it.next() {
                        items.push(Item {
                            r: r_of(i, w0 + k),
                            w: wm(bins.start + i),
                            out,
                        });
                    }
                }
                if items.len() == before {
                    break;
                }
            }
            decompose_group(alg, &mut items, ws)?;
        }
        nanos.add(1, t);
        Ok(())
    }

    /// The spectrum contributions w_k g_k P_k(d) and source counts of every window of a
    /// task (`decs`, `contrib`, `counts`: `[bin][window]` over the task's bins).
    #[allow(clippy::too_many_arguments)]
    fn spectrum_and_count(
        &self,
        bins: &std::ops::Range<usize>,
        r: &[C<f64>],
        decs: &[Decomposition<T>],
        contrib: &mut [T],
        counts: &mut [usize],
        slot: &mut ThreadScratch<T>,
        nanos: &StageNanos,
    ) {
        let plan = self.plan;
        let (m, d, nw) = (plan.num_mics, plan.num_dirs, self.nw);
        let mm = m * m;
        let c = &plan.config;
        let srp = !c.algorithm.is_music();
        let r_of = |i: usize, w: usize| &r[(i * nw + w) * mm..(i * nw + w + 1) * mm];
        let t = Instant::now();
        // 3. Within a bin the directions run in fixed blocks (`dir_block`) and every window
        // passes through each block (faer's path: its steering stays in cache; the fused
        // kernel takes a bin's directions in one block, its windows' columns in cache).
        for (i, b) in bins.clone().enumerate() {
            let cb = &mut contrib[i * nw * d..(i + 1) * nw * d];
            if srp {
                let sc = slot.srp.get_or_insert_with(|| SrpScratch::new(plan));
                for (w, acc) in cb.chunks_mut(d).enumerate() {
                    srp::accumulate_bin(plan, b, r_of(i, w), sc, acc);
                }
            } else {
                let sc = slot.spectrum.get_or_insert_with(|| SpectrumScratch::new(plan));
                let bin_decs: Vec<&Decomposition<T>> = decs[i * nw..(i + 1) * nw].iter().collect();
                let block = dir_block(plan);
                for d0 in (0..d).step_by(block) {
                    let dirs = d0..(d0 + block).min(d);
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
        let t = nanos.add(2, t);

        // 4. k̂ per window and bin (MDL; overlapping frames are not independent
        // snapshots: N = W·hop/N_fft of them, fewer with onset weighting).
        if c.counts_sources() {
            let overlap = plan.count_snapshots_per_frame;
            for (i, b) in bins.clone().enumerate() {
                if plan.weights[b] == T::zero() {
                    continue; // not used: the median skips bins without weight
                }
                for w in 0..nw {
                    let snapshots = ((self.lens[w] as f64 * overlap).round() as usize).max(1);
                    counts[i * nw + w] = count::mdl(&decs[i * nw + w].values, snapshots, plan.count_floor);
                }
            }
        }
        nanos.add(3, t);
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
