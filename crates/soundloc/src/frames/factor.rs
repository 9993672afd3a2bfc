//! A long window of given frames as M frames: its correlation sum, then a factor of it.
//!
//! Per used bin k the sum S_k = Σ_s x_{·,k,s} x_{·,k,s}ᴴ (M × M, f64) is formed straight
//! from the caller's array, each microphone's snapshots read in runs of its own memory
//! order (numpy's (M, F, S): one contiguous run per microphone and bin). Its Cholesky
//! factor with diagonal pivoting, S_k = Σ_c l_c l_cᴴ (semidefinite: once the largest
//! remaining pivot is below 10⁻¹⁴ of S's largest power the rest is left out, an error at
//! that level), gives M frames y_c = √(M / S_snap) · l_c whose correlation
//! (Σ_c y_c y_cᴴ) / M is S_k / S_snap: the window's R to rounding. A backend given those
//! M frames computes the same R, decomposition, spectrum and peaks as from the S_snap
//! frames themselves, without the transposing copy of every snapshot into its frame
//! layout.
//!
//! For SRP-PHAT, whose phase transform acts on each snapshot before the sum, the sum is
//! S̃_k = Σ_s x̃ x̃ᴴ of the transformed snapshots x̃ = x/|x| (rounded as the backend
//! rounds them, [`crate::srp::phase_in_place`]); its factor frames are handed on marked
//! as already transformed ([`crate::backend::Spectra::phased`]), so the backend sums them
//! as they are: R̃ = S̃_k / S_snap.

use super::FramesView;
use crate::real::{Real, C};
use num_complex::Complex;

/// Snapshots per block of [`bin_sum`]: a block of every microphone, split into real and
/// imaginary parts, stays in the first-level cache on small arrays (8 mics: 8 KB; 60:
/// 61 KB, in the second level with the pairs' sums).
const BLOCK: usize = 64;

/// Lanes of the sums in [`add_block`] (independent chains the compiler vectorises).
const LANES: usize = 8;

/// A pivot below this fraction of S's largest diagonal entry counts as zero.
const PIVOT_FLOOR: f64 = 1e-14;

/// Scratch of one thread: a block of snapshots in split parts, the lanes' sums, the
/// bin's sum S (row-major M × M, [`bin_sum`]'s result), the factor's working matrix and
/// pivot list.
#[derive(Default)]
pub(super) struct Scratch {
    re: Vec<f64>,
    im: Vec<f64>,
    sum_re: Vec<f64>,
    sum_im: Vec<f64>,
    pub(super) sum: Vec<Complex<f64>>,
    work: Vec<Complex<f64>>,
    rest: Vec<usize>,
}

/// What [`bin_sum`] found in a bin's values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Read {
    /// Every value is finite (else the sum is meaningless).
    pub finite: bool,
    /// With the phase transform: every value stays finite when rounded to the plan's
    /// type, as the snapshots' path rounds it (else that path names the value).
    pub held: bool,
}

