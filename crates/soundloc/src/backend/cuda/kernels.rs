//! The kernel sources (embedded with `include_str!`) and their run-time compilation with
//! NVRTC.
//!
//! One module holds every stage (`correlate`, `decompose`, `eigh`, `count`, `spectrum`, `peaks`), each a
//! template over the real type with `extern "C"` wrappers `name_f32` / `name_f64`. The
//! Jacobi kernel keeps each lane's rows of a column pair in registers, so its layout is a
//! compile-time [`Variant`] chosen from the number of microphones and passed as `-D`
//! macros; a backend compiles one variant, once per process (the image is cached).
//! Compilation targets the device's own architecture (`sm_XY`, a CUBIN: no JIT at load);
//! when the NVRTC at hand does not know it, PTX for the newest virtual architecture it
//! does know is used instead and the driver JIT-compiles it.

use super::image_cache;
use std::collections::HashMap;
use std::ffi::{c_char, c_int, CString};
use std::path::Path;
use std::sync::Mutex;

/// The kernel files, in the order they are concatenated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum KernelId {
    Correlate,
    Decompose,
    Eigh,
    Count,
    Spectrum,
    Peaks,
}

impl KernelId {
    pub(crate) const ALL: [KernelId; 6] = [
        KernelId::Correlate,
        KernelId::Decompose,
        KernelId::Eigh,
        KernelId::Count,
        KernelId::Spectrum,
        KernelId::Peaks,
    ];

    fn source(self) -> &'static str {
        match self {
            KernelId::Correlate => include_str!("../../../kernels/correlate.cu"),
            KernelId::Decompose => include_str!("../../../kernels/decompose.cu"),
            KernelId::Eigh => include_str!("../../../kernels/eigh.cu"),
            KernelId::Count => include_str!("../../../kernels/count.cu"),
            KernelId::Spectrum => include_str!("../../../kernels/spectrum.cu"),
            KernelId::Peaks => include_str!("../../../kernels/peaks.cu"),
        }
    }
}

const COMMON: &str = include_str!("../../../kernels/common.cuh");
/// The headers the kernel files include (NVRTC gets one translation unit): common.cuh goes
/// first, once; the others are inlined where they are included — eigh.cu's tridiagonal
/// eigensolver and its forming of H (the form_h kernel's products).
const HEADERS: [(&str, &str); 3] = [
    ("common.cuh", ""),
    ("tridiag.cuh", include_str!("../../../kernels/tridiag.cuh")),
    ("form_h.cuh", include_str!("../../../kernels/form_h.cuh")),
];

/// Register layout of the Jacobi kernel: `lpp` lanes share a column pair, each holding
/// `rpl` rows; it handles matrices with up to `lpp · rpl` (even) columns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) struct Variant {
    pub lpp: u32,
    pub rpl: u32,
    /// n = M rounded up to even, fixed at compile time (0: read at run time, as the
    /// emulator libraries do).
    pub nfix: u32,
    /// Only this precision's wrappers ("f32" / "f64"); empty: both.
    pub only: &'static str,
}

impl Variant {
    /// Every layout, smallest first.
    pub(crate) const ALL: [Variant; 5] = [
        Variant {
            lpp: 4,
            rpl: 4,
            nfix: 0,
            only: "",
        },
        Variant {
            lpp: 4,
            rpl: 8,
            nfix: 0,
            only: "",
        },
        Variant {
            lpp: 4,
            rpl: 16,
            nfix: 0,
            only: "",
        },
        Variant {
            lpp: 8,
            rpl: 16,
            nfix: 0,
            only: "",
        },
        Variant {
            lpp: 16,
            rpl: 16,
            nfix: 0,
            only: "",
        },
    ];

    /// The smallest generic layout for M microphones (None above 256); the emulator's.
    pub(crate) fn for_mics(m: usize) -> Option<Variant> {
        let n = m + (m & 1);
        Variant::ALL.into_iter().find(|v| v.max_cols() >= n)
    }

