// Stage 3b — the number of active sources per (window, bin): the MDL criterion of Wax &
// Kailath on every eigenvalue of the decomposed matrix, as the CPU's
// subspace::count::mdl (the same clamping, sums and tie rule; the host takes the median
// over the bins).
//
// tri    [sub-batch matrix][2M] doubles: T's diagonal (M) and off-diagonal (M − 1) from
//        eigh.cu, scaled to ‖T‖ ≈ 1 (MDL compares ratios: the scale does not matter)
// win    [window][2] (first frame, number of frames): N = max(1, round(len · overlap))
//        independent snapshots (overlap = hop / N_fft)
// floor  values below floor × the largest count as that level (count::model_floor)
// sq     1: the values are σ = √λ (GSVD: singular values of K⁻¹R, T being A Aᴴ's)
// kout   [window · nb + bin] k̂ (absolute matrix index, as gain[] in eigh.cu)
//
// Two warps per matrix, from Sturm counts (tridiag.cuh's `sturm_count`; this file comes
// after eigh.cu in the translation unit): 64 geometric slicing points at once, a lane
// each, put every value in a slice a factor of 2.5 wide; then each value is bisected
// geometrically inside its slice in a lane of its own (mdl_count raises those below the
// floor to it, as the CPU does). Bound by the instructions of the counts' recurrence:
// +5.3 µs per GSVD localization of the seed config on an H200 (2026-12-01, docs/gpu.md).
// Tried first there: a thread per matrix running the implicit QL algorithm (EISPACK's
// tql1) took 72 µs, halving the throughput; bisection from T's whole interval 6.6–8.4 µs.
#include "common.cuh"

#define CNT_MAXN 64

__device__ int mdl_count(const double* v, int m, int snapshots, double floor_ratio) {
    if (m < 2 || snapshots <= 0) return 0;
    double top = 0.0;
    for (int i = 0; i < m; ++i) top = fmax(top, v[i]);  // fmax skips NaN as the CPU's fold
    if (!(top > 0.0 && top - top == 0.0)) return 0;
    const double fl = top * fmax(floor_ratio, 1e-12);
    const double n = (double)snapshots;
    // best starts above every finite score (the CPU's +∞; a NaN score never wins).
    double sum_ln = 0.0, sum = 0.0, best = 1.7976931348623157e308;
    int bk = 0;
    for (int k = m - 1; k >= 0; --k) {
        const double x = v[k];
        const double val = (x - x == 0.0) ? fmax(x, fl) : fl;
        sum_ln += log(val);
        sum += val;
        const double q = (double)(m - k);
        const double log_g = sum_ln / q, a = sum / q;
        const double score = -n * q * (log_g - log(a)) + 0.5 * (double)k * (2.0 * (double)m - (double)k) * log(n);
        if (score <= best) {  // ties go to the smaller k
            best = score;
            bk = k;
        }
    }
    return bk;
}

// Matrices per block, 64 threads (two warps) each: a lane per value (M ≤ 64).
#define CNT_MATS 2
// Slicing: 64 points 10^(−25 + 25·s/63), s = 0 … 63, a factor of 10^(25/63) ≈ 2.5 apart
// from 10⁻²⁵ to ‖T‖ = 1 (T is scaled so; values below 10⁻²⁵ lie under every floor:
// floor ≥ 10⁻¹², squared for GSVD, times λ_0 ≥ ‖T‖/3 for a semidefinite T), one per lane.
#define CNT_DECADES 25.0
// Geometric bisection steps inside a slice: ln 2.5 / 2¹⁰ leaves each value within 10⁻³ of
// itself. MDL needs no more: a value off by δ moves a score by at most 2·N·(M − k)·δ (N
// snapshots; ~2 at M = 60, N = 16), against penalty steps of ~½(2M − 2k − 1)·ln N (~100
// there); the median over the bins then rarely moves at all.
#define CNT_STEPS 10

extern "C" __global__ void __launch_bounds__(64 * CNT_MATS)
    count_sources(const double* tri, int n, int nmat, int nb, int mat0, const int* win, double overlap,
                  double floor_ratio, int sq, int* kout) {
    __shared__ double sd[CNT_MATS][CNT_MAXN], se2[CNT_MATS][CNT_MAXN], sv[CNT_MATS][CNT_MAXN];
    __shared__ int sc[CNT_MATS][64];
    const int sub = threadIdx.x & 63, slot = threadIdx.x >> 6;
    const int i = blockIdx.x * CNT_MATS + slot;
    const bool live = i < nmat && n <= CNT_MAXN;  // uniform over the matrix's 64 threads
    double* d = sd[slot];
    double* e2 = se2[slot];
    double* v = sv[slot];
    int* cs = sc[slot];
    const double pivmin = 1e-30;
    const double ratio = pow(10.0, CNT_DECADES / 63.0);
    const double p0 = pow(10.0, -CNT_DECADES);
    if (live && sub < n) {
        const double* t = tri + (size_t)i * 2 * n;
        d[sub] = t[sub];
        e2[sub] = sub < n - 1 ? t[n + sub] * t[n + sub] : 0.0;
    }
    __syncthreads();
    // The number of values below each slicing point (tridiag.cuh's division-free count).
    if (live) cs[sub] = sturm_count(d, e2, n, p0 * pow(ratio, (double)sub), pivmin);
    __syncthreads();
    if (live && sub < n) {
        // Value `sub` (0 = the largest), ascending index `want`: the first point with more
        // than `want` values below it ends its slice; then geometric bisection inside.
        const int want = n - 1 - sub;
        int s0 = 0;
        while (s0 < 64 && cs[s0] <= want) ++s0;
        double lam = 0.0;  // below 10⁻²⁵ (or negative): under every floor
        if (s0 > 0) {
            double a = p0 * pow(ratio, (double)(s0 - 1));
            double b = s0 < 64 ? a * ratio : 1.0 + 8.0 * n * 2.220446049250313e-16;
            for (int k = 0; k < CNT_STEPS; ++k) {
                const double mid = sqrt(a * b);
                if (sturm_count(d, e2, n, mid, pivmin) > want) {
                    b = mid;
                } else {
                    a = mid;
                }
            }
            lam = sqrt(a * b);
        }
        v[sub] = sq ? sqrt(lam) : lam;
    }
    __syncthreads();
    if (live && sub == 0) {
        const int mat = mat0 + i;
        const double len = (double)win[2 * (mat / nb) + 1];
        const int snapshots = max(1, (int)floor(len * overlap + 0.5));  // Rust's round (len ≥ 0)
        kout[mat] = mdl_count(v, n, snapshots, floor_ratio);
    }
}