/// S_k of bin `k` of `x` into `ws.sum` (row-major M × M, Hermitian, real diagonal); with
/// `phat`, S̃_k of the snapshots rounded to `T` and reduced to their phase as the
/// backend's copy path does ([`phase_split`]).
pub(super) fn bin_sum<T: Real>(x: &FramesView<'_>, k: usize, phat: bool, ws: &mut Scratch) -> Read {
    let [m, _, s] = x.shape;
    ws.sum.resize(m * m, Complex::new(0.0, 0.0));
    let [st_mic, st_bin, st_snap] = x.strides;
    ws.re.resize(m * BLOCK, 0.0);
    ws.im.resize(m * BLOCK, 0.0);
    ws.sum_re.clear();
    ws.sum_re.resize(m * m * LANES, 0.0);
    ws.sum_im.clear();
    ws.sum_im.resize(m * m * LANES, 0.0);
    let (mut finite, mut held) = (true, true);
    for first in (0..s).step_by(BLOCK) {
        let n = BLOCK.min(s - first);
        // The block's snapshots rounded up to whole lanes; zeros past the last add nothing.
        let len = n.next_multiple_of(LANES);
        for mic in 0..m {
            let o = mic * st_mic + k * st_bin + first * st_snap;
            let re = &mut ws.re[mic * BLOCK..mic * BLOCK + len];
            let im = &mut ws.im[mic * BLOCK..mic * BLOCK + len];
            if phat {
                // As the copy path: rounded to T, then the phase in f64, rounded to T.
                let round = |v: f64| T::of_f64(v).to_f64();
                if st_snap == 1 {
                    let mut ok = [true; 2];
                    load_rounded::<T>(&x.data[o..o + n], &mut re[..n], &mut im[..n], &mut ok);
                    (finite, held) = (finite & ok[0], held & ok[1]);
                } else {
                    for (t, (r, i)) in re.iter_mut().zip(im.iter_mut()).take(n).enumerate() {
                        let v = x.data[o + t * st_snap];
                        finite &= v.re.is_finite() & v.im.is_finite();
                        (*r, *i) = (round(v.re), round(v.im));
                        held &= r.is_finite() & i.is_finite();
                    }
                }
                phase_split::<T>(&mut re[..n], &mut im[..n]);
            } else if st_snap == 1 {
                for ((r, i), v) in re.iter_mut().zip(im.iter_mut()).zip(&x.data[o..o + n]) {
                    finite &= v.re.is_finite() & v.im.is_finite();
                    (*r, *i) = (v.re, v.im);
                }
            } else {
                for (t, (r, i)) in re.iter_mut().zip(im.iter_mut()).take(n).enumerate() {
                    let v = x.data[o + t * st_snap];
                    finite &= v.re.is_finite() & v.im.is_finite();
                    (*r, *i) = (v.re, v.im);
                }
            }
            re[n..].fill(0.0);
            im[n..].fill(0.0);
        }
        add_block(&ws.re, &ws.im, m, len, &mut ws.sum_re, &mut ws.sum_im);
    }
    for i in 0..m {
        for j in i..m {
            let o = (i * m + j) * LANES;
            let v = Complex::new(
                ws.sum_re[o..o + LANES].iter().sum(),
                ws.sum_im[o..o + LANES].iter().sum(),
            );
            ws.sum[i * m + j] = v;
            ws.sum[j * m + i] = v.conj();
        }
        ws.sum[i * m + i].im = 0.0;
    }
    Read { finite, held }
}

crate::subspace::simd::dispatch!(
    /// `src` rounded to `T` (widened, in split parts) into `re`, `im`; `ok` becomes
    /// [every value finite, every rounded value finite].
    fn load_rounded<T: Real>(src: &[Complex<f64>], re: &mut [f64], im: &mut [f64], ok: &mut [bool; 2]) => load_rounded_imp
);

#[inline(always)]
fn load_rounded_imp<T: Real>(src: &[Complex<f64>], re: &mut [f64], im: &mut [f64], ok: &mut [bool; 2]) {
    let (mut finite, mut held) = (true, true);
    for ((r, i), v) in re.iter_mut().zip(im.iter_mut()).zip(src) {
        finite &= v.re.is_finite() & v.im.is_finite();
        (*r, *i) = (T::of_f64(v.re).to_f64(), T::of_f64(v.im).to_f64());
        held &= r.is_finite() & i.is_finite();
    }
    *ok = [finite, held];
}

crate::subspace::simd::dispatch!(
    /// The phase transform of values of `T` (widened, in split parts) in place, rounded to
    /// `T`: the bits of [`crate::srp::phase_in_place`], without its interleaved copy.
    fn phase_split<T: Real>(re: &mut [f64], im: &mut [f64]) => phase_split_imp
);

#[inline(always)]
fn phase_split_imp<T: Real>(re: &mut [f64], im: &mut [f64]) {
    let ordinary = re.iter().zip(im.iter()).fold(true, |ok, (r, i)| {
        ok & (f64::MIN_POSITIVE..f64::INFINITY).contains(&(r * r + i * i))
    });
    if ordinary {
        for (r, i) in re.iter_mut().zip(im.iter_mut()) {
            let n = (*r * *r + *i * *i).sqrt();
            (*r, *i) = (T::of_f64(*r / n).to_f64(), T::of_f64(*i / n).to_f64());
        }
    } else {
        for (r, i) in re.iter_mut().zip(im.iter_mut()) {
            let p = crate::srp::phase(C::new(T::of_f64(*r), T::of_f64(*i)));
            (*r, *i) = (p.re.to_f64(), p.im.to_f64());
        }
    }
}

crate::subspace::simd::dispatch!(
    /// Σ over the first `len` snapshots (a multiple of `LANES`) of a block of x_i conj(x_j)
    /// for i ≤ j, into `LANES` partial sums per pair.
    fn add_block(re: &[f64], im: &[f64], m: usize, len: usize, sum_re: &mut [f64], sum_im: &mut [f64]) => add_block_impl
);

