//! Small dense blocks for [`super::tracking`]: column blocks (M × n, column-major) and
//! square matrices (row-major), split real and imaginary parts, with the products
//! y = A x and y = Aᴴ x per column and a twice-repeated modified Gram–Schmidt.

use super::simd::{self, conj_axpy, dot4, dotc};
use crate::real::C;
use faer::c64;

/// A block of column vectors, M × cols column-major, split real and imaginary parts.
#[derive(Debug, Clone, Default)]
pub(crate) struct Block {
    pub(crate) m: usize,
    pub(crate) cols: usize,
    pub(crate) re: Vec<f64>,
    pub(crate) im: Vec<f64>,
}

impl Block {
    pub(crate) fn new(m: usize) -> Self {
        Block {
            m,
            ..Default::default()
        }
    }
    pub(crate) fn clear(&mut self) {
        self.cols = 0;
        self.re.clear();
        self.im.clear();
    }
    /// A zeroed column appended; its index.
    pub(crate) fn push_zero(&mut self) -> usize {
        self.cols += 1;
        self.re.resize(self.cols * self.m, 0.0);
        self.im.resize(self.cols * self.m, 0.0);
        self.cols - 1
    }
    pub(crate) fn col(&self, c: usize) -> (&[f64], &[f64]) {
        let r = c * self.m..(c + 1) * self.m;
        (&self.re[r.clone()], &self.im[r])
    }
    pub(crate) fn col_mut(&mut self, c: usize) -> (&mut [f64], &mut [f64]) {
        let r = c * self.m..(c + 1) * self.m;
        (&mut self.re[r.clone()], &mut self.im[r])
    }
    /// M × cols zeros.
    pub(crate) fn zeros(&mut self, m: usize, cols: usize) {
        self.m = m;
        self.cols = cols;
        self.re.clear();
        self.im.clear();
        self.re.resize(m * cols, 0.0);
        self.im.resize(m * cols, 0.0);
    }
    /// Same shape as `other`, zeroed.
    pub(crate) fn zero_like(&mut self, other: &Block) {
        self.zeros(other.m, other.cols);
    }
}

/// A row-major M × M matrix, split parts.
#[derive(Debug, Clone, Default)]
pub(crate) struct Square {
    pub(crate) re: Vec<f64>,
    pub(crate) im: Vec<f64>,
}

impl Square {
    pub(crate) fn load(&mut self, a: &[c64]) {
        self.re.clear();
        self.im.clear();
        self.re.extend(a.iter().map(|z| z.re));
        self.im.extend(a.iter().map(|z| z.im));
    }
}

simd::dispatch!(
    /// y = A x per column (`lower`: only A's lower triangle is non-zero).
    pub(crate) fn mul(a: &Square, lower: bool, x: &Block, y: &mut Block) => mul_impl
);

#[inline(always)]
fn mul_impl(a: &Square, lower: bool, x: &Block, y: &mut Block) {
    let m = x.m;
    y.zero_like(x);
    for c in 0..x.cols {
        let (xr, xi) = x.col(c);
        let (yr, yi) = y.col_mut(c);
        for i in 0..m {
            let len = if lower { i + 1 } else { m };
            let row = i * m..i * m + len;
            let z = dot4::<false>(&a.re[row.clone()], &a.im[row], &xr[..len], &xi[..len]);
            yr[i] = z.re;
            yi[i] = z.im;
        }
    }
}

simd::dispatch!(
    /// y = Aᴴ x per column (`lower`: only A's lower triangle is non-zero).
    pub(crate) fn mul_adjoint(a: &Square, lower: bool, x: &Block, y: &mut Block) => mul_adjoint_impl
);

#[inline(always)]
fn mul_adjoint_impl(a: &Square, lower: bool, x: &Block, y: &mut Block) {
    let m = x.m;
    y.zero_like(x);
    for c in 0..x.cols {
        let (xr, xi) = x.col(c);
        let (yr, yi) = y.col_mut(c);
        // y += conj(row j of A)ᵀ · x_j
        for j in 0..m {
            let len = if lower { j + 1 } else { m };
            let row = j * m..j * m + len;
            conj_axpy(
                C::new(xr[j], xi[j]),
                &a.re[row.clone()],
                &a.im[row],
                &mut yr[..len],
                &mut yi[..len],
            );
        }
    }
}

/// Modified Gram–Schmidt, twice, of `cols` appended to `out` (already orthonormal):
/// columns whose remainder is below 10⁻¹⁰ of their norm are dropped.
pub(crate) fn orth_append(out: &mut Block, src: &Block, cols: std::ops::Range<usize>) {
    for c in cols {
        let (sr, si) = src.col(c);
        let n0 = norm2(sr, si).sqrt();
        if !(n0 > 0.0 && n0.is_finite()) {
            continue;
        }
        let k = out.push_zero();
        {
            let (or, oi) = out.col_mut(k);
            or.copy_from_slice(sr);
            oi.copy_from_slice(si);
        }
        let m = out.m;
        let (done_r, cur_r) = out.re.split_at_mut(k * m);
        let (done_i, cur_i) = out.im.split_at_mut(k * m);
        for _ in 0..2 {
            for j in 0..k {
                let (qr, qi) = (&done_r[j * m..(j + 1) * m], &done_i[j * m..(j + 1) * m]);
                let h = dotc(qr, qi, cur_r, cur_i);
                simd::axpy(-h, qr, qi, cur_r, cur_i);
            }
        }
        let (or, oi) = out.col_mut(k);
        let n = norm2(or, oi).sqrt();
        if n <= 1e-10 * n0 {
            out.cols -= 1;
            out.re.truncate(out.cols * out.m);
            out.im.truncate(out.cols * out.m);
            continue;
        }
        or.iter_mut().chain(oi.iter_mut()).for_each(|x| *x /= n);
    }
}

pub(crate) fn norm2(re: &[f64], im: &[f64]) -> f64 {
    simd::dot_real(re, re) + simd::dot_real(im, im)
}
