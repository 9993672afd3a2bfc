//! Stage 4 — the MUSIC pseudo-spectrum (HARK CalcAveragePower).
//!
//! Per used bin k and direction d, with steering vector a = a_{d,k} (length M) and the
//! noise-subspace vectors e_m (m = Ns+1 … M) of [`crate::subspace`]:
//!
//! P_k(d) = Re(aᴴa) / Σ_{m ∈ noise} |aᴴ e_m|²    (squared denominator, HARK's code; default)
//!
//! The unsquared form Σ|aᴴ e_m| (the paper's equation 5 as printed) is
//! [`Denominator::Unsquared`]. Broadband: P̄(d) = Σ_k P_k(d)·w_k·g_k with w_k the
//! spectrum weight and g_k = √(largest eigen/singular value of bin k) when the eigenvalue
//! weight is on. Reported power: 10·log10(P̄(d) + 1) dB.
//!
//! **How the squared denominator is evaluated.** The basis is orthonormal, so
//! Σ_{noise}|aᴴe_m|² = ‖a‖² − Σ_{signal}|aᴴe_m|², which needs only the Ns signal vectors
//! (a D × M by M × Ns product instead of M × (M − Ns): ~30× less work at M = 60, Ns = 2).
//! The difference cancels where a lies almost in the signal subspace — exactly at the peaks
//! — so wherever the complement is below [`REFINE_RATIO`]·‖a‖² it is recomputed in double
//! precision from the f64 signal vectors the decomposition hands on (‖a‖² and aᴴe_m
//! summed in f64: the cancellation then costs ~10⁻¹⁶‖a‖², far below single precision).
//! The floor that keeps the denominator positive is ε_f64·‖a‖² there (an f32 floor would
//! clip the sharpest peaks in rotor noise, docs/precision.md). The result equals the full
//! noise-subspace sum to rounding, which `tests` check against the naive f64 form; the
//! decomposition computes only the Ns signal vectors ([`vectors_needed`]).
//! For the textbook GEVD, a is the whitened a_w = L⁻¹a in the denominator (and its norm in
//! the complement) while the numerator keeps the raw ‖a‖², or another
//! [`crate::config::Numerator`] ([`Plan::numerator_norm2`]).

use crate::config::Denominator;
use crate::lanes;
use crate::plan::Plan;
use crate::projections;
use crate::real::{Real, C};
use crate::subspace::Decomposition;
use faer::{Accum, MatRef, Par};

/// Complement values below this fraction of ‖a‖² are recomputed with the full sum.
pub const REFINE_RATIO: f64 = 1e-2;

/// Directions per block of the spectrum: the backend runs a bin's directions in blocks of
/// this many and every window of a batch through each block, so the block's steering
/// vectors (≈ 120 KB at M = 60 in f32) are read from memory once per batch rather than
/// once per window. Fixed, so a window's result does not depend on its batch.
pub const DIR_BLOCK: usize = 256;

/// Whether a plan's spectrum runs on the fused AVX-512 kernel ([`projections`]): single
/// precision, the squared denominator, an array larger than the planar kernels serve, a
/// signal subspace of at most [`projections::MAX_COLS`] vectors.
fn fused<T: Real>(plan: &Plan<T>) -> bool {
    plan.planar.is_none()
        && plan.config.denominator == Denominator::Squared
        && plan.config.signal_dim() <= projections::MAX_COLS
        && T::cplx_f32(&[]).is_some()
        && projections::available()
}

/// Directions per call of [`accumulate_bin`]: [`DIR_BLOCK`], or all of a bin's on the
/// fused kernel, whose steering tiles (a few directions) are small: there the windows'
/// columns, laid out once per bin and group, are what stays in cache.
pub fn dir_block<T: Real>(plan: &Plan<T>) -> usize {
    if fused(plan) {
        plan.num_dirs.max(1)
    } else {
        DIR_BLOCK
    }
}

