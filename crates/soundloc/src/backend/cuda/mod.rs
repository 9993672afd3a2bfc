//! The CUDA backend: the whole numeric pipeline on the GPU, CUDA libraries loaded at run
//! time (cudarc, `dynamic-loading`), kernels compiled by NVRTC for the device's own
//! architecture on first use.
//!
//! ```text
//!  host frames ─(pinned staging, copy stream)─► X [frame][bin][mic]
//!  per sub-batch of windows, on the compute stream:
//!   correlate  (window × bin) blocks   R = (1/W) Σ x xᴴ, HARK scaling          correlate.cu
//!   eigh       one block per matrix    H = R | W R Wᴴ | W R W | (W R)(W R)ᴴ in f64,  eigh.cu
//!                                      Householder → tridiagonal, bisection, inverse
//!                                      iteration, top-Ns vectors (squared denominator, M ≤ 64)
//!   decompose  (otherwise)             G = W R Wᴴ | W R W | W R | R, one-sided    decompose.cu
//!                                      Jacobi in shared memory (all vectors when unsquared)
//!   spectrum   direction tiles         P̄ = Σ_k w_k g_k ‖a‖²/den, complement+refine  spectrum.cu
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
//! ‖(I − E_sE_sᴴ)a‖² by two Gram–Schmidt passes, which is the full noise-subspace sum to
//! rounding. The unsquared form needs every noise vector individually: then V is
//! accumulated (on Aᴴ for GSVD) and all M vectors are kept. The small products that
//! whiten R are fused into the Jacobi kernel's prologue (no cuBLAS round trip); the
//! correlation is its own small kernel so that stage times stay separate.
//! For the squared denominator with M ≤ 64 the signal vectors come instead from a
//! Householder tridiagonalisation of the Hermitian H (eigh.cu): ~(16/3)·M³ flops instead
//! of the Jacobi's ~10 sweeps × 8·M³, and H is formed and reduced in double precision, so
//! GSVD's A Aᴴ does not square the f32 rounding. `docs/gpu.md` has the measurements.
//!
//! **Batching.** `process` splits its windows into sub-batches sized to fill the GPU a
//! few times over; STFT frames go up through two pinned staging buffers on a copy stream
//! while earlier sub-batches compute, and each sub-batch's results come back on the
//! compute stream. Stage times are CUDA event intervals on the compute stream (the
//! upload overlaps and is not in them).
//!
//! Missing libraries, no GPU or a failed compile are `Error::Device`, never a panic:
//! library presence is checked before cudarc touches them and first initialisation runs
//! under `catch_unwind`.

mod device;
mod emu;
mod frames;
mod kernels;

use super::{Backend, BatchOutput, Job, Peak, StageTimes, StreamId};
use crate::config::{Algorithm, Denominator};
use crate::plan::Plan;
use crate::real::{Real, C};
use crate::{Error, Result};
use device::{CudaGpu, DevPtr, Event, Func, Gpu, Stream};
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

