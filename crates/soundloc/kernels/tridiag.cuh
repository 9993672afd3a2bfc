// The symmetric tridiagonal eigenproblem of eigh.cu, for one block: T (diagonal d,
// off-diagonal e, e² = e2; scaled so that ‖T‖ ≈ 1) → its top Ns values by multisection of
// Sturm counts, then their vectors by inverse iteration with orthonormalisation.
// Included by eigh.cu (after warp_sum_d); every thread of the block calls the two entry
// points, which end without a barrier.

// 1/x to ~46 bits: the single-precision reciprocal and one Newton step (x scaled so that
// 1e-30 ≤ |x| ≤ 1e30; a full double division is ~3× the latency on the device).
__device__ __forceinline__ double rcp_fast(double x) {
    const double y = (double)__frcp_rn((float)x);
    return y * (2.0 - x * y);
}

// Number of eigenvalues of T (diagonal d, squared off-diagonal e2) below x (Sturm count,
// LDLᵀ form with LAPACK's pivmin guard): q_i = d_i − x − e2_{i−1} / q_{i−1}.
__device__ int sturm_count_ratio(const double* d, const double* e2, int n, double x, double pivmin) {
    double q = d[0] - x;
    if (fabs(q) < pivmin) q = -pivmin;
    int cnt = q < 0.0 ? 1 : 0;
    for (int i = 1; i < n; ++i) {
        q = d[i] - x - e2[i - 1] * rcp_fast(q);
        if (fabs(q) < pivmin) q = -pivmin;
        cnt += q < 0.0 ? 1 : 0;
    }
    return cnt;
}

// The same count without divisions: the leading minors p_i = det(T_{0..i} − x I) follow
// p_i = (d_i − x) p_{i−1} − e2_{i−1} p_{i−2} (p_{−1} = 1, q_i = p_i / p_{i−1}), and the
// count is the number of sign changes. One fused multiply-add on the dependency chain per
// row instead of a reciprocal and its conversions. ‖T‖ ≈ 1 bounds the growth (≤ (1+√2)ⁿ);
// decay is undone every fourth row by an exact power of two. A zero or a value below
// 2⁻⁹⁰⁰ (x on an eigenvalue of a leading block, or T nearly split) falls back to the ratio
// form. A nonzero pivot below pivmin is counted by its own sign here, where the ratio form
// makes it −pivmin: both are exact counts of T perturbed by ~pivmin.
__device__ int sturm_count(const double* d, const double* e2, int n, double x, double pivmin) {
    double pm = 1.0, pc = d[0] - x;
    int cnt = pc < 0.0 ? 1 : 0;
    bool bad = fabs(pc) < 0x1p-900;
    for (int i = 1; i < n; ++i) {
        const double pn = fma(d[i] - x, pc, -(e2[i - 1] * pm));
        cnt += (pn < 0.0) != (pc < 0.0) ? 1 : 0;
        bad |= fabs(pn) < 0x1p-900;
        pm = pc;
        pc = pn;
        if ((i & 3) == 0) {
            const double sc = fabs(pc) < 0x1p-200 ? 0x1p200 : 1.0;
            pc *= sc;
            pm *= sc;
        }
    }
    return bad ? sturm_count_ratio(d, e2, n, x, pivmin) : cnt;
}


