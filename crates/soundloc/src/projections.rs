//! The spectrum's signal powers for larger arrays (M > [`crate::lanes::MAX_MICS`]) in
//! single precision on AVX-512: Σ_s |aᴴe_s|² per direction (MUSIC's squared denominator,
//! complement form), the windows' signal vectors side by side in vector lanes.
//!
//! A group of windows' vectors becomes planar columns `[mic][lane]` (lane = window·Ns + s,
//! padded with zeros to a multiple of [`LANES`]) of e_r, e_i − e_r and e_r + e_i. Per
//! direction a, conj(a)·e = (p + iq)(c + id) with p = a_r, q = −a_i, c = e_r, d = e_i is
//! summed mic by mic in order as three products (Gauss's form; fused multiply-adds, one
//! accumulator each per lane):
//!
//! k₁ += (p + q)·c,  k₂ += p·(d − c),  k₃ += q·(c + d);  Re = k₁ − k₃,  Im = k₁ + k₂,
//!
//! then |aᴴe_s|² = fma(Im, Im, Re·Re), and each window's lanes are added in the order of s.
//! Three multiply-adds per complex product instead of four; the rounding is that of sums
//! of terms up to √2·|a_m||e_m| instead of |a_m||e_m| (tests bound it against f64; on the
//! 60-mic drone scene the SEVD spectrum's f32-vs-f64 RMS is 3.0e-6 dB, against 2.7e-6 dB
//! with four products). Every lane does the same operations whatever its neighbours, so a
//! window's result is the same bits alone or in a group, and for any batch. The steering
//! vectors stay interleaved (`[dir][mic]`, each value broadcast to all lanes; p + q is
//! formed once per plan, [`steering_sums`]).
//!
//! Against faer's complex product and a separate pass over its result (the path for f64,
//! the unsquared denominator, Ns > 64 and CPUs without AVX-512) no product matrix is written and reread
//! (BENCHMARKS.md, "eleventh session").

use crate::real::C;

/// Lanes of one vector register (f32 on AVX-512).
pub const LANES: usize = 16;

/// Most lanes (columns) one group may hold: four registers per accumulator.
pub const MAX_COLS: usize = 4 * LANES;

/// Whether this CPU runs [`signal_power`] (AVX-512F, checked at run time).
pub fn available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx512f")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Windows per group for `ns` signal vectors: as many as fill one register (at least
/// one), so small subspaces do not pad each window to a whole register.
pub fn windows_per_group(ns: usize) -> usize {
    (LANES / ns.max(1)).max(1)
}

/// A group of windows' signal vectors as planar columns `[mic][lane]`.
#[derive(Debug, Default, Clone)]
pub struct Columns {
    /// e_r, e_i − e_r, e_r + e_i.
    c: Vec<f32>,
    dmc: Vec<f32>,
    cpd: Vec<f32>,
    m: usize,
    /// Lanes per mic row (a multiple of [`LANES`], at most [`MAX_COLS`]).
    lanes: usize,
    ns: usize,
    windows: usize,
}

impl Columns {
    /// Lays out the first `ns` columns of each window's `vectors` (M × ≥ ns,
    /// column-major). Panics past [`MAX_COLS`] columns (callers group by
    /// [`windows_per_group`], and Ns ≤ 64 on this path: `music::fused`).
    pub fn fill<'a>(&mut self, m: usize, ns: usize, windows: impl ExactSizeIterator<Item = &'a [C<f32>]>) {
        let nw = windows.len();
        let lanes = (nw * ns).div_ceil(LANES).max(1) * LANES;
        assert!(
            lanes <= MAX_COLS,
            "{nw} windows × {ns} vectors exceed {MAX_COLS} lanes"
        );
        for v in [&mut self.c, &mut self.dmc, &mut self.cpd] {
            v.clear();
            v.resize(m * lanes, 0.0);
        }
        for (w, v) in windows.enumerate() {
            assert!(w < nw, "the iterator yielded more windows than its length");
            for s in 0..ns {
                let col = &v[s * m..(s + 1) * m];
                for (mic, z) in col.iter().enumerate() {
                    let o = mic * lanes + w * ns + s;
                    self.c[o] = z.re;
                    self.dmc[o] = z.im - z.re;
                    self.cpd[o] = z.re + z.im;
                }
            }
        }
        (self.m, self.lanes, self.ns, self.windows) = (m, lanes, ns, nw);
    }
}