#[inline(always)]
fn add_block_impl(re: &[f64], im: &[f64], m: usize, len: usize, sum_re: &mut [f64], sum_im: &mut [f64]) {
    for i in 0..m {
        let (ri, ii) = (&re[i * BLOCK..(i + 1) * BLOCK], &im[i * BLOCK..(i + 1) * BLOCK]);
        for j in i..m {
            let (rj, ij) = (&re[j * BLOCK..(j + 1) * BLOCK], &im[j * BLOCK..(j + 1) * BLOCK]);
            let o = (i * m + j) * LANES;
            let mut ar = [0.0f64; LANES];
            let mut ai = [0.0f64; LANES];
            ar.copy_from_slice(&sum_re[o..o + LANES]);
            ai.copy_from_slice(&sum_im[o..o + LANES]);
            for t in (0..len).step_by(LANES) {
                for l in 0..LANES {
                    // x_i conj(x_j) = (a + ib)(c − id) = ac + bd + i(bc − ad).
                    let (a, b, c, d) = (ri[t + l], ii[t + l], rj[t + l], ij[t + l]);
                    ar[l] = a.mul_add(c, b.mul_add(d, ar[l]));
                    ai[l] = b.mul_add(c, (-a).mul_add(d, ai[l]));
                }
            }
            sum_re[o..o + LANES].copy_from_slice(&ar);
            sum_im[o..o + LANES].copy_from_slice(&ai);
        }
    }
}

