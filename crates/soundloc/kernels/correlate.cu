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
// phat    SRP-PHAT: R̃ = (1/W) Σ x̃ x̃ᴴ unscaled (scale = 1; srp.rs); 1: every coefficient
//         reduced to its phase x/|x| (0 where |x| = 0) as it is loaded; 2: the frames are
//         x̃ already (`Spectra::phased`) and are summed as they are
// Grid: (windows × bins) blocks, matrix index = window * nb + bin; threads: any multiple
// of 32 (the host gives one per tile, `corr_threads`). Dynamic shared memory: fc × M
// complex doubles (a chunk of fc frames, converted once as they are loaded) + 32 doubles.
// Sums in double, as the CPU's running correlation, which also hands R on in double.
//
// Register tiles: a thread sums the 2 × 4 entries of rows 2g, 2g+1 and columns 4J … 4J+3
// (the tiles that reach the lower triangle, g ≥ 2J), so each frame costs it six shared
// loads for eight complex multiply-adds. In shared memory the even microphones come first,
// then the odd ones: the lanes of a warp (consecutive g) read consecutive entries.
#include "common.cuh"

// Position of microphone i in a shared frame (h2 = ⌈M/2⌉ even microphones first).
__device__ __forceinline__ int corr_pos(int i, int h2) { return (i & 1) * h2 + (i >> 1); }

// Frame coefficient x, or its phase x/|x| (0 where |x| is 0 or not finite) with phat 1;
// |x| = √(re² + im²) in double, or hypot where re² + im² leaves double's normal range
// (srp.rs `phase`, the same rule).
template <typename T>
__device__ __forceinline__ cplx<T> load_x(const cplx<T>& x, int phat) {
    if (phat != 1) return x;
    const double re = (double)x.re, im = (double)x.im, n2 = re * re + im * im;
    const double n = (n2 >= 2.2250738585072014e-308 && n2 - n2 == 0.0) ? sl_sqrt(n2) : hypot(re, im);
    if (n > 0.0 && n - n == 0.0) return cx<T>((T)((double)x.re / n), (T)((double)x.im / n));  // n finite
    return czero<T>();
}

template <typename T, typename TR>
__device__ void correlate_impl(const cplx<T>* __restrict__ X, int nb, int M, const int* __restrict__ win, int fc,
                               int mat0, int phat, cplx<TR>* __restrict__ R, TR* __restrict__ scale) {
    SL_DYN_SMEM(sl_smem);
    cplx<double>* xs = reinterpret_cast<cplx<double>*>(sl_smem);
    double* red = reinterpret_cast<double*>(xs + (size_t)fc * M);
    const int mat = mat0 + blockIdx.x;
    const int w = mat / nb, b = mat - w * nb;
    const int start = win[2 * w], len = win[2 * w + 1];
    const int tid = threadIdx.x, nt = blockDim.x;
    const int h2 = (M + 1) >> 1, nj = (M + 3) >> 2;
    int ntiles = 0;
    for (int J = 0; J < nj; ++J) ntiles += max(0, h2 - 2 * J);
    cplx<TR>* Rm = R + (size_t)blockIdx.x * M * M;
    const double inv_len = 1.0 / (double)len;
    // max_ij |Re R_ij| of a Hermitian PSD R is its largest diagonal entry (|R_ij| ≤
    // √(R_ii R_jj)): thread i < M sums |x_i|² as the first pass goes (blockDim.x ≥ M: the
    // host's corr_threads), and R is scaled as it is written (one rounding to TR).
    double diag = 0.0, k = inv_len;
    for (int base = 0; base < ntiles; base += nt) {
        int t = base + tid, J = 0, g = -1;
        if (t < ntiles) {
            while (t >= h2 - 2 * J) {
                t -= h2 - 2 * J;
                ++J;
            }
            g = 2 * J + t;
        }
        const int i0 = 2 * g, j0 = 4 * J;
        // Shared positions of the tile's rows and columns (clamped to M − 1: entries past
        // M are summed but never written).
        const int pa0 = g >= 0 ? g : 0, pa1 = corr_pos(min(i0 + 1, M - 1), h2);
        int pc[4];
#pragma unroll
        for (int q = 0; q < 4; ++q) pc[q] = corr_pos(min(j0 + q, M - 1), h2);
        cplx<double> acc[2][4];
#pragma unroll
        for (int r = 0; r < 2; ++r)
#pragma unroll
            for (int q = 0; q < 4; ++q) acc[r][q] = czero<double>();
        for (int f0 = 0; f0 < len; f0 += fc) {
            const int nf = min(fc, len - f0);
            __syncthreads();
            for (int q = tid; q < nf * M; q += nt) {
                const int f = q / M, m = q - f * M;
                const cplx<T> x = load_x(X[((size_t)(start + f0 + f) * nb + b) * M + m], phat);
                xs[f * M + corr_pos(m, h2)] = cx<double>((double)x.re, (double)x.im);
            }
            __syncthreads();
            if (base == 0 && !phat && tid < M) {
                const int p = corr_pos(tid, h2);
                for (int f = 0; f < nf; ++f) diag += cnorm2(xs[f * M + p]);
            }
            if (g >= 0) {
                for (int f = 0; f < nf; ++f) {
                    const cplx<double>* xf = xs + f * M;
                    const cplx<double> a[2] = {xf[pa0], xf[pa1]};
                    cplx<double> c[4];
#pragma unroll
                    for (int q = 0; q < 4; ++q) c[q] = xf[pc[q]];
#pragma unroll
                    for (int r = 0; r < 2; ++r)
#pragma unroll
                        for (int q = 0; q < 4; ++q) cmac_cb(acc[r][q], a[r], c[q]);
                }
            }
        }
        if (base == 0) {
            const double mx = block_max(tid < M ? diag * inv_len : 0.0, red);
            const double div = phat ? 1.0 : mx + 1.0;
            k = inv_len / div;
            if (tid == 0) scale[blockIdx.x] = (TR)div;
        }
        if (g >= 0) {
#pragma unroll
            for (int r = 0; r < 2; ++r)
#pragma unroll
                for (int q = 0; q < 4; ++q) {
                    const int i = i0 + r, j = j0 + q;
                    if (i < M && j <= i) {
                        cplx<TR> v{(TR)(acc[r][q].re * k), (TR)(acc[r][q].im * k)};
                        if (i == j) v.im = (TR)0;
                        Rm[(size_t)j * M + i] = v;
                        Rm[(size_t)i * M + j] = cconj(v);
                    }
                }
        }
    }
}

