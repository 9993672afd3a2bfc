//! Kernel launches of the CUDA backend: argument packing and one sub-batch's stages.

use super::*;

/// Kernel arguments, each stored in 8 bytes (little-endian: an i32 or f32 in the low
/// bytes), handed to the launch as `void*` to each slot.
pub(super) struct Args {
    pub(super) v: Vec<u64>,
}

impl Args {
    pub(super) fn new() -> Self {
        Args {
            v: Vec::with_capacity(24),
        }
    }
    pub(super) fn p(mut self, p: DevPtr) -> Self {
        self.v.push(p);
        self
    }
    pub(super) fn i(mut self, x: usize) -> Self {
        self.v.push(x as i32 as u32 as u64);
        self
    }
    pub(super) fn r<T: Real>(mut self, x: T) -> Self {
        if std::mem::size_of::<T>() == 4 {
            self.v.push((x.to_f64() as f32).to_bits() as u64);
        } else {
            self.v.push(x.to_f64().to_bits());
        }
        self
    }
    pub(super) fn launch(
        mut self,
        gpu: &dyn Gpu,
        f: Func,
        grid: [usize; 3],
        block: usize,
        smem: usize,
    ) -> Result<()> {
        let mut ps: Vec<*mut c_void> = self.v.iter_mut().map(|x| x as *mut u64 as *mut c_void).collect();
        let g = [grid[0] as u32, grid[1] as u32, grid[2] as u32];
        // SAFETY: the argument lists below match the kernels' signatures (kernels/*.cu).
        unsafe { gpu.launch(f, g, block as u32, smem as u32, Stream::Compute, &mut ps) }
    }
}

/// How the decomposition kernel forms the matrix it rotates (per batch).
#[derive(Debug, Clone, Copy)]
pub(super) struct DecMode {
    /// 0: the M × M matrix from R; 1: the factor W·Yᴴ (W < M frames, Hermitian cases);
    /// 2: the GSVD factor K⁻¹ R Q (Q an orthonormal basis of the frames).
    pub(super) factor: usize,
    /// Columns of the factor (even).
    pub(super) ncf: usize,
    pub(super) left: usize,
    pub(super) right: usize,
    pub(super) threads: usize,
}

impl<T: Real> CudaBackend<T> {
    /// Where the eigensolver puts a second, double copy of the signal vectors (0: none).
    pub(super) fn e64_out(&self) -> DevPtr {
        if self.lay.e64 {
            self.d_e64.ptr
        } else {
            0
        }
    }

    /// Where the spectrum reads the signal vectors in double for its near-peak
    /// recomputation: that copy, or an f64 plan's `E` itself (0: none — not squared MUSIC,
    /// or the f32 Jacobi's vectors, recomputed from in f32).
    pub(super) fn e64_in(&self) -> DevPtr {
        let l = &self.lay;
        if l.e64 {
            self.d_e64.ptr
        } else if std::mem::size_of::<T>() == 8 && l.squared && !l.srp {
            self.d_e.ptr
        } else {
            0
        }
    }

    pub(super) fn bin_groups(&self, nwb: usize) -> usize {
        let l = &self.lay;
        let xy = l.d.div_ceil(l.spec_dt) * nwb.div_ceil(l.spec_wg.min(nwb).max(1));
        // About four blocks per SM with RD = 1; RD = 4 blocks hold four times the windows
        // (as many threads), and four times the groups of bins keep as many blocks (the
        // bins' partial sums are then grouped differently: the same per-bin values, the
        // broadband sum in another order).
        (4 * l.spec_rd * self.gpu.sm_count())
            .div_ceil(xy.max(1))
            .clamp(1, l.nb)
    }

    /// Mean cycles per phase of eigh.cu over the last batch's matrices, on stderr
    /// (SOUNDLOC_CUDA_PROFILE=1; a tuning aid).
    pub(super) fn print_profile(&mut self, nmat: usize) -> Result<()> {
        let mut t = vec![0i64; nmat * 16];
        // SAFETY: synchronous copy of the profile buffer after the stream is idle.
        unsafe {
            self.gpu.dtoh(
                t.as_mut_ptr() as *mut u8,
                self.d_prof.ptr,
                nmat * 128,
                Stream::Compute,
            )?
        };
        self.gpu.sync(Stream::Compute)?;
        let names = [
            "form H",
            "tridiagonal",
            "bisection",
            "inverse iteration",
            "back-transform",
        ];
        let mut line = format!("soundloc cuda: eigh cycles per matrix ({nmat} matrices):");
        let mean =
            |f: &dyn Fn(&[i64]) -> i64| t.chunks(16).map(|c| f(c) as f64).sum::<f64>() / nmat.max(1) as f64;
        for (p, name) in names.iter().enumerate() {
            line.push_str(&format!(" {name} {:.0}", mean(&|c| c[p + 1] - c[p])));
        }
        // Inside the reduction, summed over its steps (eigh.cu's slots 8–11).
        let steps = [
            "matrix-vector",
            "warp 0 column + reflector",
            "warp 1 update",
            "final barrier (warp 0)",
        ];
        // Zeros unless the kernel was built with -DEH_PROFILE_STEPS.
        if t.chunks(16).any(|c| c[8..12].iter().any(|&x| x != 0)) {
            line.push_str(" | reduction steps:");
            for (p, name) in steps.iter().enumerate() {
                line.push_str(&format!(" {name} {:.0}", mean(&|c| c[8 + p])));
            }
        }
        let _ = writeln!(std::io::stderr(), "{line}");
        Ok(())
    }

