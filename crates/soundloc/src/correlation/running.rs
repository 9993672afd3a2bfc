//! Stage 2, incrementally: the running correlation of one stream.
//!
//! Per used bin k the sum S_k = Σ_{f=s}^{s+W−1} y_{k,f} y_{k,f}ᴴ of window [s, s + W) is
//! kept in f64 and carried from one window to the next by adding the frames that enter and
//! subtracting those that leave: S += Y_inᵀ conj(Y_in) − Y_outᵀ conj(Y_out), 2·Δ outer
//! products for a step of Δ frames instead of W (faer's SIMD products).
//! y = x for MUSIC, y = x/|x| (phase transform) for SRP-PHAT. Then
//! R_k = S_k / W and, for MUSIC, HARK's scaling R ← R / (max_ij |Re R_ij| + 1), rounded
//! to the working precision once (the f32 path no longer sums in f32).
//!
//! **When it slides.** Only when consecutive windows of a stream overlap by more than half
//! (PERIOD < W/2, e.g. PERIOD 1 in streaming) and the frames that leave are still given;
//! otherwise a direct sum (W outer products). A direct sum is also forced once the steps
//! since the last one add up to W frames, so rounding cannot build up over a long stream:
//! every S is within ~3W f64 additions of the exact sum, whatever came before. For f32
//! input the products are exact in f64.
//!
//! **Reproducible.** Each step is a fixed sequence of operations on the frames and the
//! previous sum, so a stream gives the same bits however its windows are batched or its
//! input cut into blocks (the engine hands every window of a stream to the backend in
//! order).

use crate::backend::{Job, WindowSpec};
use crate::real::{Real, C};
use crate::srp::phase_in_place;

/// How one window's sums are made from the previous window's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Step {
    /// S = Σ over the window's frames.
    Direct,
    /// S += y yᴴ for the frames `prev_start + W ..` that enter, S −= y yᴴ for the frames
    /// `prev_start ..` that leave, `delta` of each (all entering frames added, then all
    /// leaving ones subtracted).
    Slide {
        /// Start of the previous window.
        prev_start: usize,
        /// Frames moved.
        delta: usize,
    },
}

/// The running correlation of one stream over every used bin.
#[derive(Debug, Clone)]
pub struct RunningCorrelation {
    m: usize,
    /// S, `[bin][M×M]` column-major (S_ij at `j * M + i`); only the upper triangle
    /// (i ≤ j) is kept up to date, the half R is read from.
    sums: Vec<C<f64>>,
    /// The window the sums hold: (start, len).
    at: Option<(usize, usize)>,
    /// Frames slid since the last direct sum.
    since_direct: usize,
}

impl RunningCorrelation {
    /// Empty sums for `m` microphones and `nb` used bins.
    pub fn new(m: usize, nb: usize) -> Self {
        RunningCorrelation {
            m,
            sums: vec![C::new(0.0, 0.0); nb * m * m],
            at: None,
            since_direct: 0,
        }
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.sums.len() * 16
    }

    /// The step for window `w` when the caller's frames start at stream frame `first`,
    /// and advance the bookkeeping to `w` (the sums themselves move in [`run_bin`]).
    pub fn step(&mut self, w: &WindowSpec, first: usize) -> Step {
        let step = match self.at {
            Some((ps, pl))
                if pl == w.len
                    && w.start >= ps
                    && ps >= first
                    && 2 * (w.start - ps) < pl
                    && self.since_direct + (w.start - ps) <= pl =>
            {
                Step::Slide {
                    prev_start: ps,
                    delta: w.start - ps,
                }
            }
            _ => Step::Direct,
        };
        self.since_direct = match step {
            Step::Direct => 0,
            Step::Slide { delta, .. } => self.since_direct + delta,
        };
        self.at = Some((w.start, w.len));
        step
    }

    /// The sums split by bin (M × M each), for running the bins in parallel.
    pub fn bins_mut(&mut self) -> std::slice::ChunksMut<'_, C<f64>> {
        self.sums.chunks_mut(self.m * self.m)
    }
}

/// Up to this many microphones the outer products run as this file's own loops
/// ([`add_small`]): for an 8-microphone array faer's set-up per call costs more than the
/// 2 × 36 complex multiply-adds of a one-frame slide.
const SMALL_M: usize = 16;

