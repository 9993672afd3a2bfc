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
// One thread per matrix: T's eigenvalues by the implicit QL algorithm with Wilkinson
// shifts (EISPACK's tql1, eigenvalues only: ~30 M² flops), sorted descending.
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

// Eigenvalues of the symmetric tridiagonal (d, e), e[i] coupling d[i] and d[i + 1]
// (e[n − 1] = 0), into d (unordered): implicit QL with Wilkinson shifts.
__device__ void tql1(double* d, double* e, int n) {
    for (int l = 0; l < n; ++l) {
        for (int iter = 0; iter < 60; ++iter) {
            int m = l;
            for (; m < n - 1; ++m) {
                const double dd = fabs(d[m]) + fabs(d[m + 1]);
                if (fabs(e[m]) <= 2.220446049250313e-16 * dd) break;
            }
            if (m == l) break;
            double g = (d[l + 1] - d[l]) / (2.0 * e[l]);
            double r = hypot(g, 1.0);
            g = d[m] - d[l] + e[l] / (g + (g >= 0.0 ? r : -r));
            double s = 1.0, c = 1.0, p = 0.0;
            int i = m - 1;
            bool split = false;
            for (; i >= l; --i) {
                const double f = s * e[i], b = c * e[i];
                r = hypot(f, g);
                e[i + 1] = r;
                if (r == 0.0) {  // underflow: T splits here
                    d[i + 1] -= p;
                    e[m] = 0.0;
                    split = true;
                    break;
                }
                s = f / r;
                c = g / r;
                g = d[i + 1] - p;
                r = (d[i] - g) * s + 2.0 * c * b;
                p = s * r;
                d[i + 1] = g + p;
                g = c * r - b;
            }
            if (split) continue;
            d[l] -= p;
            e[l] = g;
            e[m] = 0.0;
        }
    }
}

extern "C" __global__ void __launch_bounds__(128) count_sources(const double* tri, int n, int nmat, int nb, int mat0,
                                                                const int* win, double overlap, double floor_ratio,
                                                                int sq, int* kout) {
    const int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= nmat || n > CNT_MAXN) return;
    const int mat = mat0 + i;
    const int w = mat / nb;
    double d[CNT_MAXN], e[CNT_MAXN];
    const double* t = tri + (size_t)i * 2 * n;
    for (int k = 0; k < n; ++k) {
        d[k] = t[k];
        e[k] = k < n - 1 ? t[n + k] : 0.0;
    }
    tql1(d, e, n);
    for (int k = 0; k < n; ++k) d[k] = sq ? sqrt(fmax(d[k], 0.0)) : d[k];
    // Descending (insertion sort; NaN last).
    for (int a = 1; a < n; ++a) {
        const double x = d[a];
        int b = a - 1;
        while (b >= 0 && (d[b] < x || (d[b] != d[b] && x == x))) {
            d[b + 1] = d[b];
            --b;
        }
        d[b + 1] = x;
    }
    const double len = (double)win[2 * w + 1];
    const int snapshots = max(1, (int)floor(len * overlap + 0.5));  // Rust's round (len ≥ 0)
    kout[mat] = mdl_count(d, n, snapshots, floor_ratio);
}