/// Per-thread scratch for [`accumulate_bin`].
pub struct SpectrumScratch<T: Real> {
    /// (aᴴE)ᵀ for one block of directions: a group of windows' columns as rows.
    proj: faer::Mat<C<T>>,
    /// The windows' vectors side by side (M × columns), column-major.
    cols: Vec<C<T>>,
    /// Σ_s |aᴴe_s|² per direction of the block (squared denominator; per window of a
    /// group on the AVX-512 path).
    sig: Vec<T>,
    /// The group's signal vectors in lanes (the AVX-512 path, [`projections`]).
    lanes: projections::Columns,
}

impl<T: Real> SpectrumScratch<T> {
    /// Scratch for a plan.
    pub fn new(plan: &Plan<T>) -> Self {
        // One group of windows' columns (see `accumulate_bin`).
        let ns = plan.config.signal_dim();
        let nc = match plan.config.denominator {
            Denominator::Squared => ns,
            Denominator::Unsquared => plan.num_mics - ns,
        };
        let ncols = group_size(nc) * nc;
        SpectrumScratch {
            proj: faer::Mat::zeros(ncols, plan.num_dirs.min(DIR_BLOCK)),
            cols: Vec::with_capacity(plan.num_mics * ncols),
            sig: vec![T::zero(); plan.num_dirs.min(DIR_BLOCK)],
            lanes: projections::Columns::default(),
        }
    }
}

/// How many leading vectors the decomposition must compute: the Ns signal vectors for the
/// squared denominator (complement form), all M for the unsquared one.
pub fn vectors_needed<T: Real>(plan: &Plan<T>) -> usize {
    match plan.config.denominator {
        Denominator::Squared => plan.config.signal_dim().min(plan.num_mics),
        Denominator::Unsquared => plan.num_mics,
    }
}

/// g_k: √(largest value) when the eigenvalue weight is on, else 1.
pub fn bin_gain<T: Real>(plan: &Plan<T>, dec: &Decomposition<T>) -> T {
    if plan.config.eigenvalue_weight {
        dec.largest().max(T::zero()).sqrt()
    } else {
        T::one()
    }
}

