//! One `Backend::process` call on the GPU: place the frames, upload what is new, launch
//! the sub-batches as their frames arrive, read the peaks back.

use super::*;

impl<T: Real> CudaBackend<T> {
    /// [`Backend::process`] without the clean-up on error.
    pub(super) fn run_jobs(
        &mut self,
        jobs: &[Job<'_, T>],
        want_spectrum: bool,
        out: &mut BatchOutput,
    ) -> Result<()> {
        let (m, nb, d) = (self.lay.m, self.lay.nb, self.lay.d);
        crate::backend::check_jobs("cuda backend", &self.plan, jobs)?;
        self.phased = jobs.first().is_some_and(|j| j.spectra.phased);
        out.peaks.clear();
        out.spectrum_db.clear();
        out.bin_weight.clear();
        out.source_count.clear();
        let nw = crate::backend::count_windows(jobs);
        if nw == 0 {
            return Ok(());
        }
        self.gpu.make_current()?;
        let (cs, ts) = (csize::<T>(), std::mem::size_of::<T>());
        let l = self.lay.clone();
        let kout = l.peak_kout;
        let row = (1 + kout) * 16;
        let fbytes = nb * m * cs;
        let sb = self.sub_batch;
        let subs = sub_batches(nw, sb);
        let nsb = subs.len();
        let nwb_max = sb.min(nw);

        // Where each job's frames go on the device; only frames not there yet go up.
        let needs: Vec<(StreamId, std::ops::Range<usize>)> = jobs
            .iter()
            .map(|j| {
                let lo = j.windows.iter().map(|w| w.start).min().unwrap_or(j.first);
                let hi = j.windows.iter().map(|w| w.start + w.len).max().unwrap_or(lo);
                (j.stream, lo..hi)
            })
            .collect();
        let place = self.arena.place(&needs);
        if place.arena_frames * fbytes > self.d_x.bytes {
            self.ensure(Scratch::X, place.arena_frames * fbytes)?;
            self.arena.set_capacity(self.d_x.bytes / fbytes);
        }

        // Device buffers.
        self.ensure(Scratch::Win, nw * 8)?;
        self.ensure(Scratch::R, nwb_max * nb * m * m * l.r_size)?;
        if !l.srp {
            self.ensure(Scratch::E, nwb_max * nb * l.ne * m * cs)?;
        }
        if l.e64 {
            self.ensure(Scratch::E64, nwb_max * nb * l.ns * m * 16)?;
        }
        if l.normalize {
            self.ensure(Scratch::BinMax, nwb_max * nb * ts)?;
            self.ensure_pinned(HostBuf::Zero, nwb_max * nb * ts)?;
        }
        if !l.srp && !l.dec_smem_mode {
            self.ensure(Scratch::Jacobi, nwb_max * nb * l.dec_scratch_per_mat)?;
        }
        let nbg_max = subs.iter().map(|r| self.bin_groups(r.len())).max().unwrap_or(1);
        self.ensure(Scratch::Ppart, nbg_max * nwb_max * d * ts)?;
        self.ensure(Scratch::Gain, nw * nb * ts)?;
        self.ensure(Scratch::Bw, nw * nb * 4)?;
        self.ensure(Scratch::Info, nw * nb * 4)?;
        if self.profile && l.eigh {
            self.ensure(Scratch::Prof, nw * nb * 128)?;
        }
        if l.eigh && l.valmode != 0 {
            self.ensure(Scratch::H, nwb_max * nb * m * m * 16)?;
        }
        if l.count {
            self.ensure(Scratch::Tri, nwb_max * nb * 2 * m * 8)?;
            self.ensure(Scratch::Count, nw * nb * 4)?;
        }
        self.ensure(Scratch::Scale, nwb_max * nb * l.r_size / 2)?;
        self.ensure(Scratch::Db, nw * d * 8)?;
        if want_spectrum {
            self.ensure(Scratch::Spec, nw * d * 4)?;
        }
        self.ensure(Scratch::Out, nw * row)?;
        // Pinned host buffers.
        let up_frames: usize = place.uploads.iter().map(|u| u.frames.len()).sum();
        let chunk_frames = (STAGE_BYTES / fbytes).max(1);
        let stage_bytes = chunk_frames.min(up_frames.max(1)) * fbytes;
        self.ensure_pinned(HostBuf::Stage0, stage_bytes)?;
        if up_frames > chunk_frames {
            self.ensure_pinned(HostBuf::Stage1, stage_bytes)?;
        }
        let h_win = self.ensure_pinned(HostBuf::Win, nw * 8)?;
        self.ensure_pinned(HostBuf::Out, nw * row)?;
        if want_spectrum {
            self.ensure_pinned(HostBuf::Spec, nw * d * 4)?;
            self.ensure_pinned(HostBuf::Bw, nw * nb * 4)?;
        }
        if l.count {
            self.ensure_pinned(HostBuf::Count, nw * nb * 4)?;
        }
        while self.events.len() < 5 * nsb {
            let e = self.gpu.event()?;
            self.events.push(e);
        }

        // Window table (first frame in the arena, length), and for every window the
        // number of uploaded frames (in upload order) after which its frames are all there.
        // SAFETY: h_win holds nw * 8 bytes.
        let tab = unsafe { std::slice::from_raw_parts_mut(h_win as *mut i32, 2 * nw) };
        let mut ready = Vec::with_capacity(nw);
        let mut before = vec![usize::MAX; jobs.len()];
        let mut cum = 0;
        for u in &place.uploads {
            before[u.job] = cum;
            cum += u.frames.len();
        }
        let mut i = 0;
        for (j, job) in jobs.iter().enumerate() {
            let up = place.uploads.iter().find(|u| u.job == j);
            for w in job.windows {
                tab[2 * i] = (place.base[j] + (w.start - place.lo[j])) as i32;
                tab[2 * i + 1] = w.len as i32;
                let end = w.start + w.len;
                ready.push(match up {
                    Some(u) if end > u.frames.start => before[j] + (end - u.frames.start),
                    _ => 0,
                });
                i += 1;
            }
        }
        // SAFETY: pinned source, device buffer sized above; ordered before the frame chunks.
        unsafe { self.gpu.htod(self.d_win.ptr, h_win, nw * 8, Stream::Copy)? };
        let win_ev = self.chunk_ev[2];
        self.gpu.record(win_ev, Stream::Copy)?;

        // The factor form (fewer, better-conditioned columns) when every window has fewer
        // frames than microphones and only the signal vectors are needed.
        let maxlen = jobs
            .iter()
            .flat_map(|j| j.windows.iter().map(|w| w.len))
            .max()
            .unwrap_or(0);
        // (Not with coherence normalisation: the factor is built from the raw frames.)
        let mode = if l.squared && maxlen < m && self.factor_ok && !l.coherence {
            let ncf = maxlen + (maxlen & 1);
            DecMode {
                factor: if l.alg == Algorithm::Gsvd { 2 } else { 1 },
                ncf,
                left: usize::from(l.alg != Algorithm::Sevd),
                right: 0,
                threads: (ncf / 2 * l.lpp).div_ceil(32).clamp(1, 32) * 32,
            }
        } else {
            DecMode {
                factor: 0,
                ncf: 0,
                left: l.left,
                right: l.right,
                threads: l.dec_threads,
            }
        };

        // Uploaded frames needed by sub-batches 0..=k (prefix maximum).
        let mut need = Vec::with_capacity(nsb);
        let mut mx = 0usize;
        for sub in &subs {
            for r in &ready[sub.clone()] {
                mx = mx.max(*r);
            }
            need.push(mx);
        }

        // Upload in chunks through the two staging buffers; launch each sub-batch as soon
        // as its frames are on their way.
        let events = self.events.clone();
        let mut next = 0usize;
        self.gpu.wait(Stream::Compute, win_ev)?;
        while next < nsb && need[next] == 0 {
            self.launch_sub_batch(
                subs[next].clone(),
                kout,
                want_spectrum,
                &mode,
                &events[5 * next..5 * next + 5],
            )?;
            next += 1;
        }
        let mut done = 0usize;
        let mut ci = 0usize;
        for u in &place.uploads {
            let job = &jobs[u.job];
            let mut f = u.frames.start;
            while f < u.frames.end {
                let n = chunk_frames.min(u.frames.end - f);
                let st = ci % 2;
                let ev = self.chunk_ev[st];
                if ci >= 2 {
                    self.gpu.sync_event(ev)?;
                }
                let bytes = n * fbytes;
                let stage = self.h_stage[st].ptr;
                let lf = job.local(f);
                let part = as_bytes(&job.spectra.data[lf * nb * m..(lf + n) * nb * m]);
                copy_to_pinned(part, stage);
                // The copy may wait on rayon's pool, and a thread waiting there can run
                // other jobs (another stream's work on another device): this thread's
                // context is made current again (a thread-local write).
                self.gpu.make_current()?;
                let at = u.at + (f - u.frames.start);
                // SAFETY: the staging buffer holds `bytes`; it is not rewritten before `ev`
                // (recorded next) completes; the arena holds frame `at + n`.
                unsafe {
                    self.gpu
                        .htod(self.d_x.ptr + (at * fbytes) as u64, stage, bytes, Stream::Copy)?
                };
                self.gpu.record(ev, Stream::Copy)?;
                done += n;
                f += n;
                ci += 1;
                let mut waited = false;
                while next < nsb && need[next] <= done {
                    if !waited {
                        self.gpu.wait(Stream::Compute, ev)?;
                        waited = true;
                    }
                    self.launch_sub_batch(
                        subs[next].clone(),
                        kout,
                        want_spectrum,
                        &mode,
                        &events[5 * next..5 * next + 5],
                    )?;
                    next += 1;
                }
            }
        }
        debug_assert_eq!(next, nsb);
        self.gpu.sync(Stream::Compute)?;
        self.gpu.sync(Stream::Copy)?;

        for k in 0..nsb {
            let e = &events[5 * k..5 * k + 5];
            self.times.correlation_ms += self.gpu.elapsed_ms(e[0], e[1])? as f64;
            self.times.decomposition_ms += self.gpu.elapsed_ms(e[1], e[2])? as f64;
            self.times.spectrum_ms += self.gpu.elapsed_ms(e[2], e[3])? as f64;
            self.times.peaks_ms += self.gpu.elapsed_ms(e[3], e[4])? as f64;
        }

        // Results.
        // SAFETY: the compute stream is idle; h_out holds nw rows.
        let outb = unsafe { std::slice::from_raw_parts(self.h_out.ptr, nw * row) };
        out.peaks.reserve(nw);
        for w in 0..nw {
            let r = &outb[w * row..(w + 1) * row];
            let count = i32::from_le_bytes(r[8..12].try_into().unwrap_or([0; 4])).max(0) as usize;
            let overflow = i32::from_le_bytes(r[12..16].try_into().unwrap_or([0; 4])) != 0;
            if overflow {
                // More local maxima than the kernel's sort holds: redo this window here.
                let mut db = vec![0f64; d];
                // SAFETY: synchronous copy into a host Vec after the stream is idle.
                unsafe {
                    self.gpu.dtoh(
                        db.as_mut_ptr() as *mut u8,
                        self.d_db.ptr + (w * d * 8) as u64,
                        d * 8,
                        Stream::Compute,
                    )?;
                }
                self.gpu.sync(Stream::Compute)?;
                out.peaks
                    .push(crate::peaks::find_peaks(&db, &self.plan.peak_table));
                continue;
            }
            let k = count.min(kout);
            let mut v = Vec::with_capacity(k);
            for i in 0..k {
                let e = &r[(1 + i) * 16..(2 + i) * 16];
                let db = f64::from_le_bytes(e[0..8].try_into().unwrap_or([0; 8]));
                let dir = i32::from_le_bytes(e[8..12].try_into().unwrap_or([0; 4])) as usize;
                v.push(Peak { dir, power_db: db });
            }
            out.peaks.push(v);
        }
        if l.count {
            // The number of active sources: the median of k̂ over the bins that carry
            // weight (the CPU's rule, cpu.rs).
            // SAFETY: filled by the per-sub-batch downloads; the stream is idle.
            let k = unsafe { std::slice::from_raw_parts(self.h_count.ptr as *const i32, nw * nb) };
            let w = &self.plan.weights;
            out.source_count.extend((0..nw).map(|wi| {
                let used = (0..nb)
                    .filter(|&b| w[b] != T::zero())
                    .map(|b| k[wi * nb + b].max(0) as usize)
                    .collect();
                crate::subspace::count::median(used) as u32
            }));
        }
        if self.debug && !l.srp {
            // Jacobi sweeps or multisection rounds per matrix (SOUNDLOC_CUDA_DEBUG=1).
            let mut info = vec![0i32; nw * nb];
            // SAFETY: synchronous copy after the stream is idle.
            unsafe {
                self.gpu.dtoh(
                    info.as_mut_ptr() as *mut u8,
                    self.d_info.ptr,
                    nw * nb * 4,
                    Stream::Compute,
                )?
            };
            self.gpu.sync(Stream::Compute)?;
            let mean = info.iter().map(|&x| x as f64).sum::<f64>() / info.len() as f64;
            let _ = writeln!(
                std::io::stderr(),
                "soundloc cuda: {nw} windows in {nsb} sub-batches of at most {sb}, {}; {} min {} mean {mean:.2} max {}",
                if l.eigh {
                    "tridiagonal eigensolver".to_string()
                } else {
                    format!("Jacobi, factor form {}", mode.factor)
                },
                if l.eigh { "multisection rounds" } else { "sweeps" },
                info.iter().min().unwrap_or(&0),
                info.iter().max().unwrap_or(&0)
            );
        }
        if self.profile && l.eigh {
            self.print_profile(nw * nb)?;
        }
        if want_spectrum {
            // SAFETY: filled by the downloads above.
            unsafe {
                out.spectrum_db
                    .extend_from_slice(std::slice::from_raw_parts(self.h_spec.ptr as *const f32, nw * d));
                if l.srp {
                    out.bin_weight.resize(nw * nb, 1.0);
                } else {
                    out.bin_weight
                        .extend_from_slice(std::slice::from_raw_parts(self.h_bw.ptr as *const f32, nw * nb));
                }
            }
        }
        Ok(())
    }
}

/// The sub-batches' window ranges. One when the windows fit one sub-batch of `sb`;
/// otherwise they ramp up (doubling from ⌊sb/8⌋ to sb) so that the first kernels
/// start after a small upload and the copies of the larger ones that follow overlap
/// the compute of the smaller ones before them.
pub(super) fn sub_batches(nw: usize, sb: usize) -> Vec<std::ops::Range<usize>> {
    let sb = sb.max(1);
    let mut size = if nw > sb { (sb / 8).max(1) } else { sb };
    let mut v = Vec::with_capacity(nw.div_ceil(sb) + 3);
    let mut w = 0;
    while w < nw {
        let n = size.min(nw - w);
        v.push(w..w + n);
        w += n;
        size = (2 * size).min(sb);
    }
    v
}

#[cfg(test)]
mod tests {
    use super::sub_batches;

    #[test]
    fn sub_batches_cover_every_window_once_and_ramp_up_only_when_there_are_several() {
        for (nw, sb) in [
            (1, 58),
            (58, 58),
            (59, 58),
            (256, 58),
            (1000, 7),
            (5, 1),
            (300, 3),
        ] {
            let v = sub_batches(nw, sb);
            let mut w = 0;
            for r in &v {
                assert_eq!(r.start, w, "{nw} {sb}: {v:?}");
                assert!(!r.is_empty() && r.len() <= sb, "{nw} {sb}: {v:?}");
                w = r.end;
            }
            assert_eq!(w, nw, "{nw} {sb}: {v:?}");
        }
        assert_eq!(sub_batches(58, 58), vec![0..58]);
        assert_eq!(sub_batches(20, 58), vec![0..20]);
        let v: Vec<usize> = sub_batches(256, 58).iter().map(|r| r.len()).collect();
        assert_eq!(v, vec![7, 14, 28, 56, 58, 58, 35]);
    }
}