    /// The tridiagonal eigensolver (eigh.cu) of this sub-batch's matrices: form_h for the
    /// whitened cases, then eigh.
    pub(super) fn launch_eigh(&self, mat0: usize, nmat: usize) -> Result<()> {
        let l = &self.lay;
        if l.valmode != 0 {
            Args::new()
                .p(self.d_r.ptr)
                .p(self.d_wcm.ptr)
                .p(self.d_wrm.ptr)
                .i(l.m)
                .i(l.nb)
                .i(l.valmode)
                .i(mat0)
                .p(self.d_h.ptr)
                .launch(
                    &*self.gpu,
                    self.f.form_h,
                    [nmat, 1, 1],
                    FORM_H_THREADS,
                    l.form_h_smem,
                )?;
        }
        Args::new()
            .p(self.d_r.ptr)
            .p(self.d_h.ptr)
            .i(l.m)
            .i(l.nb)
            .i(l.valmode)
            .i(l.ns)
            .i(usize::from(self.plan.config.eigenvalue_weight))
            .p(self.d_weights.ptr)
            .i(mat0)
            .i(l.eigh_shape.scr_len)
            .p(self.d_e.ptr)
            .p(self.e64_out())
            .p(self.d_gain.ptr)
            .p(self.d_bw.ptr)
            .p(self.d_info.ptr)
            .p(if self.profile { self.d_prof.ptr } else { 0 })
            .p(if l.count { self.d_tri.ptr } else { 0 })
            .launch(
                &*self.gpu,
                self.f.eigh,
                [nmat, 1, 1],
                l.eigh_shape.threads,
                l.eigh_shape.smem,
            )?;
        if l.count {
            // k̂ per matrix from T's eigenvalues (count.cu), the CPU's MDL
            // (subspace::count::mdl) with N = W·hop/N_fft snapshots (fewer with onset
            // weighting: Plan::count_snapshots_per_frame).
            let overlap = self.plan.count_snapshots_per_frame;
            Args::new()
                .p(self.d_tri.ptr)
                .i(l.m)
                .i(nmat)
                .i(l.nb)
                .i(mat0)
                .p(self.d_win.ptr)
                .r(overlap)
                .r(self.plan.count_floor)
                .i(usize::from(l.alg == Algorithm::Gsvd))
                .p(self.d_count.ptr)
                .launch(
                    &*self.gpu,
                    self.f.count,
                    [nmat.div_ceil(COUNT_THREADS / 64), 1, 1],
                    COUNT_THREADS,
                    0,
                )?;
        }
        Ok(())
    }

    /// The Jacobi decomposition (decompose.cu) of this sub-batch's matrices.
    pub(super) fn launch_jacobi(&self, mat0: usize, nmat: usize, mode: &DecMode) -> Result<()> {
        let l = &self.lay;
        let vec_all = usize::from(!l.squared);
        Args::new()
            .p(self.d_r.ptr)
            .p(self.d_x.ptr)
            .p(self.d_win.ptr)
            .p(self.d_scale.ptr)
            .p(self.d_wcm.ptr)
            .p(self.d_wrm.ptr)
            .i(l.m)
            .i(l.nb)
            .i(l.ld)
            .i(mode.ncf)
            .i(mode.factor)
            .i(mode.left)
            .i(mode.right)
            .i(l.ns)
            .i(vec_all)
            .i(MAX_SWEEPS as usize)
            .i(usize::from(self.plan.config.eigenvalue_weight))
            .i(l.valmode)
            .p(self.d_weights.ptr)
            .i(mat0)
            .p(self.d_e.ptr)
            .p(self.d_gain.ptr)
            .p(self.d_bw.ptr)
            .p(self.d_info.ptr)
            .p(self.d_scratch.ptr)
            .launch(
                &*self.gpu,
                self.f.decompose,
                [nmat, 1, 1],
                mode.threads,
                l.dec_smem,
            )
    }