/// The M frames of one bin from its sum `ws.sum` (row-major M × M, Hermitian, from
/// [`bin_sum`]) over `snapshots` snapshots: frame c's vector √(M / snapshots) · l_c (the
/// pivoted factor's c-th column, in microphone order), written at
/// `out[c * stride .. c * stride + M]` (the frame layout of [`crate::backend::Spectra`]).
pub(super) fn factor_frames<T: Real>(
    ws: &mut Scratch,
    m: usize,
    snapshots: usize,
    out: &mut [C<T>],
    stride: usize,
) {
    // `a`: the part of S not yet taken by frames (its rows and columns `rest`); `col`:
    // the frame being formed.
    let Scratch { sum, work, rest, .. } = ws;
    work.clear();
    work.extend_from_slice(&sum[..m * m]);
    work.resize(m * m + m, Complex::new(0.0, 0.0));
    let (a, col) = work.split_at_mut(m * m);
    let floor = (0..m).map(|i| sum[i * m + i].re).fold(0.0f64, f64::max) * PIVOT_FLOOR;
    let scale = (m as f64 / snapshots as f64).sqrt();
    rest.clear();
    rest.extend(0..m);
    for c in 0..m {
        // Diagonal pivoting (LAPACK's pstrf): the largest remaining power goes next, and
        // once it is at rounding level the rest — whose entries are at most that, S being
        // semidefinite — is left out; the frames left are zero.
        let Some((pos, p)) = rest
            .iter()
            .copied()
            .enumerate()
            .max_by(|x, y| a[x.1 * m + x.1].re.total_cmp(&a[y.1 * m + y.1].re))
        else {
            break;
        };
        let d = a[p * m + p].re;
        if d.is_nan() || d <= floor {
            for cc in c..m {
                out[cc * stride..cc * stride + m].fill(C::new(T::zero(), T::zero()));
            }
            return;
        }
        let s = d.sqrt();
        col.fill(Complex::new(0.0, 0.0));
        for &i in rest.iter() {
            col[i] = a[i * m + p] / s;
        }
        col[p] = Complex::new(s, 0.0);
        rest.swap_remove(pos);
        for &i in rest.iter() {
            for &k in rest.iter() {
                a[i * m + k] -= col[i] * col[k].conj();
            }
        }
        for (o, v) in out[c * stride..c * stride + m].iter_mut().zip(col.iter()) {
            *o = C::new(T::of_f64(v.re * scale), T::of_f64(v.im * scale));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Uniform values in [−0.5, 0.5) from a seed (a linear congruential generator).
    fn uniform(mut seed: u64) -> impl FnMut() -> f64 {
        move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        }
    }

    /// The split phase transform gives the bits of the copy path's, in both of its
    /// branches (ordinary blocks, and blocks with a zero, a subnormal or a huge value).
    #[test]
    fn split_phase_equals_the_copy_paths_bits() {
        fn check<T: Real>(values: &[Complex<f64>]) {
            let widened: Vec<Complex<f64>> = values
                .iter()
                .map(|v| Complex::new(T::of_f64(v.re).to_f64(), T::of_f64(v.im).to_f64()))
                .collect();
            let mut want = widened.clone();
            crate::srp::phase_in_place::<T>(&mut want);
            let mut re: Vec<f64> = widened.iter().map(|v| v.re).collect();
            let mut im: Vec<f64> = widened.iter().map(|v| v.im).collect();
            phase_split::<T>(&mut re, &mut im);
            for (k, w) in want.iter().enumerate() {
                assert_eq!(
                    (re[k].to_bits(), im[k].to_bits()),
                    (w.re.to_bits(), w.im.to_bits()),
                    "{}",
                    T::NAME
                );
            }
        }
        let mut rnd = uniform(3);
        let mut values: Vec<Complex<f64>> = (0..67).map(|_| Complex::new(rnd() * 1e3, rnd())).collect();
        check::<f32>(&values);
        check::<f64>(&values);
        for special in [
            Complex::new(0.0, 0.0),
            Complex::new(1e-160, -3e-170),
            Complex::new(1e200, 1.0),
        ] {
            values[17] = special;
            check::<f32>(&values);
            check::<f64>(&values);
        }
    }

    /// The sum equals the defined Σ x xᴴ (snapshots not a multiple of the block), the same
    /// read through the strides of an (S, F, M) array, and the factor frames' Σ y yᴴ
    /// reproduces it, also when it is singular and when a channel is 160 dB below the
    /// others (where a factor without pivoting drops a column's coupling at 10⁻⁷).
    #[test]
    fn sums_and_factors_reproduce_the_correlation() {
        let (m, f, s) = (5, 3, 150);
        let mut rnd = uniform(7);
        let mut x: Vec<Complex<f64>> = (0..m * f * s).map(|_| Complex::new(rnd(), rnd())).collect();
        // Microphone 4 = 2 × microphone 1 at bin 2: S_2 has rank 4. Microphone 0 at bin 1
        // is 160 dB below the others.
        for t in 0..s {
            x[(4 * f + 2) * s + t] = x[(f + 2) * s + t] * 2.0;
            x[s + t] *= 1e-8;
        }
        let view = FramesView::new(&x, [m, f, s], [f * s, s, 1]).unwrap();
        let mut t = vec![Complex::new(0.0, 0.0); m * f * s];
        for (i, v) in x.iter().enumerate() {
            let (mic, k, snap) = (i / (f * s), i / s % f, i % s);
            t[(snap * f + k) * m + mic] = *v;
        }
        let sfm = FramesView::new(&t, [m, f, s], [1, m, f * m]).unwrap();
        let mut ws = Scratch::default();
        for k in 0..f {
            assert!(bin_sum::<f64>(&sfm, k, false, &mut ws).finite);
            let other = ws.sum.clone();
            assert!(bin_sum::<f64>(&view, k, false, &mut ws).finite);
            let sum = ws.sum.clone();
            assert_eq!(other, sum);
            for i in 0..m {
                for j in 0..m {
                    let want: Complex<f64> = (0..s)
                        .map(|t| x[(i * f + k) * s + t] * x[(j * f + k) * s + t].conj())
                        .sum();
                    assert!((sum[i * m + j] - want).norm() < 1e-12 * s as f64, "{k} {i} {j}");
                }
            }
            let mut frames = vec![C::<f64>::new(0.0, 0.0); m * m];
            factor_frames(&mut ws, m, s, &mut frames, m);
            for i in 0..m {
                for j in 0..m {
                    let r: C<f64> = (0..m).map(|c| frames[c * m + i] * frames[c * m + j].conj()).sum();
                    let want = sum[i * m + j] / s as f64;
                    assert!(
                        (Complex::new(r.re, r.im) * (1.0 / m as f64) - want).norm()
                            < 1e-12 * (1e-16 + want.norm()).max(1e-3),
                        "{k} {i} {j}: {r} vs {want}"
                    );
                }
            }
        }
        x[(3 * f + 1) * s + 77].im = f64::NAN;
        let view = FramesView::new(&x, [m, f, s], [f * s, s, 1]).unwrap();
        assert!(!bin_sum::<f64>(&view, 1, false, &mut ws).finite);
        assert!(bin_sum::<f64>(&view, 0, false, &mut ws).finite);
    }
}