    /// The device layout for M microphones: the generic one's lanes per pair, exactly
    /// ⌈n / lanes⌉ rows per lane, n fixed.
    pub(crate) fn exact_for_mics(m: usize) -> Option<Variant> {
        let v = Variant::for_mics(m)?;
        let n = (m + (m & 1)) as u32;
        Some(Variant {
            lpp: v.lpp,
            rpl: n.div_ceil(v.lpp),
            nfix: n,
            only: "",
        })
    }

    /// Largest even column count.
    pub(crate) fn max_cols(self) -> usize {
        (self.lpp * self.rpl) as usize
    }

    /// File-name tag, e.g. `l4_r16`.
    pub(crate) fn tag(self) -> String {
        if self.nfix == 0 {
            format!("l{}_r{}", self.lpp, self.rpl)
        } else {
            format!("l{}_r{}_n{}", self.lpp, self.rpl, self.nfix)
        }
    }
}

/// The whole translation unit for one variant.
pub(crate) fn full_source(v: Variant) -> String {
    let mut s = format!("#define SL_LPP {}\n#define SL_RPL {}\n", v.lpp, v.rpl);
    if v.nfix > 0 {
        s.push_str(&format!("#define SL_NFIX {}\n", v.nfix));
    }
    match v.only {
        "f32" => s.push_str("#define SL_NO_F64\n"),
        "f64" => s.push_str("#define SL_NO_F32\n"),
        _ => {}
    }
    s.push_str(COMMON);
    s.push('\n');
    for k in KernelId::ALL {
        for line in k.source().lines() {
            let l = line.trim_start();
            let header = HEADERS.iter().find(|(name, _)| {
                l.strip_prefix("#include \"")
                    .and_then(|r| r.strip_prefix(name))
                    .is_some_and(|r| r.starts_with('"'))
            });
            match header {
                Some((_, text)) if !text.is_empty() => {
                    s.push_str(text);
                    s.push('\n');
                }
                Some(_) => {}
                None => {
                    s.push_str(line);
                    s.push('\n');
                }
            }
        }
    }
    s
}

/// A compiled module image.
#[derive(Debug, Clone)]
pub(crate) struct Image {
    /// CUBIN, or NUL-terminated PTX.
    pub bytes: Vec<u8>,
    /// The architecture option it was compiled with.
    pub arch: String,
    /// Embedded in the binary ([`super::prebuilt`]), not compiled here: where the driver
    /// refuses to load it, [`image_for`] without it compiles one.
    pub prebuilt: bool,
}

fn cache() -> &'static Mutex<HashMap<(Variant, u32), Image>> {
    static C: std::sync::OnceLock<Mutex<HashMap<(Variant, u32), Image>>> = std::sync::OnceLock::new();
    C.get_or_init(|| Mutex::new(HashMap::new()))
}

/// Whether libnvrtc can be loaded.
pub(crate) fn nvrtc_present() -> bool {
    // SAFETY: only tries to dlopen the library names cudarc would use.
    unsafe { cudarc::nvrtc::sys::is_culib_present() }
}

/// NVRTC's version, (major, minor).
pub(crate) fn nvrtc_version() -> Result<(i32, i32), String> {
    let (mut a, mut b) = (0 as c_int, 0 as c_int);
    // SAFETY: plain out-parameters.
    unsafe { cudarc::nvrtc::sys::nvrtcVersion(&mut a, &mut b) }
        .result()
        .map_err(|e| format!("nvrtcVersion: {e}"))?;
    Ok((a, b))
}

/// The real architectures NVRTC can build for (e.g. 75, 80, 90, ...).
fn supported_archs() -> Vec<i32> {
    let mut n: c_int = 0;
    // SAFETY: out-parameters sized by the first call.
    unsafe {
        if cudarc::nvrtc::sys::nvrtcGetNumSupportedArchs(&mut n)
            .result()
            .is_err()
            || n <= 0
        {
            return Vec::new();
        }
        let mut v = vec![0 as c_int; n as usize];
        if cudarc::nvrtc::sys::nvrtcGetSupportedArchs(v.as_mut_ptr())
            .result()
            .is_err()
        {
            return Vec::new();
        }
        v
    }
}