/// Adds w_k·g_k·P_k(d) for the directions `dirs` (at most [`dir_block`] of them) of used
/// bin `b` to `accs[i]` (one value per direction of `dirs`), for the windows whose
/// decompositions of bin `b` are `decs[i]`. Three paths: small arrays' planar kernels
/// ([`lanes`]); the fused AVX-512 kernel ([`projections`], f32), whose lanes keep each
/// window's operations independent of the others; otherwise faer's product, where the
/// windows' vectors go through the product with the block's steering vectors in groups (at
/// least [`MIN_PRODUCT_COLS`] columns, the last group zero-padded), so every product has the
/// same shape whatever the batch. Either way a window's result is the same bits alone or
/// among others (`tests`).
pub fn accumulate_bin<T: Real>(
    plan: &Plan<T>,
    b: usize,
    dirs: std::ops::Range<usize>,
    decs: &[&Decomposition<T>],
    scratch: &mut SpectrumScratch<T>,
    accs: &mut [&mut [T]],
) {
    let m = plan.num_mics;
    let nd = plan.num_dirs;
    let d = dirs.len();
    debug_assert!(d <= dir_block(plan) && accs.iter().all(|a| a.len() == d) && accs.len() == decs.len());
    let ns = plan.config.signal_dim();
    let (st_all, n2_all) = plan.denominator_steering();
    let (d0, d1) = (b * nd + dirs.start, b * nd + dirs.end);
    let st = &st_all[d0 * m..d1 * m];
    let n2_den = &n2_all[d0..d1];
    let n2_num = &plan.numerator_norm2()[d0..d1];
    // The projections aᴴe_c of every column the spectrum uses: the Ns signal vectors
    // (squared denominator) or the M − Ns noise vectors (unsquared), per window.
    let (c0, nc) = match plan.config.denominator {
        Denominator::Squared => (0, ns),
        Denominator::Unsquared => (ns, m - ns),
    };
    let den = DenRefs {
        st,
        n2_den,
        n2_num,
        floor: T::of_f64(T::EPS),
    };
    if let (Some(planar), Denominator::Squared) = (&plan.planar, plan.config.denominator) {
        // Small arrays: each window's signal sums straight from the planar steering.
        let block = planar.block(b, dirs.clone());
        for (dec, acc) in decs.iter().zip(accs.iter_mut()) {
            let gain = plan.weights[b] * bin_gain(plan, dec);
            if gain == T::zero() {
                continue;
            }
            scratch.sig.resize(d, T::zero());
            lanes::signal_power(&block, &dec.vectors, ns, &mut scratch.sig);
            quotients(&den, dec, ns, gain, &scratch.sig, acc);
        }
        return;
    }
    if fused(plan) {
        if let (Some(st32), Some(all32)) = (T::cplx_f32(st), T::cplx_f32(st_all)) {
            // Single precision on AVX-512: the fused kernel, windows grouped into lanes.
            let sigs = &mut scratch.sig;
            let pq = &plan
                .steering_sums
                .get_or_init(|| projections::steering_sums(all32))[d0 * m..d1 * m];
            for (gdecs, gaccs) in decs
                .chunks(projections::windows_per_group(ns))
                .zip(accs.chunks_mut(projections::windows_per_group(ns)))
            {
                scratch.lanes.fill(
                    m,
                    ns,
                    gdecs
                        .iter()
                        .map(|dec| T::cplx_f32(&dec.vectors[..m * ns]).expect("f32")),
                );
                sigs.clear();
                sigs.resize(gdecs.len() * d, T::zero());
                projections::signal_power(st32, pq, &scratch.lanes, T::f32_mut(sigs).expect("f32"));
                for (i, (dec, acc)) in gdecs.iter().zip(gaccs.iter_mut()).enumerate() {
                    let gain = plan.weights[b] * bin_gain(plan, dec);
                    if gain != T::zero() {
                        quotients(&den, dec, ns, gain, &sigs[i * d..(i + 1) * d], acc);
                    }
                }
            }
            return;
        }
    }
    // Windows go through the product in groups of a fixed size, the last group padded
    // with zero columns: every product has the same shape (this block's directions × G·nc
    // columns × M) whatever the batch, so the library takes the same path (and summation
    // order) for a window alone or among others.
    let g = group_size(nc);
    let ncols = g * nc;
    if scratch.proj.ncols() < d || scratch.proj.nrows() < ncols {
        scratch.proj = faer::Mat::zeros(ncols, DIR_BLOCK.min(nd).max(d));
    }
    // Steering block as a D × M row-major matrix; the product is (aᴴE)ᵀ = Eᵀ·Aᴴ (columns ×
    // directions), which reads the steering block in place (measured: faster than AᴴE,
    // which packs the block, both alone and batched).
    let a = MatRef::from_row_major_slice(st, d, m);
    for (gdecs, gaccs) in decs.chunks(g).zip(accs.chunks_mut(g)) {
        scratch.cols.clear();
        for dec in gdecs {
            scratch
                .cols
                .extend_from_slice(&dec.vectors[m * c0..m * (c0 + nc)]);
        }
        scratch.cols.resize(m * ncols, C::new(T::zero(), T::zero()));
        let e = MatRef::from_column_major_slice(&scratch.cols, m, ncols);
        faer::linalg::matmul::matmul(
            scratch.proj.as_mut().submatrix_mut(0, 0, ncols, d),
            Accum::Replace,
            e.transpose(),
            a.adjoint(),
            C::new(T::one(), T::zero()),
            Par::Seq,
        );
        crate::avx::clear_upper();
        for (i, (dec, acc)) in gdecs.iter().zip(gaccs.iter_mut()).enumerate() {
            accumulate_window(
                plan,
                b,
                &den,
                dec,
                scratch.proj.as_ref().submatrix(i * nc, 0, nc, d).transpose(),
                &mut scratch.sig,
                acc,
            );
        }
    }
}

/// Windows per product: enough for [`MIN_PRODUCT_COLS`] columns (never a one-column
/// product, which a library may sum differently from a wider one).
fn group_size(cols_per_window: usize) -> usize {
    MIN_PRODUCT_COLS.div_ceil(cols_per_window.max(1))
}

