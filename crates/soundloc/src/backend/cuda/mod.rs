//! The CUDA backend: the whole numeric pipeline on the GPU, CUDA libraries loaded at run
//! time (cudarc, `dynamic-loading`), kernels compiled by NVRTC for the device's own
//! architecture on first use.
//!
//! ```text
//!  host frames ─(pinned staging, copy stream)─► X [frame][bin][mic]
//!  per sub-batch of windows, on the compute stream:
//!   correlate  (window × bin) blocks   R = (1/W) Σ x xᴴ, HARK scaling          correlate.cu
//!   coherence  one block per matrix    R ← D^{-1/2} R D^{-1/2} (when asked)     correlate.cu
//!   eigh       one block per matrix    H = R | W R Wᴴ | W R W | (W R)(W R)ᴴ in f64,  eigh.cu
//!                                      Householder → tridiagonal, bisection, inverse
//!                                      iteration, top-Ns vectors (squared denominator, M ≤ 64)
//!   decompose  (otherwise)             G = W R Wᴴ | W R W | W R | R, one-sided    decompose.cu
//!                                      Jacobi in shared memory (all vectors when unsquared)
//!   spectrum   direction tiles         P̄ = Σ_k w_k g_k num/den, complement+refine  spectrum.cu
//!   peaks      one block per window    dB, local maxima, sorted candidates        peaks.cu
//!  ─► only the peak candidates (and the dB spectrum / bin weights when asked) come back.
//! ```
//!
//! **Why not cuBLAS / cuSOLVER.** The decomposition is the cost. cuSOLVER's batched
//! Jacobi (`heevjBatched`, `gesvdjBatched`) stops at 32 × 32, its other batched solvers
//! are for tall matrices or single calls; the seed matrices are 60 × 60. A one-sided
//! (Hestenes) Jacobi per block handles every algorithm with one kernel: for the Hermitian
//! PSD cases (SEVD, GEVD, GEVD-HARK) the normalised columns of G·V are the eigenvectors,
//! for GSVD (G = K⁻¹R, not Hermitian) the left singular vectors — exactly what HARK's
//! GSVD uses — without forming V. The squared MUSIC denominator needs only the Ns signal
//! vectors: Σ_noise|aᴴe|² = ‖a‖² − Σ_signal|aᴴe|², and where that complement cancels
//! (< 1 % of ‖a‖², the CPU's `music::REFINE_RATIO`) the spectrum kernel recomputes
//! the complement in double from double signal vectors (`music::complement64`, floor
//! ε_f64·‖a‖², as the CPU), or — for the f32 Jacobi's vectors, which are only f32-accurate —
//! ‖(I − E_sE_sᴴ)a‖² by two Gram–Schmidt passes in f32; either is the full noise-subspace
//! sum to rounding. The unsquared form needs every noise vector individually: then V is
//! accumulated (on Aᴴ for GSVD) and all M vectors are kept. The small products that
//! whiten R are fused into the Jacobi kernel's prologue (no cuBLAS round trip); the
//! correlation is its own small kernel so that stage times stay separate.
//! For the squared denominator with M ≤ 64 the signal vectors come instead from a
//! Householder tridiagonalisation of the Hermitian H (eigh.cu): ~(16/3)·M³ flops instead
//! of the Jacobi's ~10 sweeps × 8·M³, and H is formed and reduced in double precision, so
//! GSVD's A Aᴴ does not square the f32 rounding. Whatever the plan's precision, R leaves the
//! correlation in double, W is uploaded in double, and the tridiagonal eigensolver and the
//! unsquared Jacobi compute in double (as the CPU does; only the squared Jacobi path of an
//! f32 plan — M > 64 or `SOUNDLOC_CUDA_DEC=jacobi` — rotates in f32); the vectors go to the
//! spectrum in T, and, from the double eigensolver, in double for its near-peak
//! recomputation. `docs/gpu.md` has the measurements.
//!
//! **Batching.** `process` splits its windows into sub-batches sized to fill the GPU a
//! few times over; STFT frames go up through two pinned staging buffers on a copy stream
//! while earlier sub-batches compute, and each sub-batch's results come back on the
//! compute stream. Stage times are CUDA event intervals on the compute stream (the
//! upload overlaps and is not in them).
//!
//! **Frames stay on the device.** Each stream's frames live in a region of one device
//! buffer ([`frames`]); a call uploads only the frames the device does not hold yet — at
//! PERIOD 1 one frame per window instead of W — and one call may carry the windows of many
//! streams (a [`crate::StreamGroup`]).
//!
//! Files: `mod.rs` (construction, plan upload, the `Backend` impl), `run.rs` (one
//! `process` call), `launch.rs` (kernel launches), `layout.rs` (sizes and launch shapes),
//! `buffers.rs` (device and pinned buffers), `frames.rs` (where frames live),
//! `kernels.rs` (NVRTC), `device.rs` (the driver), `emu.rs` (the CPU emulator).
//!
//! Missing libraries, no GPU or a failed compile are `Error::Device`, never a panic:
//! library presence is checked before cudarc touches them and first initialisation runs
//! under `catch_unwind`.