/// S (column-major M × M, upper triangle) += sign · Σ_f y_f y_fᴴ over the rows y_f of `y`
/// (row-major, M per row), frame by frame in order; `replace`: S = 0 first. Fewer than
/// [`COLUMNS_FROM`] frames (a slide's): plain complex loops over the triangle ([`add_rows`]). A window's worth of
/// frames: column by column ([`add_columns`]), the frames in split real and imaginary
/// parts padded to N rows and a column's sums held in registers through all frames,
/// S_ij += y_i conj(y_j) as two fused multiply-adds per part (≈ 2× the plain loops on
/// 50 frames of 8 mics; its set-up costs more than a one-frame slide).
fn add_small(sum: &mut [C<f64>], y: &[C<f64>], m: usize, replace: bool, sign: f64) {
    if y.len() < COLUMNS_FROM * m.max(1) {
        return add_rows(sum, y, m, replace, sign);
    }
    match m {
        0..=4 => add_columns::<4>(sum, y, m, replace, sign),
        5..=8 => add_columns::<8>(sum, y, m, replace, sign),
        _ => add_columns::<16>(sum, y, m, replace, sign),
    }
}

/// Frames from which [`add_small`] goes column by column.
const COLUMNS_FROM: usize = 4;

/// [`add_small`] as plain loops over the upper triangle.
fn add_rows(sum: &mut [C<f64>], y: &[C<f64>], m: usize, replace: bool, sign: f64) {
    if replace {
        for j in 0..m {
            sum[j * m..j * m + j + 1].fill(C::new(0.0, 0.0));
        }
    }
    for row in y.chunks_exact(m) {
        for (j, &yj) in row.iter().enumerate() {
            let c = yj.conj() * sign;
            for (s, &yi) in sum[j * m..j * m + j + 1].iter_mut().zip(&row[..=j]) {
                *s += yi * c;
            }
        }
    }
}

crate::subspace::simd::dispatch!(
    /// [`add_small`] with columns padded to N ≥ M rows.
    fn add_columns<const N: usize>(sum: &mut [C<f64>], y: &[C<f64>], m: usize, replace: bool, sign: f64) => add_columns_impl
);

/// Frames per block of [`add_columns`]'s split copy.
const BLOCK: usize = 32;

#[inline(always)]
fn add_columns_impl<const N: usize>(sum: &mut [C<f64>], y: &[C<f64>], m: usize, replace: bool, sign: f64) {
    debug_assert!(m <= N);
    let (mut sr, mut si) = ([[0.0f64; N]; N], [[0.0f64; N]; N]);
    if !replace {
        for j in 0..m {
            for i in 0..=j {
                (sr[j][i], si[j][i]) = (sum[j * m + i].re, sum[j * m + i].im);
            }
        }
    }
    let (mut yr, mut yi) = ([[0.0f64; N]; BLOCK], [[0.0f64; N]; BLOCK]);
    for block in y.chunks(BLOCK * m) {
        let nf = block.len() / m.max(1);
        for (f, row) in block.chunks_exact(m).enumerate() {
            for (i, z) in row.iter().enumerate() {
                (yr[f][i], yi[f][i]) = (z.re, z.im);
            }
        }
        // 16/N columns at a time: eight independent chains of multiply-adds.
        let cols = (16 / N).max(1);
        for j0 in (0..m).step_by(cols) {
            let mut acc: [([f64; N], [f64; N]); 4] = [([0.0; N], [0.0; N]); 4];
            for (c, a) in acc.iter_mut().enumerate().take(cols) {
                if j0 + c < N {
                    *a = (sr[j0 + c], si[j0 + c]);
                }
            }
            for f in 0..nf {
                for (c, (ar, ai)) in acc.iter_mut().enumerate().take(cols) {
                    let j = (j0 + c).min(N - 1);
                    // c = conj(y_j)·sign; S_ij += y_i c.
                    let (cr, ci) = (yr[f][j] * sign, -yi[f][j] * sign);
                    for i in 0..N {
                        ar[i] = yr[f][i].mul_add(cr, (-yi[f][i]).mul_add(ci, ar[i]));
                        ai[i] = yr[f][i].mul_add(ci, yi[f][i].mul_add(cr, ai[i]));
                    }
                }
            }
            for (c, a) in acc.iter().enumerate().take(cols) {
                if j0 + c < m {
                    (sr[j0 + c], si[j0 + c]) = *a;
                }
            }
        }
    }
    for j in 0..m {
        for i in 0..=j {
            sum[j * m + i] = C::new(sr[j][i], si[j][i]);
        }
    }
}

