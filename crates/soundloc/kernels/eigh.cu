// Stage 3, signal-subspace path — the top Ns eigenvectors of one Hermitian M×M matrix
// per block, by Householder tridiagonalisation, in double precision whatever T is.
//
//   H = R                       mode 0  (SEVD)
//   H = W R Wᴴ                  mode 1  (textbook GEVD, W = L⁻¹)
//   H = W R W                   mode 2  (GEVD-HARK, W = K^{-1/2})
//   H = (W R)(W R)ᴴ             mode 3  (GSVD: the left singular vectors of A = K⁻¹R are
//                                        the eigenvectors of A Aᴴ, σ = √λ)
//   H = Q T Qᴴ,  Q = H_0 H_1 ⋯ H_{n−2},  H_k = I − τ_k v_k v_kᴴ  (LAPACK's zhetd2, lower),
//   λ_0 ≥ … ≥ λ_{Ns−1} of the real symmetric tridiagonal T by multisection of Sturm
//   counts (32 points per step, one warp per value), z_r by inverse iteration with
//   partial pivoting (LAPACK's dlagtf/dstein idea; the Ns vectors are then
//   orthonormalised, which also separates clustered values), e_r = Q z_r.
//
// This is all the squared MUSIC denominator needs (the noise projector is I − E_s E_sᴴ,
// spectrum.cu). Arithmetic: (16/3)·M³ real flops for the reduction and at most 2·8·M³ for
// forming H, against ~10 sweeps × 8·M³ for the one-sided Jacobi of decompose.cu, which
// stays for the unsquared denominator (every noise vector) and for M > 64. Forming H in
// double keeps A Aᴴ's squared condition number harmless: the rounding of H is 1e-16·‖H‖,
// below the f32 rounding of the inputs it is formed from.
//
// Threads: EH_THREADS (256 or 512) = EH_TY × 16; products use 4 (or 2) rows × 4 columns of
// registers per thread, so M ≤ 64. Shared memory (dynamic, see `eigh_smem` on the host):
// A (M × lda complex doubles, lda = M | 1: odd, so column reads are conflict-free), p and v
// (M each), τ (M), d, e, e² (M each), λ (Ns), Z (Ns × M), inverse-iteration scratch
// (EH_VEC × 5M), one int.
//
// Outputs as decompose.cu: E [blk][Ns][M] (rank order), gain[mat] = w_b·g,
// bw[mat] = g (g = √val with eigw, else 1; val = λ_0, or σ_0 = √λ_0 for GSVD), info[mat]
// = bisection steps of λ_0 (diagnostics).
#include "common.cuh"

#ifndef EH_THREADS
#define EH_THREADS 256
#endif
#define EH_MAXN 64
#define EH_TY (EH_THREADS / 16)
#define EH_RT (EH_MAXN / EH_TY)    // rows per thread in the products
#define EH_PARTS (EH_THREADS / 64)  // threads per row in the matrix-vector product
#define EH_VEC 8                    // eigenvectors of T solved at once (lanes of warp 0)

typedef cplx<double> zd;

template <typename T>
__device__ __forceinline__ zd to_zd(cplx<T> a) {
    return cx<double>((double)a.re, (double)a.im);
}

__device__ __forceinline__ double warp_sum_d(double v) { return group_sum<32>(v); }

// Number of eigenvalues of T (diagonal d, squared off-diagonal e2) below x (Sturm count,
// LDLᵀ form with LAPACK's pivmin guard).
__device__ int sturm_count(const double* d, const double* e2, int n, double x, double pivmin) {
    double q = d[0] - x;
    if (fabs(q) < pivmin) q = -pivmin;
    int cnt = q < 0.0 ? 1 : 0;
    for (int i = 1; i < n; ++i) {
        q = d[i] - x - e2[i - 1] / q;
        if (fabs(q) < pivmin) q = -pivmin;
        cnt += q < 0.0 ? 1 : 0;
    }
    return cnt;
}

