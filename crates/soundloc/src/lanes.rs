//! The spectrum's steering products for small arrays (M ≤ [`MAX_MICS`]), eight directions
//! side by side in vector lanes.
//!
//! The plan keeps its steering vectors also in planar form (real and imaginary parts,
//! `[bin][mic][direction]`, the directions padded to a multiple of eight with zeros);
//! per bin and block of directions
//!
//! - [`signal_power`]: Σ_s |aᴴe_s|² per direction (MUSIC's squared denominator, complement
//!   form), aᴴe = Σ_m conj(a_m) e_m summed over m in order;
//! - [`quadratic_form`]: Re(aᴴ R a) = Σ_i R_ii |a_i|² + 2 Σ_{i<j} Re(R_ij conj(a_i) a_j)
//!   per direction (SRP-PHAT), R Hermitian, summed i = 0…M−1, then the pairs (i, j) row by
//!   row into four partial sums (by (j − i − 1) mod 4) added pairwise at the end;
//!
//! each direction's value the same operations in the same order whatever the lane width,
//! so the AVX2 build (chosen at run time where the CPU has it) and the baseline x86-64
//! build give the same bits, and a window's result does not depend on its batch. For an
//! 8-mic array the library products these replace spend more on set-up and padding than
//! on the arithmetic (faer's product of eight vector columns against 72 directions when
//! MUSIC needs two to four).

// Lane loops index several arrays by the lane on purpose (they vectorise as written).
#![allow(clippy::needless_range_loop)]

use crate::real::{Real, C};
use crate::subspace::simd::dispatch;

/// Largest array these kernels serve; larger ones take the library products.
pub const MAX_MICS: usize = 16;

/// Directions per step (one AVX2 register of f32).
const LANES: usize = 8;

/// The steering vectors of every used bin in planar form, `[bin][mic][direction]`
/// (real and imaginary parts apart), the directions padded to a multiple of [`LANES`]
/// with zeros. Built once per plan (`Plan::planar`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Planar<T> {
    re: Vec<T>,
    im: Vec<T>,
    m: usize,
    /// The padded row length (directions).
    row: usize,
}

impl<T: Real> Planar<T> {
    /// From steering vectors `st`, `[bin][dir][mic]`, `dirs` directions and `m` mics.
    pub fn new(st: &[C<T>], dirs: usize, m: usize) -> Self {
        let row = dirs.div_ceil(LANES) * LANES;
        let bins = st.len() / (dirs * m).max(1);
        let mut p = Planar {
            re: vec![T::zero(); bins * m * row],
            im: vec![T::zero(); bins * m * row],
            m,
            row,
        };
        for (b, sb) in st.chunks_exact(dirs * m).enumerate() {
            for (d, a) in sb.chunks_exact(m).enumerate() {
                for (mic, z) in a.iter().enumerate() {
                    let o = (b * m + mic) * row + d;
                    p.re[o] = z.re;
                    p.im[o] = z.im;
                }
            }
        }
        p
    }

    /// Bin `b`'s directions `dirs` (the start a multiple of [`LANES`]).
    pub fn block(&self, b: usize, dirs: std::ops::Range<usize>) -> Block<'_, T> {
        debug_assert!(dirs.start.is_multiple_of(LANES) && dirs.end <= self.row);
        let base = b * self.m * self.row + dirs.start;
        Block {
            re: &self.re[base..],
            im: &self.im[base..],
            m: self.m,
            row: self.row,
            dirs: dirs.len(),
        }
    }
}

/// One bin's block of directions of a [`Planar`].
pub struct Block<'a, T> {
    re: &'a [T],
    im: &'a [T],
    m: usize,
    row: usize,
    dirs: usize,
}

impl<T: Real> Block<'_, T> {
    /// Mic `mic`'s values for directions c … c + LANES of the block.
    #[inline(always)]
    fn lanes(&self, mic: usize, c: usize) -> (&[T; LANES], &[T; LANES]) {
        let o = mic * self.row + c;
        let re = self.re[o..o + LANES].try_into().expect("LANES values");
        let im = self.im[o..o + LANES].try_into().expect("LANES values");
        (re, im)
    }

    /// The padded length of the block's directions.
    fn padded(&self) -> usize {
        self.dirs.div_ceil(LANES) * LANES
    }
}