/// p + q = a_r − a_i of every value of `st`: the three-product form's third factor,
/// formed once per plan (`Plan::steering_sums`).
pub fn steering_sums(st: &[C<f32>]) -> Vec<f32> {
    st.iter().map(|z| z.re - z.im).collect()
}

/// Σ_s |aᴴe_s|² for every direction of `st` (row-major directions × M, interleaved; `pq`
/// its [`steering_sums`]) and every window of `cols`: window w's value for direction d at
/// `out[w·D + d]`, D = `st.len() / M`. Call only where [`available`] (panics elsewhere).
pub fn signal_power(st: &[C<f32>], pq: &[f32], cols: &Columns, out: &mut [f32]) {
    let m = cols.m;
    assert!(m > 0 && st.len().is_multiple_of(m) && pq.len() == st.len());
    let d = st.len() / m;
    assert!(out.len() >= cols.windows * d);
    #[cfg(target_arch = "x86_64")]
    if available() {
        // SAFETY: the CPU has AVX-512F (checked just above); the slices' lengths were
        // checked against the shapes the kernel reads and writes.
        unsafe { avx512::signal_power(st, pq, cols, d, out) };
        return;
    }
    panic!("projections::signal_power needs AVX-512F");
}

#[cfg(target_arch = "x86_64")]
mod avx512 {
    use super::{Columns, LANES, MAX_COLS};
    use crate::real::C;
    use std::arch::x86_64::*;

    /// Accumulator registers per tile: RD directions × NC registers × (k₁, k₂, k₃).
    const ACC: usize = 24;

    #[target_feature(enable = "avx512f")]
    pub(super) unsafe fn signal_power(st: &[C<f32>], pq: &[f32], cols: &Columns, d: usize, out: &mut [f32]) {
        // SAFETY: AVX-512F (this function's feature).
        unsafe {
            match cols.lanes / LANES {
                1 => run::<{ ACC / 3 }, 1>(st, pq, cols, d, out),
                2 => run::<{ ACC / 6 }, 2>(st, pq, cols, d, out),
                3 => run::<{ ACC / 9 }, 3>(st, pq, cols, d, out),
                4 => run::<{ ACC / 12 }, 4>(st, pq, cols, d, out),
                _ => unreachable!("Columns::fill makes 1 to 4 registers per lane row"),
            }
        }
    }

    /// Tiles of RD directions, then single directions for the rest (the same operations
    /// per lane, so the same bits), NC registers each.
    #[target_feature(enable = "avx512f")]
    unsafe fn run<const RD: usize, const NC: usize>(
        st: &[C<f32>],
        pq: &[f32],
        cols: &Columns,
        d: usize,
        out: &mut [f32],
    ) {
        debug_assert!(cols.lanes == NC * LANES);
        let m = cols.m;
        let mut dir = 0;
        while dir + RD <= d {
            let mut tile = [[0.0f32; MAX_COLS]; RD];
            // SAFETY: AVX-512F (this function's feature); the rows hold RD·M values.
            unsafe {
                tile_rd::<RD, NC>(
                    &st[dir * m..(dir + RD) * m],
                    &pq[dir * m..(dir + RD) * m],
                    cols,
                    &mut tile,
                )
            };
            for (r, t) in tile.iter().enumerate() {
                window_sums(t, cols, d, dir + r, out);
            }
            dir += RD;
        }
        for dir in dir..d {
            let mut one = [[0.0f32; MAX_COLS]; 1];
            // SAFETY: as above, M values.
            unsafe {
                tile_rd::<1, NC>(
                    &st[dir * m..(dir + 1) * m],
                    &pq[dir * m..(dir + 1) * m],
                    cols,
                    &mut one,
                )
            };
            window_sums(&one[0], cols, d, dir, out);
        }
    }

