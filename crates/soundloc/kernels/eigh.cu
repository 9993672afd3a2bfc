// Stage 3, signal-subspace path — the top Ns eigenvectors of one Hermitian M×M matrix
// per block, by Householder tridiagonalisation, in double precision whatever T is.
//
//   H = R                       mode 0  (SEVD)
//   H = W R Wᴴ                  mode 1  (textbook GEVD, W = L⁻¹)
//   H = W R W                   mode 2  (GEVD-HARK, W = K^{-1/2})
//   H = (W R)(W R)ᴴ             mode 3  (GSVD: the left singular vectors of A = K⁻¹R are
//                                        the eigenvectors of A Aᴴ, σ = √λ)
//   H = Q T Qᴴ,  Q = H_0 H_1 ⋯ H_{n−2},  H_k = I − τ_k v_k v_kᴴ  (LAPACK's zhetd2, lower),
//   T scaled to ‖T‖ ≈ 1; then tridiag.cuh: λ_0 ≥ … ≥ λ_{Ns−1} to EH_BTOL by multisection
//   of Sturm counts (division-free leading-minor recurrence; Ns ≤ warps: the block's warps
//   shared among the values, 32 points per warp and round; more values: P ≤ 16 lanes per
//   value, all values at once); z_r by inverse iteration with partial pivoting (LAPACK's
//   dlagtf/dstein idea, one thread per vector, branch-free; two or three rounds of solving
//   every vector and orthonormalising them in rank order, EH_OB at a time, which separates
//   clustered values); λ_0 from the Rayleigh quotient z_0ᵀ T z_0; here again: e_r = Q z_r
//   (each warp applies the reflectors to up to EH_BT vectors at once).
//
// Two kernels: form_h (modes 1–3, form_h.cuh) writes H to global memory, eigh reads it
// (or R in mode 0) and does the rest; apart, the products' register tiles do not cap the
// eigensolver's occupancy (at most 80 registers).
//
// This is all the squared MUSIC denominator needs (the noise projector is I − E_s E_sᴴ,
// spectrum.cu). Arithmetic: (16/3)·M³ real flops for the reduction and at most 2·8·M³ for
// forming H, against ~10 sweeps × 8·M³ for the one-sided Jacobi of decompose.cu, which
// stays for the unsquared denominator (every noise vector) and for M > 64. Forming H in
// double keeps A Aᴴ's squared condition number harmless: the rounding of H is 1e-16·‖H‖,
// below the f32 rounding of the inputs it is formed from.
//
// Threads: 128 or 256 per block (the two kernels at the end); the products (form_h.cuh)
// take EH_THREADS = 256 = EH_TY × 16, 4 rows × 4 columns of registers per thread, so M ≤ 64.
// Shared memory (dynamic, see `eigh_shape` / `form_h_smem` on the host): A's lower
// triangle packed by columns (M(M+1)/2 complex doubles; column reads are contiguous), τ
// (M complex), a work area of max(8M, Ns·(M|1) + scr_len) doubles — p, v (two buffers) and
// the update's w during the reduction; then Z (Ns rows of stride M|1) and the inverse-iteration scratch
// (3 rows of stride M|1 per vector solved at once, at least one fits; between the solves
// it holds the orthonormalisation's dot products, tridiag.cuh) —, d, e, e² (M each),
// λ (Ns), 1 + 32 ints. After the reduction A holds the reflectors below its subdiagonal.
//
// R and W arrive in double whatever T is (the correlation hands R on unrounded).
// Outputs as decompose.cu: E [blk][Ns][M] (rank order) in T and, when E64 is not null, the
// same vectors in double (the spectrum's near-peak recomputation), gain[mat] = w_b·g,
// bw[mat] = g (g = √val with eigw, else 1; val = λ_0, or σ_0 = √λ_0 for GSVD), info[mat]
// = multisection rounds (diagnostics); when tri is not null, T itself (scaled: diagonal,
// then off-diagonal, 2M doubles per matrix of the sub-batch) for count.cu.
#include "common.cuh"

