//! The device seam: the few driver operations the backend needs, behind [`Gpu`], with
//! two implementations — [`CudaGpu`] (the CUDA driver API through cudarc, libraries
//! loaded at run time) and `emu::EmuGpu` (the CPU emulator of the kernels, for tests).
//!
//! Device memory is addressed by plain `u64` pointers and kernels are launched with
//! `void**` parameter arrays, exactly as `cuLaunchKernel` takes them, so the backend's
//! orchestration code is the same on both.

use super::kernels::{self, Variant};
use crate::{Error, Result};
use cudarc::driver::{result as drv, sys};
use std::ffi::{c_void, CString};
use std::path::Path;

/// A device pointer.
pub(crate) type DevPtr = u64;

/// The two streams the backend uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Stream {
    /// Kernels and result downloads.
    Compute,
    /// Uploads of STFT frames.
    Copy,
}

/// An event handle (opaque).
pub(crate) type Event = u64;
/// A kernel handle (opaque).
pub(crate) type Func = u64;

/// What the backend asks of a device.
pub(crate) trait Gpu: Send {
    /// e.g. `cuda:0 NVIDIA H200 (sm_90)`.
    fn describe(&self) -> String;
    /// Make this device's context current on the calling thread.
    fn make_current(&self) -> Result<()>;
    /// (free, total) device memory in bytes.
    fn mem_info(&self) -> Result<(usize, usize)>;
    /// Number of multiprocessors.
    fn sm_count(&self) -> usize;
    /// Largest dynamic shared memory a block may opt in to.
    fn max_smem_optin(&self) -> usize;
    /// Allocate device memory.
    fn alloc(&mut self, bytes: usize) -> Result<DevPtr>;
    /// Free device memory from `alloc`.
    fn free(&mut self, p: DevPtr);
    /// Allocate page-locked host memory.
    fn alloc_pinned(&mut self, bytes: usize) -> Result<*mut u8>;
    /// Free memory from `alloc_pinned`.
    fn free_pinned(&mut self, p: *mut u8);
    /// Asynchronous host → device copy (`src` must stay valid until the stream passes it).
    ///
    /// # Safety
    /// `src` valid for `bytes`, `dst` a device allocation of at least `bytes`.
    unsafe fn htod(&self, dst: DevPtr, src: *const u8, bytes: usize, s: Stream) -> Result<()>;
    /// Asynchronous device → host copy.
    ///
    /// # Safety
    /// As `htod`, reversed.
    unsafe fn dtoh(&self, dst: *mut u8, src: DevPtr, bytes: usize, s: Stream) -> Result<()>;
    /// Look up a kernel of the loaded module.
    fn function(&mut self, name: &str) -> Result<Func>;
    /// Allow `bytes` of dynamic shared memory for `f`.
    fn set_max_smem(&self, f: Func, bytes: usize) -> Result<()>;
    /// The largest block `f` can be launched with (its launch bounds and registers).
    fn max_threads(&self, f: Func) -> Result<usize>;
    /// Registers per thread and local (spilled) bytes per thread of `f` (diagnostics).
    fn resources(&self, f: Func) -> Result<(usize, usize)>;
    /// Launch `f` (1-D blocks).
    ///
    /// # Safety
    /// `params` must match the kernel's signature and point to live values.
    unsafe fn launch(
        &self,
        f: Func,
        grid: [u32; 3],
        block: u32,
        smem: u32,
        s: Stream,
        params: &mut [*mut c_void],
    ) -> Result<()>;
    /// A new timing event.
    fn event(&mut self) -> Result<Event>;
    /// Record `e` on `s`.
    fn record(&self, e: Event, s: Stream) -> Result<()>;
    /// Make `s` wait for `e`.
    fn wait(&self, s: Stream, e: Event) -> Result<()>;
    /// Block the host until `e` completed.
    fn sync_event(&self, e: Event) -> Result<()>;
    /// Milliseconds between two completed events.
    fn elapsed_ms(&self, a: Event, b: Event) -> Result<f32>;
    /// Block the host until `s` is idle.
    fn sync(&self, s: Stream) -> Result<()>;
    /// Destroy an event.
    fn destroy_event(&mut self, e: Event);
}

