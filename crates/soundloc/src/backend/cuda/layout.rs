//! Sizes and launch shapes of the CUDA backend, derived once from the plan and the device.

use super::*;

/// Sizes and launch shapes derived from the plan.
#[derive(Debug, Clone)]
pub(super) struct Layout {
    pub(super) m: usize,
    pub(super) nb: usize,
    pub(super) d: usize,
    pub(super) ns: usize,
    /// Vectors kept per matrix (ns, or M for the unsquared denominator).
    pub(super) ne: usize,
    /// Bytes per element of R on the device: complex double for the decompositions,
    /// the plan's complex type for SRP-PHAT's R̃ (its scale factors take half of that).
    pub(super) r_size: usize,
    /// Whether a double copy of the signal vectors is kept: f32 plans whose squared MUSIC
    /// vectors come from the double eigensolver (the spectrum recomputes near peaks from
    /// it). An f64 plan's `E` already is double; the f32 Jacobi's vectors are not
    /// double-accurate, and the spectrum recomputes from them in f32.
    pub(super) e64: bool,
    pub(super) squared: bool,
    pub(super) left: usize,
    pub(super) right: usize,
    /// How the decomposition kernel evaluates the largest value (decompose.cu).
    pub(super) valmode: usize,
    pub(super) alg: Algorithm,
    /// SRP-PHAT: phase-transformed correlation, no decomposition, R̃ read by the spectrum.
    pub(super) srp: bool,
    /// NormMUSIC's per-bin normalisation (two spectrum passes).
    pub(super) normalize: bool,
    /// Coherence normalisation of every R after the correlation (`coherence_f64`).
    pub(super) coherence: bool,
    pub(super) lpp: usize,
    pub(super) want_v: bool,
    pub(super) ld: usize,
    pub(super) dec_smem_mode: bool,
    /// Whether the signal subspace comes from the tridiagonal eigensolver (eigh.cu)
    /// instead of the Jacobi kernel.
    pub(super) eigh: bool,
    /// Whether the number of active sources is estimated (count.cu on eigh.cu's T): the
    /// plan asks for it ([`crate::config::LocalizeConfig::counts_sources`]) and the
    /// tridiagonal path runs (the Jacobi path, for M > 64, the unsquared denominator or
    /// `SOUNDLOC_CUDA_DEC=jacobi`, reports none).
    pub(super) count: bool,
    /// The eigensolver's block: threads, shared memory, scratch ([`eigh_shape`]).
    pub(super) eigh_shape: EighShape,
    pub(super) form_h_smem: usize,
    pub(super) dec_threads: usize,
    pub(super) dec_smem: usize,
    pub(super) dec_scratch_per_mat: usize,
    pub(super) corr_fc: usize,
    pub(super) corr_smem: usize,
    /// Threads of a correlation block (one per register tile, a multiple of 32).
    pub(super) corr_threads: usize,
    /// Directions per spectrum block.
    pub(super) spec_dt: usize,
    /// Directions per spectrum thread (spectrum.cu `RD`: 1 or 4; A/B knobs
    /// `SOUNDLOC_CUDA_SPEC_RD`, `SOUNDLOC_CUDA_SPEC_WG` windows per block,
    /// `SOUNDLOC_CUDA_SPEC_ESMEM=0` vectors read through L1 when RD is 1; with RD 4 they
    /// always are).
    pub(super) spec_rd: usize,
    /// Windows per spectrum block (at most).
    pub(super) spec_wg: usize,
    /// Whether the spectrum kernel stages the windows' vectors in shared memory.
    pub(super) spec_e_smem: bool,
    /// Shared memory of the steering tile.
    pub(super) spec_tile: usize,
    pub(super) peak_cap: usize,
    pub(super) peak_kout: usize,
    pub(super) peak_smem: usize,
}

/// The smallest signal subspace for which the spectrum runs [`SPEC_RD_DEFAULT`]
/// directions per thread (one H100, seed config, 2026-11-27 with fused multiply-adds:
/// subspace 4 0.0232 → 0.0125 ms per localization, subspace 2 0.0163 → 0.0175: slower).
const SPEC_RD_MIN_NS: usize = 4;
/// Directions per spectrum thread for deep subspaces (one H100, subspace 30 of 60 mics,
/// 2026-11-27: 0.164 → 0.122 ms per localization against one direction per thread).
const SPEC_RD_DEFAULT: usize = 4;

/// The largest signal subspace for which the eigensolver runs in blocks of 128 threads
/// (`eigh_narrow_*`, six per multiprocessor) instead of 256 (three).
const EIGH_NARROW_MAX_NS: usize = 4;
/// Shared memory per multiprocessor on the devices this backend tunes for (sm_80/sm_90:
/// 164–228 KB; the larger figure: on smaller ones fewer blocks fit, nothing fails).
const SM_SMEM: usize = 228 * 1024;