dispatch!(
    /// Σ_s |aᴴe_s|² for every direction of `p` into `out` (at least one value per
    /// direction), the `ns` vectors e_s being the columns of `vectors` (M × ns
    /// column-major).
    pub fn signal_power<T: Real>(p: &Block<'_, T>, vectors: &[C<T>], ns: usize, out: &mut [T]) => signal_power_imp
);

#[inline(always)]
fn signal_power_imp<T: Real>(p: &Block<'_, T>, vectors: &[C<T>], ns: usize, out: &mut [T]) {
    let m = p.m;
    assert!(vectors.len() >= m * ns && out.len() >= p.dirs);
    let vectors = &vectors[..m * ns];
    for c in (0..p.padded()).step_by(LANES) {
        let mut acc = [T::zero(); LANES];
        // Two vectors at a time (independent sums that overlap), then the last one.
        let mut pairs = vectors.chunks_exact(2 * m);
        for e in pairs.by_ref() {
            let (e0, e1) = e.split_at(m);
            let (mut p0, mut p1) = (Proj::<T>::zero(), Proj::<T>::zero());
            for mic in 0..m {
                let a = p.lanes(mic, c);
                p0.add(a, e0[mic]);
                p1.add(a, e1[mic]);
            }
            p0.power_into(&mut acc);
            p1.power_into(&mut acc);
        }
        if let [_, ..] = pairs.remainder() {
            let mut p0 = Proj::<T>::zero();
            for (mic, &z) in pairs.remainder().iter().enumerate() {
                p0.add(p.lanes(mic, c), z);
            }
            p0.power_into(&mut acc);
        }
        let n = LANES.min(p.dirs - c.min(p.dirs));
        out[c..c + n].copy_from_slice(&acc[..n]);
    }
}

/// aᴴe for a lane of directions, summed mic by mic.
struct Proj<T> {
    re: [T; LANES],
    im: [T; LANES],
}

impl<T: Real> Proj<T> {
    #[inline(always)]
    fn zero() -> Self {
        Proj {
            re: [T::zero(); LANES],
            im: [T::zero(); LANES],
        }
    }

    /// += conj(a) e = (ar·er + ai·ei) + i(ar·ei − ai·er).
    #[inline(always)]
    fn add(&mut self, a: (&[T; LANES], &[T; LANES]), z: C<T>) {
        let (ar, ai) = a;
        for l in 0..LANES {
            self.re[l] += ar[l] * z.re + ai[l] * z.im;
            self.im[l] += ar[l] * z.im - ai[l] * z.re;
        }
    }

    /// acc += |aᴴe|².
    #[inline(always)]
    fn power_into(&self, acc: &mut [T; LANES]) {
        for l in 0..LANES {
            acc[l] += self.re[l] * self.re[l] + self.im[l] * self.im[l];
        }
    }
}

dispatch!(
    /// Re(aᴴ R a) for every direction of `p` into `out` (at least one value per
    /// direction); `r` is R row-major M × M, Hermitian (its upper triangle and real
    /// diagonal are read).
    pub fn quadratic_form<T: Real>(p: &Block<'_, T>, r: &[C<T>], out: &mut [T]) => quadratic_form_imp
);

#[inline(always)]
fn quadratic_form_imp<T: Real>(p: &Block<'_, T>, r: &[C<T>], out: &mut [T]) {
    let m = p.m;
    assert!(r.len() >= m * m && out.len() >= p.dirs);
    let two = T::one() + T::one();
    for c in (0..p.padded()).step_by(LANES) {
        let mut diag = [T::zero(); LANES];
        for i in 0..m {
            let (ar, ai) = p.lanes(i, c);
            let rii = r[i * m + i].re;
            for l in 0..LANES {
                diag[l] += rii * (ar[l] * ar[l] + ai[l] * ai[l]);
            }
        }
        // Four partial sums (pair j of row i into sum (j − i − 1) mod 4), so the
        // additions overlap; constant indices keep them in registers.
        let mut off = [[T::zero(); LANES]; 4];
        for i in 0..m {
            let (br, bi) = p.lanes(i, c);
            let row = &r[i * m..(i + 1) * m];
            let [o0, o1, o2, o3] = &mut off;
            let mut j = i + 1;
            while j + 4 <= m {
                pair_term(o0, (br, bi), p.lanes(j, c), row[j]);
                pair_term(o1, (br, bi), p.lanes(j + 1, c), row[j + 1]);
                pair_term(o2, (br, bi), p.lanes(j + 2, c), row[j + 2]);
                pair_term(o3, (br, bi), p.lanes(j + 3, c), row[j + 3]);
                j += 4;
            }
            if j < m {
                pair_term(o0, (br, bi), p.lanes(j, c), row[j]);
            }
            if j + 1 < m {
                pair_term(o1, (br, bi), p.lanes(j + 1, c), row[j + 1]);
            }
            if j + 2 < m {
                pair_term(o2, (br, bi), p.lanes(j + 2, c), row[j + 2]);
            }
        }
        let mut v = [T::zero(); LANES];
        for l in 0..LANES {
            let sum = (off[0][l] + off[2][l]) + (off[1][l] + off[3][l]);
            v[l] = diag[l] + two * sum;
        }
        let n = LANES.min(p.dirs - c.min(p.dirs));
        out[c..c + n].copy_from_slice(&v[..n]);
    }
}

/// acc += Re(z conj(b) a) lane by lane: conj(b) a = (br·ar + bi·ai) + i(br·ai − bi·ar).
#[inline(always)]
fn pair_term<T: Real>(
    acc: &mut [T; LANES],
    b: (&[T; LANES], &[T; LANES]),
    a: (&[T; LANES], &[T; LANES]),
    z: C<T>,
) {
    let ((br, bi), (ar, ai)) = (b, a);
    for l in 0..LANES {
        let cr = br[l] * ar[l] + bi[l] * ai[l];
        let ci = br[l] * ai[l] - bi[l] * ar[l];
        acc[l] += z.re * cr - z.im * ci;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn crand(rng: &mut impl Rng) -> C<f64> {
        C::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0))
    }

    /// Both products against their definitions in f64, for sizes around the lane width
    /// (padding) and array sizes 1 … 16.
    #[test]
    fn products_match_their_definitions() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        for (m, dirs, ns) in [
            (1, 1, 1),
            (2, 7, 1),
            (8, 72, 2),
            (8, 72, 4),
            (5, 9, 3),
            (16, 17, 8),
        ] {
            let st: Vec<C<f64>> = (0..dirs * m).map(|_| crand(&mut rng)).collect();
            let e: Vec<C<f64>> = (0..m * ns).map(|_| crand(&mut rng)).collect();
            // A Hermitian R.
            let mut r = vec![C::new(0.0, 0.0); m * m];
            for i in 0..m {
                r[i * m + i] = C::new(rng.gen_range(0.0..2.0), 0.0);
                for j in i + 1..m {
                    let z = crand(&mut rng);
                    r[i * m + j] = z;
                    r[j * m + i] = z.conj();
                }
            }
            // Two bins: the second is tested.
            let mut st2 = vec![C::new(9.0, 9.0); dirs * m];
            st2.extend_from_slice(&st);
            let planar = Planar::new(&st2, dirs, m);
            let p = planar.block(1, 0..dirs);
            let mut sig = vec![f64::NAN; dirs];
            let mut quad = vec![f64::NAN; dirs];
            signal_power(&p, &e, ns, &mut sig);
            quadratic_form(&p, &r, &mut quad);
            for d in 0..dirs {
                let a = &st[d * m..(d + 1) * m];
                let want_sig: f64 = (0..ns)
                    .map(|s| {
                        a.iter()
                            .zip(&e[s * m..(s + 1) * m])
                            .map(|(x, y)| x.conj() * y)
                            .sum::<C<f64>>()
                            .norm_sqr()
                    })
                    .sum();
                let ra: Vec<C<f64>> = (0..m)
                    .map(|i| (0..m).map(|j| r[i * m + j] * a[j]).sum())
                    .collect();
                let want_quad = a.iter().zip(&ra).map(|(x, y)| x.conj() * y).sum::<C<f64>>();
                assert!(want_quad.im.abs() < 1e-12);
                let tol = 1e-12 * (1.0 + want_sig.abs() + want_quad.re.abs());
                assert!(
                    (sig[d] - want_sig).abs() < tol,
                    "m {m} d {d}: {} vs {want_sig}",
                    sig[d]
                );
                assert!(
                    (quad[d] - want_quad.re).abs() < tol,
                    "m {m} d {d}: {} vs {}",
                    quad[d],
                    want_quad.re
                );
            }
        }
    }
}
