// Stage 4 — the spectrum: for each direction d, window w and used bin b,
//   MUSIC (kind 0): P_b(d) = ‖a‖² / Σ_noise |aᴴ e_m|²  (squared, default)  or  ‖a‖² / Σ_noise |aᴴ e_m|
//   SRP-PHAT (kind 1): P_b(d) = Re(ãᴴ R̃ ã) / M²  (E is then R̃ itself, column-major, ne = M;
//                      ã the phase-only steering; srp.rs)
// and the weighted bin sum P̄_w(d) = Σ_b gain_wb P_b(d), gain = w_b g_b (w_b for SRP).
// NormMUSIC (normalize_bins) runs two passes: pass 1 takes binmax_wb = max_d P_b(d)
// (atomic max over directions, binmax zeroed before), pass 2 sums w_b P_b(d) / binmax_wb
// (g_b cancels; a bin whose maximum is 0 keeps gain·P — the CPU's normalize_bin). Pass 0:
// the plain sum.
//
// Squared: Σ_noise |aᴴe_m|² = ‖a‖² − Σ_signal |aᴴe_s|² (orthonormal basis); where that
// complement is below tau·‖a‖² (music::REFINE_RATIO, as the CPU) it is recomputed in
// double from the double signal vectors E64 (music::complement64: ‖a‖² and aᴴe_s summed
// in double, floored at ε_f64·‖a‖²); elsewhere den ← max(den, ε_T‖a‖²). Where E64 is
// null (an f32 plan's vectors from the f32 Jacobi, M > 64: only f32-accurate, so a double
// complement of them would not be exact) the recomputation is ‖(I − E_sE_sᴴ)a‖² in T by
// two Gram–Schmidt passes, floored at ε_T‖a‖². Bins with den ≤ 0
// or gain 0 add nothing — the CPU's rules. The products aᴴe_s accumulate as fused
// multiply-adds (cmacc_fma: four per complex product; the loops are bound by instruction
// issue), the same order in the one- and four-direction forms.
//
// St [bin][dir][M] the denominator's steering (whitened for the textbook GEVD),
// n2den/n2num [bin][dir] its ‖·‖² and the numerator (the raw ‖a‖², or the textbook GEVD's
// other choice: Plan::numerator_norm2), E [wl*nb + b][ne][M] the basis of the
// sub-batch's windows (ne = ns, or M for the unsquared form), E64 the same signal vectors
// in double (squared form), gain [wl*nb + b].
// Block: dt directions × (blockDim.x / (dt / RD)) windows, RD directions of one window per
// thread (RD = 1, or 4: see spectrum_impl);
// per bin the block stages the steering tile (dt × M) and, when e_smem, the windows'
// vectors in shared memory. Grid: x = direction tiles, y = window groups, z = groups of
// bins; each z writes its own partial sum Ppart[z][wl][dir] (summed in peaks.cu, in a
// fixed order). Dynamic shared memory: dt × (M | 1) complex (+ wg × ne × M complex).
#include "common.cuh"

// Signal vectors per pass over a (independent accumulators).
#define SL_SPEC_NSB 4
// Unrolling of proj_sum_rd's loop over the microphones (a tuning hook: -DSL_SPEC_UNROLL=k).
#ifndef SL_SPEC_UNROLL
#define SL_SPEC_UNROLL 4
#endif