// C = X · Y for the register tile of this thread (rows ty + EH_TY·a, columns tx + 16·b).
// xat(i, k) and yat(k, j) read the operands; C goes to acc.
template <typename XA, typename YA>
__device__ __forceinline__ void tile_product(int n, XA xat, YA yat, zd (&acc)[EH_RT][4]) {
    const int tx = threadIdx.x & 15, ty = threadIdx.x >> 4;
#pragma unroll
    for (int a = 0; a < EH_RT; ++a)
#pragma unroll
        for (int b = 0; b < 4; ++b) acc[a][b] = czero<double>();
    for (int k = 0; k < n; ++k) {
        zd x[EH_RT], y[4];
#pragma unroll
        for (int a = 0; a < EH_RT; ++a) {
            const int i = ty + EH_TY * a;
            x[a] = i < n ? xat(i, k) : czero<double>();
        }
#pragma unroll
        for (int b = 0; b < 4; ++b) {
            const int j = tx + 16 * b;
            y[b] = j < n ? yat(k, j) : czero<double>();
        }
#pragma unroll
        for (int a = 0; a < EH_RT; ++a)
#pragma unroll
            for (int b = 0; b < 4; ++b) cmac(acc[a][b], x[a], y[b]);
    }
}

// Store the tile into A (after a barrier that ends every read of A).
__device__ __forceinline__ void tile_store(zd* A, int lda, int n, const zd (&acc)[EH_RT][4]) {
    const int tx = threadIdx.x & 15, ty = threadIdx.x >> 4;
#pragma unroll
    for (int a = 0; a < EH_RT; ++a)
#pragma unroll
        for (int b = 0; b < 4; ++b) {
            const int i = ty + EH_TY * a, j = tx + 16 * b;
            if (i < n && j < n) A[(size_t)j * lda + i] = acc[a][b];
        }
}

