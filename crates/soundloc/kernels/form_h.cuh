// Forming H for eigh.cu (modes 1–3: W R Wᴴ, W R W, (W R)(W R)ᴴ) in double, one block per
// matrix: P = W R, then H's lower triangle from P, mirrored, each product by register
// tiles on the double-precision pipe (EH_RT rows × 4 columns per thread, so M ≤ 64), the
// known zeros of W's triangle and H's symmetry skipped. Included by eigh.cu after `zd`,
// `to_zd` and the EH_* sizes (EH_MAXN, EH_TY, EH_RT).
//
// Tried on the double-precision tensor cores (mma.sync m8n8k4 .f64, 8 × 8 tiles a warp
// each; branch experiments/form-h-dmma): on an H100 the decomposition went 58.7 → 58.4 µs
// per localization for GSVD and 56.8 → 55.1 for the textbook GEVD (seed config, batch 256,
// 2026-11-28), too little for a second form of these products; docs/gpu.md.

// Known zeros of a product, skipped (exact zeros only, so the sums keep their bits; on the
// H100, 2026-11-27: form_h 16 → 12.5 µs per localization for the textbook GEVD, 14.8 for
// GSVD):
#define EH_X_LOWER 1  // x(i, k) = 0 for k > i (X lower triangular)
#define EH_Y_UPPER 2  // y(k, j) = 0 for k > j (Y = Wᴴ with W lower triangular)
#define EH_C_LOWER 4  // only C's lower triangle is wanted (C Hermitian; tile_store mirrors it)

// C = X · Y for the register tile of this thread (rows ty + EH_TY·a, columns tx + 16·b).
// xat(i, k) and yat(k, j) read the operands; C goes to acc (fused multiply-adds:
// form_h was bound by the double-precision pipe, 2026-11-27). k runs in chunks of 16 (n ≤
// EH_MAXN); the row block a (rows EH_TY·a …) and column block b (columns 16·b …) of a
// chunk are skipped where S says their terms vanish.
template <int S, typename XA, typename YA>
__device__ __forceinline__ void tile_product(int n, XA xat, YA yat, zd (&acc)[EH_RT][4]) {
    const int tx = threadIdx.x & 15, ty = threadIdx.x >> 4;
#pragma unroll
    for (int a = 0; a < EH_RT; ++a)
#pragma unroll
        for (int b = 0; b < 4; ++b) acc[a][b] = czero<double>();
    // The chunks are unrolled, so every skip is decided at compile time (predicated
    // products would still take their issue slots).
#pragma unroll
    for (int c = 0; c < EH_MAXN / 16; ++c) {
        const int k0 = 16 * c, k1 = min(n, k0 + 16);
        bool live[EH_RT][4], xl[EH_RT], yl[4];
#pragma unroll
        for (int b = 0; b < 4; ++b) yl[b] = false;
#pragma unroll
        for (int a = 0; a < EH_RT; ++a) {
            xl[a] = false;
            const int rmax = EH_TY * a + EH_TY - 1;
#pragma unroll
            for (int b = 0; b < 4; ++b) {
                const int cmin = 16 * b, cmax = cmin + 15;
                live[a][b] = !((S & EH_X_LOWER) && rmax < k0) && !((S & EH_Y_UPPER) && cmax < k0) &&
                             !((S & EH_C_LOWER) && rmax < cmin);
                xl[a] = xl[a] || live[a][b];
                yl[b] = yl[b] || live[a][b];
            }
        }
        for (int k = k0; k < k1; ++k) {
            zd x[EH_RT], y[4];
#pragma unroll
            for (int a = 0; a < EH_RT; ++a) {
                const int i = ty + EH_TY * a;
                x[a] = xl[a] && i < n ? xat(i, k) : czero<double>();
            }
#pragma unroll
            for (int b = 0; b < 4; ++b) {
                const int j = tx + 16 * b;
                y[b] = yl[b] && j < n ? yat(k, j) : czero<double>();
            }
#pragma unroll
            for (int a = 0; a < EH_RT; ++a)
#pragma unroll
                for (int b = 0; b < 4; ++b)
                    if (live[a][b]) cmac_fma(acc[a][b], x[a], y[b]);
        }
    }
}

