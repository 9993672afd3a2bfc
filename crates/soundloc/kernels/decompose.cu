// Stage 3 — subspace decomposition of one M×M matrix per block: one-sided (Hestenes)
// cyclic Jacobi with the round-robin parallel ordering.
//
// Prologue (per block, all in shared memory or a global scratch slot):
//   G = R                                   (SEVD)
//   G = W R Wᴴ   left=1 right=1             (textbook GEVD, W = L⁻¹)
//   G = W R W    left=1 right=2             (GEVD-HARK, W = K^{-1/2})
//   G = W R      left=1 right=0             (GSVD: A = K⁻¹R, its left singular vectors)
//   G = R Wᴴ     left=0 right=1             (GSVD when all vectors are wanted: Aᴴ)
// Hestenes rotates pairs of columns of G (and of V = I when WANT_V) until every pair is
// orthogonal to sqrt(n)·ε: G V = U Σ. Without V the normalised columns of G are the left
// singular vectors of G (the eigenvectors of the Hermitian PSD cases; the GSVD's u_m),
// which is all the squared MUSIC denominator needs: the Ns signal vectors (the noise
// projection is I − E_s E_sᴴ, see spectrum.cu). With V (unsquared denominator) V is the
// full orthonormal basis: eigenvectors of a Hermitian G, left singular vectors of A when
// G = Aᴴ. Values σ_j = ‖G v_j‖ (= |λ_j| for Hermitian PSD G), sorted descending.
//
// Threads: groups of SL_LPP consecutive lanes share one column pair; each lane holds
// SL_RPL rows of both columns in registers (rows lane, lane + SL_LPP, ...). A round
// pairs all n columns (n = M rounded up to even, a zero column added when M is odd);
// n − 1 rounds make a sweep; a sweep with no rotation ends the iteration.
//
// Outputs per matrix (index mat = mat0 + blockIdx.x, bin = mat % nb; R, E and the
// scratch slots are indexed by blockIdx.x, i.e. relative to the sub-batch):
//   E     [blk][nout][M]  vectors (row s = vector of rank s), nout = vec_all ? M : ns
//   gain  [mat]           w_b · g (g = √σ_max when eigw, else 1)
//   bw    [mat]           g as f32
//   info  [mat]           sweeps used (diagnostics)
#include "common.cuh"

__device__ __forceinline__ void rr_pair(int r, int k, int n, int& p, int& q) {
    int a, b;
    if (k == 0) {
        a = r;
        b = n - 1;
    } else {
        const int m = n - 1;
        a = (r + k) % m;
        b = (r - k + m) % m;
    }
    p = a < b ? a : b;
    q = a < b ? b : a;
}

