// Stage 3 — subspace decomposition of one M×M matrix per block: one-sided (Hestenes)
// cyclic Jacobi with the round-robin parallel ordering.
//
// Prologue (per block, all in shared memory or a global scratch slot):
//   G = R                                   (SEVD)
//   G = W R Wᴴ   left=1 right=1             (textbook GEVD, W = L⁻¹)
//   G = W R W    left=1 right=2             (GEVD-HARK, W = K^{-1/2})
//   G = W R      left=1 right=0             (GSVD: A = K⁻¹R, its left singular vectors)
//   G = R Wᴴ     left=0 right=1             (GSVD when all vectors are wanted: Aᴴ)
// then G ← G / ‖G‖_F (σ is scaled back for the eigenvalue weight).
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
// Precision: R and W arrive in double. The rotations run in double for the unsquared
// denominator (every noise vector counts individually, as the CPU's f64 decomposition) and
// for f64 plans; the squared path of an f32 plan (M > 64, or forced: below, eigh.cu serves it in
// double) rotates in f32, as before, for twice the throughput. The vectors are stored in
// P (E): the double copy the spectrum recomputes near peaks from comes from eigh.cu only
// (an f64 plan's E is double; the f32 Jacobi's vectors are f32-accurate).
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

// G[:, j] ← A · G[:, j] for j < ncols (A column-major M × M, A_ik = A[k*M + i]); one warp
// per column, in place (column j only depends on column j).
template <typename T, typename TA>
__device__ void left_mul(cplx<T>* G, int ld, int ncols, const cplx<TA>* __restrict__ A, int M) {
    const int lane = threadIdx.x & 31, warp = threadIdx.x >> 5, nwarps = blockDim.x >> 5;
    for (int j = warp; j < ncols; j += nwarps) {
        cplx<T> acc[SL_R32];
#pragma unroll
        for (int t = 0; t < SL_R32; ++t) acc[t] = czero<T>();
        for (int k = 0; k < M; ++k) {
            const cplx<T> g = G[(size_t)j * ld + k];
#pragma unroll
            for (int t = 0; t < SL_R32; ++t) {
                const int i = lane + 32 * t;
                if (i < M) cmac(acc[t], cto<T>(A[(size_t)k * M + i]), g);
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

// G[i, :] ← G[i, :] Wᴴ (which = 1: conj(W_jk) = conj(Wcm[k*M + j])) or G[i, :] W
// (which = 2: W_kj = Wrm[k*M + j]); one warp per row, in place.
template <typename T, typename TA>
__device__ void right_mul(cplx<T>* G, int ld, const cplx<TA>* __restrict__ Wc, const cplx<TA>* __restrict__ Wr,
                          int M, int which) {
    const int lane = threadIdx.x & 31, warp = threadIdx.x >> 5, nwarps = blockDim.x >> 5;
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
                    if (which == 1)
                        cmac_cb(acc[t], g, cto<T>(Wc[(size_t)k * M + j]));
                    else
                        cmac(acc[t], g, cto<T>(Wr[(size_t)k * M + j]));
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

// Orthonormalise the first ncols columns of G (length M) in place: classical Gram–Schmidt
// applied twice per column. A column whose residual is at rounding level of its own norm
// (linearly dependent frames, silent frames) becomes zero.
template <typename T>
__device__ void cgs2(cplx<T>* G, int ld, int M, int ncols, cplx<T>* coef, T* red) {
    const int tid = threadIdx.x, nt = blockDim.x;
    const int lane = tid & 31, warp = tid >> 5, nwarps = nt >> 5;
    const T eps = sl_eps<T>::v();
    const T drop2 = ((T)M * eps) * ((T)M * eps);
    for (int j = 0; j < ncols; ++j) {
        cplx<T>* g = G + (size_t)j * ld;
        T s0 = (T)0;
        for (int i = tid; i < M; i += nt) s0 += cnorm2(g[i]);
        const T nrm0 = block_sum(s0, red);
        for (int pass = 0; pass < 2 && j > 0; ++pass) {
            for (int k = warp; k < j; k += nwarps) {
                cplx<T> c = czero<T>();
                for (int i = lane; i < M; i += 32) cmacc(c, G[(size_t)k * ld + i], g[i]);  // q_kᴴ g
                c.re = group_sum<32>(c.re);
                c.im = group_sum<32>(c.im);
                if (lane == 0) coef[k] = c;
            }
            __syncthreads();
            for (int i = tid; i < M; i += nt) {
                cplx<T> acc = czero<T>();
                for (int k = 0; k < j; ++k) cmac(acc, G[(size_t)k * ld + i], coef[k]);
                g[i].re -= acc.re;
                g[i].im -= acc.im;
            }
            __syncthreads();
        }
        T s1 = (T)0;
        for (int i = tid; i < M; i += nt) s1 += cnorm2(g[i]);
        const T nrm = block_sum(s1, red);
        const T inv = (nrm > drop2 * nrm0 && nrm > (T)0) ? (T)1 / sl_sqrt(nrm) : (T)0;
        for (int i = tid; i < M; i += nt) g[i] = cscale(g[i], inv);
        __syncthreads();
    }
}

template <typename P, bool SMEM, bool WANT_V>
__device__ void decompose_impl(const cplx<double>* __restrict__ R, const cplx<P>* __restrict__ X,
                               const int* __restrict__ win, const double* __restrict__ scale,
                               const cplx<double>* __restrict__ Wcm, const cplx<double>* __restrict__ Wrm, int M,
                               int nb, int ld, int ncf, int factor, int left, int right, int ns, int vec_all,
                               int max_sweeps, int eigw, int valmode, const P* __restrict__ weights, int mat0,
                               cplx<P>* __restrict__ E, P* __restrict__ gain,
                               float* __restrict__ bw, int* __restrict__ info, cplx<double>* __restrict__ scratch) {
    // The arithmetic: double when every vector counts (unsquared) or the plan is f64; the
    // plan's f32 otherwise (the Jacobi's squared path serves M > 64, where the
    // double-precision tridiagonal eigensolver does not reach: rotating in double there
    // halves the throughput, and --precision f64 gives the double path).
    typedef typename sl_if<WANT_V || sizeof(P) == 8, double, P>::type T;
    SL_DYN_SMEM(sl_smem);
#ifdef SL_NFIX
    // The device build fixes n = M rounded up to even at compile time (-DSL_NFIX).
    constexpr int n = SL_NFIX;
#else
    const int n = M + (M & 1);
#endif
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
        G = reinterpret_cast<cplx<T>*>(scratch) + (size_t)blockIdx.x * (WANT_V ? 2 : 1) * mat_elems;
        small = sl_smem;
    }
    cplx<T>* V = G + mat_elems;
    // Small shared area: 3 vectors of n, σ/norms, reduction scratch, ranks, sweep order.
    cplx<T>* vec = reinterpret_cast<cplx<T>*>(small);
    T* sig = reinterpret_cast<T*>(vec + 3 * n);
    T* red = sig + n;
    int* rank = reinterpret_cast<int*>(red + 32);
    int* perm = rank + n;
    const cplx<double>* Rm = R + (size_t)blockIdx.x * M * M;
    const cplx<double>* Wc = Wcm + (size_t)b * M * M;
    const cplx<double>* Wr = Wrm + (size_t)b * M * M;
    // Columns the Jacobi works on (even), and those that are real (not padding).
    const int nc = factor ? ncf : n;
    const int ncr = factor ? ncf : M;

    // ---- prologue ----
    if (factor) {
        // G = Yᴴ, the window's frames as columns, scaled so that Yᴴ Y = R (this block's R).
        const int w = mat / nb;
        const int start = win[2 * w], len = win[2 * w + 1];
        const T c = (T)1 / sl_sqrt((T)len * (T)scale[blockIdx.x]);
        for (int idx = tid; idx < n * ld; idx += nt) {
            const int j = idx / ld, i = idx - j * ld;
            if (i < M && j < len) {
                const cplx<P> x = X[((size_t)(start + j) * nb + b) * M + i];
                G[idx] = cscale(cx<T>((T)x.re, (T)x.im), c);
            } else {
                G[idx] = czero<T>();
            }
        }
        __syncthreads();
        if (factor == 2) {
            // GSVD: F = A Q = K⁻¹ R Q, Q an orthonormal basis of range(Yᴴ) = range(R);
            // F Fᴴ = A Aᴴ, so F's left singular vectors are A's.
            cgs2(G, ld, M, nc, vec, red);
            left_mul(G, ld, nc, Rm, M);
        }
        if (left) left_mul(G, ld, nc, Wc, M);  // W Yᴴ (GEVD, GEVD-HARK) or K⁻¹ R Q (GSVD)
    } else {
        for (int idx = tid; idx < n * ld; idx += nt) {
            const int j = idx / ld, i = idx - j * ld;
            G[idx] = (i < M && j < M) ? cto<T>(Rm[(size_t)j * M + i]) : czero<T>();
            if (WANT_V) V[idx] = cx<T>((i == j) ? (T)1 : (T)0, (T)0);
        }
        __syncthreads();
        if (left) left_mul(G, ld, M, Wc, M);
        if (right) right_mul(G, ld, Wc, Wr, M, right);
    }
    // Normalise ‖G‖_F to 1 (the vectors do not change; σ is scaled back at the end), so
    // that the thresholds below neither underflow nor overflow for very quiet or loud input.
    T fro = (T)0;
    for (int idx = tid; idx < n * ld; idx += nt) fro += cnorm2(G[idx]);
    fro = block_sum(fro, red);
    const T gscale = sl_sqrt(fro);
    if (fro > (T)0) {
        const T inv = (T)1 / gscale;
        for (int idx = tid; idx < n * ld; idx += nt) G[idx] = cscale(G[idx], inv);
        __syncthreads();
    }

    // ---- Hestenes sweeps ----
    const T eps = sl_eps<T>::v();
    // Skip a pair when |γ| ≤ tol·√(αβ) (tol = √n·ε, LAPACK's choice), or when either
    // column is at rounding level (‖g‖ ≤ n·ε·‖G‖_F = n·ε): such a column is noise that
    // every rotation with a large column re-creates, and rotating it only prolongs the
    // iteration (it changes the large column by less than its rounding). Compared squared.
    const T tol2 = (T)n * eps * eps;
    // With V (unsquared denominator) every noise vector counts individually, so only
    // columns at the floor of the representable range are skipped there.
    const T tiny2 = WANT_V ? (eps * eps) * (eps * eps) : ((T)n * eps) * ((T)n * eps);
    const int lg = tid & (SL_LPP - 1);  // SL_LPP is a power of two
    const int grp = tid / SL_LPP;
    const int ngroups = nt / SL_LPP;
    const int npairs = nc / 2;
    int sweep = 0;
    for (; sweep < max_sweeps; ++sweep) {
        // De Rijk's ordering: each sweep visits the columns sorted by decreasing norm
        // (perm maps the round-robin's logical index to the stored column).
        for (int j0 = 0; j0 < nc; j0 += ngroups) {
            const int j = j0 + grp;
            T s2 = (T)0;
            if (j < nc) {
#pragma unroll
                for (int t = 0; t < SL_RPL; ++t) {
                    const int i = lg + SL_LPP * t;
                    if (i < n) s2 += cnorm2(G[(size_t)j * ld + i]);
                }
            }
            s2 = group_sum<SL_LPP>(s2);
            if (j < nc && lg == 0) sig[j] = s2;
        }
        __syncthreads();
        for (int j = tid; j < nc; j += nt) {
            const T sj = sig[j];
            int rk = 0;
            for (int k = 0; k < nc; ++k) rk += (sig[k] > sj || (sig[k] == sj && k < j)) ? 1 : 0;
            perm[rk] = j;
        }
        __syncthreads();
        int rotated = 0;
        for (int r = 0; r < nc - 1; ++r) {
            for (int k0 = 0; k0 < npairs; k0 += ngroups) {
                const int k = k0 + grp;
                const bool active = k < npairs;
                int p = 0, q = 1;
                if (active) {
                    rr_pair(r, k, nc, p, q);
                    p = perm[p];
                    q = perm[q];
                }
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
                const T g2 = gr * gr + gi * gi;
                if (active && g2 > tol2 * (al * be) && al > tiny2 && be > tiny2) {
                    rotated = 1;
                    // Real rotation on [g_p, e^{-iφ} g_q] (γ = |γ| e^{iφ}) that zeroes the
                    // off-diagonal of the 2×2 Gram matrix [[α, |γ|], [|γ|, β]].
                    const T inv_ag = (T)1 / sl_sqrt(g2);
                    const T zeta = (be - al) * (T)0.5 * inv_ag;
                    const T az = sl_abs(zeta);
                    T tt = (az > (T)1e15) ? (T)0.5 / az : (T)1 / (az + sl_sqrt((T)1 + az * az));
                    if (zeta < (T)0) tt = -tt;
                    const T c = (T)1 / sl_sqrt((T)1 + tt * tt);
                    const T s = tt * c;
                    const T er = gr * inv_ag, ei = -gi * inv_ag;  // e^{-iφ}
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
    for (int j = tid; j < nc; j += nt) {
        T s = (T)0;
        for (int i = 0; i < n; ++i) s += cnorm2(G[(size_t)j * ld + i]);
        sig[j] = sl_sqrt(s);
    }
    __syncthreads();
    for (int j = tid; j < ncr; j += nt) {
        const T sj = sig[j];
        int rk = 0;
        for (int k = 0; k < ncr; ++k) rk += (sig[k] > sj || (sig[k] == sj && k < j)) ? 1 : 0;
        rank[j] = rk;
    }
    __syncthreads();
    const int nout = vec_all ? M : ns;
    cplx<T>* u1 = vec;  // the top vector, for the value below
    for (int j = warp; j < ncr; j += nwarps) {
        const int rk = rank[j];
        if (rk < nout) {
            const size_t off = ((size_t)blockIdx.x * nout + rk) * M;
            const T inv = WANT_V ? (T)1 : (sig[j] > (T)0 ? (T)1 / sig[j] : (T)0);
            for (int i = lane; i < M; i += 32) {
                const cplx<T> v = WANT_V ? V[(size_t)j * ld + i] : cscale(G[(size_t)j * ld + i], inv);
                E[off + i] = cx<P>((P)v.re, (P)v.im);
                if (rk == 0) u1[i] = v;
            }
        }
    }
    __syncthreads();
    // The largest value from the original matrices and the converged top vector u (the
    // rotated column norms carry the rounding of every rotation; these carry O(δ²)):
    //   valmode 0  uᴴ R u                       (SEVD)
    //   valmode 1  vᴴ R v, v = Wᴴu              (GEVD: W R Wᴴ)
    //   valmode 2  vᴴ R w, v = Wᴴu, w = W u     (GEVD-HARK: W R W)
    //   valmode 3  ‖R v‖, v = Wᴴu               (GSVD: σ = ‖Aᴴu‖, A = W R)
    cplx<T>* v1 = vec + n;
    cplx<T>* w1 = vec + 2 * n;
    for (int k = tid; k < M; k += nt) {
        cplx<T> a = czero<T>(), c = czero<T>();
        if (valmode == 0) {
            a = u1[k];
        } else {
            for (int i = 0; i < M; ++i) cmacc(a, cto<T>(Wc[(size_t)k * M + i]), u1[i]);  // Σ_i conj(W_ik) u_i
        }
        if (valmode == 2) {
            for (int j = 0; j < M; ++j) cmac(c, cto<T>(Wr[(size_t)k * M + j]), u1[j]);  // Σ_j W_kj u_j
        } else {
            c = a;
        }
        v1[k] = a;
        w1[k] = c;
    }
    __syncthreads();
    T part = (T)0;
    for (int i = tid; i < M; i += nt) {
        cplx<T> y = czero<T>();
        for (int k = 0; k < M; ++k) cmac(y, cto<T>(Rm[(size_t)k * M + i]), w1[k]);  // (R w)_i
        if (valmode == 3)
            part += cnorm2(y);
        else
            part += v1[i].re * y.re + v1[i].im * y.im;  // Re(conj(v_i) y_i)
    }
    const T tot = block_sum(part, red);
    if (tid == 0) {
        const T val = valmode == 3 ? sl_sqrt(sl_max(tot, (T)0)) : tot;
        const T g = eigw ? sl_sqrt(sl_max(val, (T)0)) : (T)1;
        gain[mat] = weights[b] * (P)g;
        bw[mat] = (float)g;
        info[mat] = sweep + 1;
    }
}

// Threads per block the host launches at most for this variant (n/2 pairs × SL_LPP lanes,
// rounded up to whole warps; must match `layout` in backend/cuda/mod.rs).
#define SL_DEC_WARPS ((SL_MAXN / 2 * SL_LPP + 31) / 32)
#define SL_DEC_THREADS (SL_DEC_WARPS > 32 ? 1024 : SL_DEC_WARPS * 32)

#define SL_DECOMPOSE(NAME, P, SMEM, WANT_V, MINB)                                                                  \
    extern "C" __global__ void __launch_bounds__(SL_DEC_THREADS, MINB)                                               \
        NAME(const cplx<double>* R, const cplx<P>* X, const int* win, const double* scale, const cplx<double>* Wcm,  \
             const cplx<double>* Wrm, int M, int nb, int ld, int ncf, int factor, int left, int right, int ns,         \
             int vec_all, int max_sweeps, int eigw, int valmode, const P* weights, int mat0, cplx<P>* E, P* gain,     \
             float* bw, int* info, cplx<double>* scratch) {                                                         \
        decompose_impl<P, SMEM, WANT_V>(R, X, win, scale, Wcm, Wrm, M, nb, ld, ncf, factor, left, right, ns, vec_all,  \
                                        max_sweeps, eigw, valmode, weights, mat0, E, gain, bw, info, scratch);  \
    }

// f32 rotating in f32 (the squared _n kernels) with 128-thread blocks: at most 128
// registers, four blocks per multiprocessor. The _v kernels rotate in double.
#ifndef SL_F32_MINB
#define SL_F32_MINB (SL_DEC_THREADS <= 128 ? 4 : 1)
#endif
#ifndef SL_NO_F32
SL_DECOMPOSE(decompose_sn_f32, float, true, false, SL_F32_MINB)
SL_DECOMPOSE(decompose_sv_f32, float, true, true, 1)
SL_DECOMPOSE(decompose_gn_f32, float, false, false, SL_F32_MINB)
SL_DECOMPOSE(decompose_gv_f32, float, false, true, 1)
#endif
#ifndef SL_NO_F64
SL_DECOMPOSE(decompose_sn_f64, double, true, false, 1)
SL_DECOMPOSE(decompose_sv_f64, double, true, true, 1)
SL_DECOMPOSE(decompose_gn_f64, double, false, false, 1)
SL_DECOMPOSE(decompose_gv_f64, double, false, true, 1)
#endif
