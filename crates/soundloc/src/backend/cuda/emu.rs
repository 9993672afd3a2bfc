//! [`EmuGpu`]: the [`Gpu`] seam over the CPU emulator of the kernels
//! (`kernels/emu/`, built by `scripts/build_cuda_emu.sh`). Tests only: it lets the
//! whole CUDA backend — buffer layout, launch parameters, sub-batching, peak parsing —
//! run and be compared with the CPU path on a machine without a GPU. Device pointers are
//! host addresses; launches run to completion; events measure nothing.

use super::device::{DevPtr, Event, Func, Gpu, Stream};
use super::kernels::Variant;
use crate::{Error, Result};
use std::collections::HashMap;
use std::ffi::{c_char, c_int, c_uint, c_void, CString};
use std::path::Path;

extern "C" {
    fn dlopen(filename: *const c_char, flag: c_int) -> *mut c_void;
    fn dlsym(handle: *mut c_void, symbol: *const c_char) -> *mut c_void;
    fn dlerror() -> *const c_char;
}
const RTLD_NOW: c_int = 2;
const RTLD_LOCAL: c_int = 0;

type LaunchFn = unsafe extern "C" fn(
    *const c_char,
    c_uint,
    c_uint,
    c_uint,
    c_uint,
    c_uint,
    c_uint,
    c_uint,
    *mut *mut c_void,
) -> c_int;

pub(crate) struct EmuGpu {
    launch_fn: LaunchFn,
    names: Vec<CString>,
    allocs: HashMap<u64, Vec<u128>>,
    lib: String,
}

// SAFETY: the library handle is process-global and the emulator runs on the caller's thread.
unsafe impl Send for EmuGpu {}

impl EmuGpu {
    /// Load `dir/libsoundloc_emu_<variant>.so`.
    pub(crate) fn new(dir: &Path, v: Variant) -> Result<Self> {
        let path = dir.join(format!("libsoundloc_emu_{}.so", v.tag()));
        let c = CString::new(path.to_string_lossy().as_bytes()).map_err(|e| Error::Device(e.to_string()))?;
        // SAFETY: dlopen/dlsym with valid C strings; the handle is never closed.
        unsafe {
            let h = dlopen(c.as_ptr(), RTLD_NOW | RTLD_LOCAL);
            if h.is_null() {
                let msg = std::ffi::CStr::from_ptr(dlerror()).to_string_lossy().into_owned();
                return Err(Error::Device(format!("emulator {}: {msg}", path.display())));
            }
            let f = dlsym(h, c"emu_launch".as_ptr());
            if f.is_null() {
                return Err(Error::Device(format!(
                    "emulator {}: no emu_launch",
                    path.display()
                )));
            }
            Ok(EmuGpu {
                launch_fn: std::mem::transmute::<*mut c_void, LaunchFn>(f),
                names: Vec::new(),
                allocs: HashMap::new(),
                lib: path.display().to_string(),
            })
        }
    }
}

impl Gpu for EmuGpu {
    fn describe(&self) -> String {
        format!("cuda-emulator ({})", self.lib)
    }
    fn make_current(&self) -> Result<()> {
        Ok(())
    }
    fn mem_info(&self) -> Result<(usize, usize)> {
        Ok((4 << 30, 4 << 30))
    }
    fn sm_count(&self) -> usize {
        4
    }
    fn max_smem_optin(&self) -> usize {
        227 * 1024
    }
    fn alloc(&mut self, bytes: usize) -> Result<DevPtr> {
        let mut v = vec![0u128; bytes.div_ceil(16).max(1)];
        // Poison: NaN patterns in every float slot, like uninitialised device memory.
        for x in v.iter_mut() {
            *x = u128::MAX;
        }
        let p = v.as_mut_ptr() as u64;
        self.allocs.insert(p, v);
        Ok(p)
    }
    fn free(&mut self, p: DevPtr) {
        self.allocs.remove(&p);
    }
    fn alloc_pinned(&mut self, bytes: usize) -> Result<*mut u8> {
        self.alloc(bytes).map(|p| p as *mut u8)
    }
    fn free_pinned(&mut self, p: *mut u8) {
        self.free(p as u64)
    }
    unsafe fn htod(&self, dst: DevPtr, src: *const u8, bytes: usize, _s: Stream) -> Result<()> {
        // SAFETY: caller's contract.
        unsafe { std::ptr::copy_nonoverlapping(src, dst as *mut u8, bytes) };
        Ok(())
    }
    unsafe fn dtoh(&self, dst: *mut u8, src: DevPtr, bytes: usize, _s: Stream) -> Result<()> {
        // SAFETY: caller's contract.
        unsafe { std::ptr::copy_nonoverlapping(src as *const u8, dst, bytes) };
        Ok(())
    }
    fn function(&mut self, name: &str) -> Result<Func> {
        self.names
            .push(CString::new(name).map_err(|e| Error::Device(e.to_string()))?);
        Ok((self.names.len() - 1) as u64)
    }
    fn set_max_smem(&self, _f: Func, _bytes: usize) -> Result<()> {
        Ok(())
    }
    fn max_threads(&self, _f: Func) -> Result<usize> {
        Ok(1024)
    }
    fn resources(&self, _f: Func) -> Result<(usize, usize)> {
        Ok((0, 0))
    }
    unsafe fn launch(
        &self,
        f: Func,
        grid: [u32; 3],
        block: u32,
        smem: u32,
        _s: Stream,
        params: &mut [*mut c_void],
    ) -> Result<()> {
        let name = &self.names[f as usize];
        // SAFETY: caller's contract; the emulator copies the parameter values.
        let r = unsafe {
            (self.launch_fn)(
                name.as_ptr(),
                grid[0],
                grid[1],
                grid[2],
                block,
                1,
                1,
                smem,
                params.as_mut_ptr(),
            )
        };
        if r != 0 {
            return Err(Error::Device(format!("emulator: unknown kernel {name:?}")));
        }
        Ok(())
    }
    fn event(&mut self) -> Result<Event> {
        Ok(0)
    }
    fn record(&self, _e: Event, _s: Stream) -> Result<()> {
        Ok(())
    }
    fn wait(&self, _s: Stream, _e: Event) -> Result<()> {
        Ok(())
    }
    fn sync_event(&self, _e: Event) -> Result<()> {
        Ok(())
    }
    fn elapsed_ms(&self, _a: Event, _b: Event) -> Result<f32> {
        Ok(0.0)
    }
    fn sync(&self, _s: Stream) -> Result<()> {
        Ok(())
    }
    fn destroy_event(&mut self, _e: Event) {}
}