mod buffers;
mod device;
mod emu;
mod frames;
mod image_cache;
mod kernels;
mod launch;
mod layout;
mod prebuilt;
mod prewarm;
mod run;

use buffers::*;
use launch::*;
use layout::*;
pub use prewarm::{prewarm, Prewarm};

use super::{Backend, BatchOutput, Job, Peak, StageTimes, StreamId};
use crate::config::{Algorithm, Denominator};
use crate::plan::Plan;
use crate::real::{Real, C};
use crate::{Error, Result};
use device::{CudaGpu, DevPtr, Event, Func, Gpu, Stream};
use faer::c64;
use kernels::Variant;
use rayon::prelude::*;
use std::ffi::c_void;
use std::io::Write;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;
use std::sync::Arc;

/// Bytes per pinned staging buffer for frame uploads.
const STAGE_BYTES: usize = 16 << 20;
/// Jacobi sweep cap (a converged 60 × 60 problem takes well under this).
const MAX_SWEEPS: i32 = 40;
/// Default dynamic shared memory limit without opt-in.
const SMEM_DEFAULT: usize = 48 * 1024;
/// Threads of a form_h block (eigh.cu `EH_THREADS`: its register tiles are 16 columns wide).
const FORM_H_THREADS: usize = 256;
/// Threads per block of `coherence_f64` (one block per matrix).
const COHERENCE_THREADS: usize = 128;
/// Threads per block of count.cu (64 per matrix, CNT_MATS matrices; its `__launch_bounds__`).
const COUNT_THREADS: usize = 128;

/// Name of CUDA device 0 and its capability, or why CUDA cannot be used.
pub fn probe() -> std::result::Result<String, String> {
    guarded(|| {
        let (name, cc, sms) = device::device_info(0)?;
        if !kernels::nvrtc_present() {
            return Err(Error::Device(format!(
                "{name} found, but libnvrtc (the CUDA run-time compiler) was not; add the CUDA toolkit's lib64 to LD_LIBRARY_PATH"
            )));
        }
        let (a, b) = kernels::nvrtc_version().map_err(Error::Device)?;
        Ok(format!("cuda:0 {name} (sm_{cc}, {sms} SMs, NVRTC {a}.{b})"))
    })
    .map_err(|e| e.to_string())
}

/// Number of GPUs present, or why there are none.
pub fn device_count() -> Result<usize> {
    device::device_count()
}

/// Build a CUDA backend on device `ordinal`, or say why none can be had. `cache`: the
/// folder that keeps compiled kernels between runs (None: compile every time).
pub fn new_backend<T: Real>(
    plan: Arc<Plan<T>>,
    ordinal: usize,
    cache: Option<&Path>,
) -> Result<Box<dyn Backend<T>>> {
    guarded(|| {
        variant_for(&plan)?;
        let v = Variant {
            only: T::NAME,
            ..Variant::exact_for_mics(plan.num_mics).expect("checked by variant_for")
        };
        let gpu = CudaGpu::new(ordinal, v, cache)?;
        Ok(Box::new(CudaBackend::new(plan, Box::new(gpu))?) as Box<dyn Backend<T>>)
    })
}

