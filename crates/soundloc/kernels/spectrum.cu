// Stage 4 — MUSIC spectrum: for each direction d, window w and used bin b,
//   P_b(d) = ‖a‖² / Σ_noise |aᴴ e_m|²   (squared, default)   or   ‖a‖² / Σ_noise |aᴴ e_m|
// and the weighted bin sum P̄_w(d) = Σ_b gain_wb P_b(d), gain = w_b g_b.
//
// Squared: Σ_noise |aᴴe_m|² = ‖a‖² − Σ_signal |aᴴe_s|² (orthonormal basis); where that
// complement is below tau·‖a‖² (music::REFINE_RATIO, as the CPU) it is recomputed as
// ‖(I − E_s E_sᴴ) a‖² with two passes of modified Gram–Schmidt, which equals the full
// noise-subspace sum to rounding. Then den ← max(den, ε‖a‖²) and bins with den ≤ 0 or
// gain 0 add nothing — the CPU's rules.
//
// St [bin][dir][M] the denominator's steering (whitened for the textbook GEVD),
// n2den/n2num [bin][dir] its ‖·‖² and the raw ‖a‖², E [wl*nb + b][ne][M] the basis of the
// sub-batch's windows (ne = ns, or M for the unsquared form), gain [wl*nb + b].
// Grid: x = direction tiles of blockDim.x, y = groups of SL_SPEC_WG windows, z = groups of
// bins; each z writes its own partial sum Ppart[z][wl][dir] (summed in peaks.cu, in a
// fixed order). Dynamic shared memory: blockDim.x × (M | 1) complex (the steering tile).
#include "common.cuh"

#define SL_SPEC_WG 8

// ‖(I − E Eᴴ) a‖² for the ns rows of E (each of length M), two MGS passes.
template <typename T>
__device__ __noinline__ T residual_norm2(const cplx<T>* a, const cplx<T>* __restrict__ e, int M, int ns) {
    cplx<T> r[SL_MAXN];
    for (int i = 0; i < M; ++i) r[i] = a[i];
    for (int pass = 0; pass < 2; ++pass) {
        for (int s = 0; s < ns; ++s) {
            const cplx<T>* es = e + (size_t)s * M;
            cplx<T> c = czero<T>();
            for (int i = 0; i < M; ++i) cmacc(c, es[i], r[i]);  // e_sᴴ r
            for (int i = 0; i < M; ++i) {
                const cplx<T> v = es[i];
                r[i].re -= v.re * c.re - v.im * c.im;
                r[i].im -= v.re * c.im + v.im * c.re;
            }
        }
    }
    T s2 = (T)0;
    for (int i = 0; i < M; ++i) s2 += cnorm2(r[i]);
    return s2;
}

template <typename T>
__device__ void spectrum_impl(const cplx<T>* __restrict__ St, const T* __restrict__ n2den,
                              const T* __restrict__ n2num, const cplx<T>* __restrict__ E, int ne,
                              const T* __restrict__ gain, int M, int nb, int D, int ns, int squared, int nwin, T tau,
                              T* __restrict__ Ppart) {
    SL_DYN_SMEM(sl_smem);
    cplx<T>* tile = reinterpret_cast<cplx<T>*>(sl_smem);
    const int lds = M | 1;
    const int tid = threadIdx.x, nt = blockDim.x;
    const int d0 = blockIdx.x * nt;
    const int d = d0 + tid;
    const int w0 = blockIdx.y * SL_SPEC_WG;
    const int bpg = (nb + gridDim.z - 1) / gridDim.z;
    const int b0 = blockIdx.z * bpg, b1 = min(nb, b0 + bpg);
    const int ndt = min(nt, D - d0);
    const T eps = sl_eps<T>::v();
    T acc[SL_SPEC_WG];
#pragma unroll
    for (int k = 0; k < SL_SPEC_WG; ++k) acc[k] = (T)0;
    for (int b = b0; b < b1; ++b) {
        __syncthreads();
        const cplx<T>* src = St + ((size_t)b * D + d0) * M;
        for (int idx = tid; idx < ndt * M; idx += nt) {
            const int dl = idx / M, i = idx - dl * M;
            tile[dl * lds + i] = src[idx];
        }
        __syncthreads();
        if (d >= D) continue;
        const cplx<T>* a = tile + tid * lds;
        const T nd = n2den[(size_t)b * D + d], nn = n2num[(size_t)b * D + d];
#pragma unroll
        for (int k = 0; k < SL_SPEC_WG; ++k) {
            const int wl = w0 + k;
            if (wl >= nwin) break;
            const T g = gain[(size_t)wl * nb + b];
            if (g == (T)0) continue;
            const cplx<T>* e = E + ((size_t)wl * nb + b) * ne * M;
            T den;
            if (squared) {
                T sig = (T)0;
                for (int s = 0; s < ns; ++s) {
                    const cplx<T>* es = e + (size_t)s * M;
                    cplx<T> pr = czero<T>();
                    for (int i = 0; i < M; ++i) cmacc(pr, a[i], es[i]);  // aᴴ e_s
                    sig += cnorm2(pr);
                }
                den = nd - sig;
                if (den < tau * nd) den = residual_norm2(a, e, M, ns);
                den = sl_max(den, eps * nd);
            } else {
                den = (T)0;
                for (int s = ns; s < M; ++s) {
                    const cplx<T>* es = e + (size_t)s * M;
                    cplx<T> pr = czero<T>();
                    for (int i = 0; i < M; ++i) cmacc(pr, a[i], es[i]);
                    den += sl_sqrt(cnorm2(pr));
                }
                den = sl_max(den, eps * sl_sqrt(nd));
            }
            if (den > (T)0) acc[k] += g * nn / den;
        }
    }
    if (d < D) {
#pragma unroll
        for (int k = 0; k < SL_SPEC_WG; ++k) {
            const int wl = w0 + k;
            if (wl < nwin) Ppart[((size_t)blockIdx.z * nwin + wl) * D + d] = acc[k];
        }
    }
}

extern "C" __global__ void spectrum_f32(const cplx<float>* St, const float* n2den, const float* n2num,
                                        const cplx<float>* E, int ne, const float* gain, int M, int nb, int D, int ns,
                                        int squared, int nwin, float tau, float* Ppart) {
    spectrum_impl<float>(St, n2den, n2num, E, ne, gain, M, nb, D, ns, squared, nwin, tau, Ppart);
}
extern "C" __global__ void spectrum_f64(const cplx<double>* St, const double* n2den, const double* n2num,
                                        const cplx<double>* E, int ne, const double* gain, int M, int nb, int D,
                                        int ns, int squared, int nwin, double tau, double* Ppart) {
    spectrum_impl<double>(St, n2den, n2num, E, ne, gain, M, nb, D, ns, squared, nwin, tau, Ppart);
}