// correlate_T: R in double for the decompositions; correlate_phat_T: SRP-PHAT's R̃ in T.
#define SL_CORR_KERNEL(NAME, T, TR)                                                                       \
    extern "C" __global__ void __launch_bounds__(512)                                                     \
        NAME(const cplx<T>* X, int nb, int M, const int* win, int fc, int mat0, int phat, cplx<TR>* R, TR* scale) { \
        correlate_impl<T, TR>(X, nb, M, win, fc, mat0, phat, R, scale);                                   \
    }
#ifndef SL_NO_F32
SL_CORR_KERNEL(correlate_f32, float, double)
SL_CORR_KERNEL(correlate_phat_f32, float, float)
#endif
#ifndef SL_NO_F64
SL_CORR_KERNEL(correlate_f64, double, double)
SL_CORR_KERNEL(correlate_phat_f64, double, double)
#endif

// Coherence normalisation (LocalizeConfig::coherence, correlation::normalize_coherence on
// the CPU, the same operations in the same order): every matrix of R (double, M × M, the
// correlate kernel's output, block b = matrix b) in place, R_ij ← R_ij · (s_i s_j) with
// s_i = 1/√R_ii, or 0 for a silent channel (R_ii ≤ 1e-10 · the largest finite R_jj, or not
// finite: correlation::SILENT); the diagonal is set to exactly 1 (0 for such a channel).
// One block per matrix, any number of threads; dynamic shared memory: M doubles.
extern "C" __global__ void __launch_bounds__(256) coherence_f64(cplx<double>* R, int M) {
    SL_DYN_SMEM(sl_smem);
    double* s = reinterpret_cast<double*>(sl_smem);
    cplx<double>* Rm = R + (size_t)blockIdx.x * M * M;
    for (int i = threadIdx.x; i < M; i += blockDim.x) s[i] = Rm[(size_t)i * M + i].re;
    __syncthreads();
    double mx = 0.0;
    for (int i = 0; i < M; ++i) {
        const double d = s[i];
        if (d - d == 0.0 && d > mx) mx = d;
    }
    __syncthreads();
    for (int i = threadIdx.x; i < M; i += blockDim.x) {
        const double d = Rm[(size_t)i * M + i].re;
        s[i] = (d > 1e-10 * mx && d - d == 0.0) ? 1.0 / sl_sqrt(d) : 0.0;
    }
    __syncthreads();
    for (int q = threadIdx.x; q < M * M; q += blockDim.x) {
        const int j = q / M, i = q - j * M;
        const double k = s[i] * s[j];
        cplx<double> v = Rm[q];
        if (i == j) {
            v = cx<double>(k > 0.0 ? 1.0 : 0.0, 0.0);
        } else {
            v = cx<double>(v.re * k, v.im * k);
        }
        Rm[q] = v;
    }
}