// Store the tile into A (after a barrier that ends every read of A). HERM: C is
// Hermitian and only its lower triangle was summed (EH_C_LOWER): each entry below the
// diagonal is stored with its mirror, the diagonal real.
template <bool HERM>
__device__ __forceinline__ void tile_store(zd* A, int lda, int n, const zd (&acc)[EH_RT][4]) {
    const int tx = threadIdx.x & 15, ty = threadIdx.x >> 4;
#pragma unroll
    for (int a = 0; a < EH_RT; ++a)
#pragma unroll
        for (int b = 0; b < 4; ++b) {
            const int i = ty + EH_TY * a, j = tx + 16 * b;
            if (i >= n || j >= n) continue;
            if (!HERM) {
                A[(size_t)j * lda + i] = acc[a][b];
            } else if (i > j) {
                A[(size_t)j * lda + i] = acc[a][b];
                A[(size_t)i * lda + j] = cconj(acc[a][b]);
            } else if (i == j) {
                A[(size_t)j * lda + i] = cx<double>(acc[a][b].re, 0.0);
            }
        }
}

// H = W R Wᴴ | W R W | (W R)(W R)ᴴ (mode 1 | 2 | 3) in double, one block per matrix, into
// Hg [blk][M][M] (column-major). A kernel of its own: its register tiles would otherwise
// cap the eigensolver's occupancy.
__device__ void form_h_impl(const zd* __restrict__ R, const zd* __restrict__ Wcm, const zd* __restrict__ Wrm, int M,
                            int nb, int mode, int mat0, zd* __restrict__ Hg) {
    SL_DYN_SMEM(sm);
    const int n = M, lda = M | 1;
    const int tid = threadIdx.x, nt = blockDim.x;
    const int b = (mat0 + blockIdx.x) % nb;
    zd* A = reinterpret_cast<zd*>(sm);
    const zd* Rm = R + (size_t)blockIdx.x * M * M;  // column-major, R_ik = Rm[k*M + i]
    const zd* Wc = Wcm + (size_t)b * M * M;         // W_ik = Wc[k*M + i]
    const zd* Wr = Wrm + (size_t)b * M * M;         // W_kj = Wr[k*M + j]
    for (int idx = tid; idx < n * n; idx += nt) {
        const int j = idx / n, i = idx - j * n;
        A[(size_t)j * lda + i] = to_zd(Rm[idx]);
    }
    __syncthreads();
    if (mode != 0) {
        zd acc[EH_RT][4];
        // P = W R: column j of P needs only column j of R, so it is written in place.
        // Textbook GEVD: W = L⁻¹ is lower triangular (plan.rs).
        const auto wr = [&](int i, int k) { return to_zd(Wc[(size_t)k * M + i]); };
        const auto ra = [&](int k, int j) { return A[(size_t)j * lda + k]; };
        if (mode == 1) {
            tile_product<EH_X_LOWER>(n, wr, ra, acc);
        } else {
            tile_product<0>(n, wr, ra, acc);
        }
        __syncthreads();
        tile_store<false>(A, lda, n, acc);
        __syncthreads();
        // H is Hermitian in every mode: its lower triangle only.
        const auto pa = [&](int i, int k) { return A[(size_t)k * lda + i]; };
        if (mode == 1) {  // H = P Wᴴ: H_ij = Σ_{k ≤ j} P_ik conj(W_jk)
            tile_product<EH_Y_UPPER | EH_C_LOWER>(
                n, pa, [&](int k, int j) { return cconj(to_zd(Wc[(size_t)k * M + j])); }, acc);
        } else if (mode == 2) {  // H = P W
            tile_product<EH_C_LOWER>(n, pa, [&](int k, int j) { return to_zd(Wr[(size_t)k * M + j]); }, acc);
        } else {  // H = P Pᴴ
            tile_product<EH_C_LOWER>(n, pa, [&](int k, int j) { return cconj(A[(size_t)k * lda + j]); }, acc);
        }
        __syncthreads();
        tile_store<true>(A, lda, n, acc);
        __syncthreads();
    }
    for (int idx = tid; idx < n * n; idx += nt) {
        const int j = idx / n, i = idx - j * n;
        Hg[(size_t)blockIdx.x * n * n + idx] = A[(size_t)j * lda + i];
    }
}