/// The eigensolver's launch shape (eigh.cu).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct EighShape {
    /// Threads per block: 128 (`eigh_narrow_*`) or 256 (`eigh_*`).
    pub(super) threads: usize,
    /// Dynamic shared memory per block, bytes.
    pub(super) smem: usize,
    /// Doubles of inverse-iteration scratch (eigh.cu `scr_len`).
    pub(super) scr_len: usize,
}

impl EighShape {
    /// The kernel's name for element type `t` ("f32" or "f64").
    pub(super) fn kernel(&self, t: &str) -> String {
        if self.threads == 128 {
            format!("eigh_narrow_{t}")
        } else {
            format!("eigh_{t}")
        }
    }
}

/// Whether Ns signal vectors use the 128-thread eigensolver
/// (`SOUNDLOC_CUDA_EIGH_THREADS=128|256` forces one, for A/B runs).
fn eigh_narrow(ns: usize) -> bool {
    match std::env::var("SOUNDLOC_CUDA_EIGH_THREADS").as_deref() {
        Ok("128") => true,
        Ok("256") => false,
        _ => ns <= EIGH_NARROW_MAX_NS,
    }
}

/// eigh.cu's shared memory for M = `m`, Ns = `ns`: the packed lower triangle (M(M+1)/2
/// complex doubles), τ (M complex), the work area max(8M, Ns·(M|1) + scr_len) doubles
/// (rounded up to even), d, e, e², λ, and 1 + 32 ints. The scratch holds as many
/// inverse-iteration solves at once (3·(M|1) doubles each, at least one, at most Ns) as
/// keep the block within its share of a multiprocessor (six blocks of 128 threads or three
/// of 256; where not even one solve fits that share, the share of one block fewer), and at
/// least Ns dot products.
pub(super) fn eigh_shape(m: usize, ns: usize, narrow: bool) -> EighShape {
    let us = m | 1;
    let smem_for = |scr_len: usize| {
        let wlen = ((8 * m).max(ns * us + scr_len) + 1) & !1;
        (m * (m + 1) / 2 + m) * 16 + (wlen + 3 * m + ns) * 8 + 33 * 4
    };
    let mut blocks = if narrow { 6 } else { 3 };
    while blocks > 1 && smem_for(3 * us) > SM_SMEM / blocks - 1024 {
        blocks -= 1;
    }
    let budget = SM_SMEM / blocks - 1024;
    let mut vpp = ns.max(1);
    while vpp > 1 && smem_for(3 * us * vpp) > budget {
        vpp -= 1;
    }
    let scr_len = (3 * us * vpp).max(ns);
    EighShape {
        threads: if narrow { 128 } else { 256 },
        smem: smem_for(scr_len),
        scr_len,
    }
}

impl Layout {
    /// Threads of a spectrum block of `wg` windows.
    pub(super) fn spec_threads(&self, wg: usize) -> usize {
        self.spec_dt / self.spec_rd * wg
    }
}

