// soundloc CUDA kernels: shared definitions.
//
// Compiled at run time by NVRTC (no CUDA headers needed: only builtins are used), with
// the layout variant passed as -D macros (see backend/cuda/kernels.rs):
//   SL_LPP  lanes that share one column pair in the Jacobi kernel (4, 8 or 16)
//   SL_RPL  rows each of those lanes holds in registers (4, 8 or 16; exact on the device)
//   SL_NFIX the Jacobi's row count n = M rounded up to even (device builds only)
// The same sources also build, with -DSOUNDLOC_EMU, into a CPU emulator library
// (kernels/emu/) that the parity tests use where no GPU is present.
//
// Complex numbers are {re, im} pairs, layout-compatible with num_complex::Complex<T>.
// Every kernel is a template over T (float or double) with extern "C" wrappers
// name_f32 / name_f64.
#pragma once

#ifdef SOUNDLOC_EMU
#include "emu/emu.h"
#define SL_DYN_SMEM(name) unsigned char* name = emu_dyn_smem()
#else
#define SL_DYN_SMEM(name) extern __shared__ __align__(16) unsigned char name[]
#endif

#ifndef SL_LPP
#define SL_LPP 4
#endif
#ifndef SL_RPL
#define SL_RPL 16
#endif

// Largest even column count the Jacobi variant holds in registers.
#define SL_MAXN (SL_LPP * SL_RPL)
// Rows (or columns) per lane when one warp spans a whole column of at most SL_MAXN.
#define SL_R32 ((SL_MAXN + 31) / 32)

template <typename T>
struct __align__(2 * sizeof(T)) cplx {
    T re, im;
};

template <typename T>
__device__ __forceinline__ cplx<T> cx(T re, T im) {
    cplx<T> z;
    z.re = re;
    z.im = im;
    return z;
}

template <typename T>
__device__ __forceinline__ cplx<T> czero() {
    return cx<T>((T)0, (T)0);
}

template <typename T>
__device__ __forceinline__ cplx<T> cadd(cplx<T> a, cplx<T> b) {
    return cx<T>(a.re + b.re, a.im + b.im);
}

template <typename T>
__device__ __forceinline__ cplx<T> cconj(cplx<T> a) {
    return cx<T>(a.re, -a.im);
}

// A complex number in another precision.
template <typename T, typename S>
__device__ __forceinline__ cplx<T> cto(cplx<S> a) {
    return cx<T>((T)a.re, (T)a.im);
}

// sl_if<B, A, C>::type is A when B, else C (no <type_traits> under NVRTC).
template <bool B, typename A, typename C>
struct sl_if {
    typedef A type;
};
template <typename A, typename C>
struct sl_if<false, A, C> {
    typedef C type;
};

template <typename T>
__device__ __forceinline__ cplx<T> cscale(cplx<T> a, T s) {
    return cx<T>(a.re * s, a.im * s);
}

// acc += a * b
template <typename T>
__device__ __forceinline__ void cmac(cplx<T>& acc, cplx<T> a, cplx<T> b) {
    acc.re += a.re * b.re - a.im * b.im;
    acc.im += a.re * b.im + a.im * b.re;
}

// acc += conj(a) * b
template <typename T>
__device__ __forceinline__ void cmacc(cplx<T>& acc, cplx<T> a, cplx<T> b) {
    acc.re += a.re * b.re + a.im * b.im;
    acc.im += a.re * b.im - a.im * b.re;
}

__device__ __forceinline__ float sl_fma(float a, float b, float c) { return fmaf(a, b, c); }
__device__ __forceinline__ double sl_fma(double a, double b, double c) { return fma(a, b, c); }

// acc += conj(a) * b as four fused multiply-adds, in a fixed order (cmacc's form
// compiles to a multiply, a fused multiply-add and an add per component: three
// instructions where two do, with one rounding less). The spectrum's inner loops, which
// are bound by instruction issue (docs/gpu.md, 2026-11-27 fourth session).
template <typename T>
__device__ __forceinline__ void cmacc_fma(cplx<T>& acc, cplx<T> a, cplx<T> b) {
    acc.re = sl_fma(a.re, b.re, acc.re);
    acc.re = sl_fma(a.im, b.im, acc.re);
    acc.im = sl_fma(a.re, b.im, acc.im);
    acc.im = sl_fma(-a.im, b.re, acc.im);
}