pub(crate) fn dev_err(what: &str, e: impl std::fmt::Display) -> Error {
    Error::Device(format!("{what}: {e}"))
}

/// Check that the driver library can be loaded (cudarc would panic otherwise).
pub(crate) fn driver_present() -> bool {
    // SAFETY: only tries to dlopen the library names cudarc would use.
    unsafe { sys::is_culib_present() }
}

/// A CUDA device with its primary context, two streams and the soundloc module.
pub(crate) struct CudaGpu {
    ordinal: usize,
    dev: sys::CUdevice,
    ctx: sys::CUcontext,
    compute: sys::CUstream,
    copy: sys::CUstream,
    module: sys::CUmodule,
    name: String,
    cc: u32,
    sms: usize,
    smem_optin: usize,
    arch: String,
}

// SAFETY: the handles are plain driver handles; every entry point makes the context
// current on the calling thread first, and the backend is used by one thread at a time.
unsafe impl Send for CudaGpu {}

/// Number of GPUs the driver reports (initialises the driver).
pub(crate) fn device_count() -> Result<usize> {
    if !driver_present() {
        return Err(Error::Device(
            "the NVIDIA driver library (libcuda.so.1) was not found: no CUDA driver installed".into(),
        ));
    }
    drv::init().map_err(|e| dev_err("cuInit", e))?;
    let count = drv::device::get_count().map_err(|e| dev_err("cuDeviceGetCount", e))?;
    if count <= 0 {
        return Err(Error::Device("the CUDA driver reports no GPU".into()));
    }
    Ok(count as usize)
}

/// Initialise the driver and retain device `ordinal`'s primary context: the slow part of a
/// first [`CudaGpu::new`] (≈ 0.2 s), which [`super::prewarm`] runs while the transfer
/// functions load. The reference is given back with [`release_context`] once the backend
/// (which retains its own) exists, so the context lives exactly as long as before.
pub(crate) fn retain_context(ordinal: usize) -> Result<()> {
    device_info(ordinal)?;
    let dev = drv::device::get(ordinal as i32).map_err(|e| dev_err("cuDeviceGet", e))?;
    // SAFETY: `dev` is valid; released by `release_context`.
    unsafe { drv::primary_ctx::retain(dev) }.map_err(|e| dev_err("cuDevicePrimaryCtxRetain", e))?;
    Ok(())
}

/// Give back a reference taken by [`retain_context`].
pub(crate) fn release_context(ordinal: usize) {
    if let Ok(dev) = drv::device::get(ordinal as i32) {
        // SAFETY: pairs with the retain in `retain_context`.
        let _ = unsafe { drv::primary_ctx::release(dev) };
    }
}

/// Name and compute capability of device `ordinal` (initialises the driver).
pub(crate) fn device_info(ordinal: usize) -> Result<(String, u32, usize)> {
    if !driver_present() {
        return Err(Error::Device(
            "the NVIDIA driver library (libcuda.so.1) was not found: no CUDA driver installed".into(),
        ));
    }
    drv::init().map_err(|e| dev_err("cuInit", e))?;
    let count = drv::device::get_count().map_err(|e| dev_err("cuDeviceGetCount", e))?;
    if count <= 0 {
        return Err(Error::Device("the CUDA driver reports no GPU".into()));
    }
    if ordinal >= count as usize {
        return Err(Error::Device(format!(
            "cuda:{ordinal} requested, but only {count} GPU(s) present"
        )));
    }
    let dev = drv::device::get(ordinal as i32).map_err(|e| dev_err("cuDeviceGet", e))?;
    let name = drv::device::get_name(dev).map_err(|e| dev_err("cuDeviceGetName", e))?;
    use sys::CUdevice_attribute as A;
    // SAFETY: `dev` came from cuDeviceGet.
    let (major, minor, sms) = unsafe {
        (
            drv::device::get_attribute(dev, A::CU_DEVICE_ATTRIBUTE_COMPUTE_CAPABILITY_MAJOR)
                .map_err(|e| dev_err("cuDeviceGetAttribute", e))?,
            drv::device::get_attribute(dev, A::CU_DEVICE_ATTRIBUTE_COMPUTE_CAPABILITY_MINOR)
                .map_err(|e| dev_err("cuDeviceGetAttribute", e))?,
            drv::device::get_attribute(dev, A::CU_DEVICE_ATTRIBUTE_MULTIPROCESSOR_COUNT)
                .map_err(|e| dev_err("cuDeviceGetAttribute", e))?,
        )
    };
    Ok((name, (major * 10 + minor) as u32, sms as usize))
}