pub(super) fn layout<T: Real>(plan: &Plan<T>, gpu: &dyn Gpu) -> Result<Layout> {
    let cs = csize::<T>();
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
        (Algorithm::SrpPhat, _) => (0, 0),
    };
    let srp = plan.config.algorithm == Algorithm::SrpPhat;
    // SRP's "vectors" are R̃'s M columns, squared-form tiles.
    let squared = squared || srp;
    let valmode = match plan.config.algorithm {
        Algorithm::Sevd => 0,
        Algorithm::Gevd => 1,
        Algorithm::GevdHark => 2,
        Algorithm::Gsvd => 3,
        Algorithm::SrpPhat => 0,
    };
    let want_v = !squared;
    let ne = if srp {
        m
    } else if squared {
        ns
    } else {
        m
    };
    let v = variant_for(plan)?;
    let n = m + (m & 1);
    let mut ld = n;
    while ld % 16 != 4 {
        ld += 1;
    }
    let optin = gpu.max_smem_optin().max(SMEM_DEFAULT);
    // The Jacobi kernel rotates in double for the unsquared denominator and f64 plans, in
    // T otherwise (decompose.cu).
    let jcs = if want_v { 16 } else { cs };
    let mats = if want_v { 2 } else { 1 } * n * ld * jcs;
    let small = (3 * n * jcs + n * jcs / 2 + 32 * jcs / 2 + 2 * n * 4).div_ceil(16) * 16;
    let dec_smem_mode = mats + small <= optin;
    let (dec_smem, dec_scratch_per_mat) = if dec_smem_mode {
        (mats + small, 0)
    } else {
        (small, mats)
    };
    // The tridiagonal eigensolver whenever only the signal vectors are needed and its
    // register tiles cover M (SOUNDLOC_CUDA_DEC=jacobi keeps the Jacobi kernel, for A/B runs).
    let eigh_shape = eigh_shape(m, ns, eigh_narrow(ns));
    let form_h_smem = m * (m | 1) * 16;
    let eigh = squared
        && !srp
        && m <= 64
        && eigh_shape.smem <= optin
        && std::env::var("SOUNDLOC_CUDA_DEC").map_or(true, |v| v != "jacobi");
    let groups = n / 2 * v.lpp as usize;
    let dec_threads = groups.div_ceil(32).clamp(1, 32) * 32;
    // correlate.cu: a chunk of frames in complex double, one thread per 2 × 4 tile of the
    // lower triangle (rows 2g, 2g + 1, columns 4J … 4J + 3, g ≥ 2J), at most 512 a pass.
    let corr_fc = ((SMEM_DEFAULT - 32 * 8) / (m * 16)).clamp(1, 32);
    let corr_smem = corr_fc * m * 16 + 32 * 8;
    let corr_tiles: usize = (0..m.div_ceil(4))
        .map(|j| m.div_ceil(2).saturating_sub(2 * j))
        .sum();
    let corr_threads = (corr_tiles.div_ceil(32) * 32).clamp(32, 512);
    // The kernel's diagonal sums take one thread per microphone.
    debug_assert!(corr_threads >= m.min(512));
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
    let knob = |name: &str| std::env::var(name).ok().and_then(|v| v.parse::<usize>().ok());
    let spec_rd = match knob("SOUNDLOC_CUDA_SPEC_RD") {
        Some(4) if squared && !srp => 4,
        Some(_) => 1,
        None if squared && !srp && ns >= SPEC_RD_MIN_NS => SPEC_RD_DEFAULT,
        None => 1,
    };
    // Four directions per thread read the vectors through L1 (a block's sixteen windows of
    // vectors would not fit beside the steering tile); one direction per thread stages
    // its four windows' vectors in shared memory (docs/gpu.md, 2026-11-27 third session).
    let deep = spec_rd == 4;
    let spec_wg = knob("SOUNDLOC_CUDA_SPEC_WG")
        // spectrum4_f32 is bounded to 256 threads per block (spectrum.cu).
        .filter(|&w| {
            (1..=64).contains(&w) && spec_dt / spec_rd * w <= if deep && cs == 8 { 256 } else { 1024 }
        })
        .unwrap_or(if deep {
            16
        } else if squared {
            4
        } else {
            1
        });
    let spec_e_smem = !deep
        && knob("SOUNDLOC_CUDA_SPEC_ESMEM") != Some(0)
        && spec_tile + spec_wg * ne * m * cs <= optin.min(160 * 1024);
    let peak_cap = d.next_power_of_two().clamp(1, 4096);
    let peak_kout = plan.peak_table.max_out.min(peak_cap);
    let peak_smem = peak_cap * 12;
    // (SOUNDLOC_CUDA_COUNT=0 leaves it out: for A/B runs of its cost.)
    let count = eigh
        && plan.config.counts_sources()
        && std::env::var("SOUNDLOC_CUDA_COUNT").map_or(true, |v| v != "0");
    Ok(Layout {
        count,
        m,
        nb,
        d,
        ns,
        ne,
        r_size: if srp { cs } else { 16 },
        e64: squared && !srp && cs == 8 && eigh,
        squared,
        left,
        right,
        valmode,
        alg: plan.config.algorithm,
        srp,
        normalize: plan.config.normalize_bins,
        coherence: plan.config.normalizes_r(),
        lpp: v.lpp as usize,
        want_v,
        ld,
        dec_smem_mode,
        eigh,
        eigh_shape,
        form_h_smem,
        dec_threads,
        dec_smem,
        dec_scratch_per_mat,
        corr_fc,
        corr_smem,
        corr_threads,
        spec_dt,
        spec_rd,
        spec_wg,
        spec_e_smem,
        spec_tile,
        peak_cap,
        peak_kout,
        peak_smem,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eigh_shape_fits_its_share_of_a_multiprocessor() {
        // Seed config (M = 60, Ns = 2): six narrow blocks per multiprocessor.
        let s = eigh_shape(60, 2, true);
        assert_eq!(s.threads, 128);
        assert!(6 * (s.smem + 1024) <= SM_SMEM, "{s:?}");
        assert_eq!(s.scr_len, 3 * 61 * 2, "both solves at once");
        // The robust default's subspace (30 of 60): three wide blocks, several solves at once.
        let s = eigh_shape(60, 30, false);
        assert_eq!(s.threads, 256);
        assert!(3 * (s.smem + 1024) <= SM_SMEM, "{s:?}");
        assert_eq!(s.scr_len, 3 * 61 * 20, "twenty solves at once: {s:?}");
        // Where six narrow blocks cannot fit (M = 63, 64), five do, with both solves.
        let s = eigh_shape(64, 2, true);
        assert!(5 * (s.smem + 1024) <= SM_SMEM, "{s:?}");
        assert_eq!(s.scr_len, 3 * 65 * 2, "{s:?}");
        // Every size the eigensolver serves (M ≤ 64) fits one block's opt-in limit (227 KB
        // on sm_80/sm_90), so none falls back to the Jacobi kernel for lack of memory.
        for m in 2..=64 {
            for ns in 1..m {
                for narrow in [false, true] {
                    let s = eigh_shape(m, ns, narrow);
                    assert!(s.smem <= 227 * 1024, "{m} {ns} {s:?}");
                }
            }
        }
    }
}