// λ_0 ≥ … ≥ λ_{ns−1} of T to EH_BTOL·‖T‖ into lam (steps[0] = the rounds taken; bfirst:
// one int per warp). Not live (T = 0): lam is left alone.
__device__ __forceinline__ void tridiag_values(const double* __restrict__ dd, const double* __restrict__ e2, int n, int ns, bool live,
                               double* __restrict__ lam, int* __restrict__ steps, int* __restrict__ bfirst) {
    const int tid = threadIdx.x, nt = blockDim.x;
    const int lane = tid & 31, warp = tid >> 5, nwarps = nt >> 5;
    const double eps = 2.220446049250313e-16;
    const double tiny = 1e-30;  // pivot guard, relative to ‖T‖ = 1 (LAPACK's pivmin role)
    const double glo = -1.0 - 4.0 * n * eps, ghi = 1.0 + 4.0 * n * eps;  // Gershgorin
    // To EH_BTOL·‖T‖ only: inverse iteration below converges from there, and λ_0 is then
    // taken from the Rayleigh quotient of its vector.
    const double btol = fmax(EH_BTOL, 4.0 * eps);
    if (ns <= nwarps) {
        // Few values: the block's warps shared among them (wpe warps per value: 32·wpe
        // points per round).
        const int cnt_e = ns;
        const int wpe = nwarps / cnt_e;
        const int npts = 32 * wpe;
        int rounds = 0;  // the same in every thread: each round divides the width by npts + 1
        for (double w = ghi - glo; w > btol && rounds < 64; w /= (double)(npts + 1)) ++rounds;
        const int e = warp / wpe, sub = warp - e * wpe;
        const bool act = e < cnt_e && live;
        const int r = e;
        const int want = n - 1 - r;  // ascending index of λ_r
        double lo = glo, hi = ghi;
        for (int it = 0; it < rounds; ++it) {
            int first = 32;
            if (act) {
                const double x = lo + (hi - lo) * (double)(sub * 32 + lane + 1) / (double)(npts + 1);
                const int cnt = sturm_count(dd, e2, n, x, tiny);
                // first point of this warp with more than `want` values below it
                const unsigned bal = __ballot_sync(0xffffffffu, cnt > want);
                first = bal ? __ffs((int)bal) - 1 : 32;
            }
            if (lane == 0) bfirst[warp] = first;
            __syncthreads();
            if (act) {
                int gp = npts;
                for (int q = wpe - 1; q >= 0; --q) {
                    const int f = bfirst[e * wpe + q];
                    if (f < 32) gp = q * 32 + f;
                }
                const double nlo = gp == 0 ? lo : lo + (hi - lo) * (double)gp / (double)(npts + 1);
                const double nhi = gp == npts ? hi : lo + (hi - lo) * (double)(gp + 1) / (double)(npts + 1);
                lo = nlo;
                hi = fmax(nhi, nlo);
            }
            __syncthreads();
        }
        if (act && sub == 0 && lane == 0) {
            lam[r] = 0.5 * (lo + hi);
            if (r == 0) steps[0] = rounds;
        }
    } else {
        // Many values (the robust default's M/2): P lanes of one warp per value, all values
        // at once (fewer, wider rounds than a warp each in turn); no barrier inside.
        int P = 16;
        while (P > 1 && P * ns > nt) P >>= 1;
        const int vpass = nt / P;
        int rounds = 0;
        for (double w = ghi - glo; w > btol && rounds < 64; w /= (double)(P + 1)) ++rounds;
        const int e = tid / P, sub = tid - e * P;
        const int sh = (lane / P) * P;
        const unsigned segm = (1u << P) - 1u;
        for (int r0e = 0; r0e < ns; r0e += vpass) {  // uniform over the block
            const int r = r0e + e;
            const bool act = r < ns && live;
            const int want = n - 1 - r;
            double lo = glo, hi = ghi;
            for (int it = 0; it < rounds; ++it) {
                int cnt = 0;
                if (act) cnt = sturm_count(dd, e2, n, lo + (hi - lo) * (double)(sub + 1) / (double)(P + 1), tiny);
                const unsigned bal = (__ballot_sync(0xffffffffu, act && cnt > want) >> sh) & segm;
                const int gp = bal ? __ffs((int)bal) - 1 : P;
                const double nlo = gp == 0 ? lo : lo + (hi - lo) * (double)gp / (double)(P + 1);
                const double nhi = gp == P ? hi : lo + (hi - lo) * (double)(gp + 1) / (double)(P + 1);
                lo = nlo;
                hi = fmax(nhi, nlo);
            }
            if (act && sub == 0) {
                lam[r] = 0.5 * (lo + hi);
                if (r == 0) steps[0] = rounds;
            }
        }
    }
}