#define EH_THREADS 256
#define EH_MAXN 64
#define EH_TY (EH_THREADS / 16)
#define EH_RT (EH_MAXN / EH_TY)    // rows per thread in the products
#ifndef EH_BTOL
// Bisection stops at this fraction of ‖T‖ (then inverse iteration). Not 1e-10: values
// near the noise floor are ~1e-4‖T‖ and close together, and shifts that far off left
// the robust default's deepest vectors 1e-4 dB from the CPU's (2026-11-27).
#define EH_BTOL 1e-14
#endif
#ifndef EH_BT
#define EH_BT 2                     // vectors per warp at once in the back-transformation
#endif
#ifndef EH_OB
#define EH_OB 4                     // vectors orthonormalised by one warp at once
#endif
#ifndef EH_UPD
#define EH_UPD 2                    // columns per pass in the reduction's rank-2 update (4: more registers, slower)
#endif

typedef cplx<double> zd;

template <typename T>
__device__ __forceinline__ zd to_zd(cplx<T> a) {
    return cx<double>((double)a.re, (double)a.im);
}

__device__ __forceinline__ double warp_sum_d(double v) { return group_sum<32>(v); }

#include "tridiag.cuh"

// w = p − γ v (one entry of the reduction's w).
__device__ __forceinline__ zd w_of(zd p, zd g, zd v) {
    return cx<double>(p.re - (g.re * v.re - g.im * v.im), p.im - (g.re * v.im + g.im * v.re));
}

// a ← a − v_r conj(w_c) − w_r conj(v_c) (one entry of the Hermitian rank-2 update).
// As fused multiply-adds (four per component instead of a multiply, three fused
// multiply-adds and a subtraction).
__device__ __forceinline__ void rank2(zd& a, zd vr, zd wr, zd vc, zd wc) {
    a.re = fma(-vr.re, wc.re, a.re);
    a.re = fma(-vr.im, wc.im, a.re);
    a.re = fma(-wr.re, vc.re, a.re);
    a.re = fma(-wr.im, vc.im, a.re);
    a.im = fma(-vr.im, wc.re, a.im);
    a.im = fma(vr.re, wc.im, a.im);
    a.im = fma(-wr.im, vc.re, a.im);
    a.im = fma(wr.re, vc.im, a.im);
}

// Column c of the packed lower triangle (column-major, columns of n − c entries):
// entry (r, c), r ≥ c, is A[pcol(n, c) + r].
__device__ __forceinline__ int pcol(int n, int c) { return c * (2 * n - c - 1) / 2; }

// Reflector k (LAPACK zlarfg) from x = A(k+1:n, k), by one warp: H_kᴴ x = β e_1 with β
// real, H_k = I − τ v vᴴ, v(0) = 1; v(1:) is stored in A(k+2:n, k) and all of v in vout.
__device__ void make_reflector(zd* A, int n, int k, zd* tau, double* ee, zd* vout, int lane) {
    const int r0 = k + 1, m = n - r0;
    zd* col = A + pcol(n, k);
    const zd alpha = col[r0];
    double s = 0.0;
    for (int i = r0 + 1 + lane; i < n; i += 32) s += cnorm2(col[i]);
    const double xn2 = warp_sum_d(s);
    if (xn2 == 0.0 && alpha.im == 0.0) {
        if (lane == 0) {
            tau[k] = czero<double>();
            ee[k] = alpha.re;
        }
        for (int i = lane; i < m; i += 32) vout[i] = cx<double>(i == 0 ? 1.0 : 0.0, 0.0);
        return;
    }
    const double nrm = sqrt(alpha.re * alpha.re + alpha.im * alpha.im + xn2);
    const double beta = alpha.re >= 0.0 ? -nrm : nrm;
    // 1 / (α − β) = conj(α − β) / |α − β|²
    const double dr = alpha.re - beta, di = alpha.im;
    const double iden = 1.0 / (dr * dr + di * di);
    const zd sc = cx<double>(dr * iden, -di * iden);
    if (lane == 0) {
        const double ib = 1.0 / beta;
        tau[k] = cx<double>((beta - alpha.re) * ib, -alpha.im * ib);
        ee[k] = beta;
        vout[0] = cx<double>(1.0, 0.0);
    }
    for (int i = r0 + 1 + lane; i < n; i += 32) {
        const zd x = col[i];
        const zd v = cx<double>(x.re * sc.re - x.im * sc.im, x.re * sc.im + x.im * sc.re);
        col[i] = v;  // kept for the back-transformation
        vout[i - r0] = v;
    }
}