    /// Window w's Σ_s of the lanes w·Ns … w·Ns + Ns − 1 of `pw`, in order of s.
    #[inline(always)]
    fn window_sums(pw: &[f32; MAX_COLS], cols: &Columns, d: usize, dir: usize, out: &mut [f32]) {
        let ns = cols.ns;
        for w in 0..cols.windows {
            let mut s = 0.0f32;
            for &v in &pw[w * ns..(w + 1) * ns] {
                s += v;
            }
            out[w * d + dir] = s;
        }
    }

    /// |aᴴe|² per lane for RD directions (rows of `st`, M values each) into `pw[r]`.
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn tile_rd<const RD: usize, const NC: usize>(
        st: &[C<f32>],
        pq: &[f32],
        cols: &Columns,
        pw: &mut [[f32; MAX_COLS]; RD],
    ) {
        let (m, lanes) = (cols.m, cols.lanes);
        assert!(
            NC * LANES <= lanes
                && st.len() >= RD * m
                && pq.len() >= RD * m
                && [&cols.c, &cols.dmc, &cols.cpd]
                    .iter()
                    .all(|v| v.len() >= m * lanes)
        );
        let mut k1 = [[_mm512_setzero_ps(); NC]; RD];
        let mut k2 = [[_mm512_setzero_ps(); NC]; RD];
        let mut k3 = [[_mm512_setzero_ps(); NC]; RD];
        let (cp, dp, sp) = (cols.c.as_ptr(), cols.dmc.as_ptr(), cols.cpd.as_ptr());
        for i in 0..m {
            let mut c = [_mm512_setzero_ps(); NC];
            let mut dmc = [_mm512_setzero_ps(); NC];
            let mut cpd = [_mm512_setzero_ps(); NC];
            for q in 0..NC {
                let o = i * lanes + q * LANES;
                // SAFETY: o + 16 ≤ m·lanes (checked above).
                unsafe {
                    c[q] = _mm512_loadu_ps(cp.add(o));
                    dmc[q] = _mm512_loadu_ps(dp.add(o));
                    cpd[q] = _mm512_loadu_ps(sp.add(o));
                }
            }
            for r in 0..RD {
                let a = st[r * m + i];
                let (p, q, s) = (
                    _mm512_set1_ps(a.re),
                    _mm512_set1_ps(a.im),
                    _mm512_set1_ps(pq[r * m + i]),
                );
                for l in 0..NC {
                    k1[r][l] = _mm512_fmadd_ps(s, c[l], k1[r][l]);
                    k2[r][l] = _mm512_fmadd_ps(p, dmc[l], k2[r][l]);
                    // q = −a_i: k₃ −= a_i·(c + d)
                    k3[r][l] = _mm512_fnmadd_ps(q, cpd[l], k3[r][l]);
                }
            }
        }
        for r in 0..RD {
            for l in 0..NC {
                let re = _mm512_sub_ps(k1[r][l], k3[r][l]);
                let im = _mm512_add_ps(k1[r][l], k2[r][l]);
                let p = _mm512_fmadd_ps(im, im, _mm512_mul_ps(re, re));
                // SAFETY: l·16 + 16 ≤ NC·16 ≤ MAX_COLS.
                unsafe { _mm512_storeu_ps(pw[r].as_mut_ptr().add(l * LANES), p) };
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(seed: &mut u64) -> f32 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*seed >> 40) as f32 / (1u64 << 24) as f32) - 0.5
    }

    fn random(n: usize, seed: &mut u64) -> Vec<C<f32>> {
        (0..n).map(|_| C::new(lcg(seed), lcg(seed))).collect()
    }