// z_0 … z_{ns−1} (rows of stride us in zs; the solver scratch scr holds vpp × 3 rows of
// stride us, or ob·ns dot products) for the values in lam, then lam[0] = z_0ᵀ T z_0.
// Not live (T = 0): the unit vectors.
__device__ __forceinline__ void tridiag_vectors(const double* __restrict__ dd, const double* __restrict__ ee, int n, int ns, bool live,
                                double* __restrict__ lam, double* __restrict__ zs, int us, double* __restrict__ scr,
                                int vpp, int ob) {
    const int tid = threadIdx.x, nt = blockDim.x;
    const int lane = tid & 31, warp = tid >> 5;
    const double eps = 2.220446049250313e-16;
    // rounds of (solve every vector; orthonormalise them all): two, or three when two of
    // the values are closer than 10⁻³‖T‖ (dstein's cluster distance; LAPACK iterates
    // such clusters more, the CPU path three times). P L U = T − λ I with
    // partial pivoting is factored again in each solve together with its forward
    // elimination (so only U is kept: three rows of stride us per thread). Orthonormalising
    // between the solves, not only after them, keeps close values apart: vectors of one
    // cluster come out of the first solve nearly parallel, and the second solve, from an
    // orthonormal start, amplifies each within the cluster's span only.
    int close = 0;
    for (int r = 1 + tid; r < ns; r += nt) close |= lam[r - 1] - lam[r] < 1e-3;
    const int rounds_v = __syncthreads_or(close) ? 3 : 2;
    for (int iter = 0; iter < rounds_v; ++iter) {
        for (int r0v = 0; r0v < ns; r0v += vpp) {  // uniform over the block
            const int r = r0v + tid;
            if (tid < vpp && r < ns) {
                double* u0 = scr + (size_t)tid * us;              // 1 / U diagonal
                double* u1 = scr + (size_t)(vpp + tid) * us;      // U first superdiagonal
                double* u2 = scr + (size_t)(2 * vpp + tid) * us;  // U second superdiagonal
                double* z = zs + (size_t)r * us;
                if (!live) {
                    for (int i = 0; i < n; ++i) z[i] = i == r ? 1.0 : 0.0;
                } else {
                    const double lm = lam[r];
                    const double piv_min = 4.0 * eps;  // |pivot| floor (‖T‖ = 1)
                    if (iter == 0) {
                        for (int i = 0; i < n; ++i) {
                            // a fixed, non-special start vector (dstein uses random numbers)
                            const unsigned h = (unsigned)(i * 2654435761u) ^ (unsigned)(r * 40503u + 12345u);
                            z[i] = 0.5 + (double)(h % 1024u) / 1024.0;
                        }
                    }
                    // Each solve multiplies the wanted component by ≥ 1 / EH_BTOL against
                    // values outside its cluster (growth ≤ 1 / (4ε): no rescaling needed).
                    // Branch-free (the vectors of a warp pivot differently) with row k's
                    // pending entries p0, p1 and right-hand side zk carried in registers.
                    double p0 = dd[0] - lm, p1 = n > 1 ? ee[0] : 0.0, zk = z[0];
                    for (int kk = 0; kk < n - 1; ++kk) {
                        const double sub = ee[kk];                             // T(k+1, k)
                        const double dn = dd[kk + 1] - lm;                     // T(k+1, k+1)
                        const double sup = kk + 1 < n - 1 ? ee[kk + 1] : 0.0;  // T(k+1, k+2)
                        const double zn = z[kk + 1];
                        // pivot on row k (keep) or on row k + 1 (swap the rows)
                        const bool keep = fabs(p0) >= fabs(sub) || fabs(sub) < piv_min;
                        const double ip =
                            rcp_fast(keep ? (fabs(p0) < piv_min ? (p0 < 0.0 ? -piv_min : piv_min) : p0) : sub);
                        const double mu = (keep ? sub : p0) * ip;
                        u0[kk] = ip;
                        u1[kk] = keep ? p1 : dn;
                        u2[kk] = keep ? 0.0 : sup;
                        const double zp = keep ? zk : zn;  // the pivot row's right-hand side
                        z[kk] = zp;
                        zk = (keep ? zn : zk) - mu * zp;
                        p0 = (keep ? dn : p1) - mu * (keep ? p1 : dn);
                        p1 = keep ? sup : -mu * sup;
                    }
                    u0[n - 1] = rcp_fast(fabs(p0) < piv_min ? (p0 < 0.0 ? -piv_min : piv_min) : p0);
                    double z2 = zk * u0[n - 1];  // U z = rhs, z[k + 1] and z[k + 2] carried
                    z[n - 1] = z2;
                    if (n > 1) {
                        double z1 = (z[n - 2] - u1[n - 2] * z2) * u0[n - 2];
                        z[n - 2] = z1;
                        for (int kk = n - 3; kk >= 0; --kk) {
                            const double v = (z[kk] - u1[kk] * z1 - u2[kk] * z2) * u0[kk];
                            z[kk] = v;
                            z2 = z1;
                            z1 = v;
                        }
                    }
                }
            }
            __syncthreads();
        }
        // Orthonormalise Z in rank order (classical Gram–Schmidt, twice), ob vectors at a
        // time: the block first frees them of the vectors before them (one thread per dot
        // product, then one per entry), then warp 0 alone orthonormalises them in order
        // (each lane keeps to rows lane and lane + 32: warp sums, no barriers): ~5 barriers
        // per ob vectors, not per vector. In exact arithmetic the same as one vector at a
        // time; in rounding, a vector that cancels against earlier vectors of its own group
        // down to a fraction δ of its norm keeps ~ε/δ of the earlier groups (one vector at
        // a time left ~ε). The parity scenes at the robust default's subspace, deep in the
        // noise floor's clusters, agree with the CPU as before (docs/gpu.md).
        double* dots = scr;
        for (int b0 = 0; b0 < ns; b0 += ob) {  // uniform over the block
            const int bn = min(ob, ns - b0);
            double* zb = zs + (size_t)b0 * us;
            for (int pass = 0; pass < 2 && b0 > 0; ++pass) {
                for (int it = tid; it < b0 * bn; it += nt) {
                    const int c = it / b0, q = it - c * b0;
                    const double* zq = zs + (size_t)q * us;
                    const double* zc = zb + (size_t)c * us;
                    double s0 = 0.0, s1 = 0.0;
                    int i = 0;
                    for (; i + 1 < n; i += 2) {
                        s0 = fma(zq[i], zc[i], s0);
                        s1 = fma(zq[i + 1], zc[i + 1], s1);
                    }
                    if (i < n) s0 = fma(zq[i], zc[i], s0);
                    dots[it] = s0 + s1;
                }
                __syncthreads();
                for (int it = tid; it < n * bn; it += nt) {
                    const int c = it / n, i = it - c * n;
                    const double* dc = dots + (size_t)c * b0;
                    double acc = zb[(size_t)c * us + i];
                    for (int q = 0; q < b0; ++q) acc = fma(-dc[q], zs[(size_t)q * us + i], acc);
                    zb[(size_t)c * us + i] = acc;
                }
                __syncthreads();
            }
            if (warp == 0) {
                double x[EH_OB][2];
#pragma unroll
                for (int c = 0; c < EH_OB; ++c) {
#pragma unroll
                    for (int h = 0; h < 2; ++h) {
                        const int i = lane + 32 * h;
                        x[c][h] = c < bn && i < n ? zb[(size_t)c * us + i] : 0.0;
                    }
                }
#pragma unroll
                for (int c = 0; c < EH_OB; ++c) {
                    if (c < bn) {
                        for (int pass = 0; pass < 2 && c > 0; ++pass) {
                            double d[EH_OB];
#pragma unroll
                            for (int q = 0; q < EH_OB; ++q)
                                if (q < c) d[q] = warp_sum_d(fma(x[q][0], x[c][0], x[q][1] * x[c][1]));
#pragma unroll
                            for (int q = 0; q < EH_OB; ++q) {
                                if (q < c) {
                                    x[c][0] = fma(-d[q], x[q][0], x[c][0]);
                                    x[c][1] = fma(-d[q], x[q][1], x[c][1]);
                                }
                            }
                        }
                        const double s = warp_sum_d(fma(x[c][0], x[c][0], x[c][1] * x[c][1]));
                        const double inv = s > 0.0 ? 1.0 / sqrt(s) : 0.0;
                        x[c][0] *= inv;
                        x[c][1] *= inv;
                    }
                }
#pragma unroll
                for (int c = 0; c < EH_OB; ++c) {
#pragma unroll
                    for (int h = 0; h < 2; ++h) {
                        const int i = lane + 32 * h;
                        if (c < bn && i < n) zb[(size_t)c * us + i] = x[c][h];
                    }
                }
            }
            __syncthreads();
        }
    }
    // λ_0 = z_0ᵀ T z_0 (error O(‖T‖ δ²) for a vector error δ).
    if (warp == 0 && ns > 0 && live) {
        double s = 0.0;
        for (int i = lane; i < n; i += 32) {
            double tz = dd[i] * zs[i];
            if (i > 0) tz += ee[i - 1] * zs[i - 1];
            if (i < n - 1) tz += ee[i] * zs[i + 1];
            s += zs[i] * tz;
        }
        s = warp_sum_d(s);
        if (lane == 0) lam[0] = s;  // of the scaled T
    }
}