/// Columns of every projection product at least (see [`accumulate_bin`]).
const MIN_PRODUCT_COLS: usize = 8;

/// One window's w_k·g_k·P_k(d) for a block of directions from its projections `proj`
/// (directions × the columns the denominator uses). The squared denominator runs as
/// passes over the block: the signal sums column by column (strided reads), then the
/// complement, floor and quotient for every direction — branch-free over contiguous
/// arrays, so it vectorises — and a last pass recomputes the few directions whose
/// complement fell below [`REFINE_RATIO`]·‖a‖². The same operations in the same order per
/// direction as a direction-by-direction loop, so the same bits.
fn accumulate_window<T: Real>(
    plan: &Plan<T>,
    b: usize,
    den: &DenRefs<'_, T>,
    dec: &Decomposition<T>,
    proj: MatRef<'_, C<T>>,
    sig: &mut Vec<T>,
    acc: &mut [T],
) {
    let d = acc.len();
    let ns = plan.config.signal_dim();
    let nc = proj.ncols();
    let gain = plan.weights[b] * bin_gain(plan, dec);
    if gain == T::zero() {
        return;
    }
    match plan.config.denominator {
        Denominator::Squared => {
            sig.clear();
            sig.resize(d, T::zero());
            for s in 0..ns {
                for (x, z) in sig.iter_mut().zip(proj.col(s).iter()) {
                    *x += z.norm_sqr();
                }
            }
            quotients(den, dec, ns, gain, sig, acc);
        }
        Denominator::Unsquared => {
            for dir in 0..d {
                let mut sum = T::zero();
                for s in 0..nc {
                    sum += proj[(dir, s)].norm();
                }
                let sum = sum.max(den.floor * den.n2_den[dir].sqrt());
                if sum > T::zero() {
                    acc[dir] += gain * den.n2_num[dir] / sum;
                }
            }
        }
    }
}

/// What the squared denominator's quotients read for a block of directions: the
/// denominator's steering vectors and norms, the numerator's norms, the floor's factor.
struct DenRefs<'a, T: Real> {
    st: &'a [C<T>],
    n2_den: &'a [T],
    n2_num: &'a [T],
    floor: T,
}

/// acc(d) += gain·num(d)/(‖a_den‖² − sig(d)) for the block's directions (num: the
/// numerator, [`Plan::numerator_norm2`]), sig(d) = Σ_s
/// |aᴴe_s|²: branch-free over contiguous arrays (it vectorises), then the few directions
/// whose complement fell below [`REFINE_RATIO`]·‖a‖² recomputed in f64.
fn quotients<T: Real>(
    den: &DenRefs<'_, T>,
    dec: &Decomposition<T>,
    ns: usize,
    gain: T,
    sig: &[T],
    acc: &mut [T],
) {
    let m = dec.m;
    let tau = T::of_f64(REFINE_RATIO);
    let mut any_small = false;
    for (((a, &x), &n2), &num) in acc.iter_mut().zip(sig).zip(den.n2_den).zip(den.n2_num) {
        let d = n2 - x;
        let small = d < tau * n2;
        any_small |= small;
        let d = d.max(den.floor * n2);
        let add = gain * num / d;
        *a += if !small && d > T::zero() { add } else { T::zero() };
    }
    if any_small {
        for (dir, (a, &x)) in acc.iter_mut().zip(sig).enumerate() {
            let n2 = den.n2_den[dir];
            if n2 - x < tau * n2 {
                let d = T::of_f64(complement64(&den.st[dir * m..(dir + 1) * m], dec, ns));
                if d > T::zero() {
                    *a += gain * den.n2_num[dir] / d;
                }
            }
        }
    }
}