/// The same backend over the CPU emulator of the kernels found in `emu_dir`
/// (`scripts/build_cuda_emu.sh`). For tests on machines without a GPU; very slow.
#[doc(hidden)]
pub fn new_emulated_backend<T: Real>(plan: Arc<Plan<T>>, emu_dir: &Path) -> Result<Box<dyn Backend<T>>> {
    let v = variant_for(&plan)?;
    let gpu = emu::EmuGpu::new(emu_dir, v)?;
    Ok(Box::new(CudaBackend::new(plan, Box::new(gpu))?))
}

/// Whether libnvrtc can be loaded here.
#[doc(hidden)]
pub fn nvrtc_available() -> bool {
    guarded(|| Ok(kernels::nvrtc_present())).unwrap_or(false)
}

/// Compile every kernel variant for `arch` (e.g. `sm_90`) with NVRTC; (variant, image
/// bytes) per variant. For the compile test.
#[doc(hidden)]
pub fn nvrtc_compile_all(arch: &str) -> std::result::Result<Vec<(String, usize)>, String> {
    guarded(|| kernels::compile_all(arch).map_err(Error::Device)).map_err(|e| e.to_string())
}

/// The embedded kernel bundle for `arch` (`sm_90`), compiled here with NVRTC
/// (`soundloc cuda-prebuild`; [`prebuilt`]).
#[doc(hidden)]
pub fn nvrtc_prebuild(arch: &str) -> std::result::Result<Vec<u8>, String> {
    guarded(|| prebuilt::build(arch).map_err(Error::Device)).map_err(|e| e.to_string())
}

fn guarded<R>(f: impl FnOnce() -> Result<R>) -> Result<R> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(p) => {
            let msg = p
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "unknown panic".into());
            Err(Error::Device(format!("CUDA library failure: {msg}")))
        }
    }
}

fn variant_for<T: Real>(plan: &Plan<T>) -> Result<Variant> {
    Variant::for_mics(plan.num_mics).ok_or_else(|| {
        Error::Device(format!(
            "the CUDA backend handles up to 256 microphones, the array has {}",
            plan.num_mics
        ))
    })
}

struct Funcs {
    correlate: Func,
    coherence: Func,
    decompose: Func,
    eigh: Func,
    form_h: Func,
    count: Func,
    spectrum: Func,
    peaks: Func,
}

/// The CUDA implementation of [`Backend`].
pub struct CudaBackend<T: Real> {
    plan: Arc<Plan<T>>,
    gpu: Box<dyn Gpu>,
    lay: Layout,
    f: Funcs,
    times: StageTimes,
    max_batch: usize,
    sub_batch: usize,
    debug: bool,
    /// Whether the factor form may be used (SOUNDLOC_CUDA_FACTOR=0 turns it off).
    factor_ok: bool,
    // Plan data on the device.
    d_st: Buf,
    d_n2den: Buf,
    d_n2num: Buf,
    d_wcm: Buf,
    d_wrm: Buf,
    d_weights: Buf,
    d_offs: Buf,
    d_nbrs: Buf,
    d_azok: Buf,
    // Batch buffers.
    d_x: Buf,
    d_win: Buf,
    d_r: Buf,
    d_e: Buf,
    /// The eigensolver's signal vectors in double for the spectrum's near-peak
    /// recomputation (f32 plans; an f64 plan's `d_e` already is).
    d_e64: Buf,
    d_scratch: Buf,
    d_ppart: Buf,
    d_gain: Buf,
    d_bw: Buf,
    d_info: Buf,
    /// Phase cycle counts of eigh.cu, [matrix][8] (SOUNDLOC_CUDA_PROFILE=1 only).
    d_prof: Buf,
    profile: bool,
    /// H = W R Wᴴ etc. in f64 from form_h for eigh (Hermitian cases other than SEVD).
    d_h: Buf,
    d_scale: Buf,
    d_db: Buf,
    d_spec: Buf,
    d_out: Buf,
    /// Per (window, bin) maximum over directions (NormMUSIC's first pass).
    d_binmax: Buf,
    /// eigh.cu's T per matrix of a sub-batch, for count.cu.
    d_tri: Buf,
    /// count.cu's k̂ per (window, bin).
    d_count: Buf,
    h_stage: [Pinned; 2],
    h_win: Pinned,
    h_out: Pinned,
    h_spec: Pinned,
    h_bw: Pinned,
    h_zero: Pinned,
    h_count: Pinned,
    /// Staging buffers 0 and 1 reusable; the window table is up.
    chunk_ev: [Event; 3],
    /// Where streams' frames are in `d_x`.
    arena: frames::FrameArena,
    events: Vec<Event>,
    /// The present call's frames are [`crate::backend::Spectra::phased`].
    phased: bool,
}