/// Build a CUDA backend on device `ordinal`, or say why none can be had.
pub fn new_backend<T: Real>(plan: Arc<Plan<T>>, ordinal: usize) -> Result<Box<dyn Backend<T>>> {
    guarded(|| {
        variant_for(&plan)?;
        let v = Variant {
            only: T::NAME,
            ..Variant::exact_for_mics(plan.num_mics).expect("checked by variant_for")
        };
        let gpu = CudaGpu::new(ordinal, v)?;
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
    if !plan.config.algorithm.is_music() || plan.config.normalize_bins {
        return Err(Error::Device(format!(
            "{}{} runs on the CPU only (no CUDA kernels for it yet)",
            plan.config.algorithm.name(),
            if plan.config.normalize_bins {
                " with per-bin normalisation"
            } else {
                ""
            }
        )));
    }
    Variant::for_mics(plan.num_mics).ok_or_else(|| {
        Error::Device(format!(
            "the CUDA backend handles up to 256 microphones, the array has {}",
            plan.num_mics
        ))
    })
}

/// A device buffer (freed by the backend).
#[derive(Default)]
struct Buf {
    ptr: DevPtr,
    bytes: usize,
}

/// A pinned host buffer.
struct Pinned {
    ptr: *mut u8,
    bytes: usize,
}

impl Default for Pinned {
    fn default() -> Self {
        Pinned {
            ptr: std::ptr::null_mut(),
            bytes: 0,
        }
    }
}

/// Kernel arguments, each stored in 8 bytes (little-endian: an i32 or f32 in the low
/// bytes), handed to the launch as `void*` to each slot.
struct Args {
    v: Vec<u64>,
}

impl Args {
    fn new() -> Self {
        Args {
            v: Vec::with_capacity(24),
        }
    }
    fn p(mut self, p: DevPtr) -> Self {
        self.v.push(p);
        self
    }
    fn i(mut self, x: usize) -> Self {
        self.v.push(x as i32 as u32 as u64);
        self
    }
    fn r<T: Real>(mut self, x: T) -> Self {
        if std::mem::size_of::<T>() == 4 {
            self.v.push((x.to_f64() as f32).to_bits() as u64);
        } else {
            self.v.push(x.to_f64().to_bits());
        }
        self
    }
    fn launch(mut self, gpu: &dyn Gpu, f: Func, grid: [usize; 3], block: usize, smem: usize) -> Result<()> {
        let mut ps: Vec<*mut c_void> = self.v.iter_mut().map(|x| x as *mut u64 as *mut c_void).collect();
        let g = [grid[0] as u32, grid[1] as u32, grid[2] as u32];
        // SAFETY: the argument lists below match the kernels' signatures (kernels/*.cu).
        unsafe { gpu.launch(f, g, block as u32, smem as u32, Stream::Compute, &mut ps) }
    }
}

/// Sizes and launch shapes derived from the plan.
#[derive(Debug, Clone)]
struct Layout {
    m: usize,
    nb: usize,
    d: usize,
    ns: usize,
    /// Vectors kept per matrix (ns, or M for the unsquared denominator).
    ne: usize,
    squared: bool,
    left: usize,
    right: usize,
    /// How the decomposition kernel evaluates the largest value (decompose.cu).
    valmode: usize,
    alg: Algorithm,
    lpp: usize,
    want_v: bool,
    ld: usize,
    dec_smem_mode: bool,
    /// Whether the signal subspace comes from the tridiagonal eigensolver (eigh.cu)
    /// instead of the Jacobi kernel.
    eigh: bool,
    eigh_threads: usize,
    eigh_smem: usize,
    form_h_smem: usize,
    dec_threads: usize,
    dec_smem: usize,
    dec_scratch_per_mat: usize,
    corr_fc: usize,
    corr_smem: usize,
    /// Directions per spectrum block.
    spec_dt: usize,
    /// Windows per spectrum block (at most).
    spec_wg: usize,
    /// Whether the spectrum kernel stages the windows' vectors in shared memory.
    spec_e_smem: bool,
    /// Shared memory of the steering tile.
    spec_tile: usize,
    peak_cap: usize,
    peak_kout: usize,
    peak_smem: usize,
}

struct Funcs {
    correlate: Func,
    decompose: Func,
    eigh: Func,
    form_h: Func,
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
    h_stage: [Pinned; 2],
    h_win: Pinned,
    h_out: Pinned,
    h_spec: Pinned,
    h_bw: Pinned,
    /// Staging buffers 0 and 1 reusable; the window table is up.
    chunk_ev: [Event; 3],
    /// Where streams' frames are in `d_x`.
    arena: frames::FrameArena,
    events: Vec<Event>,
}

// SAFETY: the pinned pointers are owned by this struct and only touched by the thread
// that calls its methods; the device handle is Send.
unsafe impl<T: Real> Send for CudaBackend<T> {}

fn csize<T: Real>() -> usize {
    std::mem::size_of::<C<T>>()
}

fn as_bytes<V>(v: &[V]) -> &[u8] {
    // SAFETY: plain-old-data slices (reals, complex pairs, integers).
    unsafe { std::slice::from_raw_parts(v.as_ptr() as *const u8, std::mem::size_of_val(v)) }
}

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
                decompose: 0,
                eigh: 0,
                form_h: 0,
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
            h_stage: [Pinned::default(), Pinned::default()],
            h_win: Pinned::default(),
            h_out: Pinned::default(),
            h_spec: Pinned::default(),
            h_bw: Pinned::default(),
            chunk_ev: [0, 0, 0],
            arena: frames::FrameArena::default(),
            events: Vec::new(),
        };
        b.load_functions()?;
        b.upload_plan(None)?;
        b.chunk_ev = [b.gpu.event()?, b.gpu.event()?, b.gpu.event()?];
        b.size_batches()?;
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
            correlate: self.gpu.function(&format!("correlate_{t}"))?,
            decompose: self.gpu.function(&dec)?,
            eigh: self.gpu.function(&format!("eigh_{t}"))?,
            form_h: self.gpu.function(&format!("form_h_{t}"))?,
            spectrum: self.gpu.function(&format!("spectrum_{t}"))?,
            peaks: self.gpu.function(&format!("peaks_{t}"))?,
        };
        for (f, s) in [
            (self.f.correlate, l.corr_smem),
            (self.f.decompose, l.dec_smem),
            (self.f.eigh, l.eigh_smem),
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
            (self.f.correlate, "correlate", 256),
            (self.f.decompose, "decompose", l.dec_threads),
            (self.f.eigh, "eigh", l.eigh_threads),
            (self.f.form_h, "form_h", l.eigh_threads),
            (self.f.spectrum, "spectrum", l.spec_dt * l.spec_wg),
            (self.f.peaks, "peaks", 256),
        ] {
            let most = self.gpu.max_threads(f)?;
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
                && Arc::ptr_eq(&o.steering_norm2, &plan.steering_norm2)
        });
        if !same_steering {
            self.upload(BufId::St, as_bytes(st))?;
            self.upload(BufId::N2Den, as_bytes(n2den))?;
            self.upload(BufId::N2Num, as_bytes(&plan.steering_norm2))?;
        }
        if let Some(w) = &plan.whitening {
            if w.matrix.len() == nb * m * m {
                let mut wcm = vec![C::new(T::zero(), T::zero()); nb * m * m];
                for b in 0..nb {
                    let src = &w.matrix[b * m * m..(b + 1) * m * m];
                    let dst = &mut wcm[b * m * m..(b + 1) * m * m];
                    for i in 0..m {
                        for k in 0..m {
                            dst[k * m + i] = src[i * m + k];
                        }
                    }
                }
                self.upload(BufId::Wcm, as_bytes(&wcm))?;
                self.upload(BufId::Wrm, as_bytes(&w.matrix))?;
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

    fn buf(&mut self, id: BufId) -> &mut Buf {
        match id {
            BufId::St => &mut self.d_st,
            BufId::N2Den => &mut self.d_n2den,
            BufId::N2Num => &mut self.d_n2num,
            BufId::Wcm => &mut self.d_wcm,
            BufId::Wrm => &mut self.d_wrm,
            BufId::Weights => &mut self.d_weights,
            BufId::Offs => &mut self.d_offs,
            BufId::Nbrs => &mut self.d_nbrs,
            BufId::AzOk => &mut self.d_azok,
        }
    }

    /// Synchronous upload of plan data into its buffer (grown as needed).
    fn upload(&mut self, id: BufId, data: &[u8]) -> Result<()> {
        let need = data.len().max(16);
        let (ptr, bytes) = {
            let b = self.buf(id);
            (b.ptr, b.bytes)
        };
        if bytes < need {
            if ptr != 0 {
                self.gpu.free(ptr);
            }
            let p = self.gpu.alloc(need)?;
            *self.buf(id) = Buf { ptr: p, bytes: need };
        }
        let dst = self.buf(id).ptr;
        if !data.is_empty() {
            // SAFETY: `data` outlives the synchronisation below; dst holds `need` bytes.
            unsafe { self.gpu.htod(dst, data.as_ptr(), data.len(), Stream::Copy)? };
            self.gpu.sync(Stream::Copy)?;
        }
        Ok(())
    }

    /// Pick the sub-batch size and the largest batch from free device memory.
    fn size_batches(&mut self) -> Result<()> {
        let l = &self.lay;
        let (cs, ts) = (csize::<T>(), std::mem::size_of::<T>());
        let sms = self.gpu.sm_count().max(1);
        // About 32 matrices per multiprocessor per sub-batch: several waves of the
        // decomposition kernel, so that the tail of one wave does not dominate.
        let sub = (32 * sms).div_ceil(l.nb).clamp(1, 256);
        let h_per_mat = if l.eigh && l.valmode != 0 {
            l.m * l.m * 16
        } else {
            0
        };
        let per_sub_window = l.nb * l.m * l.m * cs
            + l.nb * l.ne * l.m * cs
            + l.nb * (l.dec_scratch_per_mat + h_per_mat)
            + l.nb * l.d * ts;
        let (free, _) = self.gpu.mem_info()?;
        let budget = free / 4;
        self.sub_batch = sub.min((budget / per_sub_window.max(1)).max(1));
        let w = self.plan.config.window.max(1);
        let per_window = w * l.nb * l.m * cs + l.d * (8 + 4 + ts) + l.nb * (ts + 8) + (1 + l.peak_kout) * 16;
        self.max_batch =
            ((free / 4).saturating_sub(self.sub_batch * per_sub_window) / per_window.max(1)).clamp(1, 4096);
        Ok(())
    }

    /// The device buffer behind a scratch slot.
    fn slot(&mut self, which: Scratch) -> &mut Buf {
        match which {
            Scratch::X => &mut self.d_x,
            Scratch::Win => &mut self.d_win,
            Scratch::R => &mut self.d_r,
            Scratch::E => &mut self.d_e,
            Scratch::Jacobi => &mut self.d_scratch,
            Scratch::Ppart => &mut self.d_ppart,
            Scratch::Gain => &mut self.d_gain,
            Scratch::Bw => &mut self.d_bw,
            Scratch::Info => &mut self.d_info,
            Scratch::Prof => &mut self.d_prof,
            Scratch::H => &mut self.d_h,
            Scratch::Scale => &mut self.d_scale,
            Scratch::Db => &mut self.d_db,
            Scratch::Spec => &mut self.d_spec,
            Scratch::Out => &mut self.d_out,
        }
    }

    fn ensure(&mut self, which: Scratch, bytes: usize) -> Result<DevPtr> {
        let Buf {
            ptr: old,
            bytes: have,
        } = *self.slot(which);
        if have >= bytes.max(16) {
            return Ok(old);
        }
        let grow = (bytes.max(16) + bytes / 4).max(have * 3 / 2);
        if old != 0 {
            self.gpu.free(old);
            // Never leave a freed pointer in the slot if the allocation below fails.
            *self.slot(which) = Buf { ptr: 0, bytes: 0 };
        }
        let p = self.gpu.alloc(grow)?;
        *self.slot(which) = Buf { ptr: p, bytes: grow };
        Ok(p)
    }

    fn ensure_pinned(&mut self, which: HostBuf, bytes: usize) -> Result<*mut u8> {
        let need = bytes.max(16);
        let cur = match which {
            HostBuf::Stage0 => &self.h_stage[0],
            HostBuf::Stage1 => &self.h_stage[1],
            HostBuf::Win => &self.h_win,
            HostBuf::Out => &self.h_out,
            HostBuf::Spec => &self.h_spec,
            HostBuf::Bw => &self.h_bw,
        };
        if cur.bytes >= need {
            return Ok(cur.ptr);
        }
        let old = cur.ptr;
        let grow = need.max(cur.bytes * 3 / 2);
        if !old.is_null() {
            // Outstanding copies may still read or write it.
            self.gpu.sync(Stream::Copy)?;
            self.gpu.sync(Stream::Compute)?;
            self.gpu.free_pinned(old);
        }
        let p = self.gpu.alloc_pinned(grow)?;
        let slot = match which {
            HostBuf::Stage0 => &mut self.h_stage[0],
            HostBuf::Stage1 => &mut self.h_stage[1],
            HostBuf::Win => &mut self.h_win,
            HostBuf::Out => &mut self.h_out,
            HostBuf::Spec => &mut self.h_spec,
            HostBuf::Bw => &mut self.h_bw,
        };
        *slot = Pinned { ptr: p, bytes: grow };
        Ok(p)
    }

    /// Spectrum bin groups for a sub-batch of `nwb` windows: enough blocks to fill the GPU.
    fn bin_groups(&self, nwb: usize) -> usize {
        let l = &self.lay;
        let xy = l.d.div_ceil(l.spec_dt) * nwb.div_ceil(l.spec_wg.min(nwb).max(1));
        (4 * self.gpu.sm_count()).div_ceil(xy.max(1)).clamp(1, l.nb)
    }

    /// Mean cycles per phase of eigh.cu over the last batch's matrices, on stderr
    /// (SOUNDLOC_CUDA_PROFILE=1; a tuning aid).
    fn print_profile(&mut self, nmat: usize) -> Result<()> {
        let mut t = vec![0i64; nmat * 8];
        // SAFETY: synchronous copy of the profile buffer after the stream is idle.
        unsafe {
            self.gpu.dtoh(
                t.as_mut_ptr() as *mut u8,
                self.d_prof.ptr,
                nmat * 64,
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
        for (p, name) in names.iter().enumerate() {
            let mean = t.chunks(8).map(|c| (c[p + 1] - c[p]) as f64).sum::<f64>() / nmat.max(1) as f64;
            line.push_str(&format!(" {name} {mean:.0}"));
        }
        let _ = writeln!(std::io::stderr(), "{line}");
        Ok(())
    }

    /// The tridiagonal eigensolver (eigh.cu) of this sub-batch's matrices: form_h for the
    /// whitened cases, then eigh.
    fn launch_eigh(&self, mat0: usize, nmat: usize) -> Result<()> {
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
                    l.eigh_threads,
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
            .p(self.d_e.ptr)
            .p(self.d_gain.ptr)
            .p(self.d_bw.ptr)
            .p(self.d_info.ptr)
            .p(if self.profile { self.d_prof.ptr } else { 0 })
            .launch(&*self.gpu, self.f.eigh, [nmat, 1, 1], l.eigh_threads, l.eigh_smem)
    }

    /// The Jacobi decomposition (decompose.cu) of this sub-batch's matrices.
    fn launch_jacobi(&self, mat0: usize, nmat: usize, mode: &DecMode) -> Result<()> {
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

    #[allow(clippy::too_many_arguments)]
    fn launch_sub_batch(
        &mut self,
        k: usize,
        nw: usize,
        kout: usize,
        want_spectrum: bool,
        mode: &DecMode,
        ev: &[Event],
    ) -> Result<()> {
        let l = self.lay.clone();
        let (cs, ts) = (csize::<T>(), std::mem::size_of::<T>());
        let sb = self.sub_batch;
        let w0 = k * sb;
        let nwb = sb.min(nw - w0);
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
            .p(self.d_r.ptr)
            .p(self.d_scale.ptr)
            .launch(g, self.f.correlate, [nmat, 1, 1], 256, l.corr_smem)?;
        g.record(ev[1], Stream::Compute)?;
        if l.eigh {
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
        Args::new()
            .p(self.d_st.ptr)
            .p(n2den)
            .p(self.d_n2num.ptr)
            .p(self.d_e.ptr)
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
            .p(self.d_ppart.ptr)
            .launch(
                g,
                self.f.spectrum,
                [l.d.div_ceil(l.spec_dt), nwb.div_ceil(wg), nbg],
                l.spec_dt * wg,
                spec_smem,
            )?;
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
                g.dtoh(
                    self.h_bw.ptr.add(mat0 * 4),
                    self.d_bw.ptr + (mat0 * 4) as u64,
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

/// How the decomposition kernel forms the matrix it rotates (per batch).
#[derive(Debug, Clone, Copy)]
struct DecMode {
    /// 0: the M × M matrix from R; 1: the factor W·Yᴴ (W < M frames, Hermitian cases);
    /// 2: the GSVD factor K⁻¹ R Q (Q an orthonormal basis of the frames).
    factor: usize,
    /// Columns of the factor (even).
    ncf: usize,
    left: usize,
    right: usize,
    threads: usize,
}

#[derive(Clone, Copy)]
enum BufId {
    St,
    N2Den,
    N2Num,
    Wcm,
    Wrm,
    Weights,
    Offs,
    Nbrs,
    AzOk,
}

#[derive(Clone, Copy)]
enum Scratch {
    X,
    Win,
    R,
    E,
    Jacobi,
    Ppart,
    Gain,
    Bw,
    Info,
    Prof,
    H,
    Scale,
    Db,
    Spec,
    Out,
}

#[derive(Clone, Copy)]
enum HostBuf {
    Stage0,
    Stage1,
    Win,
    Out,
    Spec,
    Bw,
}

/// Eigenvectors of the tridiagonal matrix solved at once by eigh.cu (its EH_VEC).
const EIGH_VEC: usize = 8;

fn layout<T: Real>(plan: &Plan<T>, gpu: &dyn Gpu) -> Result<Layout> {
    let (cs, ts) = (csize::<T>(), std::mem::size_of::<T>());
    let m = plan.num_mics;
    let nb = plan.num_bins();
    let d = plan.num_dirs;
    let ns = plan.config.signal_dim();
    let squared = plan.config.denominator == Denominator::Squared;
    let (left, right) = match (plan.config.algorithm, squared) {
        (Algorithm::Sevd, _) => (0, 0),
        (Algorithm::Gevd, _) => (1, 1),
        (Algorithm::GevdHark, _) => (1, 2),
        (Algorithm::Gsvd, true) => (1, 0),
        (Algorithm::Gsvd, false) => (0, 1),
        (Algorithm::SrpPhat, _) => {
            return Err(variant_for(plan)
                .err()
                .unwrap_or_else(|| Error::Device("srp-phat".into())))
        }
    };
    let valmode = match plan.config.algorithm {
        Algorithm::Sevd => 0,
        Algorithm::Gevd => 1,
        Algorithm::GevdHark => 2,
        Algorithm::Gsvd => 3,
        Algorithm::SrpPhat => 0,
    };
    let want_v = !squared;
    let ne = if squared { ns } else { m };
    let v = variant_for(plan)?;
    let n = m + (m & 1);
    let mut ld = n;
    while ld % 16 != 4 {
        ld += 1;
    }
    let optin = gpu.max_smem_optin().max(SMEM_DEFAULT);
    let mats = if want_v { 2 } else { 1 } * n * ld * cs;
    let small = (3 * n * cs + n * ts + 32 * ts + 2 * n * 4).div_ceil(16) * 16;
    let dec_smem_mode = mats + small <= optin;
    let (dec_smem, dec_scratch_per_mat) = if dec_smem_mode {
        (mats + small, 0)
    } else {
        (small, mats)
    };
    // The tridiagonal eigensolver whenever only the signal vectors are needed and its
    // register tiles cover M (SOUNDLOC_CUDA_DEC=jacobi keeps the Jacobi kernel, for A/B runs).
    let eigh_threads = kernels::eigh_threads();
    let eigh_smem =
        (m * (m | 1) + 4 * m) * 16 + (3 * m + ns + ns * m + ns.min(EIGH_VEC) * 5 * m) * 8 + 33 * 4;
    let form_h_smem = m * (m | 1) * 16;
    let eigh = squared
        && m <= 64
        && eigh_smem <= optin
        && std::env::var("SOUNDLOC_CUDA_DEC").map_or(true, |v| v != "jacobi");
    let groups = n / 2 * v.lpp as usize;
    let dec_threads = groups.div_ceil(32).clamp(1, 32) * 32;
    let corr_fc = ((SMEM_DEFAULT - 32 * 8) / (m * cs)).clamp(1, 32);
    let corr_smem = corr_fc * m * cs + 32 * 8;
    let lds = m | 1;
    let mut spec_dt = 64;
    while spec_dt > 32 && spec_dt * lds * cs > 64 * 1024 {
        spec_dt /= 2;
    }
    let spec_tile = spec_dt * lds * cs;
    if spec_tile > optin {
        return Err(Error::Device(format!(
            "{m} microphones: the spectrum tile does not fit in shared memory"
        )));
    }
    let spec_wg = if squared { 4 } else { 1 };
    let spec_e_smem = spec_tile + spec_wg * ne * m * cs <= optin.min(160 * 1024);
    let peak_cap = d.next_power_of_two().clamp(1, 4096);
    let peak_kout = plan.peak_table.max_out.min(peak_cap);
    let peak_smem = peak_cap * 12;
    Ok(Layout {
        m,
        nb,
        d,
        ns,
        ne,
        squared,
        left,
        right,
        valmode,
        alg: plan.config.algorithm,
        lpp: v.lpp as usize,
        want_v,
        ld,
        dec_smem_mode,
        eigh,
        eigh_threads,
        eigh_smem,
        form_h_smem,
        dec_threads,
        dec_smem,
        dec_scratch_per_mat,
        corr_fc,
        corr_smem,
        spec_dt,
        spec_wg,
        spec_e_smem,
        spec_tile,
        peak_cap,
        peak_kout,
        peak_smem,
    })
}

impl<T: Real> CudaBackend<T> {
    /// [`Backend::process`] without the clean-up on error.
    fn run_jobs(&mut self, jobs: &[Job<'_, T>], want_spectrum: bool, out: &mut BatchOutput) -> Result<()> {
        let (m, nb, d) = (self.lay.m, self.lay.nb, self.lay.d);
        super::check_jobs("cuda backend", &self.plan, jobs)?;
        out.peaks.clear();
        out.spectrum_db.clear();
        out.bin_weight.clear();
        out.source_count.clear();
        let nw = super::count_windows(jobs);
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
        let nsb = nw.div_ceil(sb);
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
        self.ensure(Scratch::R, nwb_max * nb * m * m * cs)?;
        self.ensure(Scratch::E, nwb_max * nb * l.ne * m * cs)?;
        if !l.dec_smem_mode {
            self.ensure(Scratch::Jacobi, nwb_max * nb * l.dec_scratch_per_mat)?;
        }
        let nbg_max = (0..nsb)
            .map(|k| self.bin_groups(sb.min(nw - k * sb)))
            .max()
            .unwrap_or(1);
        self.ensure(Scratch::Ppart, nbg_max * nwb_max * d * ts)?;
        self.ensure(Scratch::Gain, nw * nb * ts)?;
        self.ensure(Scratch::Bw, nw * nb * 4)?;
        self.ensure(Scratch::Info, nw * nb * 4)?;
        if self.profile && l.eigh {
            self.ensure(Scratch::Prof, nw * nb * 64)?;
        }
        if l.eigh && l.valmode != 0 {
            self.ensure(Scratch::H, nwb_max * nb * m * m * 16)?;
        }
        self.ensure(Scratch::Scale, nwb_max * nb * ts)?;
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
        let mode = if l.squared && maxlen < m && self.factor_ok {
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
        for k in 0..nsb {
            for r in &ready[k * sb..(k * sb + sb).min(nw)] {
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
            self.launch_sub_batch(next, nw, kout, want_spectrum, &mode, &events[5 * next..5 * next + 5])?;
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
                    self.launch_sub_batch(next, nw, kout, want_spectrum, &mode, &events[5 * next..5 * next + 5])?;
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
        if self.debug {
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
                "soundloc cuda: {nw} windows in {nsb} sub-batches of {sb}, {}; {} min {} mean {mean:.2} max {}",
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
                out.bin_weight
                    .extend_from_slice(std::slice::from_raw_parts(self.h_bw.ptr as *const f32, nw * nb));
            }
        }
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
        let relayout = lay.left != self.lay.left
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
}

/// Copy host bytes into pinned memory, in parallel for large copies.
fn copy_to_pinned(src: &[u8], dst: *mut u8) {
    const PIECE: usize = 256 << 10;
    struct P(*mut u8);
    // SAFETY: disjoint pieces of one buffer are written by different threads.
    unsafe impl Sync for P {}
    unsafe impl Send for P {}
    let d = P(dst);
    if src.len() <= 2 * PIECE || rayon::current_num_threads() < 2 {
        // SAFETY: the caller sized `dst` for `src`.
        unsafe { std::ptr::copy_nonoverlapping(src.as_ptr(), dst, src.len()) };
        return;
    }
    src.par_chunks(PIECE).enumerate().for_each(|(i, c)| {
        let d = &d;
        // SAFETY: piece i lands at offset i·PIECE, inside the buffer, disjoint from others.
        unsafe { std::ptr::copy_nonoverlapping(c.as_ptr(), d.0.add(i * PIECE), c.len()) };
    });
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