// ‖(I − E Eᴴ) a‖² for the ns rows of E (each of length M), two MGS passes.
template <typename T>
__device__ __noinline__ T residual_norm2(const cplx<T>* a, const cplx<T>* e, int M, int ns) {
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

// ‖a‖² − Σ_s |aᴴ e_s|² in double over the ns rows of e (double), floored at ε_f64·‖a‖².
template <typename T>
__device__ __noinline__ double complement64(const cplx<T>* a, const cplx<double>* e, int M, int ns) {
    double n2 = 0.0;
    for (int i = 0; i < M; ++i) n2 += (double)a[i].re * (double)a[i].re + (double)a[i].im * (double)a[i].im;
    double sig = 0.0;
    for (int s = 0; s < ns; ++s) {
        const cplx<double>* es = e + (size_t)s * M;
        double re = 0.0, im = 0.0;
        for (int i = 0; i < M; ++i) {
            const double ar = (double)a[i].re, ai = (double)a[i].im;
            re += ar * es[i].re + ai * es[i].im;  // conj(a)·e
            im += ar * es[i].im - ai * es[i].re;
        }
        sig += re * re + im * im;
    }
    return sl_max(n2 - sig, sl_eps<double>::v() * n2);
}

// Σ_{s0 ≤ s < s1} f(aᴴ e_s), SL_SPEC_NSB vectors per pass; f = |·|² (sq) or |·|.
template <typename T, bool SQ>
__device__ __forceinline__ T proj_sum(const cplx<T>* a, const cplx<T>* e, int M, int s0, int s1) {
    T tot = (T)0;
    for (int sb = s0; sb < s1; sb += SL_SPEC_NSB) {
        cplx<T> pr[SL_SPEC_NSB];
#pragma unroll
        for (int k = 0; k < SL_SPEC_NSB; ++k) pr[k] = czero<T>();
        const int cnt = min(SL_SPEC_NSB, s1 - sb);
        const cplx<T>* eb = e + (size_t)sb * M;
        if (cnt == SL_SPEC_NSB) {
            for (int i = 0; i < M; ++i) {
                const cplx<T> ai = a[i];
#pragma unroll
                for (int k = 0; k < SL_SPEC_NSB; ++k) cmacc_fma(pr[k], ai, eb[(size_t)k * M + i]);
            }
        } else if (cnt == 2) {
            for (int i = 0; i < M; ++i) {
                const cplx<T> ai = a[i];
                cmacc_fma(pr[0], ai, eb[i]);
                cmacc_fma(pr[1], ai, eb[(size_t)M + i]);
            }
        } else {
            for (int i = 0; i < M; ++i) {
                const cplx<T> ai = a[i];
                for (int k = 0; k < cnt; ++k) cmacc_fma(pr[k], ai, eb[(size_t)k * M + i]);
            }
        }
#pragma unroll
        for (int k = 0; k < SL_SPEC_NSB; ++k) {
            if (k < cnt) tot += SQ ? cnorm2(pr[k]) : sl_sqrt(cnorm2(pr[k]));
        }
    }
    return tot;
}

// proj_sum<T, true> for RD directions at once (rows a + r·astep of the steering tile):
// every vector value loaded once serves RD directions (register blocking; the
// single-direction loop issues about one shared load per complex product). Per
// direction the same operations in the same order as proj_sum: the same bits.
template <typename T, int RD>
__device__ __forceinline__ void proj_sum_rd(const cplx<T>* a, int astep, const cplx<T>* e, int M, int ns,
                                            T (&tot)[RD]) {
#pragma unroll
    for (int r = 0; r < RD; ++r) tot[r] = (T)0;
    for (int sb = 0; sb < ns; sb += SL_SPEC_NSB) {
        cplx<T> pr[RD][SL_SPEC_NSB];
#pragma unroll
        for (int r = 0; r < RD; ++r)
#pragma unroll
            for (int k = 0; k < SL_SPEC_NSB; ++k) pr[r][k] = czero<T>();
        const int cnt = min(SL_SPEC_NSB, ns - sb);
        const cplx<T>* eb = e + (size_t)sb * M;
        if (cnt == SL_SPEC_NSB) {
#pragma unroll SL_SPEC_UNROLL
            for (int i = 0; i < M; ++i) {
                cplx<T> ek[SL_SPEC_NSB];
#pragma unroll
                for (int k = 0; k < SL_SPEC_NSB; ++k) ek[k] = eb[(size_t)k * M + i];
#pragma unroll
                for (int r = 0; r < RD; ++r) {
                    const cplx<T> ai = a[r * astep + i];
#pragma unroll
                    for (int k = 0; k < SL_SPEC_NSB; ++k) cmacc_fma(pr[r][k], ai, ek[k]);
                }
            }
        } else {
            for (int i = 0; i < M; ++i) {
#pragma unroll
                for (int r = 0; r < RD; ++r) {
                    const cplx<T> ai = a[r * astep + i];
                    for (int k = 0; k < cnt; ++k) cmacc_fma(pr[r][k], ai, eb[(size_t)k * M + i]);
                }
            }
        }
#pragma unroll
        for (int r = 0; r < RD; ++r)
#pragma unroll
            for (int k = 0; k < SL_SPEC_NSB; ++k)
                if (k < cnt) tot[r] += cnorm2(pr[r][k]);
    }
}

// Re(aᴴ R a) for R column-major M × M (column j at R + j·M).
template <typename T>
__device__ __noinline__ T quad_form(const cplx<T>* a, const cplx<T>* R, int M) {
    T q = (T)0;
    for (int j = 0; j < M; ++j) {
        const cplx<T>* col = R + (size_t)j * M;
        cplx<T> c = czero<T>();
        for (int i = 0; i < M; ++i) cmacc(c, a[i], col[i]);  // (aᴴ R)_j
        q += c.re * a[j].re - c.im * a[j].im;
    }
    return q;
}

// RD directions per thread (dt / RD threads per window): 1, or 4 for the squared MUSIC
// form with a deep signal subspace (proj_sum_rd), chosen by the host (layout.rs).
template <typename T, int RD>
__device__ void spectrum_impl(const cplx<T>* __restrict__ St, const T* __restrict__ n2den,
                              const T* __restrict__ n2num, const cplx<T>* __restrict__ E,
                              const cplx<double>* __restrict__ E64, int ne,
                              const T* __restrict__ gain, int M, int nb, int D, int ns, int squared, int nwin, T tau,
                              int dt, int e_smem, int kind, int pass, const T* __restrict__ weights,
                              T* __restrict__ binmax, T* __restrict__ Ppart) {
    SL_DYN_SMEM(sl_smem);
    const int lds = M | 1;
    cplx<T>* tile = reinterpret_cast<cplx<T>*>(sl_smem);
    cplx<T>* etile = tile + (size_t)dt * lds;
    const int tid = threadIdx.x, nt = blockDim.x;
    const int tpw = dt / RD;  // threads per window; thread dl has directions dl + r·tpw
    const int wg = nt / tpw;
    const int dl = tid % tpw, wi = tid / tpw;
    const int d0 = blockIdx.x * dt;
    const int w0 = blockIdx.y * wg;
    const int wl = w0 + wi;
    const int nwg = min(wg, nwin - w0);
    const int bpg = (nb + gridDim.z - 1) / gridDim.z;
    const int b0 = blockIdx.z * bpg, b1 = min(nb, b0 + bpg);
    const int ndt = min(dt, D - d0);
    const bool mine = dl < ndt && wl < nwin;  // its first direction exists
    const T eps = sl_eps<T>::v();
    T acc[RD];
#pragma unroll
    for (int r = 0; r < RD; ++r) acc[r] = (T)0;
    for (int b = b0; b < b1; ++b) {
        __syncthreads();
        const cplx<T>* src = St + ((size_t)b * D + d0) * M;
        for (int idx = tid; idx < ndt * M; idx += nt) {
            const int r = idx / M, i = idx - r * M;
            tile[r * lds + i] = src[idx];
        }
        if (e_smem) {
            const int per = ne * M;
            for (int idx = tid; idx < nwg * per; idx += nt) {
                const int k = idx / per, j = idx - k * per;
                etile[idx] = E[((size_t)(w0 + k) * nb + b) * per + j];
            }
        }
        __syncthreads();
        if (!mine) continue;
        const T g = kind ? weights[b] : gain[(size_t)wl * nb + b];
        if (g == (T)0) continue;
        const cplx<T>* e = e_smem ? etile + (size_t)wi * ne * M : E + ((size_t)wl * nb + b) * ne * M;
        T tot[RD];
        // Rows past ndt hold stale (on the first bin uninitialised) values; their sums are
        // computed and never used.
        if (RD > 1 && !kind && squared) proj_sum_rd<T, RD>(tile + dl * lds, tpw * lds, e, M, ns, tot);
#pragma unroll
        for (int r = 0; r < RD; ++r) {
            if (dl + r * tpw >= ndt) continue;
            const int d = d0 + dl + r * tpw;
            const cplx<T>* a = tile + (dl + r * tpw) * lds;
            T num, den;
            if (kind) {
                num = sl_max(quad_form(a, e, M) / (T)(M * M), (T)0);  // ≥ 0, as srp.rs
                den = (T)1;
            } else {
                const T nd = n2den[(size_t)b * D + d];
                num = n2num[(size_t)b * D + d];
                if (squared) {
                    den = nd - (RD > 1 ? tot[r] : proj_sum<T, true>(a, e, M, 0, ns));
                    if (den < tau * nd && E64 != nullptr) {
                        den = (T)complement64(a, E64 + ((size_t)wl * nb + b) * ns * M, M, ns);
                    } else {
                        // Without double vectors (the f32 Jacobi of an f32 plan): the
                        // residual in T by two Gram–Schmidt passes, floored at ε_T.
                        if (den < tau * nd) den = residual_norm2(a, e, M, ns);
                        den = sl_max(den, eps * nd);
                    }
                } else {
                    den = proj_sum<T, false>(a, e, M, ns, M);
                    den = sl_max(den, eps * sl_sqrt(nd));
                }
            }
            if (!(den > (T)0)) continue;
            if (pass == 1) {
                const T p = num / den;
                if (p > (T)0) atomic_max_pos(binmax + (size_t)wl * nb + b, p);
            } else if (pass == 2) {
                const T bm = binmax[(size_t)wl * nb + b];
                acc[r] += bm > (T)0 ? weights[b] * ((num / den) / bm) : g * num / den;
            } else {
                acc[r] += g * num / den;
            }
        }
    }
    if (mine && pass != 1) {
#pragma unroll
        for (int r = 0; r < RD; ++r)
            if (dl + r * tpw < ndt) Ppart[((size_t)blockIdx.z * nwin + wl) * D + d0 + dl + r * tpw] = acc[r];
    }
}

// spectrum4_f32 is bounded to 256 threads (its default block: 16 windows × 16 threads)
// and SL_SPEC4_MINB blocks per SM: three blocks (24 warps) hide the loads of the vectors
// better than two blocks at 128 registers, at the cost of a few spilled registers outside
// the inner loop (H100, 2026-11-27: 0.094 → 0.086 ms per localization at Ns = 30).
#ifndef SL_SPEC4_MINB
#define SL_SPEC4_MINB 3
#endif
#define SL_SPEC4_BOUNDS __launch_bounds__(256, SL_SPEC4_MINB)
#define SL_SPECTRUM_KERNEL(NAME, T, RD, BOUNDS)                                                                 \
    extern "C" __global__ void BOUNDS NAME(const cplx<T>* St, const T* n2den, const T* n2num, const cplx<T>* E,             \
                                    const cplx<double>* E64, int ne, const T* gain, int M, int nb, int D, int ns,      \
                                    int squared, int nwin, T tau, int dt, int e_smem, int kind, int pass,             \
                                    const T* weights, T* binmax, T* Ppart) {                                          \
        spectrum_impl<T, RD>(St, n2den, n2num, E, E64, ne, gain, M, nb, D, ns, squared, nwin, tau, dt, e_smem,   \
                                  kind, pass, weights, binmax, Ppart);                                                \
    }

#ifndef SL_NO_F32
SL_SPECTRUM_KERNEL(spectrum_f32, float, 1, )
SL_SPECTRUM_KERNEL(spectrum4_f32, float, 4, SL_SPEC4_BOUNDS)
#endif
#ifndef SL_NO_F64
SL_SPECTRUM_KERNEL(spectrum_f64, double, 1, )
SL_SPECTRUM_KERNEL(spectrum4_f64, double, 4, )
#endif