// acc += a * b as four fused multiply-adds (see cmacc_fma).
template <typename T>
__device__ __forceinline__ void cmac_fma(cplx<T>& acc, cplx<T> a, cplx<T> b) {
    acc.re = sl_fma(a.re, b.re, acc.re);
    acc.re = sl_fma(-a.im, b.im, acc.re);
    acc.im = sl_fma(a.re, b.im, acc.im);
    acc.im = sl_fma(a.im, b.re, acc.im);
}

// acc += a * conj(b)
template <typename T>
__device__ __forceinline__ void cmac_cb(cplx<T>& acc, cplx<T> a, cplx<T> b) {
    acc.re += a.re * b.re + a.im * b.im;
    acc.im += a.im * b.re - a.re * b.im;
}

template <typename T>
__device__ __forceinline__ T cnorm2(cplx<T> a) {
    return a.re * a.re + a.im * a.im;
}

__device__ __forceinline__ float sl_sqrt(float x) { return sqrtf(x); }
__device__ __forceinline__ double sl_sqrt(double x) { return sqrt(x); }
__device__ __forceinline__ float sl_abs(float x) { return fabsf(x); }
__device__ __forceinline__ double sl_abs(double x) { return fabs(x); }
__device__ __forceinline__ float sl_max(float a, float b) { return a > b ? a : b; }
__device__ __forceinline__ double sl_max(double a, double b) { return a > b ? a : b; }

// *p = max(*p, v) for v ≥ 0 and *p ≥ 0 (non-negative IEEE values order as their bits).
__device__ __forceinline__ void atomic_max_pos(float* p, float v) {
    atomicMax(reinterpret_cast<unsigned int*>(p), __float_as_uint(v));
}
__device__ __forceinline__ void atomic_max_pos(double* p, double v) {
    atomicMax(reinterpret_cast<unsigned long long*>(p), (unsigned long long)__double_as_longlong(v));
}

template <typename T>
struct sl_eps;
template <>
struct sl_eps<float> {
    static __device__ __forceinline__ float v() { return 1.1920928955078125e-7f; }
};
template <>
struct sl_eps<double> {
    static __device__ __forceinline__ double v() { return 2.220446049250313e-16; }
};

// Warp-level sum over groups of G consecutive lanes (G a power of two, at most 32).
// Every lane of the warp must call it.
template <int G, typename T>
__device__ __forceinline__ T group_sum(T v) {
#pragma unroll
    for (int off = 1; off < G; off <<= 1) v += __shfl_xor_sync(0xffffffffu, v, off);
    return v;
}

// Block-wide sum (all threads call it; blockDim.x a multiple of 32, at most 1024).
// `red` is shared scratch of at least 32 values. Returns the sum to every thread.
template <typename T>
__device__ T block_sum(T v, T* red) {
    const int lane = threadIdx.x & 31, warp = threadIdx.x >> 5, nw = blockDim.x >> 5;
    v = group_sum<32>(v);
    __syncthreads();
    if (lane == 0) red[warp] = v;
    __syncthreads();
    T s = (T)0;
    for (int i = 0; i < nw; ++i) s += red[i];
    return s;
}

// Block-wide max of non-negative values (same contract as block_sum).
template <typename T>
__device__ T block_max(T v, T* red) {
    const int lane = threadIdx.x & 31, warp = threadIdx.x >> 5, nw = blockDim.x >> 5;
#pragma unroll
    for (int off = 1; off < 32; off <<= 1) v = sl_max(v, __shfl_xor_sync(0xffffffffu, v, off));
    __syncthreads();
    if (lane == 0) red[warp] = v;
    __syncthreads();
    T s = (T)0;
    for (int i = 0; i < nw; ++i) s = sl_max(s, red[i]);
    return s;
}

// One peak candidate as copied back to the host (16 bytes).
struct PeakOut {
    double db;
    int dir;
    int pad;
};
