// Stage 2 — correlation windows: R = (1/W) Σ_f x_f x_fᴴ for one (window, bin) per block,
// then HARK's scaling R ← R / (max_ij |Re R_ij| + 1), exactly Hermitian, real diagonal.
//
// X       [frame][bin][mic]   the uploaded frames (frame 0 = first uploaded frame)
// win     [window][2]         (first frame relative to X, number of frames)
// R       [window][bin][M×M]  column-major output (R[j*M+i] = R_ij), in double for the
//                             decompositions whatever the frames' precision (TR = double:
//                             one rounding of the double sums, none to T); SRP-PHAT's R̃ in
//                             T (TR = T), which its spectrum reads directly
// scale   [window][bin]       the divisor max|Re R_ij| + 1 in TR (for the decomposition's
//                             factor form, which rebuilds R's factor from the frames)
// phat    SRP-PHAT: every coefficient reduced to its phase x/|x| (0 where |x| = 0) as it is
//         loaded, and R̃ = (1/W) Σ x̃ x̃ᴴ unscaled (scale = 1; srp.rs)
// Grid: (windows × bins) blocks, matrix index = window * nb + bin. Dynamic shared
// memory: fc × M complex (a chunk of fc frames) + 32 doubles. Sums in double, as the CPU's
// running correlation, which also hands R on in double.
#include "common.cuh"

#define SL_CORR_EPT 8

// Frame coefficient x, or its phase x/|x| (0 where |x| is 0 or not finite) with `phat`;
// |x| = √(re² + im²) in double, or hypot where re² + im² leaves double's normal range
// (srp.rs `phase`, the same rule).
template <typename T>
__device__ __forceinline__ cplx<T> load_x(const cplx<T>& x, int phat) {
    if (!phat) return x;
    const double re = (double)x.re, im = (double)x.im, n2 = re * re + im * im;
    const double n = (n2 >= 2.2250738585072014e-308 && n2 - n2 == 0.0) ? sl_sqrt(n2) : hypot(re, im);
    if (n > 0.0 && n - n == 0.0) return cx<T>((T)((double)x.re / n), (T)((double)x.im / n));  // n finite
    return czero<T>();
}