template <typename T>
__device__ void eigh_impl(const cplx<T>* __restrict__ R, const cplx<T>* __restrict__ Wcm,
                          const cplx<T>* __restrict__ Wrm, int M, int nb, int mode, int ns, int eigw,
                          const T* __restrict__ weights, int mat0, cplx<T>* __restrict__ E, T* __restrict__ gain,
                          float* __restrict__ bw, int* __restrict__ info) {
    SL_DYN_SMEM(sm);
    const int n = M, lda = M | 1;
    const int tid = threadIdx.x, nt = blockDim.x;
    const int lane = tid & 31, warp = tid >> 5, nwarps = nt >> 5;
    const int mat = mat0 + blockIdx.x;
    const int b = mat % nb;
    zd* A = reinterpret_cast<zd*>(sm);
    zd* pv = A + (size_t)n * lda;
    zd* vv = pv + n;
    zd* tau = vv + n;
    double* dd = reinterpret_cast<double*>(tau + n);
    double* ee = dd + n;  // off-diagonal β_k (real, signed)
    double* e2 = ee + n;  // β_k²
    double* lam = e2 + n;
    double* zs = lam + ns;                    // Ns × n
    double* scr = zs + (size_t)ns * n;         // EH_VEC × 5n
    int* steps = reinterpret_cast<int*>(scr + (size_t)EH_VEC * 5 * n);
    const cplx<T>* Rm = R + (size_t)blockIdx.x * M * M;    // column-major, R_ik = Rm[k*M + i]
    const cplx<T>* Wc = Wcm + (size_t)b * M * M;           // W_ik = Wc[k*M + i]
    const cplx<T>* Wr = Wrm + (size_t)b * M * M;           // W_kj = Wr[k*M + j]

    // ---- H in A ----
    for (int idx = tid; idx < n * n; idx += nt) {
        const int j = idx / n, i = idx - j * n;
        A[(size_t)j * lda + i] = to_zd(Rm[idx]);
    }
    __syncthreads();
    if (mode != 0) {
        zd acc[EH_RT][4];
        // P = W R: column j of P needs only column j of R, so it is written in place.
        tile_product(
            n, [&](int i, int k) { return to_zd(Wc[(size_t)k * M + i]); },
            [&](int k, int j) { return A[(size_t)j * lda + k]; }, acc);
        __syncthreads();
        tile_store(A, lda, n, acc);
        __syncthreads();
        if (mode == 1) {  // H = P Wᴴ: H_ij = Σ_k P_ik conj(W_jk)
            tile_product(
                n, [&](int i, int k) { return A[(size_t)k * lda + i]; },
                [&](int k, int j) { return cconj(to_zd(Wc[(size_t)k * M + j])); }, acc);
        } else if (mode == 2) {  // H = P W
            tile_product(
                n, [&](int i, int k) { return A[(size_t)k * lda + i]; },
                [&](int k, int j) { return to_zd(Wr[(size_t)k * M + j]); }, acc);
        } else {  // H = P Pᴴ
            tile_product(
                n, [&](int i, int k) { return A[(size_t)k * lda + i]; },
                [&](int k, int j) { return cconj(A[(size_t)k * lda + j]); }, acc);
        }
        __syncthreads();
        tile_store(A, lda, n, acc);
        __syncthreads();
    }
    // Exact Hermitian symmetry (the products round differently above and below).
    for (int idx = tid; idx < n * n; idx += nt) {
        const int j = idx / n, i = idx - j * n;
        if (i > j) {
            const zd a = A[(size_t)j * lda + i], c = A[(size_t)i * lda + j];
            const zd h = cx<double>(0.5 * (a.re + c.re), 0.5 * (a.im - c.im));
            A[(size_t)j * lda + i] = h;
            A[(size_t)i * lda + j] = cconj(h);
        } else if (i == j) {
            A[(size_t)j * lda + i].im = 0.0;
        }
    }
    __syncthreads();

    // ---- Householder reduction to tridiagonal form (lower) ----
    for (int k = 0; k < n - 1; ++k) {
        const int m = n - k - 1;  // length of x = A(k+1 : n, k)
        const int r0 = k + 1;
        if (warp == 0) {
            // Reflector (LAPACK zlarfg): H_kᴴ x = β e_1, β real, v(0) = 1.
            const zd alpha = A[(size_t)k * lda + r0];
            double s = 0.0;
            for (int i = r0 + 1 + lane; i < n; i += 32) s += cnorm2(A[(size_t)k * lda + i]);
            const double xn2 = warp_sum_d(s);
            if (xn2 == 0.0 && alpha.im == 0.0) {
                if (lane == 0) {
                    tau[k] = czero<double>();
                    ee[k] = alpha.re;
                }
                for (int i = lane; i < m; i += 32) vv[i] = cx<double>(i == 0 ? 1.0 : 0.0, 0.0);
            } else {
                const double nrm = sqrt(alpha.re * alpha.re + alpha.im * alpha.im + xn2);
                const double beta = alpha.re >= 0.0 ? -nrm : nrm;
                // scale = 1 / (α − β)
                const double dr = alpha.re - beta, di = alpha.im;
                const double den = dr * dr + di * di;
                const zd sc = cx<double>(dr / den, -di / den);
                if (lane == 0) {
                    tau[k] = cx<double>((beta - alpha.re) / beta, -alpha.im / beta);
                    ee[k] = beta;
                    vv[0] = cx<double>(1.0, 0.0);
                }
                for (int i = r0 + 1 + lane; i < n; i += 32) {
                    const zd x = A[(size_t)k * lda + i];
                    const zd v = cx<double>(x.re * sc.re - x.im * sc.im, x.re * sc.im + x.im * sc.re);
                    A[(size_t)k * lda + i] = v;  // kept for the back-transformation
                    vv[i - r0] = v;
                }
            }
        }
        __syncthreads();
        const zd tk = tau[k];
        if (tk.re == 0.0 && tk.im == 0.0) continue;  // uniform: H_k = I
        // p = τ A22 v (A22 = A(k+1:n, k+1:n)); EH_PARTS consecutive lanes share a row.
        {
            const int r = tid / EH_PARTS, part = tid - r * EH_PARTS;
            zd s = czero<double>();
            if (r < m)
                for (int c = part; c < m; c += EH_PARTS) {
#ifndef EH_FULL
                    // only the lower triangle is current: h_rc = conj(h_cr) above it
                    const zd h = c <= r ? A[(size_t)(r0 + c) * lda + r0 + r] : cconj(A[(size_t)(r0 + r) * lda + r0 + c]);
#else
                    const zd h = A[(size_t)(r0 + c) * lda + r0 + r];
#endif
                    cmac(s, h, vv[c]);
                }
            s.re = group_sum<EH_PARTS>(s.re);
            s.im = group_sum<EH_PARTS>(s.im);
            if (r < m && part == 0) pv[r] = cx<double>(tk.re * s.re - tk.im * s.im, tk.re * s.im + tk.im * s.re);
        }
        __syncthreads();
        // w = p − γ v with γ = ½ τ̄ (vᴴ p) (every warp forms γ itself: no barrier);
        // A22 ← A22 − v wᴴ − w vᴴ.
        zd g;
        {
            zd s = czero<double>();
            for (int c = lane; c < m; c += 32) cmacc(s, vv[c], pv[c]);
            s.re = warp_sum_d(s.re);
            s.im = warp_sum_d(s.im);
            // ½ conj(τ) s
            g = cx<double>(0.5 * (tk.re * s.re + tk.im * s.im), 0.5 * (tk.re * s.im - tk.im * s.re));
        }
#ifndef EH_FULL
        // Lower triangle only, packed from the bottom-right corner: entry idx is (row, col) =
        // (n−1−r', n−1−c') with c' = ⌊(√(8 idx + 1) − 1)/2⌋, r' = idx − c'(c'+1)/2 ≤ c', so
        // the first m(m+1)/2 entries are exactly A22's lower triangle.
        for (int idx = tid, tot = m * (m + 1) / 2; idx < tot; idx += nt) {
            int cq = (int)((sqrtf(8.0f * (float)idx + 1.0f) - 1.0f) * 0.5f);
            if ((cq + 1) * (cq + 2) / 2 <= idx) ++cq;
            if (cq * (cq + 1) / 2 > idx) --cq;
            const int r = m - 1 - (idx - cq * (cq + 1) / 2), c = m - 1 - cq;
            const zd vr = vv[r], pr = pv[r], vc = vv[c], pc = pv[c];
            const zd wr = cx<double>(pr.re - (g.re * vr.re - g.im * vr.im), pr.im - (g.re * vr.im + g.im * vr.re));
            const zd wc = cx<double>(pc.re - (g.re * vc.re - g.im * vc.im), pc.im - (g.re * vc.im + g.im * vc.re));
            zd a = A[(size_t)(r0 + c) * lda + r0 + r];
            a.re -= vr.re * wc.re + vr.im * wc.im + wr.re * vc.re + wr.im * vc.im;
            a.im -= vr.im * wc.re - vr.re * wc.im + wr.im * vc.re - wr.re * vc.im;
            A[(size_t)(r0 + c) * lda + r0 + r] = a;
        }
#else
        {
            const int r = tid & 63;
            if (r < m) {
                const zd vr = vv[r], pr = pv[r];
                const zd wr = cx<double>(pr.re - (g.re * vr.re - g.im * vr.im), pr.im - (g.re * vr.im + g.im * vr.re));
                for (int c = tid >> 6; c < m; c += nt >> 6) {
                    const zd vc = vv[c], pc = pv[c];
                    const zd wc =
                        cx<double>(pc.re - (g.re * vc.re - g.im * vc.im), pc.im - (g.re * vc.im + g.im * vc.re));
                    zd a = A[(size_t)(r0 + c) * lda + r0 + r];
                    // a −= v_r conj(w_c) + w_r conj(v_c)
                    a.re -= vr.re * wc.re + vr.im * wc.im + wr.re * vc.re + wr.im * vc.im;
                    a.im -= vr.im * wc.re - vr.re * wc.im + wr.im * vc.re - wr.re * vc.im;
                    A[(size_t)(r0 + c) * lda + r0 + r] = a;
                }
            }
        }
#endif
        __syncthreads();
    }
    for (int i = tid; i < n; i += nt) dd[i] = A[(size_t)i * lda + i].re;
    __syncthreads();

    // ---- the top Ns eigenvalues of T (one warp each, 32-point multisection) ----
    // Gershgorin bounds, widened; pivmin as LAPACK (safe minimum × max(1, max e²)).
    double glo = 1e308, ghi = -1e308, emax2 = 0.0;
    for (int i = lane; i < n; i += 32) {
        const double el = i > 0 ? fabs(ee[i - 1]) : 0.0, er = i < n - 1 ? fabs(ee[i]) : 0.0;
        glo = fmin(glo, dd[i] - el - er);
        ghi = fmax(ghi, dd[i] + el + er);
        if (i < n - 1) emax2 = fmax(emax2, ee[i] * ee[i]);
    }
#pragma unroll
    for (int off = 1; off < 32; off <<= 1) {
        glo = fmin(glo, __shfl_xor_sync(0xffffffffu, glo, off));
        ghi = fmax(ghi, __shfl_xor_sync(0xffffffffu, ghi, off));
        emax2 = fmax(emax2, __shfl_xor_sync(0xffffffffu, emax2, off));
    }
    const double bnorm = fmax(fabs(glo), fabs(ghi));
    const double eps = 2.220446049250313e-16;
    const double pivmin = 2.2250738585072014e-308 * fmax(1.0, emax2);
    glo -= 2.0 * eps * bnorm * n + 2.0 * pivmin;
    ghi += 2.0 * eps * bnorm * n + 2.0 * pivmin;
    for (int i = tid; i < n - 1; i += nt) e2[i] = ee[i] * ee[i];
    __syncthreads();
    for (int r = warp; r < ns; r += nwarps) {
        const int want = n - 1 - r;  // ascending index of λ_r
        double lo = glo, hi = ghi;
        int it = 0;
        while (hi - lo > 4.0 * eps * bnorm + 4.0 * pivmin && it < 64) {
            const double x = lo + (hi - lo) * (double)(lane + 1) / 33.0;
            const int cnt = sturm_count(dd, e2, n, x, pivmin);
            // first lane whose point has more than `want` values below it
            const unsigned bal = __ballot_sync(0xffffffffu, cnt > want);
            const int first = bal ? __ffs((int)bal) - 1 : 32;
            const double nlo = first == 0 ? lo : lo + (hi - lo) * (double)first / 33.0;
            const double nhi = first == 32 ? hi : lo + (hi - lo) * (double)(first + 1) / 33.0;
            lo = nlo;
            hi = fmax(nhi, nlo);
            ++it;
        }
        if (lane == 0) {
            lam[r] = 0.5 * (lo + hi);
            if (r == 0) steps[0] = it;
        }
    }
    __syncthreads();

    // ---- eigenvectors of T: inverse iteration, EH_VEC at a time on warp 0 ----
    if (warp == 0) {
        for (int r0v = 0; r0v < ns; r0v += EH_VEC) {
            const int r = r0v + lane;
            if (lane < EH_VEC && r < ns) {
                double* u0 = scr + (size_t)lane * 5 * n;  // U diagonal
                double* u1 = u0 + n;                       // U first superdiagonal
                double* u2 = u1 + n;                       // U second superdiagonal
                double* ml = u2 + n;                       // multipliers (negative: a swap)
                double* y = ml + n;
                double* z = zs + (size_t)r * n;
                const double tiny = fmax(eps * bnorm, pivmin);
                if (bnorm == 0.0) {
                    for (int i = 0; i < n; ++i) z[i] = i == r ? 1.0 : 0.0;
                } else {
                    const double lm = lam[r];
                    // P L U = T − λ I with partial pivoting; row k's pending entries (p0, p1).
                    double p0 = dd[0] - lm, p1 = n > 1 ? ee[0] : 0.0;
                    for (int kk = 0; kk < n - 1; ++kk) {
                        const double sub = ee[kk];                         // T(k+1, k)
                        const double dn = dd[kk + 1] - lm;                 // T(k+1, k+1)
                        const double sup = kk + 1 < n - 1 ? ee[kk + 1] : 0.0;  // T(k+1, k+2)
                        if (fabs(p0) >= fabs(sub)) {
                            const double piv = fabs(p0) < tiny ? (p0 < 0.0 ? -tiny : tiny) : p0;
                            const double mu = sub / piv;
                            u0[kk] = piv;
                            u1[kk] = p1;
                            u2[kk] = 0.0;
                            ml[kk] = mu;
                            y[kk] = 0.0;  // no swap
                            p0 = dn - mu * p1;
                            p1 = sup;
                        } else {
                            const double mu = p0 / sub;
                            u0[kk] = sub;
                            u1[kk] = dn;
                            u2[kk] = sup;
                            ml[kk] = mu;
                            y[kk] = 1.0;  // swap
                            p0 = p1 - mu * dn;
                            p1 = -mu * sup;
                        }
                    }
                    u0[n - 1] = fabs(p0) < tiny ? (p0 < 0.0 ? -tiny : tiny) : p0;
                    // y holds the pivot flags (1: rows swapped); z the right-hand side.
                    for (int i = 0; i < n; ++i) {
                        // a fixed, non-special start vector (dstein uses random numbers)
                        const unsigned h = (unsigned)(i * 2654435761u) ^ (unsigned)(r * 40503u + 12345u);
                        z[i] = 0.5 + (double)(h % 1024u) / 1024.0;
                    }
                    for (int iter = 0; iter < 3; ++iter) {
                        // forward: the row operations of the factorisation
                        for (int kk = 0; kk < n - 1; ++kk) {
                            if (y[kk] != 0.0) {
                                const double t = z[kk];
                                z[kk] = z[kk + 1];
                                z[kk + 1] = t - ml[kk] * z[kk + 1];
                            } else {
                                z[kk + 1] -= ml[kk] * z[kk];
                            }
                        }
                        // backward: U z = rhs
                        z[n - 1] /= u0[n - 1];
                        if (n > 1) z[n - 2] = (z[n - 2] - u1[n - 2] * z[n - 1]) / u0[n - 2];
                        for (int kk = n - 3; kk >= 0; --kk)
                            z[kk] = (z[kk] - u1[kk] * z[kk + 1] - u2[kk] * z[kk + 2]) / u0[kk];
                        double mx = 0.0;
                        for (int i = 0; i < n; ++i) mx = fmax(mx, fabs(z[i]));
                        const double inv = mx > 0.0 ? 1.0 / mx : 1.0;
                        for (int i = 0; i < n; ++i) z[i] *= inv;
                    }
                }
            }
            __syncwarp();
        }
        // Orthonormalise Z (modified Gram–Schmidt, twice): separates clustered values.
        for (int r = 0; r < ns; ++r) {
            double* z = zs + (size_t)r * n;
            for (int pass = 0; pass < 2; ++pass) {
                for (int q = 0; q < r; ++q) {
                    const double* zq = zs + (size_t)q * n;
                    double s = 0.0;
                    for (int i = lane; i < n; i += 32) s += zq[i] * z[i];
                    s = warp_sum_d(s);
                    __syncwarp();
                    for (int i = lane; i < n; i += 32) z[i] -= s * zq[i];
                    __syncwarp();
                }
            }
            double s = 0.0;
            for (int i = lane; i < n; i += 32) s += z[i] * z[i];
            s = warp_sum_d(s);
            const double inv = s > 0.0 ? 1.0 / sqrt(s) : 0.0;
            __syncwarp();
            for (int i = lane; i < n; i += 32) z[i] *= inv;
            __syncwarp();
        }
    }
    __syncthreads();

    // ---- e_r = Q z_r = H_0 (H_1 (⋯ H_{n−2} z_r)) (one warp per vector), rank order ----
    for (int r = warp; r < ns; r += nwarps) {
        const double* z = zs + (size_t)r * n;
        zd u[2];
#pragma unroll
        for (int h = 0; h < 2; ++h) {
            const int i = lane + 32 * h;
            u[h] = cx<double>(i < n ? z[i] : 0.0, 0.0);
        }
        for (int k = n - 2; k >= 0; --k) {
            const zd tk = tau[k];
            if (tk.re == 0.0 && tk.im == 0.0) continue;
            zd v[2];
            zd s = czero<double>();
#pragma unroll
            for (int h = 0; h < 2; ++h) {
                const int i = lane + 32 * h;
                v[h] = i == k + 1 ? cx<double>(1.0, 0.0) : (i > k + 1 && i < n ? A[(size_t)k * lda + i] : czero<double>());
                cmacc(s, v[h], u[h]);
            }
            s.re = warp_sum_d(s.re);
            s.im = warp_sum_d(s.im);
            const zd f = cx<double>(tk.re * s.re - tk.im * s.im, tk.re * s.im + tk.im * s.re);  // τ vᴴu
#pragma unroll
            for (int h = 0; h < 2; ++h) {
                u[h].re -= v[h].re * f.re - v[h].im * f.im;
                u[h].im -= v[h].re * f.im + v[h].im * f.re;
            }
        }
        cplx<T>* dst = E + ((size_t)blockIdx.x * ns + r) * M;
#pragma unroll
        for (int h = 0; h < 2; ++h) {
            const int i = lane + 32 * h;
            if (i < n) dst[i] = cx<T>((T)u[h].re, (T)u[h].im);
        }
    }
    if (tid == 0) {
        // λ_0 of H: the largest value itself (Hermitian cases) or σ_0² (GSVD).
        const double l0 = fmax(lam[0], 0.0);
        const double val = mode == 3 ? sqrt(l0) : l0;
        const double g = eigw ? sqrt(val) : 1.0;
        gain[mat] = weights[b] * (T)g;
        bw[mat] = (float)g;
        info[mat] = steps[0];
    }
}

#define SL_EIGH(NAME, T)                                                                                    \
    extern "C" __global__ void __launch_bounds__(EH_THREADS, EH_MINB)                                      \
        NAME(const cplx<T>* R, const cplx<T>* Wcm, const cplx<T>* Wrm, int M, int nb, int mode, int ns,      \
             int eigw, const T* weights, int mat0, cplx<T>* E, T* gain, float* bw, int* info) {               \
        eigh_impl<T>(R, Wcm, Wrm, M, nb, mode, ns, eigw, weights, mat0, E, gain, bw, info);                 \
    }

#ifndef EH_MINB
#define EH_MINB (EH_THREADS <= 256 ? 2 : 1)
#endif
#ifndef SL_NO_F32
SL_EIGH(eigh_f32, float)
#endif
#ifndef SL_NO_F64
SL_EIGH(eigh_f64, double)
#endif