// SAFETY: the pinned pointers are owned by this struct and only touched by the thread
// that calls its methods; the device handle is Send.
unsafe impl<T: Real> Send for CudaBackend<T> {}

impl<T: Real> CudaBackend<T> {
    fn new(plan: Arc<Plan<T>>, gpu: Box<dyn Gpu>) -> Result<Self> {
        gpu.make_current()?;
        let lay = layout(&plan, &*gpu)?;
        let mut b = CudaBackend {
            plan: plan.clone(),
            gpu,
            lay: lay.clone(),
            f: Funcs {
                correlate: 0,
                coherence: 0,
                decompose: 0,
                eigh: 0,
                form_h: 0,
                count: 0,
                spectrum: 0,
                peaks: 0,
            },
            times: StageTimes::default(),
            max_batch: 1,
            sub_batch: 1,
            debug: std::env::var("SOUNDLOC_CUDA_DEBUG").is_ok_and(|v| v == "1"),
            factor_ok: std::env::var("SOUNDLOC_CUDA_FACTOR").map_or(true, |v| v != "0"),
            d_st: Buf::default(),
            d_n2den: Buf::default(),
            d_n2num: Buf::default(),
            d_wcm: Buf::default(),
            d_wrm: Buf::default(),
            d_weights: Buf::default(),
            d_offs: Buf::default(),
            d_nbrs: Buf::default(),
            d_azok: Buf::default(),
            d_x: Buf::default(),
            d_win: Buf::default(),
            d_r: Buf::default(),
            d_e: Buf::default(),
            d_e64: Buf::default(),
            d_scratch: Buf::default(),
            d_ppart: Buf::default(),
            d_gain: Buf::default(),
            d_bw: Buf::default(),
            d_info: Buf::default(),
            d_prof: Buf::default(),
            d_h: Buf::default(),
            profile: std::env::var("SOUNDLOC_CUDA_PROFILE").is_ok_and(|v| v == "1"),
            d_scale: Buf::default(),
            d_db: Buf::default(),
            d_spec: Buf::default(),
            d_out: Buf::default(),
            d_binmax: Buf::default(),
            d_tri: Buf::default(),
            d_count: Buf::default(),
            h_stage: [Pinned::default(), Pinned::default()],
            h_win: Pinned::default(),
            h_out: Pinned::default(),
            h_spec: Pinned::default(),
            h_bw: Pinned::default(),
            h_zero: Pinned::default(),
            h_count: Pinned::default(),
            chunk_ev: [0, 0, 0],
            arena: frames::FrameArena::default(),
            phased: false,
            events: Vec::new(),
        };
        b.load_functions()?;
        b.upload_plan(None)?;
        tracing::debug!("cuda: plan uploaded");
        b.chunk_ev = [b.gpu.event()?, b.gpu.event()?, b.gpu.event()?];
        b.size_batches()?;
        tracing::debug!("cuda: batches sized ({} windows per call)", b.max_batch);
        Ok(b)
    }

