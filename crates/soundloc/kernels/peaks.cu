// Stages 5–6 — dB and peaks, one block per window (of the sub-batch; every pointer is
// offset to the sub-batch by the host).
//   P̄(d) = Σ_z Ppart[z][w][d] (fixed order), dB(d) = 10·log10(P̄(d) + 1) in double (the
//   CPU's to_db), kept in DB[w][d] (and as f32 in spec[w][d] when spec is not null);
//   a direction is a candidate when its azimuth is allowed and its dB is strictly greater
//   than every neighbour's (CSR table offs/nbrs); candidates are sorted by (dB desc,
//   direction asc) with a bitonic sort in shared memory and the first kout written out.
// out[w][0].dir = number of candidates (all of them, even beyond cap), out[w][0].pad = 1
// when they did not fit in cap (the host then redoes this window from DB);
// out[w][1 + i] = candidate i. Dynamic shared memory: cap × (8 + 4) bytes, cap a power of two.
#include "common.cuh"

__device__ __forceinline__ bool peak_worse(double va, int da, double vb, int db) {
    return va < vb || (va == vb && da > db);
}

template <typename T>
__device__ void peaks_impl(const T* __restrict__ Ppart, int nbg, int nwin, int D, const int* __restrict__ offs,
                           const int* __restrict__ nbrs, const unsigned char* __restrict__ azok, int kout, int cap,
                           double* __restrict__ DB, float* __restrict__ spec, PeakOut* __restrict__ out) {
    SL_DYN_SMEM(sl_smem);
    double* key = reinterpret_cast<double*>(sl_smem);
    int* dir = reinterpret_cast<int*>(key + cap);
    __shared__ int count;
    const int w = blockIdx.x;
    const int tid = threadIdx.x, nt = blockDim.x;
    double* dbw = DB + (size_t)w * D;
    for (int d = tid; d < D; d += nt) {
        T p = (T)0;
        for (int z = 0; z < nbg; ++z) p += Ppart[((size_t)z * nwin + w) * D + d];
        const double v = 10.0 * log10((double)p + 1.0);
        dbw[d] = v;
        if (spec) spec[(size_t)w * D + d] = (float)v;
    }
    if (tid == 0) count = 0;
    __syncthreads();
    for (int d = tid; d < D; d += nt) {
        if (!azok[d]) continue;
        const double v = dbw[d];
        bool is_max = true;
        for (int k = offs[d]; k < offs[d + 1]; ++k) {
            if (!(v > dbw[nbrs[k]])) {
                is_max = false;
                break;
            }
        }
        if (is_max) {
            const int idx = atomicAdd(&count, 1);
            if (idx < cap) {
                key[idx] = v;
                dir[idx] = d;
            }
        }
    }
    __syncthreads();
    const int total = count;
    const int nc = min(total, cap);
    int p2 = 1;
    while (p2 < nc) p2 <<= 1;
    for (int i = nc + tid; i < p2; i += nt) {
        key[i] = -1.0e308;
        dir[i] = 0x7fffffff;
    }
    __syncthreads();
    // Bitonic sort: best (largest dB, then smallest direction) first.
    for (int k = 2; k <= p2; k <<= 1) {
        for (int j = k >> 1; j > 0; j >>= 1) {
            for (int i = tid; i < p2; i += nt) {
                const int ixj = i ^ j;
                if (ixj > i) {
                    const bool asc = (i & k) == 0;
                    const bool sw = asc ? peak_worse(key[i], dir[i], key[ixj], dir[ixj])
                                        : peak_worse(key[ixj], dir[ixj], key[i], dir[i]);
                    if (sw) {
                        const double tk = key[i];
                        key[i] = key[ixj];
                        key[ixj] = tk;
                        const int td = dir[i];
                        dir[i] = dir[ixj];
                        dir[ixj] = td;
                    }
                }
            }
            __syncthreads();
        }
    }
    PeakOut* o = out + (size_t)w * (1 + kout);
    const int nw = min(nc, kout);
    for (int i = tid; i < nw; i += nt) {
        o[1 + i].db = key[i];
        o[1 + i].dir = dir[i];
        o[1 + i].pad = 0;
    }
    if (tid == 0) {
        o[0].db = 0.0;
        o[0].dir = total;
        o[0].pad = total > cap ? 1 : 0;
    }
}

#ifndef SL_NO_F32
extern "C" __global__ void peaks_f32(const float* Ppart, int nbg, int nwin, int D, const int* offs, const int* nbrs,
                                     const unsigned char* azok, int kout, int cap, double* DB, float* spec,
                                     PeakOut* out) {
    peaks_impl<float>(Ppart, nbg, nwin, D, offs, nbrs, azok, kout, cap, DB, spec, out);
}
#endif
#ifndef SL_NO_F64
extern "C" __global__ void peaks_f64(const double* Ppart, int nbg, int nwin, int D, const int* offs, const int* nbrs,
                                     const unsigned char* azok, int kout, int cap, double* DB, float* spec,
                                     PeakOut* out) {
    peaks_impl<double>(Ppart, nbg, nwin, D, offs, nbrs, azok, kout, cap, DB, spec, out);
}
#endif