impl CudaGpu {
    /// Open device `ordinal` and load the module for `variant`.
    pub(crate) fn new(ordinal: usize, variant: Variant, cache: Option<&Path>) -> Result<Self> {
        let (name, cc, sms) = device_info(ordinal)?;
        if cc < 60 {
            return Err(Error::Device(format!(
                "{name} has compute capability {}.{}; soundloc needs 6.0 or newer (f64 atomics, shuffles)",
                cc / 10,
                cc % 10
            )));
        }
        tracing::debug!("cuda:{ordinal}: {name} (sm_{cc}, {sms} SMs)");
        let mut img = kernels::image_for(variant, cc, cache, true).map_err(Error::Device)?;
        tracing::debug!(
            "cuda:{ordinal}: kernels ready ({}, {} bytes)",
            img.arch,
            img.bytes.len()
        );
        let dev = drv::device::get(ordinal as i32).map_err(|e| dev_err("cuDeviceGet", e))?;
        // SAFETY: `dev` is valid; the context is retained until Drop.
        let ctx =
            unsafe { drv::primary_ctx::retain(dev) }.map_err(|e| dev_err("cuDevicePrimaryCtxRetain", e))?;
        tracing::debug!("cuda:{ordinal}: context ready");
        // SAFETY: ctx is a live primary context.
        unsafe { drv::ctx::set_current(ctx) }.map_err(|e| dev_err("cuCtxSetCurrent", e))?;
        let smem_optin = unsafe {
            drv::device::get_attribute(
                dev,
                sys::CUdevice_attribute::CU_DEVICE_ATTRIBUTE_MAX_SHARED_MEMORY_PER_BLOCK_OPTIN,
            )
        }
        .map_err(|e| dev_err("cuDeviceGetAttribute", e))? as usize;
        let mut g = CudaGpu {
            ordinal,
            dev,
            ctx,
            compute: std::ptr::null_mut(),
            copy: std::ptr::null_mut(),
            module: std::ptr::null_mut(),
            name,
            cc,
            sms,
            smem_optin,
            arch: img.arch.clone(),
        };
        g.compute = drv::stream::create(drv::stream::StreamKind::NonBlocking)
            .map_err(|e| dev_err("cuStreamCreate", e))?;
        g.copy = drv::stream::create(drv::stream::StreamKind::NonBlocking)
            .map_err(|e| dev_err("cuStreamCreate", e))?;
        // SAFETY: a CUBIN, or NUL-terminated PTX.
        let mut loaded = unsafe { drv::module::load_data(img.bytes.as_ptr() as *const c_void) };
        if let (Err(e), true) = (&loaded, img.prebuilt) {
            // A driver older than the compiler that made the embedded image: compile here.
            tracing::debug!("cuda:{ordinal}: the embedded kernels do not load ({e}); compiling them");
            let refused = e.to_string();
            img = kernels::image_for(variant, cc, cache, false).map_err(|why| {
                Error::Device(format!(
                    "the driver does not load the kernels built into soundloc ({refused}; a CUDA 13 \
                     driver, 580 or later, does), and they cannot be compiled here: {why}"
                ))
            })?;
            // SAFETY: as above.
            loaded = unsafe { drv::module::load_data(img.bytes.as_ptr() as *const c_void) };
        }
        g.module = loaded.map_err(|e| dev_err(&format!("cuModuleLoadData ({})", img.arch), e))?;
        g.arch = img.arch;
        tracing::debug!("cuda:{ordinal}: module loaded");
        Ok(g)
    }