/// Carry bin `bin`'s sum (`sum`: M × M column-major) through `step` to window `w` of
/// `job`, then write R (row-major M × M, exactly Hermitian, real diagonal) into `out`;
/// `phat` applies the phase transform to the frames (unless they are
/// [`crate::backend::Spectra::phased`] already) and skips HARK's scaling. `y` is
/// scratch. Returns the scale divisor (1 without scaling). R is written in `U` (f64 for
/// the CPU's decompositions, which whiten it in double precision).
#[allow(clippy::too_many_arguments)]
pub fn run_bin<T: Real, U: Real>(
    sum: &mut [C<f64>],
    step: Step,
    job: &Job<'_, T>,
    w: &WindowSpec,
    bin: usize,
    phat: bool,
    y: &mut Vec<C<f64>>,
    out: &mut [C<U>],
) -> U {
    let sp = job.spectra;
    let m = sp.num_mics;
    debug_assert_eq!(out.len(), m * m);
    // Frames `frames` as the rows of a row-major matrix in `y`.
    let gather = |frames: std::ops::Range<usize>, y: &mut Vec<C<f64>>| {
        y.clear();
        for f in frames {
            let o = (job.local(f) * sp.num_bins + bin) * m;
            y.extend(
                sp.data[o..o + m]
                    .iter()
                    .map(|&z| C::new(z.re.to_f64(), z.im.to_f64())),
            );
        }
        if phat && !sp.phased {
            phase_in_place::<T>(y);
        }
    };
    // S += sign · Yᵀ conj(Y) = sign · Σ_f y_f y_fᴴ (S_ij = Σ y_i conj(y_j)), its upper
    // triangle only (column-major: rows i ≤ j of column j), the half R is read from.
    let add = |sum: &mut [C<f64>], y: &[C<f64>], accum: faer::Accum, sign: f64| {
        use faer::linalg::matmul::triangular::{matmul, BlockStructure as B};
        if m <= SMALL_M {
            return add_small(sum, y, m, accum == faer::Accum::Replace, sign);
        }
        let rows = y.len() / m.max(1);
        let ym = faer::MatRef::from_row_major_slice(y, rows, m);
        let s = faer::MatMut::from_column_major_slice_mut(sum, m, m);
        matmul(
            s,
            B::TriangularUpper,
            accum,
            ym.transpose(),
            B::Rectangular,
            ym.conjugate(),
            B::Rectangular,
            C::new(sign, 0.0),
            faer::Par::Seq,
        );
        crate::avx::clear_upper();
    };
    match step {
        Step::Direct => {
            gather(w.start..w.start + w.len, y);
            add(sum, y, faer::Accum::Replace, 1.0);
        }
        Step::Slide { prev_start, delta } => {
            if delta > 0 {
                gather(prev_start + w.len..prev_start + w.len + delta, y);
                add(sum, y, faer::Accum::Add, 1.0);
                gather(prev_start..prev_start + delta, y);
                add(sum, y, faer::Accum::Add, -1.0);
            }
        }
    }
    let inv_w = 1.0 / w.len.max(1) as f64;
    let mut s = 1.0;
    if !phat {
        let mx = (0..m)
            .flat_map(|j| &sum[j * m..j * m + j + 1])
            .fold(0.0f64, |a, v| a.max(v.re.abs()));
        s = mx * inv_w + 1.0;
    }
    let k = inv_w / s;
    for i in 0..m {
        // Row i of R from the upper triangle of S (column j, row i ≤ j).
        out[i * m + i] = C::new(U::of_f64(sum[i * m + i].re * k), U::zero());
        for j in i + 1..m {
            let v = sum[j * m + i] * k;
            let v = C::new(U::of_f64(v.re), U::of_f64(v.im));
            out[i * m + j] = v;
            out[j * m + i] = v.conj();
        }
    }
    U::of_f64(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::{Spectra, StreamId};
    use rand::{Rng, SeedableRng};

    fn spectra(frames: usize, nb: usize, m: usize, seed: u64) -> Spectra<f32> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let mut s = Spectra::zeros(frames, nb, m);
        for v in &mut s.data {
            // Wide dynamic range: a loud stretch, then quiet frames.
            *v = C::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0));
        }
        for f in 40..60 {
            for v in &mut s.data[f * nb * m..(f + 1) * nb * m] {
                *v *= 1e4;
            }
        }
        s
    }

    /// R of window [start, start + len) of bin b, summed directly in f64 (naive).
    fn naive(s: &Spectra<f32>, start: usize, len: usize, b: usize) -> Vec<C<f64>> {
        let m = s.num_mics;
        let mut r = vec![C::new(0.0, 0.0); m * m];
        for f in start..start + len {
            let x = s.frame_bin(f, b);
            for i in 0..m {
                for j in 0..m {
                    let xi = C::new(x[i].re as f64, x[i].im as f64);
                    let xj = C::new(x[j].re as f64, x[j].im as f64);
                    r[i * m + j] += xi * xj.conj() / len as f64;
                }
            }
        }
        let mx = r.iter().map(|v| v.re.abs()).fold(0.0, f64::max) + 1.0;
        r.iter().map(|v| v / mx).collect()
    }

    fn run(s: &Spectra<f32>, windows: &[WindowSpec]) -> Vec<Vec<C<f32>>> {
        let (m, nb) = (s.num_mics, s.num_bins);
        let job = Job {
            stream: StreamId::fresh(),
            first: 0,
            spectra: s,
            windows,
        };
        let mut rc = RunningCorrelation::new(m, nb);
        let mut y = Vec::new();
        let mut out = Vec::new();
        for w in windows {
            let st = rc.step(w, 0);
            let mut per_bin = Vec::new();
            for (b, sum) in rc.bins_mut().enumerate() {
                let mut r = vec![C::new(0.0f32, 0.0); m * m];
                run_bin(sum, st, &job, w, b, false, &mut y, &mut r);
                per_bin.extend(r);
            }
            out.push(per_bin);
        }
        out
    }

    #[test]
    fn sliding_equals_the_direct_sum_through_loud_and_quiet_frames() {
        let (m, nb, len) = (5, 3, 16);
        let s = spectra(200, nb, m, 7);
        let windows: Vec<WindowSpec> = (0..=200 - len)
            .map(|c| WindowSpec {
                frame: c,
                start: c,
                len,
            })
            .collect();
        let got = run(&s, &windows);
        let mut worst = 0.0f64;
        for (w, r) in windows.iter().zip(&got) {
            for b in 0..nb {
                let want = naive(&s, w.start, len, b);
                for (g, x) in r[b * m * m..(b + 1) * m * m].iter().zip(&want) {
                    let e = (C::new(g.re as f64, g.im as f64) - x).norm();
                    worst = worst.max(e);
                }
            }
        }
        // The f32 rounding of R (entries ≤ 1 after scaling), nothing built up through
        // the 1e8-times louder stretch.
        assert!(worst < 2e-7, "worst {worst}");
    }

    #[test]
    fn steps_slide_at_small_periods_and_refresh_every_window_length() {
        let mut rc = RunningCorrelation::new(2, 1);
        let w = |s| WindowSpec {
            frame: s,
            start: s,
            len: 10,
        };
        assert_eq!(rc.step(&w(0), 0), Step::Direct);
        assert_eq!(
            rc.step(&w(3), 0),
            Step::Slide {
                prev_start: 0,
                delta: 3
            }
        );
        assert_eq!(
            rc.step(&w(7), 0),
            Step::Slide {
                prev_start: 3,
                delta: 4
            }
        );
        // 3 + 4 + 4 > 10 frames slid: refresh.
        assert_eq!(rc.step(&w(11), 0), Step::Direct);
        // A step of half the window or more: direct.
        assert_eq!(rc.step(&w(16), 0), Step::Direct);
        // The frames that would leave are no longer given: direct.
        assert_eq!(rc.step(&w(17), 17), Step::Direct);
    }

    #[test]
    fn a_slid_window_equals_its_direct_sum_at_even_steps() {
        let (m, nb, len) = (4, 2, 12);
        let s = spectra(120, nb, m, 3);
        let windows: Vec<WindowSpec> = (0..=120 - len)
            .step_by(2)
            .map(|c| WindowSpec {
                frame: c,
                start: c,
                len,
            })
            .collect();
        let whole = run(&s, &windows);
        // Window 7 was reached by slides (steps of 2 after the direct sum at 0, 12 ...);
        // on its own it is a direct sum: equal to f32 rounding.
        let direct = run(&s, &windows[7..8]);
        for (a, b) in whole[7].iter().zip(&direct[0]) {
            assert!((a - b).norm() < 1e-6);
        }
    }

    /// Both outer-product kernels (the triangle loops for a slide's frames, the column
    /// kernel for a window's) against the sum by definition, for every array size they
    /// serve, replacing and accumulating, with either sign.
    #[test]
    fn small_kernels_equal_the_defined_sum() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        for m in 1..=SMALL_M {
            for frames in [1, 2, COLUMNS_FROM, 50, 77] {
                let y: Vec<C<f64>> = (0..frames * m)
                    .map(|_| C::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0)))
                    .collect();
                let start: Vec<C<f64>> = (0..m * m)
                    .map(|_| C::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0)))
                    .collect();
                for (replace, sign) in [(true, 1.0), (false, -1.0)] {
                    let mut got = start.clone();
                    add_small(&mut got, &y, m, replace, sign);
                    for j in 0..m {
                        for i in 0..=j {
                            let base = if replace {
                                C::new(0.0, 0.0)
                            } else {
                                start[j * m + i]
                            };
                            let want =
                                base + y.chunks_exact(m).map(|r| r[i] * r[j].conj()).sum::<C<f64>>() * sign;
                            let e = (got[j * m + i] - want).norm();
                            assert!(
                                e < 1e-13 * frames as f64,
                                "m={m} frames={frames} ({i},{j}): off by {e:e}"
                            );
                        }
                    }
                }
            }
        }
    }
}