/// Compile `source` with `opts`; returns CUBIN (when `cubin`) or NUL-terminated PTX.
pub(crate) fn nvrtc_compile(source: &str, opts: &[String], cubin: bool) -> Result<Vec<u8>, String> {
    use cudarc::nvrtc::{result, sys};
    let src = CString::new(source).map_err(|e| e.to_string())?;
    let prog =
        result::create_program(&src, Some(c"soundloc.cu")).map_err(|e| format!("nvrtcCreateProgram: {e}"))?;
    // SAFETY: `prog` is valid until destroyed below; buffers are sized by the size calls.
    unsafe {
        let compiled = result::compile_program(prog, opts);
        if let Err(e) = compiled {
            let log = result::get_program_log(prog)
                .map(|l| {
                    let b: Vec<u8> = l.iter().map(|&c| c as u8).take_while(|&c| c != 0).collect();
                    String::from_utf8_lossy(&b).into_owned()
                })
                .unwrap_or_default();
            let _ = result::destroy_program(prog);
            return Err(format!("NVRTC compile failed ({e}) with {opts:?}:\n{log}"));
        }
        let out = if cubin {
            let mut size = 0usize;
            let r = sys::nvrtcGetCUBINSize(prog, &mut size).result();
            match r {
                Ok(()) if size > 0 => {
                    let mut v = vec![0u8; size];
                    sys::nvrtcGetCUBIN(prog, v.as_mut_ptr() as *mut c_char)
                        .result()
                        .map(|_| v)
                        .map_err(|e| format!("nvrtcGetCUBIN: {e}"))
                }
                Ok(()) => Err("nvrtcGetCUBIN: empty image".to_string()),
                Err(e) => Err(format!("nvrtcGetCUBINSize: {e}")),
            }
        } else {
            result::get_ptx(prog)
                .map(|p| {
                    let mut v: Vec<u8> = p.iter().map(|&c| c as u8).take_while(|&c| c != 0).collect();
                    v.push(0);
                    v
                })
                .map_err(|e| format!("nvrtcGetPTX: {e}"))
        };
        let _ = result::destroy_program(prog);
        out
    }
}

pub(crate) fn options(arch: &str) -> Vec<String> {
    let mut o = vec![format!("--gpu-architecture={arch}"), "--std=c++17".to_string()];
    // Developer hook for tuning runs (e.g. "-DSL_F32_MINB=3"); fixed for the process.
    if let Ok(extra) = std::env::var("SOUNDLOC_CUDA_NVRTC_OPTS") {
        o.extend(extra.split_whitespace().map(str::to_string));
    }
    o
}

/// The module for a device of compute capability `cc` = major·10 + minor: from the
/// process-wide cache, else embedded in the binary (with `prebuilt`: [`super::prebuilt`]),
/// else from the on-disk cache in `disk` ([`super::image_cache`]), else compiled.
pub(crate) fn image_for(v: Variant, cc: u32, disk: Option<&Path>, prebuilt: bool) -> Result<Image, String> {
    if let Some(img) = cache().lock().map_err(|e| e.to_string())?.get(&(v, cc)) {
        if prebuilt || !img.prebuilt {
            return Ok(img.clone());
        }
    }
    // SOUNDLOC_CUDA_PREBUILT=0 compiles with NVRTC even where an embedded image exists.
    let prebuilt = prebuilt && std::env::var_os("SOUNDLOC_CUDA_PREBUILT").is_none_or(|x| x != "0");
    if prebuilt {
        if let Some(img) = super::prebuilt::find(v, cc) {
            tracing::debug!("kernels ({}, {}) embedded in the binary", v.tag(), img.arch);
            cache()
                .lock()
                .map_err(|e| e.to_string())?
                .insert((v, cc), img.clone());
            return Ok(img);
        }
    }
    if !nvrtc_present() {
        return Err(
            "libnvrtc (the CUDA run-time compiler) was not found; install the CUDA toolkit \
                    or add its lib64 folder to LD_LIBRARY_PATH"
                .into(),
        );
    }
    let src = full_source(v);
    // Without NVRTC's version there is no safe key: compile, skip the disk cache.
    let entry = match (disk, nvrtc_version()) {
        (Some(dir), Ok(ver)) => Some((
            dir,
            image_cache::entry(dir, &src, &options(&format!("sm_{cc}")), ver, cc),
        )),
        _ => None,
    };
    if let Some((_, file)) = &entry {
        match image_cache::read(file) {
            Ok(img) => {
                tracing::debug!("kernels ({}, {}) from {}", v.tag(), img.arch, file.display());
                cache()
                    .lock()
                    .map_err(|e| e.to_string())?
                    .insert((v, cc), img.clone());
                return Ok(img);
            }
            Err(why) => tracing::debug!("kernel cache {}: {why}", file.display()),
        }
    }
    let t0 = std::time::Instant::now();
    let archs = supported_archs();
    let img = if archs.is_empty() || archs.contains(&(cc as i32)) {
        let arch = format!("sm_{cc}");
        match nvrtc_compile(&src, &options(&arch), true) {
            Ok(bytes) => Image {
                bytes,
                arch,
                prebuilt: false,
            },
            Err(e) if archs.contains(&(cc as i32)) => return Err(e),
            Err(_) => ptx_fallback(&src, cc, &archs)?,
        }
    } else {
        ptx_fallback(&src, cc, &archs)?
    };
    tracing::debug!(
        "NVRTC compiled the kernels ({}, {}) in {:.0} ms",
        v.tag(),
        img.arch,
        t0.elapsed().as_secs_f64() * 1e3
    );
    if let Some((dir, file)) = &entry {
        if let Err(e) = image_cache::write(dir, file, &img) {
            tracing::debug!("kernel cache {}: not stored: {e}", dir.display());
        }
    }
    cache()
        .lock()
        .map_err(|e| e.to_string())?
        .insert((v, cc), img.clone());
    Ok(img)
}