    fn load_functions(&mut self) -> Result<()> {
        let t = T::NAME;
        let l = &self.lay;
        let dec = format!(
            "decompose_{}{}_{t}",
            if l.dec_smem_mode { 's' } else { 'g' },
            if l.want_v { 'v' } else { 'n' }
        );
        self.f = Funcs {
            correlate: self.gpu.function(&if l.srp {
                format!("correlate_phat_{t}")
            } else {
                format!("correlate_{t}")
            })?,
            coherence: self.gpu.function("coherence_f64")?,
            decompose: self.gpu.function(&dec)?,
            eigh: self.gpu.function(&l.eigh_shape.kernel(t))?,
            form_h: self.gpu.function(&format!("form_h_{t}"))?,
            count: self.gpu.function("count_sources")?,
            spectrum: self.gpu.function(&if l.spec_rd == 4 {
                format!("spectrum4_{t}")
            } else {
                format!("spectrum_{t}")
            })?,
            peaks: self.gpu.function(&format!("peaks_{t}"))?,
        };
        for (f, s) in [
            (self.f.correlate, l.corr_smem),
            (self.f.decompose, l.dec_smem),
            (self.f.eigh, l.eigh_shape.smem),
            (self.f.form_h, l.form_h_smem),
            (
                self.f.spectrum,
                l.spec_tile
                    + if l.spec_e_smem {
                        l.spec_wg * l.ne * l.m * csize::<T>()
                    } else {
                        0
                    },
            ),
            (self.f.peaks, l.peak_smem + 64),
        ] {
            if s > SMEM_DEFAULT {
                self.gpu.set_max_smem(f, s)?;
            }
        }
        // The largest blocks each kernel is launched with must be within its limit
        // (launch bounds, registers): a clear error here rather than a failed launch.
        let l = &self.lay;
        for (f, name, threads) in [
            (self.f.correlate, "correlate", l.corr_threads),
            (self.f.coherence, "coherence", COHERENCE_THREADS),
            (self.f.decompose, "decompose", l.dec_threads),
            (self.f.eigh, "eigh", l.eigh_shape.threads),
            (self.f.form_h, "form_h", FORM_H_THREADS),
            (self.f.count, "count", COUNT_THREADS),
            (self.f.spectrum, "spectrum", l.spec_threads(l.spec_wg)),
            (self.f.peaks, "peaks", 256),
        ] {
            let most = self.gpu.max_threads(f)?;
            if self.debug {
                let (regs, local) = self.gpu.resources(f)?;
                let _ = writeln!(
                    std::io::stderr(),
                    "soundloc cuda: {name}: {threads} threads, {regs} registers, {local} local bytes per thread"
                );
            }
            if threads > most {
                return Err(Error::Device(format!(
                    "internal: {name} is launched with {threads} threads but allows {most}"
                )));
            }
        }
        Ok(())
    }

    /// Upload what the plan precomputed; `old` (the previous plan) lets unchanged
    /// steering vectors stay on the device.
    fn upload_plan(&mut self, old: Option<&Plan<T>>) -> Result<()> {
        let plan = self.plan.clone();
        let (m, nb) = (plan.num_mics, plan.num_bins());
        let (st, n2den) = plan.denominator_steering();
        // A plan made by a K update shares the steering arrays of the old one (only GEVD's
        // whitened steering is new): compare addresses, not 88 MB of values.
        let same_steering = old.is_some_and(|o| {
            let (ost, on2) = o.denominator_steering();
            std::ptr::eq(ost, st)
                && std::ptr::eq(on2, n2den)
                && std::ptr::eq(o.numerator_norm2(), plan.numerator_norm2())
        });
        if !same_steering {
            self.upload(BufId::St, as_bytes(st))?;
            self.upload(BufId::N2Den, as_bytes(n2den))?;
            self.upload(BufId::N2Num, as_bytes(plan.numerator_norm2()))?;
        }
        // W in double whatever T is: the decompositions whiten in double (as the CPU).
        if let Some(w) = &plan.whitening {
            if w.matrix64.len() == nb * m * m {
                let mut wcm = vec![c64::new(0.0, 0.0); nb * m * m];
                for b in 0..nb {
                    let src = &w.matrix64[b * m * m..(b + 1) * m * m];
                    let dst = &mut wcm[b * m * m..(b + 1) * m * m];
                    for i in 0..m {
                        for k in 0..m {
                            dst[k * m + i] = src[i * m + k];
                        }
                    }
                }
                self.upload(BufId::Wcm, as_bytes(&wcm))?;
                self.upload(BufId::Wrm, as_bytes(&w.matrix64))?;
            }
        }
        if (self.lay.left != 0 || self.lay.right != 0) && self.d_wcm.bytes == 0 {
            return Err(Error::Config(format!(
                "{} needs a noise correlation matrix",
                plan.config.algorithm.name()
            )));
        }
        self.upload(BufId::Weights, as_bytes(&plan.weights))?;
        let t = &plan.peak_table;
        let offs: Vec<i32> = t.offsets.iter().map(|&x| x as i32).collect();
        let nbrs: Vec<i32> = t.neighbors.iter().map(|&x| x as i32).collect();
        let az: Vec<u8> = t.azimuth_ok.iter().map(|&x| x as u8).collect();
        self.upload(BufId::Offs, as_bytes(&offs))?;
        self.upload(BufId::Nbrs, as_bytes(&nbrs))?;
        self.upload(BufId::AzOk, as_bytes(&az))?;
        self.gpu.sync(Stream::Copy)?;
        Ok(())
    }
}

