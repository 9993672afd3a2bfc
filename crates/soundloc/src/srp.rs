//! SRP-PHAT — steered response power with the phase transform (DiBiase 2000; the
//! algorithm ODAS, pyroomacoustics' `SRP` and SpeechBrain ship), over the same grids,
//! transfer functions, bins and windows as MUSIC.
//!
//! Per STFT frame f and microphone m the coefficient is reduced to its phase,
//! x̃_m = x_m / |x_m| (0 where |x_m| = 0): the frame's cross-spectrum x̃ x̃ᴴ is then the
//! GCC-PHAT weighting X_i X_j^* / |X_i X_j^*|. Per window and used bin k
//!
//! R̃_k = (1/W) Σ_f x̃_f x̃_fᴴ                      (no HARK scaling, no K)
//!
//! and with the phase-only steering ã = a / |a| elementwise (the plan stores it so for
//! this algorithm),
//!
//! P_k(d) = Re(ãᴴ R̃_k ã) / M²  ∈ [0, 1],   P̄(d) = Σ_k w_k P_k(d),
//!
//! reported as 10·log10(P̄ + 1) dB like MUSIC. The pairwise sum Σ_{i≠j} of the classical
//! definition differs from ãᴴR̃ã by the diagonal Σ_i R̃_ii |ã_i|², which does not depend
//! on d: the peaks are the same. There is no eigenvalue weight (PHAT already whitens the
//! magnitudes) and no subspace dimension.

use crate::backend::{Spectra, WindowSpec};
use crate::lanes;
use crate::plan::Plan;
use crate::real::{Real, C};
use crate::subspace::simd::dispatch;
use faer::{Accum, MatRef, Par};

/// Per-thread scratch for [`accumulate_bin`].
pub struct SrpScratch<T: Real> {
    z: faer::Mat<C<T>>,
    r: faer::Mat<C<T>>,
    /// Small arrays: R̃ row-major in T, the values.
    r_small: Vec<C<T>>,
    quad: Vec<T>,
}

impl<T: Real> SrpScratch<T> {
    /// Scratch for a plan.
    pub fn new(plan: &Plan<T>) -> Self {
        SrpScratch {
            z: faer::Mat::zeros(plan.num_dirs, plan.num_mics),
            r: faer::Mat::zeros(plan.num_mics, plan.num_mics),
            r_small: Vec::new(),
            quad: Vec::new(),
        }
    }
}

/// Phase of a complex value: z/|z|, or 0 when z = 0 or |z| is not finite. |z| and the
/// quotient are taken in f64 as the GPU's `load_x` does (`kernels/correlate.cu`):
/// √(re² + im²), or `hypot` where re² + im² overflows or falls below the normal range of
/// f64 (|z| < 1.5e-154, only possible in f64 plans).
#[inline]
pub fn phase<T: Real>(z: C<T>) -> C<T> {
    let (re, im) = (z.re.to_f64(), z.im.to_f64());
    let n2 = re * re + im * im;
    let n = if (f64::MIN_POSITIVE..f64::INFINITY).contains(&n2) {
        n2.sqrt()
    } else {
        re.hypot(im)
    };
    if n > 0.0 && n.is_finite() {
        C::new(T::of_f64(re / n), T::of_f64(im / n))
    } else {
        C::new(T::zero(), T::zero())
    }
}

dispatch!(
    /// [`phase`] of every value of `y` (values of `T` widened to f64), in place, rounded
    /// to `T` as [`phase`] rounds. When every |z|² is finite and normal — all but hostile
    /// input — one branch-free pass the compiler vectorises (AVX2 where the CPU has it);
    /// else value by value. (libm's `hypot` per coefficient, then a scalar chain, was half
    /// of an SRP call on 8 mics.)
    pub fn phase_in_place<T: Real>(y: &mut [C<f64>]) => phase_in_place_imp
);

/// [`phase_in_place`]'s body, compiled for AVX2 (the same IEEE operations, four lanes)
/// and as it is.
#[inline(always)]
fn phase_in_place_imp<T: Real>(y: &mut [C<f64>]) {
    let ordinary = y.iter().fold(true, |ok, z| {
        let n2 = z.re * z.re + z.im * z.im;
        ok & (f64::MIN_POSITIVE..f64::INFINITY).contains(&n2)
    });
    if ordinary {
        for z in y.iter_mut() {
            let n = (z.re * z.re + z.im * z.im).sqrt();
            *z = C::new(T::of_f64(z.re / n).to_f64(), T::of_f64(z.im / n).to_f64());
        }
    } else {
        for z in y.iter_mut() {
            let p = phase(C::new(T::of_f64(z.re), T::of_f64(z.im)));
            *z = C::new(p.re.to_f64(), p.im.to_f64());
        }
    }
}

