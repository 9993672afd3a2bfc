// A small CUDA emulator for the soundloc kernels (development and CI without a GPU).
//
// Each block runs on one OS thread; its CUDA threads are cooperative fibers (ucontext)
// that switch only at barriers (__syncthreads, __syncthreads_or, __syncwarp, shuffles).
// Blocks run one after another, so `__shared__` variables can be plain statics and the
// dynamic shared memory one buffer (filled with 0xFF — NaN — before each block, to catch
// reads of unwritten memory). Races between threads of a block are NOT detected: the
// emulator checks indexing and arithmetic, not the memory model.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>

#define __global__
#define __device__
#define __host__
#define __forceinline__ inline
#define __noinline__ __attribute__((noinline))
#define __restrict__ __restrict
#define __align__(n) alignas(n)
#define __launch_bounds__(...)
#define __shared__ static

using std::max;
using std::min;

struct emu_dim3 {
    unsigned x, y, z;
};

struct EmuThreadState {
    emu_dim3 tid;
    int lane, warp;
    unsigned long wgen;  // warp barriers this thread has passed
};

extern EmuThreadState* emu_cur;
extern emu_dim3 emu_block_idx, emu_block_dim, emu_grid_dim;

#define threadIdx (emu_cur->tid)
#define blockIdx (emu_block_idx)
#define blockDim (emu_block_dim)
#define gridDim (emu_grid_dim)

unsigned char* emu_dyn_smem();
int emu_block_barrier(int v);
void emu_warp_barrier();
uint64_t* emu_warp_slots(int buf);

inline void __syncthreads() { emu_block_barrier(0); }
inline int __syncthreads_or(int v) { return emu_block_barrier(v ? 1 : 0); }
inline void __syncwarp(unsigned = 0xffffffffu) { emu_warp_barrier(); }

template <typename T>
inline T __shfl_xor_sync(unsigned, T v, int lane_mask) {
    static_assert(sizeof(T) <= 8, "shuffle of at most 8 bytes");
    const int buf = (int)(emu_cur->wgen & 1);
    uint64_t* slots = emu_warp_slots(buf);
    uint64_t bits = 0;
    std::memcpy(&bits, &v, sizeof(T));
    slots[emu_cur->lane] = bits;
    emu_warp_barrier();
    bits = slots[emu_cur->lane ^ lane_mask];
    T r;
    std::memcpy(&r, &bits, sizeof(T));
    return r;
}

// Bit l set when lane l's predicate is true (every lane of the warp calls it).
inline unsigned __ballot_sync(unsigned, int pred) {
    const int buf = (int)(emu_cur->wgen & 1);
    uint64_t* slots = emu_warp_slots(buf);
    slots[emu_cur->lane] = pred ? 1 : 0;
    emu_warp_barrier();
    unsigned r = 0;
    for (int l = 0; l < 32; ++l)
        if (slots[l]) r |= 1u << l;
    return r;
}

inline int __ffs(int x) { return __builtin_ffs(x); }

inline long long clock64() { return 0; }

inline float __frcp_rn(float x) { return 1.0f / x; }

inline unsigned atomicMax(unsigned* p, unsigned v) {
    unsigned old = *p;
    if (v > old) *p = v;
    return old;
}
inline unsigned long long atomicMax(unsigned long long* p, unsigned long long v) {
    unsigned long long old = *p;
    if (v > old) *p = v;
    return old;
}
inline unsigned __float_as_uint(float x) {
    unsigned u;
    std::memcpy(&u, &x, 4);
    return u;
}
inline long long __double_as_longlong(double x) {
    long long u;
    std::memcpy(&u, &x, 8);
    return u;
}

inline int atomicAdd(int* p, int v) {
    int old = *p;
    *p = old + v;
    return old;
}