    /// Random steering (d directions × m) and a full group of windows' Ns vectors, and
    /// the kernel's values for them (`[window][direction]`).
    struct Case {
        st: Vec<C<f32>>,
        vecs: Vec<Vec<C<f32>>>,
        out: Vec<f32>,
    }

    fn case(m: usize, ns: usize, d: usize, seed: &mut u64) -> Case {
        let st = random(d * m, seed);
        let vecs: Vec<Vec<C<f32>>> = (0..windows_per_group(ns)).map(|_| random(m * ns, seed)).collect();
        let out = powers(&st, m, ns, &vecs);
        Case { st, vecs, out }
    }

    fn powers(st: &[C<f32>], m: usize, ns: usize, vecs: &[Vec<C<f32>>]) -> Vec<f32> {
        let mut cols = Columns::default();
        cols.fill(m, ns, vecs.iter().map(|v| v.as_slice()));
        let mut out = vec![f32::NAN; vecs.len() * (st.len() / m)];
        signal_power(st, &steering_sums(st), &cols, &mut out);
        out
    }

    /// Against Σ_s |aᴴe_s|² in f64, for arrays and subspaces that take one to four
    /// registers, several windows per group, and direction counts off the tile size.
    #[test]
    fn signal_power_equals_the_f64_sum() {
        if !available() {
            println!("SKIPPED signal_power_equals_the_f64_sum: this CPU lacks AVX-512F");
            return;
        }
        let mut seed = 7u64;
        for (m, ns, d) in [
            (17, 1, 5),
            (24, 2, 37),
            (24, 3, 13),
            (60, 2, 50),
            (60, 16, 29),
            (60, 17, 25),
            (60, 30, 23),
            (64, 48, 9),
            (64, 63, 7),
        ] {
            let Case { st, vecs, out } = case(m, ns, d, &mut seed);
            for (w, v) in vecs.iter().enumerate() {
                for dir in 0..d {
                    let a = &st[dir * m..(dir + 1) * m];
                    // Each projection's three M-term sums (terms up to √2|a_m||e_m|) and
                    // their sum or difference err by at most ~3M·ε·Σ_m|a_m||e_m| (δ);
                    // |z|² then by 2|z|δ + δ², and the Ns-term sum by Ns·ε of the total.
                    let (mut want, mut tol) = (0.0f64, 0.0f64);
                    for s in 0..ns {
                        let e = &v[s * m..(s + 1) * m];
                        let mut z = C::new(0.0f64, 0.0);
                        let mut scale = 0.0f64;
                        for (x, y) in a.iter().zip(e) {
                            z += C::new(x.re as f64, -x.im as f64) * C::new(y.re as f64, y.im as f64);
                            scale += (x.norm() * y.norm()) as f64;
                        }
                        let delta = 3.0 * m as f64 * f32::EPSILON as f64 * scale;
                        want += z.norm_sqr();
                        tol += 2.0 * z.norm() * delta + delta * delta;
                    }
                    let got = out[w * d + dir] as f64;
                    let tol = tol + 2.0 * ns as f64 * f32::EPSILON as f64 * want;
                    assert!(
                        (got - want).abs() <= tol,
                        "M {m} Ns {ns} w {w} d {dir}: {got} vs {want}"
                    );
                }
            }
        }
    }

    /// A window's values are the same bits alone as among others in its group.
    #[test]
    fn a_window_alone_equals_it_in_a_group() {
        if !available() {
            println!("SKIPPED a_window_alone_equals_it_in_a_group: this CPU lacks AVX-512F");
            return;
        }
        let mut seed = 11u64;
        for (m, ns) in [(24, 2), (60, 5), (40, 3)] {
            let d = 31;
            let Case { st, vecs, out: all } = case(m, ns, d, &mut seed);
            for (w, v) in vecs.iter().enumerate() {
                let one = powers(&st, m, ns, std::slice::from_ref(v));
                let bits = |x: &[f32]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                assert_eq!(
                    bits(&one),
                    bits(&all[w * d..(w + 1) * d]),
                    "M {m} Ns {ns} window {w}"
                );
            }
        }
    }
}