/// R̃ = (1/W) Σ x̃ x̃ᴴ over the window's frames of used bin `bin`, row-major M × M into
/// `out` (exactly Hermitian): a direct step of [`crate::correlation::running`] with the
/// phase transform.
pub fn correlate_phat<T: Real>(spectra: &Spectra<T>, w: &WindowSpec, bin: usize, out: &mut [C<T>]) {
    use crate::correlation::running::{run_bin, Step};
    let m = spectra.num_mics;
    let mut sum = vec![C::new(0.0, 0.0); m * m];
    let job = crate::backend::Job::once(spectra, std::slice::from_ref(w));
    run_bin(&mut sum, Step::Direct, &job, w, bin, true, &mut Vec::new(), out);
}

/// Adds w_k·P_k(d) = w_k·Re(ãᴴ R̃ ã)/M² for every direction d of used bin `b` to `acc`.
pub fn accumulate_bin<T: Real>(
    plan: &Plan<T>,
    b: usize,
    r: &[C<f64>],
    scratch: &mut SrpScratch<T>,
    acc: &mut [T],
) {
    let (m, d) = (plan.num_mics, plan.num_dirs);
    let gain = plan.weights[b];
    if gain == T::zero() {
        return;
    }
    let st = &plan.steering[b * d * m..(b + 1) * d * m];
    let scale = gain / T::of_f64((m * m) as f64);
    if let Some(planar) = &plan.planar {
        // Small arrays: the Hermitian form's pairs, directions in lanes.
        let block = planar.block(b, 0..d);
        scratch.r_small.clear();
        scratch.r_small.extend(
            r[..m * m]
                .iter()
                .map(|z| C::new(T::of_f64(z.re), T::of_f64(z.im))),
        );
        scratch.quad.resize(d, T::zero());
        lanes::quadratic_form(&block, &scratch.r_small, &mut scratch.quad);
        for (out, &s) in acc.iter_mut().zip(&scratch.quad) {
            *out += scale * s.max(T::zero());
        }
        return;
    }
    let a = MatRef::from_row_major_slice(st, d, m);
    for i in 0..m {
        for j in 0..m {
            let z = r[i * m + j];
            scratch.r[(i, j)] = C::new(T::of_f64(z.re), T::of_f64(z.im));
        }
    }
    let rm = scratch.r.as_ref();
    // Z = conj(Ã) R̃: Z_dj = Σ_i conj(ã_di) R̃_ij, then ãᴴR̃ã = Σ_j Z_dj ã_dj.
    faer::linalg::matmul::matmul(
        scratch.z.as_mut(),
        Accum::Replace,
        a.conjugate(),
        rm,
        C::new(T::one(), T::zero()),
        Par::Seq,
    );
    crate::avx::clear_upper();
    for (dir, out) in acc.iter_mut().enumerate().take(d) {
        let row = &st[dir * m..(dir + 1) * m];
        let mut s = T::zero();
        for (j, aj) in row.iter().enumerate() {
            let z = scratch.z[(dir, j)];
            s += z.re * aj.re - z.im * aj.im;
        }
        *out += scale * s.max(T::zero());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::Spectra;

    /// With per-bin normalisation the backend's SRP-PHAT spectrum is the sum of each
    /// bin's contributions scaled to a maximum of w_k (and differs from the plain sum).
    #[test]
    fn the_backend_normalises_each_bin_when_asked() {
        use crate::backend::{cpu::CpuBackend, Backend, BatchOutput, Job};
        use crate::bench::{inputs, BenchConfig};
        use crate::config::Algorithm;
        use crate::music::{normalize_bin, to_db};
        let cfg = BenchConfig {
            algorithm: Algorithm::SrpPhat,
            num_mics: 8,
            num_dirs: 72,
            batch: 2,
            ..Default::default()
        };
        let inp = inputs::<f64>(&cfg).unwrap();
        let mut plan = (*inp.plan).clone();
        plan.config.normalize_bins = true;
        let plan = std::sync::Arc::new(plan);
        let mut be = CpuBackend::new(plan.clone());
        let mut out = BatchOutput::default();
        be.process(&[Job::once(&inp.spectra, &inp.windows)], true, &mut out)
            .unwrap();
        let (m, d, nb) = (plan.num_mics, plan.num_dirs, plan.num_bins());
        let mut sc = SrpScratch::new(&plan);
        let mut r = vec![C::new(0.0, 0.0); m * m];
        let (mut worst, mut plain_gap) = (0.0f64, 0.0f64);
        for (wi, w) in inp.windows.iter().enumerate() {
            let (mut normalised, mut plain) = (vec![0.0; d], vec![0.0; d]);
            for b in 0..nb {
                correlate_phat(&inp.spectra, w, b, &mut r);
                let mut acc = vec![0.0; d];
                accumulate_bin(&plan, b, &r, &mut sc, &mut acc);
                plain.iter_mut().zip(&acc).for_each(|(t, a)| *t += a);
                normalize_bin(&mut acc, plan.weights[b]);
                normalised.iter_mut().zip(&acc).for_each(|(t, a)| *t += a);
            }
            for dir in 0..d {
                let got = out.spectrum_db[wi * d + dir] as f64;
                worst = worst.max((to_db(normalised[dir]) - got).abs());
                plain_gap = plain_gap.max((to_db(plain[dir]) - got).abs());
            }
        }
        assert!(worst < 1e-4, "normalised spectrum off by {worst} dB");
        assert!(plain_gap > 0.1, "normalisation changed nothing ({plain_gap} dB)");
    }

    /// ãᴴR̃ã against the explicit pairwise GCC-PHAT sum in f64 on random frames.
    #[test]
    fn quadratic_form_equals_the_pairwise_phat_sum() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let (m, w) = (5, 7);
        let mut sp = Spectra::<f64>::zeros(w, 1, m);
        for z in sp.data.iter_mut() {
            *z = C::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0));
        }
        let win = WindowSpec {
            frame: 0,
            start: 0,
            len: w,
        };
        let mut r = vec![C::new(0.0, 0.0); m * m];
        correlate_phat(&sp, &win, 0, &mut r);
        let a: Vec<C<f64>> = (0..m)
            .map(|_| phase(C::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0))))
            .collect();
        // Quadratic form.
        let mut q = C::new(0.0, 0.0);
        for i in 0..m {
            for j in 0..m {
                q += a[i].conj() * r[i * m + j] * a[j];
            }
        }
        // Pairwise: Σ_{i≠j} mean_f (x_i/|x_i|)(x_j/|x_j|)^* conj(a_i) a_j, plus the diagonal M.
        let mut pair = 0.0;
        for i in 0..m {
            for j in 0..m {
                if i == j {
                    continue;
                }
                let mut c = C::new(0.0, 0.0);
                for f in 0..w {
                    let xi = sp.data[f * m + i];
                    let xj = sp.data[f * m + j];
                    c += xi * xj.conj() / (xi.norm() * xj.norm());
                }
                pair += (c / w as f64 * a[i].conj() * a[j]).re;
            }
        }
        assert!(q.im.abs() < 1e-12);
        assert!(
            (q.re - (pair + m as f64)).abs() < 1e-12,
            "{} vs {}",
            q.re,
            pair + m as f64
        );
    }

    /// The in-place pass gives [`phase`]'s bits value by value: ordinary values (one
    /// vectorised pass), and blocks holding a zero or an |z|² that overflows f64 (the
    /// value-by-value path, with `hypot`), in f32 and f64.
    #[test]
    fn phase_in_place_equals_phase_value_by_value() {
        fn check<T: Real>(vals: &[C<f64>]) {
            let mut y: Vec<C<f64>> = vals
                .iter()
                .map(|z| C::new(T::of_f64(z.re).to_f64(), T::of_f64(z.im).to_f64()))
                .collect();
            let want: Vec<C<f64>> = y
                .iter()
                .map(|z| {
                    let p = phase(C::new(T::of_f64(z.re), T::of_f64(z.im)));
                    C::new(p.re.to_f64(), p.im.to_f64())
                })
                .collect();
            phase_in_place::<T>(&mut y);
            for (k, (a, b)) in y.iter().zip(&want).enumerate() {
                assert_eq!(
                    (a.re.to_bits(), a.im.to_bits()),
                    (b.re.to_bits(), b.im.to_bits()),
                    "value {k}"
                );
                let n = (a.re * a.re + a.im * a.im).sqrt();
                assert!(n == 0.0 || (n - 1.0).abs() < 1e-6, "value {k}: |phase| = {n}");
            }
        }
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let mut next = || rng.gen_range(-0.5..0.5);
        let ordinary: Vec<C<f64>> = (0..37).map(|_| C::new(next() * 1e3, next() * 1e-3)).collect();
        check::<f32>(&ordinary);
        check::<f64>(&ordinary);
        let mut with_zero = ordinary.clone();
        with_zero[5] = C::new(0.0, 0.0);
        check::<f32>(&with_zero);
        check::<f64>(&with_zero);
        // Known answers where |z|² leaves f64's normal range (hypot), and for NaN / ±∞.
        let mut odd = ordinary.clone();
        odd[3] = C::new(3e200, -4e200); // |z|² overflows; |z| = 5e200
        odd[4] = C::new(-3e-200, 4e-200); // |z|² underflows to 0; |z| = 5e-200
        odd[6] = C::new(3e-160, 4e-160); // |z|² subnormal
        odd[7] = C::new(f64::NAN, 1.0);
        odd[8] = C::new(f64::INFINITY, 0.0);
        check::<f64>(&odd);
        let mut y = odd.clone();
        phase_in_place::<f64>(&mut y);
        let close = |z: C<f64>, re: f64, im: f64| (z.re - re).abs() < 1e-15 && (z.im - im).abs() < 1e-15;
        assert!(close(y[3], 0.6, -0.8) && close(y[4], -0.6, 0.8) && close(y[6], 0.6, 0.8));
        assert!(close(y[7], 0.0, 0.0) && close(y[8], 0.0, 0.0));
        // The baseline (non-AVX2) body gives the dispatched bits; phase = z/|z| to rounding.
        let mut a = ordinary.clone();
        let mut b = ordinary.clone();
        phase_in_place::<f64>(&mut a);
        phase_in_place_imp::<f64>(&mut b);
        assert_eq!(a, b);
        for (z, p) in ordinary.iter().zip(&a) {
            let n = z.re.hypot(z.im);
            assert!(close(*p, z.re / n, z.im / n));
        }
    }
}