#include "form_h.cuh"

// NT threads per block (EH_THREADS, or EH_NARROW for few vectors: see the kernels below);
// scr_len doubles of inverse-iteration scratch (at least 3·(M|1) and Ns; the host's
// `eigh_shape`).
template <typename T, int NT>
__device__ void eigh_impl(const zd* __restrict__ R, const zd* __restrict__ Hg, int M, int nb, int mode, int ns, int eigw,
                          const T* __restrict__ weights, int mat0, int scr_len, cplx<T>* __restrict__ E,
                          zd* __restrict__ E64, T* __restrict__ gain,
                          float* __restrict__ bw, int* __restrict__ info, long long* __restrict__ prof,
                          double* __restrict__ tri) {
    constexpr int PARTS = NT / 64;  // threads per row in the matrix-vector product
    SL_DYN_SMEM(sm);
    const int n = M;
    const int tid = threadIdx.x, nt = NT;
    const int lane = tid & 31, warp = tid >> 5, nwarps = NT >> 5;
    const int mat = mat0 + blockIdx.x;
    const int b = mat % nb;
    // Cycle counts at the phase boundaries (SOUNDLOC_CUDA_PROFILE=1 passes a buffer).
#define EH_PROF(i)                                                          \
    do {                                                                    \
        if (prof != nullptr && tid == 0) prof[(size_t)mat * 16 + (i)] = clock64(); \
    } while (0)
    EH_PROF(0);
    // A: the packed lower triangle (pcol), which after the reduction holds the reflectors
    // below its subdiagonal; τ; then a work area that holds p, v (two buffers) and w
    // during the reduction and the vectors of T (Ns rows of stride us, odd: conflict-free when
    // each thread walks its own row) and the inverse-iteration scratch after it.
    const int us = n | 1;
    const int npk = n * (n + 1) / 2;
    const int wlen = (max(8 * n, ns * us + scr_len) + 1) & ~1;
    zd* A = reinterpret_cast<zd*>(sm);
    zd* tau = A + npk;
    double* W = reinterpret_cast<double*>(tau + n);
    zd* pv = reinterpret_cast<zd*>(W);
    zd* vv = pv + n;  // two buffers of n
    zd* wv = vv + 2 * n;  // w_c = p_c − γ v_c of the update warps' columns
    double* zs = W;                      // Ns × us
    double* scr = zs + (size_t)ns * us;  // vpp × 3 × us: 1/U diagonal, U's two superdiagonals
    double* dd = W + wlen;
    double* ee = dd + n;  // off-diagonal β_k (real, signed)
    double* e2 = ee + n;  // β_k²
    double* lam = e2 + n;
    int* steps = reinterpret_cast<int*>(lam + ns);
    int* bfirst = steps + 1;  // per warp, multisection
    const int vpp = max(1, min(ns, scr_len / (3 * us)));
    // vectors per orthonormalisation step: their dot products with the ones before (≤ ns
    // each) fit the scratch
    const int ob = max(1, min(EH_OB, scr_len / max(ns, 1)));
    const zd* Rm = R + (size_t)blockIdx.x * M * M;    // column-major, R_ik = Rm[k*M + i]

    // ---- H in A: R itself (mode 0) or the product form_h wrote. The reduction reads only
    // the lower triangle, which both hand on exactly Hermitian (one rounding per entry,
    // mirrored); the diagonal is made exactly real as it is loaded. ----
    for (int idx = tid; idx < n * n; idx += nt) {
        const int j = idx / n, i = idx - j * n;
        if (i < j) continue;
        zd h = mode == 0 ? to_zd(Rm[idx]) : Hg[(size_t)blockIdx.x * n * n + idx];
        if (i == j) h.im = 0.0;
        A[pcol(n, j) + i] = h;
    }
    __syncthreads();
    EH_PROF(1);

    // ---- Householder reduction to tridiagonal form (lower triangle only) ----
    // Step k: p = τ A22 v, w = p − ½ τ̄ (vᴴp) v, A22 ← A22 − v wᴴ − w vᴴ (A22 = A(k+1:, k+1:)).
    // Look-ahead: warp 0 updates A22's first column itself and at once forms the next
    // reflector from it, while the other warps update the rest; one barrier fewer per step
    // and the reflector's latency hidden. v is double-buffered for that reason.
    if (warp == 0) make_reflector(A, n, 0, tau, ee, vv, lane);
    __syncthreads();
    // SOUNDLOC_CUDA_PROFILE with -DEH_PROFILE_STEPS (SOUNDLOC_CUDA_NVRTC_OPTS): cycles
    // inside the steps, summed (slots 8–11); off, the compiler drops all of it.
    long long pr_mv = 0, pr_w0 = 0, pr_w1 = 0, pr_bar = 0, pr_t = 0;
#ifdef EH_PROFILE_STEPS
    const bool pr_on = prof != nullptr && (tid == 0 || tid == 32);
#else
    constexpr bool pr_on = false;
#endif
    for (int k = 0; k < n - 1; ++k) {
        if (pr_on) pr_t = clock64();
        const int m = n - k - 1;  // length of x = A(k+1 : n, k)
        const int r0 = k + 1;
        const zd* v = vv + (k & 1) * n;
        zd* vnext = vv + ((k + 1) & 1) * n;
        const zd tk = tau[k];
        if (tk.re == 0.0 && tk.im == 0.0) {  // uniform: H_k = I, A22 unchanged
            if (warp == 0 && k + 1 < n - 1) make_reflector(A, n, k + 1, tau, ee, vnext, lane);
            __syncthreads();
            continue;
        }
        // p = τ A22 v; PARTS consecutive lanes share a row (h_rc = conj(h_cr) above the
        // diagonal: only the lower triangle is current).
        {
            const int r = tid / PARTS, part = tid - r * PARTS;
            zd s0 = czero<double>(), s1 = czero<double>();
            if (r < m) {
                // h(c): one load from either triangle. Four columns per pass with every
                // load issued first (the loads cannot be moved above the accumulation by
                // the compiler otherwise); s0 and s1 take the columns in the same order
                // as two per pass would.
                const int rowcol = pcol(n, r0 + r) + r0;  // A(r0 + c, r0 + r) = A[rowcol + c], c ≥ r
                const auto h = [&](int c) {
                    const bool lo = c <= r;
                    zd x = A[lo ? pcol(n, r0 + c) + r0 + r : rowcol + c];
                    if (!lo) x.im = -x.im;
                    return x;
                };
                int c = part;
                for (; c + 3 * PARTS < m; c += 4 * PARTS) {
                    const zd h0 = h(c), h1 = h(c + PARTS), h2 = h(c + 2 * PARTS), h3 = h(c + 3 * PARTS);
                    const zd v0 = v[c], v1 = v[c + PARTS], v2 = v[c + 2 * PARTS], v3 = v[c + 3 * PARTS];
                    cmac(s0, h0, v0);
                    cmac(s1, h1, v1);
                    cmac(s0, h2, v2);
                    cmac(s1, h3, v3);
                }
                for (; c + PARTS < m; c += 2 * PARTS) {
                    const zd h0 = h(c), h1 = h(c + PARTS);
                    cmac(s0, h0, v[c]);
                    cmac(s1, h1, v[c + PARTS]);
                }
                if (c < m) cmac(s0, h(c), v[c]);
            }
            zd s = cadd(s0, s1);
            s.re = group_sum<PARTS>(s.re);
            s.im = group_sum<PARTS>(s.im);
            if (r < m && part == 0) pv[r] = cx<double>(tk.re * s.re - tk.im * s.im, tk.re * s.im + tk.im * s.re);
        }
        __syncthreads();
        if (pr_on) {
            const long long t = clock64();
            pr_mv += t - pr_t;
            pr_t = t;
        }
        // γ = ½ τ̄ (vᴴ p), formed by every warp itself (no barrier).
        zd g;
        {
            zd s = czero<double>();
            for (int c = lane; c < m; c += 32) cmacc(s, v[c], pv[c]);
            s.re = warp_sum_d(s.re);
            s.im = warp_sum_d(s.im);
            g = cx<double>(0.5 * (tk.re * s.re + tk.im * s.im), 0.5 * (tk.re * s.im - tk.im * s.re));
        }
        if (warp == 0) {
            // A22's first column (rows r ≥ 0), then the next reflector from it.
            const zd v0 = v[0], p0 = pv[0];
            const zd w0 = w_of(p0, g, v0);
            zd* col = A + pcol(n, r0) + r0;
            for (int r = lane; r < m; r += 32) {
                const zd vr = v[r], pr = pv[r];
                const zd wr =
                    w_of(pr, g, vr);
                rank2(col[r], vr, wr, v0, w0);
            }
            __syncwarp();
            if (k + 1 < n - 1) make_reflector(A, n, k + 1, tau, ee, vnext, lane);
        } else {
            // The rest of A22's lower triangle: lane p takes rows p and m−1−p (balanced
            // lengths), warp q = 1, 2, … the columns c ≡ q (mod nwarps − 1), c ≥ 1; the
            // row values stay in registers, the column values are broadcasts.
            const int nq = nwarps - 1;
            // w of this warp's columns, once (not once per row that uses it).
            for (int c = warp + lane * nq; c < m; c += 32 * nq) wv[c] = w_of(pv[c], g, v[c]);
            __syncwarp();
#pragma unroll
            for (int h = 0; h < 2; ++h) {
                const int r = h == 0 ? lane : m - 1 - lane;
                if (h == 0 ? 2 * lane > m - 1 : 2 * lane >= m - 1) continue;
                const zd vr = v[r], pr = pv[r];
                const zd wr =
                    w_of(pr, g, vr);
                // EH_UPD columns per pass, loads first (see the matrix-vector product).
                int c = warp;
                for (; c + (EH_UPD - 1) * nq <= r; c += EH_UPD * nq) {
                    int ix[EH_UPD];
                    zd a[EH_UPD], vc[EH_UPD], wc[EH_UPD];
#pragma unroll
                    for (int j = 0; j < EH_UPD; ++j) {
                        ix[j] = pcol(n, r0 + c + j * nq) + r0 + r;
                        a[j] = A[ix[j]];
                        vc[j] = v[c + j * nq];
                        wc[j] = wv[c + j * nq];
                    }
#pragma unroll
                    for (int j = 0; j < EH_UPD; ++j) {
                        rank2(a[j], vr, wr, vc[j], wc[j]);
                        A[ix[j]] = a[j];
                    }
                }
                for (; c <= r; c += nq) rank2(A[pcol(n, r0 + c) + r0 + r], vr, wr, v[c], wv[c]);
            }
        }
        if (pr_on) {
            const long long t = clock64();
            (tid == 0 ? pr_w0 : pr_w1) += t - pr_t;
            pr_t = t;
        }
        __syncthreads();
        if (pr_on) pr_bar += clock64() - pr_t;
    }
    // Written whenever profiling (zeros without EH_PROFILE_STEPS: the host then leaves
    // them out).
    if (prof != nullptr && (tid == 0 || tid == 32)) {
        long long* q = prof + (size_t)mat * 16 + 8;
        if (tid == 0) {
            q[0] = pr_mv;
            q[1] = pr_w0;
            q[3] = pr_bar;
        } else {
            q[2] = pr_w1;
        }
    }
    // T is scaled to ‖T‖ ≈ 1 (Gershgorin) for what follows, so that one guard `tiny`
    // serves every matrix and reciprocals can start from single precision.
    double tn = 0.0;
    for (int i = lane; i < n; i += 32) {
        const double el = i > 0 ? fabs(ee[i - 1]) : 0.0, er = i < n - 1 ? fabs(ee[i]) : 0.0;
        tn = fmax(tn, fabs(A[pcol(n, i) + i].re) + el + er);
    }
#pragma unroll
    for (int off = 1; off < 32; off <<= 1) tn = fmax(tn, __shfl_xor_sync(0xffffffffu, tn, off));
    const double tscale = tn > 0.0 ? 1.0 / tn : 0.0;
    __syncthreads();  // every warp has its norm before ee is rescaled
    double* tr = tri != nullptr ? tri + (size_t)blockIdx.x * 2 * n : nullptr;  // count.cu's input
    for (int i = tid; i < n; i += nt) {
        dd[i] = A[pcol(n, i) + i].re * tscale;
        if (i < n - 1) {
            ee[i] *= tscale;
            e2[i] = ee[i] * ee[i];
        }
        if (tr != nullptr) {
            tr[i] = dd[i];
            if (i < n - 1) tr[n + i] = ee[i];
        }
    }
    __syncthreads();
    EH_PROF(2);

    // ---- the top Ns eigenvalues of T (tridiag.cuh) ----
    tridiag_values(dd, e2, n, ns, tn > 0.0, lam, steps, bfirst);
    __syncthreads();
    EH_PROF(3);

    // ---- their vectors z_r (tridiag.cuh), and λ_0 from z_0's Rayleigh quotient ----
    tridiag_vectors(dd, ee, n, ns, tn > 0.0, lam, zs, us, scr, vpp, ob);
    __syncthreads();
    EH_PROF(4);

    // ---- e_r = Q z_r = H_0 (H_1 (⋯ H_{n−2} z_r)), rank order: warp q takes vectors
    // q, q + nwarps, … (up to EH_BT at once, their reductions interleaved) ----
    for (int rb = 0; rb < ns; rb += nwarps * EH_BT) {  // uniform over the block
        const int jn = min(EH_BT, max(0, (ns - rb - warp + nwarps - 1) / nwarps));  // this warp's vectors
        zd u[EH_BT][2];
#pragma unroll
        for (int j = 0; j < EH_BT; ++j) {
            const int r = rb + warp + nwarps * j;
#pragma unroll
            for (int h = 0; h < 2; ++h) {
                const int i = lane + 32 * h;
                u[j][h] = cx<double>(j < jn && i < n ? zs[(size_t)r * us + i] : 0.0, 0.0);
            }
        }
        for (int k = n - 2; k >= 0 && jn > 0; --k) {
            const zd tk = tau[k];
            if (tk.re == 0.0 && tk.im == 0.0) continue;
            const zd* col = A + pcol(n, k);  // v_k(i) = col[i], i ≥ k + 2
            zd v[2];
#pragma unroll
            for (int h = 0; h < 2; ++h) {
                const int i = lane + 32 * h;
                v[h] = i == k + 1 ? cx<double>(1.0, 0.0) : (i > k + 1 && i < n ? col[i] : czero<double>());
            }
#pragma unroll
            for (int j = 0; j < EH_BT; ++j) {
                if (j < jn) {
                    zd s = czero<double>();
#pragma unroll
                    for (int h = 0; h < 2; ++h) cmacc(s, v[h], u[j][h]);
                    s.re = warp_sum_d(s.re);
                    s.im = warp_sum_d(s.im);
                    const zd f = cx<double>(tk.re * s.re - tk.im * s.im, tk.re * s.im + tk.im * s.re);  // τ vᴴu
#pragma unroll
                    for (int h = 0; h < 2; ++h) {
                        u[j][h].re -= v[h].re * f.re - v[h].im * f.im;
                        u[j][h].im -= v[h].re * f.im + v[h].im * f.re;
                    }
                }
            }
        }
#pragma unroll
        for (int j = 0; j < EH_BT; ++j) {
            const int r = rb + warp + nwarps * j;
            if (j < jn) {
                const size_t o = ((size_t)blockIdx.x * ns + r) * M;
#pragma unroll
                for (int h = 0; h < 2; ++h) {
                    const int i = lane + 32 * h;
                    if (i < n) {
                        E[o + i] = cx<T>((T)u[j][h].re, (T)u[j][h].im);
                        if (E64 != nullptr) E64[o + i] = u[j][h];
                    }
                }
            }
        }
    }
    EH_PROF(5);
    if (tid == 0) {
        // λ_0 of H: the largest value itself (Hermitian cases) or σ_0² (GSVD).
        const double l0 = tn > 0.0 ? fmax(lam[0] * tn, 0.0) : 0.0;
        const double val = mode == 3 ? sqrt(l0) : l0;
        const double g = eigw ? sqrt(val) : 1.0;
        gain[mat] = weights[b] * (T)g;
        bw[mat] = (float)g;
        info[mat] = steps[0];
    }
}