template <typename T, bool SMEM, bool WANT_V>
__device__ void decompose_impl(const cplx<T>* __restrict__ R, const cplx<T>* __restrict__ Wcm,
                               const cplx<T>* __restrict__ Wrm, int M, int nb, int ld, int left, int right, int ns,
                               int vec_all, int max_sweeps, int eigw, const T* __restrict__ weights, int mat0,
                               cplx<T>* __restrict__ E, T* __restrict__ gain, float* __restrict__ bw,
                               int* __restrict__ info, cplx<T>* __restrict__ scratch) {
    SL_DYN_SMEM(sl_smem);
    const int n = M + (M & 1);
    const int tid = threadIdx.x, nt = blockDim.x;
    const int lane = tid & 31, warp = tid >> 5, nwarps = nt >> 5;
    const int mat = mat0 + blockIdx.x;
    const int b = mat % nb;
    const size_t mat_elems = (size_t)n * ld;
    cplx<T>* G;
    unsigned char* small;
    if (SMEM) {
        G = reinterpret_cast<cplx<T>*>(sl_smem);
        small = sl_smem + (WANT_V ? 2 : 1) * mat_elems * sizeof(cplx<T>);
    } else {
        G = scratch + (size_t)blockIdx.x * (WANT_V ? 2 : 1) * mat_elems;
        small = sl_smem;
    }
    cplx<T>* V = G + mat_elems;
    T* sig = reinterpret_cast<T*>(small);
    T* red = sig + n;
    int* rank = reinterpret_cast<int*>(red + 32);

    // ---- prologue: G from R (and W) ----
    const cplx<T>* Rm = R + (size_t)blockIdx.x * M * M;
    for (int idx = tid; idx < n * ld; idx += nt) {
        const int j = idx / ld, i = idx - j * ld;
        G[idx] = (i < M && j < M) ? Rm[(size_t)j * M + i] : czero<T>();
        if (WANT_V) V[idx] = cx<T>((i == j) ? (T)1 : (T)0, (T)0);
    }
    __syncthreads();
    if (left) {
        // Column phase: G[:, j] ← W G[:, j]; W_ik = Wcm[k*M + i].
        const cplx<T>* Wc = Wcm + (size_t)b * M * M;
        for (int j = warp; j < M; j += nwarps) {
            cplx<T> acc[SL_R32];
#pragma unroll
            for (int t = 0; t < SL_R32; ++t) acc[t] = czero<T>();
            for (int k = 0; k < M; ++k) {
                const cplx<T> g = G[(size_t)j * ld + k];
#pragma unroll
                for (int t = 0; t < SL_R32; ++t) {
                    const int i = lane + 32 * t;
                    if (i < M) cmac(acc[t], Wc[(size_t)k * M + i], g);
                }
            }
            __syncwarp();
#pragma unroll
            for (int t = 0; t < SL_R32; ++t) {
                const int i = lane + 32 * t;
                if (i < M) G[(size_t)j * ld + i] = acc[t];
            }
            __syncwarp();
        }
        __syncthreads();
    }
    if (right) {
        // Row phase: G[i, :] ← G[i, :] Wᴴ (right = 1: conj(W_jk) = conj(Wcm[k*M + j]))
        //                   or G[i, :] W  (right = 2: W_kj = Wrm[k*M + j]).
        const cplx<T>* Wc = Wcm + (size_t)b * M * M;
        const cplx<T>* Wr = Wrm + (size_t)b * M * M;
        for (int i = warp; i < M; i += nwarps) {
            cplx<T> acc[SL_R32];
#pragma unroll
            for (int t = 0; t < SL_R32; ++t) acc[t] = czero<T>();
            for (int k = 0; k < M; ++k) {
                const cplx<T> g = G[(size_t)k * ld + i];
#pragma unroll
                for (int t = 0; t < SL_R32; ++t) {
                    const int j = lane + 32 * t;
                    if (j < M) {
                        if (right == 1)
                            cmac_cb(acc[t], g, Wc[(size_t)k * M + j]);
                        else
                            cmac(acc[t], g, Wr[(size_t)k * M + j]);
                    }
                }
            }
            __syncwarp();
#pragma unroll
            for (int t = 0; t < SL_R32; ++t) {
                const int j = lane + 32 * t;
                if (j < M) G[(size_t)j * ld + i] = acc[t];
            }
            __syncwarp();
        }
        __syncthreads();
    }
    // ‖G‖_F² for the absolute skip threshold.
    T fro = (T)0;
    for (int idx = tid; idx < n * ld; idx += nt) fro += cnorm2(G[idx]);
    fro = block_sum(fro, red);

    // ---- Hestenes sweeps ----
    const T eps = sl_eps<T>::v();
    const T tol = sl_sqrt((T)n) * eps;
    const T floor_abs = eps * eps * fro;
    const int lg = tid % SL_LPP;
    const int grp = tid / SL_LPP;
    const int ngroups = nt / SL_LPP;
    const int npairs = n / 2;
    int sweep = 0;
    for (; sweep < max_sweeps; ++sweep) {
        int rotated = 0;
        for (int r = 0; r < n - 1; ++r) {
            for (int k0 = 0; k0 < npairs; k0 += ngroups) {
                const int k = k0 + grp;
                const bool active = k < npairs;
                int p = 0, q = 1;
                if (active) rr_pair(r, k, n, p, q);
                cplx<T> gp[SL_RPL], gq[SL_RPL];
                T al = (T)0, be = (T)0, gr = (T)0, gi = (T)0;
#pragma unroll
                for (int t = 0; t < SL_RPL; ++t) {
                    const int i = lg + SL_LPP * t;
                    if (active && i < n) {
                        gp[t] = G[(size_t)p * ld + i];
                        gq[t] = G[(size_t)q * ld + i];
                    } else {
                        gp[t] = czero<T>();
                        gq[t] = czero<T>();
                    }
                    al += cnorm2(gp[t]);
                    be += cnorm2(gq[t]);
                    gr += gp[t].re * gq[t].re + gp[t].im * gq[t].im;
                    gi += gp[t].re * gq[t].im - gp[t].im * gq[t].re;
                }
                al = group_sum<SL_LPP>(al);
                be = group_sum<SL_LPP>(be);
                gr = group_sum<SL_LPP>(gr);
                gi = group_sum<SL_LPP>(gi);
                const T ag = sl_sqrt(gr * gr + gi * gi);
                if (active && ag > tol * sl_sqrt(al * be) && ag > floor_abs) {
                    rotated = 1;
                    // Real rotation on [g_p, e^{-iφ} g_q] (γ = |γ| e^{iφ}) that zeroes the
                    // off-diagonal of the 2×2 Gram matrix [[α, |γ|], [|γ|, β]].
                    const T zeta = (be - al) / ((T)2 * ag);
                    const T az = sl_abs(zeta);
                    T tt = (az > (T)1e15) ? (T)0.5 / az : (T)1 / (az + sl_sqrt((T)1 + az * az));
                    if (zeta < (T)0) tt = -tt;
                    const T c = (T)1 / sl_sqrt((T)1 + tt * tt);
                    const T s = tt * c;
                    const T er = gr / ag, ei = -gi / ag;  // e^{-iφ}
                    const T ser = s * er, sei = s * ei, cer = c * er, cei = c * ei;
#pragma unroll
                    for (int t = 0; t < SL_RPL; ++t) {
                        const int i = lg + SL_LPP * t;
                        if (i < n) {
                            const cplx<T> a = gp[t], bq = gq[t];
                            // p' = c p − s e q ; q' = s p + c e q
                            G[(size_t)p * ld + i] =
                                cx<T>(c * a.re - (ser * bq.re - sei * bq.im), c * a.im - (ser * bq.im + sei * bq.re));
                            G[(size_t)q * ld + i] =
                                cx<T>(s * a.re + (cer * bq.re - cei * bq.im), s * a.im + (cer * bq.im + cei * bq.re));
                        }
                    }
                    if (WANT_V) {
#pragma unroll
                        for (int t = 0; t < SL_RPL; ++t) {
                            const int i = lg + SL_LPP * t;
                            if (i < n) {
                                const cplx<T> a = V[(size_t)p * ld + i], bq = V[(size_t)q * ld + i];
                                V[(size_t)p * ld + i] = cx<T>(c * a.re - (ser * bq.re - sei * bq.im),
                                                              c * a.im - (ser * bq.im + sei * bq.re));
                                V[(size_t)q * ld + i] = cx<T>(s * a.re + (cer * bq.re - cei * bq.im),
                                                              s * a.im + (cer * bq.im + cei * bq.re));
                            }
                        }
                    }
                }
            }
            __syncthreads();
        }
        if (!__syncthreads_or(rotated)) break;
    }

    // ---- epilogue: σ_j, ranks, outputs ----
    for (int j = tid; j < n; j += nt) {
        T s = (T)0;
        for (int i = 0; i < n; ++i) s += cnorm2(G[(size_t)j * ld + i]);
        sig[j] = sl_sqrt(s);
    }
    __syncthreads();
    for (int j = tid; j < M; j += nt) {
        const T sj = sig[j];
        int rk = 0;
        for (int k = 0; k < M; ++k) rk += (sig[k] > sj || (sig[k] == sj && k < j)) ? 1 : 0;
        rank[j] = rk;
    }
    __syncthreads();
    const int nout = vec_all ? M : ns;
    for (int j = warp; j < M; j += nwarps) {
        const int rk = rank[j];
        if (rk < nout) {
            cplx<T>* dst = E + ((size_t)blockIdx.x * nout + rk) * M;
            if (WANT_V) {
                for (int i = lane; i < M; i += 32) dst[i] = V[(size_t)j * ld + i];
            } else {
                const T inv = sig[j] > (T)0 ? (T)1 / sig[j] : (T)0;
                for (int i = lane; i < M; i += 32) dst[i] = cscale(G[(size_t)j * ld + i], inv);
            }
        }
        if (rk == 0 && lane == 0) {
            const T g = eigw ? sl_sqrt(sl_max(sig[j], (T)0)) : (T)1;
            gain[mat] = weights[b] * g;
            bw[mat] = (float)g;
            info[mat] = sweep + 1;
        }
    }
}