    pub(super) fn launch_sub_batch(
        &mut self,
        windows: std::ops::Range<usize>,
        kout: usize,
        want_spectrum: bool,
        mode: &DecMode,
        ev: &[Event],
    ) -> Result<()> {
        let l = self.lay.clone();
        let (cs, ts) = (csize::<T>(), std::mem::size_of::<T>());
        let (w0, nwb) = (windows.start, windows.len());
        let mat0 = w0 * l.nb;
        let nmat = nwb * l.nb;
        let nbg = self.bin_groups(nwb);
        let g = &*self.gpu;
        g.record(ev[0], Stream::Compute)?;
        Args::new()
            .p(self.d_x.ptr)
            .i(l.nb)
            .i(l.m)
            .p(self.d_win.ptr)
            .i(l.corr_fc)
            .i(mat0)
            .i(match (l.srp, self.phased) {
                (false, _) => 0,
                (true, false) => 1,
                (true, true) => 2, // the frames are x̃ already
            })
            .p(self.d_r.ptr)
            .p(self.d_scale.ptr)
            .launch(g, self.f.correlate, [nmat, 1, 1], l.corr_threads, l.corr_smem)?;
        if l.coherence {
            Args::new().p(self.d_r.ptr).i(l.m).launch(
                g,
                self.f.coherence,
                [nmat, 1, 1],
                super::COHERENCE_THREADS,
                l.m * 8,
            )?;
        }
        g.record(ev[1], Stream::Compute)?;
        if l.srp {
            // No decomposition: the spectrum reads R̃.
        } else if l.eigh {
            self.launch_eigh(mat0, nmat)?;
        } else {
            self.launch_jacobi(mat0, nmat, mode)?;
        }
        g.record(ev[2], Stream::Compute)?;
        let n2den = if self.d_n2den.bytes > 0 {
            self.d_n2den.ptr
        } else {
            self.d_n2num.ptr
        };
        let wg = l.spec_wg.min(nwb).max(1);
        let spec_smem = l.spec_tile + if l.spec_e_smem { wg * l.ne * l.m * cs } else { 0 };
        if l.normalize {
            // SAFETY: h_zero (pinned, zeros) and d_binmax hold nmat·ts bytes (run_jobs).
            unsafe { g.htod(self.d_binmax.ptr, self.h_zero.ptr, nmat * ts, Stream::Compute)? };
        }
        let passes: &[usize] = if l.normalize { &[1, 2] } else { &[0] };
        for &pass in passes {
            Args::new()
                .p(self.d_st.ptr)
                .p(n2den)
                .p(self.d_n2num.ptr)
                .p(if l.srp { self.d_r.ptr } else { self.d_e.ptr })
                .p(self.e64_in())
                .i(l.ne)
                .p(self.d_gain.ptr + (mat0 * ts) as u64)
                .i(l.m)
                .i(l.nb)
                .i(l.d)
                .i(l.ns)
                .i(usize::from(l.squared))
                .i(nwb)
                .r(T::of_f64(crate::music::REFINE_RATIO))
                .i(l.spec_dt)
                .i(usize::from(l.spec_e_smem))
                .i(usize::from(l.srp))
                .i(pass)
                .p(self.d_weights.ptr)
                .p(self.d_binmax.ptr)
                .p(self.d_ppart.ptr)
                .launch(
                    g,
                    self.f.spectrum,
                    [l.d.div_ceil(l.spec_dt), nwb.div_ceil(wg), nbg],
                    l.spec_threads(wg),
                    spec_smem,
                )?;
        }
        g.record(ev[3], Stream::Compute)?;
        let row = (1 + kout) * 16;
        let spec_ptr = if want_spectrum {
            self.d_spec.ptr + (w0 * l.d * 4) as u64
        } else {
            0
        };
        Args::new()
            .p(self.d_ppart.ptr)
            .i(nbg)
            .i(nwb)
            .i(l.d)
            .p(self.d_offs.ptr)
            .p(self.d_nbrs.ptr)
            .p(self.d_azok.ptr)
            .i(kout)
            .i(l.peak_cap)
            .p(self.d_db.ptr + (w0 * l.d * 8) as u64)
            .p(spec_ptr)
            .p(self.d_out.ptr + (w0 * row) as u64)
            .launch(g, self.f.peaks, [nwb, 1, 1], 256, l.peak_smem)?;
        // SAFETY: the pinned buffers were sized for the whole batch before the loop and
        // are not touched by the host until the compute stream is synchronised.
        unsafe {
            g.dtoh(
                self.h_out.ptr.add(w0 * row),
                self.d_out.ptr + (w0 * row) as u64,
                nwb * row,
                Stream::Compute,
            )?;
            if want_spectrum {
                g.dtoh(
                    self.h_spec.ptr.add(w0 * l.d * 4),
                    self.d_spec.ptr + (w0 * l.d * 4) as u64,
                    nwb * l.d * 4,
                    Stream::Compute,
                )?;
            }
            if want_spectrum && !l.srp {
                g.dtoh(
                    self.h_bw.ptr.add(mat0 * 4),
                    self.d_bw.ptr + (mat0 * 4) as u64,
                    nmat * 4,
                    Stream::Compute,
                )?;
            }
            if l.count {
                g.dtoh(
                    self.h_count.ptr.add(mat0 * 4),
                    self.d_count.ptr + (mat0 * 4) as u64,
                    nmat * 4,
                    Stream::Compute,
                )?;
            }
        }
        g.record(ev[4], Stream::Compute)?;
        let _ = cs;
        Ok(())
    }
}