    fn stream(&self, s: Stream) -> sys::CUstream {
        match s {
            Stream::Compute => self.compute,
            Stream::Copy => self.copy,
        }
    }
}

impl Drop for CudaGpu {
    fn drop(&mut self) {
        // SAFETY: handles created in `new`; errors at teardown are ignored.
        unsafe {
            let _ = drv::ctx::set_current(self.ctx);
            if !self.compute.is_null() {
                let _ = drv::stream::synchronize(self.compute);
                let _ = drv::stream::destroy(self.compute);
            }
            if !self.copy.is_null() {
                let _ = drv::stream::synchronize(self.copy);
                let _ = drv::stream::destroy(self.copy);
            }
            if !self.module.is_null() {
                let _ = drv::module::unload(self.module);
            }
            let _ = drv::primary_ctx::release(self.dev);
        }
    }
}

impl Gpu for CudaGpu {
    fn describe(&self) -> String {
        format!(
            "cuda:{} {} (sm_{}, {})",
            self.ordinal, self.name, self.cc, self.arch
        )
    }

    fn make_current(&self) -> Result<()> {
        // SAFETY: ctx retained for our lifetime.
        unsafe { drv::ctx::set_current(self.ctx) }.map_err(|e| dev_err("cuCtxSetCurrent", e))
    }

    fn mem_info(&self) -> Result<(usize, usize)> {
        drv::mem_get_info().map_err(|e| dev_err("cuMemGetInfo", e))
    }

    fn sm_count(&self) -> usize {
        self.sms
    }

    fn max_smem_optin(&self) -> usize {
        self.smem_optin
    }

    fn alloc(&mut self, bytes: usize) -> Result<DevPtr> {
        // SAFETY: plain allocation in the current context.
        unsafe { drv::malloc_sync(bytes.max(16)) }
            .map_err(|e| dev_err(&format!("cuMemAlloc({bytes} bytes)"), e))
    }

    fn free(&mut self, p: DevPtr) {
        // SAFETY: `p` came from alloc; the streams are synchronised by the owner first.
        unsafe {
            let _ = drv::free_sync(p);
        }
    }

    fn alloc_pinned(&mut self, bytes: usize) -> Result<*mut u8> {
        // SAFETY: plain allocation.
        unsafe { drv::malloc_host(bytes.max(16), 0) }
            .map(|p| p as *mut u8)
            .map_err(|e| dev_err(&format!("cuMemHostAlloc({bytes} bytes)"), e))
    }

    fn free_pinned(&mut self, p: *mut u8) {
        // SAFETY: `p` came from alloc_pinned.
        unsafe {
            let _ = drv::free_host(p as *mut c_void);
        }
    }

    unsafe fn htod(&self, dst: DevPtr, src: *const u8, bytes: usize, s: Stream) -> Result<()> {
        // SAFETY: per the caller's contract.
        unsafe { sys::cuMemcpyHtoDAsync_v2(dst, src as *const c_void, bytes, self.stream(s)) }
            .result()
            .map_err(|e| dev_err("cuMemcpyHtoDAsync", e))
    }

    unsafe fn dtoh(&self, dst: *mut u8, src: DevPtr, bytes: usize, s: Stream) -> Result<()> {
        // SAFETY: per the caller's contract.
        unsafe { sys::cuMemcpyDtoHAsync_v2(dst as *mut c_void, src, bytes, self.stream(s)) }
            .result()
            .map_err(|e| dev_err("cuMemcpyDtoHAsync", e))
    }

    fn function(&mut self, name: &str) -> Result<Func> {
        let c = CString::new(name).map_err(|e| Error::Device(e.to_string()))?;
        // SAFETY: module loaded in `new`.
        unsafe { drv::module::get_function(self.module, c) }
            .map(|f| f as u64)
            .map_err(|e| dev_err(&format!("cuModuleGetFunction({name})"), e))
    }