/// NormMUSIC's per-bin normalisation: scale one bin's contributions (w_k g_k P_k(d) over
/// the directions) so that their maximum is `weight` (= w_k): P_k(d)/max_d P_k(d)·w_k.
/// A bin whose maximum is 0 or not finite is left as it is.
pub fn normalize_bin<T: Real>(acc: &mut [T], weight: T) {
    let mx = acc.iter().fold(T::zero(), |a, &b| a.max(b));
    if mx > T::zero() && mx.is_finite() {
        let s = weight / mx;
        for v in acc.iter_mut() {
            *v *= s;
        }
    }
}

/// ‖a‖² − Σ_{m < Ns} |aᴴ e_m|² in f64 from the f64 signal vectors, floored at
/// ε_f64·‖a‖²: the squared noise-subspace denominator where it is small.
#[inline]
pub fn complement64<T: Real>(a: &[C<T>], dec: &Decomposition<T>, ns: usize) -> f64 {
    let n2: f64 = a
        .iter()
        .map(|z| z.re.to_f64().powi(2) + z.im.to_f64().powi(2))
        .sum();
    let mut sig = 0.0;
    for c in 0..ns {
        let e = dec.vector64(c);
        let (mut re, mut im) = (0.0, 0.0);
        for (ai, ei) in a.iter().zip(e) {
            let (ar, aim) = (ai.re.to_f64(), ai.im.to_f64());
            // conj(a)·e
            re += ar * ei.re + aim * ei.im;
            im += ar * ei.im - aim * ei.re;
        }
        sig += re * re + im * im;
    }
    (n2 - sig).max(f64::EPSILON * n2)
}