#define SL_FORM_H(FORM, T)                                                                                     \
    extern "C" __global__ void __launch_bounds__(EH_THREADS, EH_FORM_MINB)                                    \
        FORM(const zd* R, const zd* Wcm, const zd* Wrm, int M, int nb, int mode, int mat0, zd* Hg) {             \
        form_h_impl(R, Wcm, Wrm, M, nb, mode, mat0, Hg);                                                       \
    }
#define SL_EIGH(NAME, T, NT, MINB)                                                                             \
    extern "C" __global__ void __launch_bounds__(NT, MINB)                                                    \
        NAME(const zd* R, const zd* Hg, int M, int nb, int mode, int ns, int eigw, const T* weights, int mat0,   \
             int scr_len, cplx<T>* E, zd* E64, T* gain, float* bw, int* info, long long* prof, double* tri) { \
        eigh_impl<T, NT>(R, Hg, M, nb, mode, ns, eigw, weights, mat0, scr_len, E, E64, gain, bw, info, prof,    \
                         tri);                                                                                 \
    }

// Two eigensolver sizes (the host's `eigh_shape` picks one): EH_THREADS = 256 threads,
// three blocks per multiprocessor (at most 80 registers; ~35–75 KB of shared memory at
// M = 60 depending on Ns), and EH_NARROW = 128 threads, six blocks (the same registers;
// ~35 KB at Ns = 2): the reduction is bound by the latency of its steps, so more
// matrices in flight per multiprocessor outweigh fewer threads on each. The products
// (form_h) take two blocks of EH_THREADS.
#define EH_NARROW 128
#ifndef EH_MINB
#define EH_MINB 3
#endif
#ifndef EH_NARROW_MINB
#define EH_NARROW_MINB 6
#endif
#ifndef EH_FORM_MINB
#define EH_FORM_MINB 2
#endif
#ifndef SL_NO_F32
SL_FORM_H(form_h_f32, float)
SL_EIGH(eigh_f32, float, EH_THREADS, EH_MINB)
SL_EIGH(eigh_narrow_f32, float, EH_NARROW, EH_NARROW_MINB)
#endif
#ifndef SL_NO_F64
SL_FORM_H(form_h_f64, double)
SL_EIGH(eigh_f64, double, EH_THREADS, EH_MINB)
SL_EIGH(eigh_narrow_f64, double, EH_NARROW, EH_NARROW_MINB)
#endif