template <typename T, typename TR>
__device__ void correlate_impl(const cplx<T>* __restrict__ X, int nb, int M, const int* __restrict__ win, int fc,
                               int mat0, int phat, cplx<TR>* __restrict__ R, TR* __restrict__ scale) {
    SL_DYN_SMEM(sl_smem);
    cplx<T>* xs = reinterpret_cast<cplx<T>*>(sl_smem);
    double* red = reinterpret_cast<double*>(xs + (size_t)fc * M);
    const int mat = mat0 + blockIdx.x;
    const int w = mat / nb, b = mat - w * nb;
    const int start = win[2 * w], len = win[2 * w + 1];
    const int tid = threadIdx.x, nt = blockDim.x;
    const int ntri = M * (M + 1) / 2;
    cplx<TR>* Rm = R + (size_t)blockIdx.x * M * M;
    const double inv_len = 1.0 / (double)len;
    // The divisor first: for Hermitian PSD R, max_ij |Re R_ij| is the largest diagonal
    // entry (|R_ij| ≤ √(R_ii R_jj)), so R is scaled as it is written — one rounding to T.
    double diag = 0.0;
    for (int f0 = 0; f0 < (phat ? 0 : len); f0 += fc) {
        const int nf = min(fc, len - f0);
        __syncthreads();
        for (int k = tid; k < nf * M; k += nt) {
            const int f = k / M, m = k - f * M;
            xs[k] = X[((size_t)(start + f0 + f) * nb + b) * M + m];
        }
        __syncthreads();
        if (tid < M) {
            for (int f = 0; f < nf; ++f) {
                const cplx<T> x = xs[f * M + tid];
                diag += (double)x.re * (double)x.re + (double)x.im * (double)x.im;
            }
        }
    }
    const double mx = block_max(tid < M ? diag * inv_len : 0.0, red);
    const double div = phat ? 1.0 : mx + 1.0;
    const double k = inv_len / div;
    if (tid == 0) scale[blockIdx.x] = (TR)div;
    for (int base = 0; base < ntri; base += SL_CORR_EPT * nt) {
        // Sums in double: f32 frames multiply exactly, and 50-term sums keep their digits.
        cplx<double> acc[SL_CORR_EPT];
        int ii[SL_CORR_EPT], jj[SL_CORR_EPT];
#pragma unroll
        for (int e = 0; e < SL_CORR_EPT; ++e) {
            acc[e] = czero<double>();
            int idx = base + tid + e * nt;
            int j = 0, i = 0;
            if (idx < ntri) {
                j = (int)((sl_sqrt(8.0 * (double)idx + 1.0) - 1.0) * 0.5);
                while (j * (j + 1) / 2 > idx) --j;
                while ((j + 1) * (j + 2) / 2 <= idx) ++j;
                i = idx - j * (j + 1) / 2;
            } else {
                j = -1;
            }
            ii[e] = i;
            jj[e] = j;
        }
        for (int f0 = 0; f0 < len; f0 += fc) {
            const int nf = min(fc, len - f0);
            __syncthreads();
            for (int q = tid; q < nf * M; q += nt) {
                const int f = q / M, m = q - f * M;
                xs[q] = load_x(X[((size_t)(start + f0 + f) * nb + b) * M + m], phat);
            }
            __syncthreads();
            for (int f = 0; f < nf; ++f) {
                const cplx<T>* xf = xs + f * M;
#pragma unroll
                for (int e = 0; e < SL_CORR_EPT; ++e) {
                    if (jj[e] >= 0) {
                        const cplx<T> a = xf[ii[e]], c = xf[jj[e]];
                        cmac_cb(acc[e], cplx<double>{(double)a.re, (double)a.im},
                                cplx<double>{(double)c.re, (double)c.im});
                    }
                }
            }
        }
#pragma unroll
        for (int e = 0; e < SL_CORR_EPT; ++e) {
            if (jj[e] >= 0) {
                const int i = ii[e], j = jj[e];
                cplx<TR> v{(TR)(acc[e].re * k), (TR)(acc[e].im * k)};
                if (i == j) v.im = (TR)0;
                Rm[(size_t)j * M + i] = v;
                Rm[(size_t)i * M + j] = cconj(v);
            }
        }
    }
}

// correlate_T: R in double for the decompositions; correlate_phat_T: SRP-PHAT's R̃ in T.
#ifndef SL_NO_F32
extern "C" __global__ void correlate_f32(const cplx<float>* X, int nb, int M, const int* win, int fc, int mat0,
                                         int phat, cplx<double>* R, double* scale) {
    correlate_impl<float, double>(X, nb, M, win, fc, mat0, phat, R, scale);
}
extern "C" __global__ void correlate_phat_f32(const cplx<float>* X, int nb, int M, const int* win, int fc, int mat0,
                                              int phat, cplx<float>* R, float* scale) {
    correlate_impl<float, float>(X, nb, M, win, fc, mat0, phat, R, scale);
}
#endif
#ifndef SL_NO_F64
extern "C" __global__ void correlate_f64(const cplx<double>* X, int nb, int M, const int* win, int fc, int mat0,
                                         int phat, cplx<double>* R, double* scale) {
    correlate_impl<double, double>(X, nb, M, win, fc, mat0, phat, R, scale);
}
extern "C" __global__ void correlate_phat_f64(const cplx<double>* X, int nb, int M, const int* win, int fc,
                                              int mat0, int phat, cplx<double>* R, double* scale) {
    correlate_impl<double, double>(X, nb, M, win, fc, mat0, phat, R, scale);
}
#endif