    fn set_max_smem(&self, f: Func, bytes: usize) -> Result<()> {
        // SAFETY: `f` from `function`.
        unsafe {
            drv::function::set_function_attribute(
                f as sys::CUfunction,
                sys::CUfunction_attribute::CU_FUNC_ATTRIBUTE_MAX_DYNAMIC_SHARED_SIZE_BYTES,
                bytes as i32,
            )
        }
        .map_err(|e| dev_err("cuFuncSetAttribute(max dynamic shared memory)", e))
    }

    fn max_threads(&self, f: Func) -> Result<usize> {
        // SAFETY: `f` from `function`.
        unsafe {
            drv::function::get_function_attribute(
                f as sys::CUfunction,
                sys::CUfunction_attribute::CU_FUNC_ATTRIBUTE_MAX_THREADS_PER_BLOCK,
            )
        }
        .map(|v| v as usize)
        .map_err(|e| dev_err("cuFuncGetAttribute(max threads per block)", e))
    }

    fn resources(&self, f: Func) -> Result<(usize, usize)> {
        let get = |a| {
            // SAFETY: `f` from `function`.
            unsafe { drv::function::get_function_attribute(f as sys::CUfunction, a) }
                .map(|v| v as usize)
                .map_err(|e| dev_err("cuFuncGetAttribute(registers, local bytes)", e))
        };
        Ok((
            get(sys::CUfunction_attribute::CU_FUNC_ATTRIBUTE_NUM_REGS)?,
            get(sys::CUfunction_attribute::CU_FUNC_ATTRIBUTE_LOCAL_SIZE_BYTES)?,
        ))
    }

    unsafe fn launch(
        &self,
        f: Func,
        grid: [u32; 3],
        block: u32,
        smem: u32,
        s: Stream,
        params: &mut [*mut c_void],
    ) -> Result<()> {
        // SAFETY: per the caller's contract.
        unsafe {
            drv::launch_kernel(
                f as sys::CUfunction,
                (grid[0], grid[1], grid[2]),
                (block, 1, 1),
                smem,
                self.stream(s),
                params,
            )
        }
        .map_err(|e| dev_err("cuLaunchKernel", e))
    }

    fn event(&mut self) -> Result<Event> {
        drv::event::create(sys::CUevent_flags::CU_EVENT_DEFAULT)
            .map(|e| e as u64)
            .map_err(|e| dev_err("cuEventCreate", e))
    }

    fn record(&self, e: Event, s: Stream) -> Result<()> {
        // SAFETY: `e` from `event`.
        unsafe { drv::event::record(e as sys::CUevent, self.stream(s)) }
            .map_err(|e| dev_err("cuEventRecord", e))
    }

    fn wait(&self, s: Stream, e: Event) -> Result<()> {
        // SAFETY: `e` from `event`.
        unsafe {
            drv::stream::wait_event(
                self.stream(s),
                e as sys::CUevent,
                sys::CUevent_wait_flags::CU_EVENT_WAIT_DEFAULT,
            )
        }
        .map_err(|e| dev_err("cuStreamWaitEvent", e))
    }

    fn sync_event(&self, e: Event) -> Result<()> {
        // SAFETY: `e` from `event`.
        unsafe { drv::event::synchronize(e as sys::CUevent) }.map_err(|e| dev_err("cuEventSynchronize", e))
    }

    fn elapsed_ms(&self, a: Event, b: Event) -> Result<f32> {
        // SAFETY: both from `event`, recorded and completed.
        unsafe { drv::event::elapsed(a as sys::CUevent, b as sys::CUevent) }
            .map_err(|e| dev_err("cuEventElapsedTime", e))
    }

    fn sync(&self, s: Stream) -> Result<()> {
        // SAFETY: our stream.
        unsafe { drv::stream::synchronize(self.stream(s)) }.map_err(|e| dev_err("cuStreamSynchronize", e))
    }

    fn destroy_event(&mut self, e: Event) {
        // SAFETY: `e` from `event`.
        unsafe {
            let _ = drv::event::destroy(e as sys::CUevent);
        }
    }
}