#define SL_DECOMPOSE(NAME, T, SMEM, WANT_V)                                                                           \
    extern "C" __global__ void NAME(const cplx<T>* R, const cplx<T>* Wcm, const cplx<T>* Wrm, int M, int nb, int ld,  \
                                    int left, int right, int ns, int vec_all, int max_sweeps, int eigw,              \
                                    const T* weights, int mat0, cplx<T>* E, T* gain, float* bw, int* info,           \
                                    cplx<T>* scratch) {                                                             \
        decompose_impl<T, SMEM, WANT_V>(R, Wcm, Wrm, M, nb, ld, left, right, ns, vec_all, max_sweeps, eigw, weights, \
                                        mat0, E, gain, bw, info, scratch);                                           \
    }

SL_DECOMPOSE(decompose_sn_f32, float, true, false)
SL_DECOMPOSE(decompose_sv_f32, float, true, true)
SL_DECOMPOSE(decompose_gn_f32, float, false, false)
SL_DECOMPOSE(decompose_gv_f32, float, false, true)
SL_DECOMPOSE(decompose_sn_f64, double, true, false)
SL_DECOMPOSE(decompose_sv_f64, double, true, true)
SL_DECOMPOSE(decompose_gn_f64, double, false, false)
SL_DECOMPOSE(decompose_gv_f64, double, false, true)