/// 10·log10(P̄ + 1).
#[inline]
pub fn to_db<T: Real>(p: T) -> f64 {
    10.0 * (p.to_f64() + 1.0).log10()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::{cpu::CpuBackend, Backend, BatchOutput, Job};
    use crate::bench::{inputs, BenchConfig};
    use crate::config::Algorithm;
    use crate::correlation::correlate;
    use crate::subspace::{decompose, Workspace};

    /// The backend's spectrum (complement + refinement, all stages) against the naive
    /// formula in f64: P̄(d) = Σ_k w_k g_k ‖a‖² / Σ_{m ∈ noise} |a_denᴴ e_m|².
    fn naive_vs_backend(alg: Algorithm) -> f64 {
        let cfg = BenchConfig {
            algorithm: alg,
            num_mics: 8,
            num_dirs: 300,
            batch: 2,
            ..Default::default()
        };
        let inp = inputs::<f64>(&cfg).unwrap();
        let plan = &*inp.plan;
        let mut be = CpuBackend::new(inp.plan.clone());
        let mut out = BatchOutput::default();
        be.process(&[Job::once(&inp.spectra, &inp.windows)], true, &mut out)
            .unwrap();
        let (m, d, nb, ns) = (
            plan.num_mics,
            plan.num_dirs,
            plan.num_bins(),
            plan.config.signal_dim(),
        );
        let (st, _) = plan.denominator_steering();
        let mut worst = 0.0f64;
        for (wi, w) in inp.windows.iter().enumerate() {
            let mut pbar = vec![0.0f64; d];
            let mut ws = Workspace::new(m);
            let mut dec = Decomposition::<f64>::new(m, m);
            let mut r = vec![C::new(0.0, 0.0); m * m];
            for b in 0..nb {
                correlate(&inp.spectra, w, b, &mut r);
                decompose(alg, &r, plan.whitening_matrix64(b), &mut ws, &mut dec).unwrap();
                let g = dec.values[0].max(0.0).sqrt();
                for dir in 0..d {
                    let a = &st[(b * d + dir) * m..(b * d + dir + 1) * m];
                    let mut den = 0.0;
                    for e in ns..m {
                        let v = dec.vector(e);
                        let dot: C<f64> = a.iter().zip(v).map(|(x, y)| x.conj() * y).sum();
                        den += dot.norm_sqr();
                    }
                    pbar[dir] += plan.weights[b] * g * plan.numerator_norm2()[b * d + dir] / den;
                }
            }
            for (dir, p) in pbar.iter().enumerate() {
                let want = to_db(*p);
                let got = out.spectrum_db[wi * d + dir] as f64;
                worst = worst.max((want - got).abs());
            }
        }
        worst
    }

    /// A window's spectrum is the same bits whether it runs alone or in a batch (the
    /// windows of a bin share products with the steering block), for both denominators,
    /// one or two signal vectors, small and larger products.
    #[test]
    fn a_window_alone_equals_it_in_a_batch() {
        let cases = [(24, 600, 2), (24, 600, 1), (8, 72, 2), (8, 72, 1)];
        for ((mics, dirs, ns), denominator) in cases
            .into_iter()
            .flat_map(|c| [(c, Denominator::Squared), (c, Denominator::Unsquared)])
        {
            let cfg = BenchConfig {
                algorithm: Algorithm::Gevd,
                num_mics: mics,
                num_dirs: dirs,
                num_sources: ns,
                batch: 7,
                ..Default::default()
            };
            let inp = inputs::<f32>(&cfg).unwrap();
            let mut plan = (*inp.plan).clone();
            plan.config.denominator = denominator;
            let mut be = CpuBackend::new(std::sync::Arc::new(plan));
            let mut all = BatchOutput::default();
            be.process(&[Job::once(&inp.spectra, &inp.windows)], true, &mut all)
                .unwrap();
            let d = inp.plan.num_dirs;
            for (i, w) in inp.windows.iter().enumerate() {
                let mut one = BatchOutput::default();
                be.process(
                    &[Job::once(&inp.spectra, std::slice::from_ref(w))],
                    true,
                    &mut one,
                )
                .unwrap();
                let batch = &all.spectrum_db[i * d..(i + 1) * d];
                assert!(
                    one.spectrum_db
                        .iter()
                        .zip(batch)
                        .all(|(a, b)| a.to_bits() == b.to_bits()),
                    "{denominator:?} M {mics} D {dirs} Ns {ns}: window {i} differs alone and in the batch"
                );
            }
        }
    }

    /// The CPU backend's results are the same bits whatever the size of the pool it runs
    /// in (one thread: one task after another; many: bins in parallel and, with few
    /// tasks per thread, windows split into parts), for MUSIC, the approximate mode's
    /// exact start and SRP-PHAT, on small and larger arrays.
    #[test]
    fn results_do_not_depend_on_the_pool_size() {
        for (alg, mics, dirs) in [
            (Algorithm::Gevd, 8, 72),
            (Algorithm::Gsvd, 24, 300),
            (Algorithm::SrpPhat, 8, 72),
            (Algorithm::Sevd, 20, 100),
        ] {
            let cfg = BenchConfig {
                algorithm: alg,
                num_mics: mics,
                num_dirs: dirs,
                batch: 9,
                ..Default::default()
            };
            let inp = inputs::<f32>(&cfg).unwrap();
            let run = |threads: usize| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                pool.install(|| {
                    let mut be = CpuBackend::new(inp.plan.clone());
                    let mut out = BatchOutput::default();
                    be.process(&[Job::once(&inp.spectra, &inp.windows)], true, &mut out)
                        .unwrap();
                    out
                })
            };
            let one = run(1);
            assert!(
                one.spectrum_db.iter().any(|&v| v > 0.0),
                "{alg:?}: an empty spectrum"
            );
            for threads in [3, 16] {
                let many = run(threads);
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(
                    bits(&one.spectrum_db),
                    bits(&many.spectrum_db),
                    "{alg:?} {threads} threads"
                );
                assert_eq!(
                    bits(&one.bin_weight),
                    bits(&many.bin_weight),
                    "{alg:?} {threads} threads"
                );
                assert_eq!(one.source_count, many.source_count, "{alg:?} {threads} threads");
            }
        }
    }

    #[test]
    fn complement_with_refinement_equals_the_full_noise_sum() {
        for alg in Algorithm::MUSIC {
            let worst = naive_vs_backend(alg);
            // dB values are stored as f32 (~1e-6 relative at ~10-40 dB).
            assert!(worst < 1e-4, "{alg:?}: max |dB difference| {worst:e}");
        }
    }
}