impl<T: Real> Backend<T> for CudaBackend<T> {
    fn device_name(&self) -> String {
        format!("{} ({})", self.gpu.describe(), T::NAME)
    }

    fn max_windows_per_batch(&self) -> usize {
        self.max_batch
    }

    fn process(&mut self, jobs: &[Job<'_, T>], want_spectrum: bool, out: &mut BatchOutput) -> Result<()> {
        let r = self.run_jobs(jobs, want_spectrum, out);
        if r.is_err() {
            // Frames may be half up: trust nothing the arena says it holds.
            self.arena.forget();
        }
        r
    }

    fn set_plan(&mut self, plan: Arc<Plan<T>>) -> Result<()> {
        super::check_replacement_plan("cuda backend", &self.plan, &plan)?;
        self.gpu.make_current()?;
        self.gpu.sync(Stream::Compute)?;
        let old = std::mem::replace(&mut self.plan, plan);
        let lay = layout(&self.plan, &*self.gpu)?;
        let relayout = lay.srp != self.lay.srp
            || lay.eigh != self.lay.eigh
            || lay.left != self.lay.left
            || lay.right != self.lay.right
            || lay.want_v != self.lay.want_v
            || lay.ne != self.lay.ne
            || lay.peak_kout != self.lay.peak_kout;
        self.lay = lay;
        if relayout {
            self.load_functions()?;
            self.size_batches()?;
        }
        self.upload_plan(Some(&old))
    }

    fn stage_times(&self) -> StageTimes {
        self.times
    }

    fn reset_stage_times(&mut self) {
        self.times = StageTimes::default();
    }

    fn forget(&mut self, stream: StreamId) {
        self.arena.release(stream);
    }
}

impl<T: Real> Drop for CudaBackend<T> {
    fn drop(&mut self) {
        let _ = self.gpu.make_current();
        let _ = self.gpu.sync(Stream::Copy);
        let _ = self.gpu.sync(Stream::Compute);
        let bufs = [
            self.d_st.ptr,
            self.d_n2den.ptr,
            self.d_n2num.ptr,
            self.d_wcm.ptr,
            self.d_wrm.ptr,
            self.d_weights.ptr,
            self.d_offs.ptr,
            self.d_nbrs.ptr,
            self.d_azok.ptr,
            self.d_x.ptr,
            self.d_win.ptr,
            self.d_r.ptr,
            self.d_e.ptr,
            self.d_e64.ptr,
            self.d_scratch.ptr,
            self.d_ppart.ptr,
            self.d_gain.ptr,
            self.d_bw.ptr,
            self.d_info.ptr,
            self.d_prof.ptr,
            self.d_h.ptr,
            self.d_scale.ptr,
            self.d_db.ptr,
            self.d_spec.ptr,
            self.d_out.ptr,
            self.d_binmax.ptr,
            self.d_tri.ptr,
            self.d_count.ptr,
        ];
        for p in bufs {
            if p != 0 {
                self.gpu.free(p);
            }
        }
        let pinned = [
            self.h_stage[0].ptr,
            self.h_stage[1].ptr,
            self.h_win.ptr,
            self.h_out.ptr,
            self.h_spec.ptr,
            self.h_bw.ptr,
            self.h_zero.ptr,
            self.h_count.ptr,
        ];
        for p in pinned {
            if !p.is_null() {
                self.gpu.free_pinned(p);
            }
        }
        for e in self.events.drain(..).chain(self.chunk_ev) {
            if e != 0 {
                self.gpu.destroy_event(e);
            }
        }
    }
}