fn ptx_fallback(src: &str, cc: u32, archs: &[i32]) -> Result<Image, String> {
    // The newest virtual architecture NVRTC knows that the device can run.
    let best = archs
        .iter()
        .copied()
        .filter(|&a| a as u32 <= cc)
        .max()
        .unwrap_or(75);
    let arch = format!("compute_{best}");
    let bytes = nvrtc_compile(src, &options(&arch), false)?;
    Ok(Image {
        bytes,
        arch,
        prebuilt: false,
    })
}

/// Compile every generic variant and the device layouts of 8, 60 and 128 microphones
/// for `arch` (e.g. `sm_90`); returns (variant tag, image bytes).
pub(crate) fn compile_all(arch: &str) -> Result<Vec<(String, usize)>, String> {
    let mut out = Vec::new();
    let exact = [8, 60, 127].into_iter().filter_map(Variant::exact_for_mics);
    for v in Variant::ALL.into_iter().chain(exact) {
        let bytes = nvrtc_compile(&full_source(v), &options(arch), arch.starts_with("sm_"))?;
        out.push((v.tag(), bytes.len()));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// NVRTC gets one translation unit: every local header is inlined where it is included
    /// (NVRTC would not find it), and its code is there exactly once.
    #[test]
    fn the_full_source_inlines_every_local_header() {
        for v in Variant::ALL {
            let s = full_source(v);
            for (header, _) in HEADERS {
                let inc = format!("#include \"{header}\"");
                assert!(
                    !s.lines().any(|l| l.trim_start().starts_with(&inc)),
                    "{v:?}: {header} is still included"
                );
            }
            // Only the emulator's header stays, behind SOUNDLOC_EMU (common.cuh).
            let left: Vec<&str> = s
                .lines()
                .map(str::trim_start)
                .filter(|l| l.starts_with("#include \""))
                .collect();
            assert_eq!(left, ["#include \"emu/emu.h\""], "{v:?}");
            for marker in [
                "void form_h_impl(",
                "int sturm_count_ratio(",
                "struct sl_eps<double>",
            ] {
                assert_eq!(s.matches(marker).count(), 1, "{v:?}: {marker}");
            }
            // Each header where eigh.cu includes it: after the names it uses, before
            // their users.
            let at = |m: &str| s.find(m).unwrap_or_else(|| panic!("{v:?}: {m} missing"));
            assert!(at("typedef cplx<double> zd;") < at("int sturm_count_ratio("));
            assert!(at("int sturm_count_ratio(") < at("void eigh_impl("));
            assert!(at("void make_reflector(") < at("void form_h_impl("));
            assert!(at("void form_h_impl(") < at("void eigh_impl("));
        }
    }
}
