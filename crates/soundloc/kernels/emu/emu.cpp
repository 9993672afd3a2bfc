// CPU emulator of the soundloc CUDA kernels (see emu.h). Built by
// scripts/build_cuda_emu.sh into libsoundloc_emu_l<LPP>_r<RPL>.so; the Rust backend loads
// it through `backend::cuda::new_emulated_backend` (tests only).
//
// C interface: emu_launch(name, grid, block, shared bytes, kernel parameters) runs the
// kernel to completion and returns 0, or -1 for an unknown name.
#include <ucontext.h>

#include <cstdio>
#include <cstdlib>
#include <functional>
#include <mutex>
#include <string>
#include <tuple>
#include <unordered_map>
#include <utility>
#include <vector>

#include "../correlate.cu"
#include "../decompose.cu"
#include "../eigh.cu"
#include "../count.cu"  // after eigh.cu: it uses tridiag.cuh's sturm_count
#include "../peaks.cu"
#include "../spectrum.cu"

EmuThreadState* emu_cur = nullptr;
emu_dim3 emu_block_idx, emu_block_dim, emu_grid_dim;

namespace {

constexpr size_t kStack = 256 * 1024;

struct Fiber {
    ucontext_t ctx;
    char* stack = nullptr;
    bool done = false;
    EmuThreadState st;
};

struct WarpState {
    int arrived = 0;
    int live = 0;
    unsigned long gen = 0;
    uint64_t slots[2][32];
};

struct BlockState {
    std::vector<Fiber> fibers;
    std::vector<WarpState> warps;
    int arrived = 0;
    int live = 0;
    unsigned long gen = 0;
    int or_acc[2] = {0, 0};
    int result[2] = {0, 0};
    std::vector<unsigned char> smem;
    const std::function<void()>* body = nullptr;
    ucontext_t sched;
};

BlockState g_block;
Fiber* g_fiber = nullptr;

void yield_to_scheduler() { swapcontext(&g_fiber->ctx, &g_block.sched); }

void complete_block_barrier() {
    const unsigned long g = g_block.gen;
    g_block.arrived = 0;
    g_block.result[g & 1] = g_block.or_acc[g & 1];
    g_block.or_acc[(g + 1) & 1] = 0;
    g_block.gen = g + 1;
}

void complete_warp_barrier(WarpState& w) {
    w.arrived = 0;
    w.gen += 1;
}

void fiber_main() {
    Fiber* f = g_fiber;
    (*g_block.body)();
    f->done = true;
    g_block.live -= 1;
    WarpState& w = g_block.warps[f->st.warp];
    w.live -= 1;
    if (g_block.arrived > 0 && g_block.arrived == g_block.live) complete_block_barrier();
    if (w.arrived > 0 && w.arrived == w.live) complete_warp_barrier(w);
    // Returning resumes uc_link (the scheduler).
}

using Binder = std::function<std::function<void()>(void**)>;

template <typename... A, size_t... I>
std::function<void()> bind_impl(void (*f)(A...), void** p, std::index_sequence<I...>) {
    std::tuple<A...> args(*reinterpret_cast<A*>(p[I])...);
    return [f, args]() { std::apply(f, args); };
}

template <typename... A>
Binder binder(void (*f)(A...)) {
    return [f](void** p) { return bind_impl(f, p, std::index_sequence_for<A...>{}); };
}

#define REG(name) {#name, binder(name)}

const std::unordered_map<std::string, Binder>& registry() {
    static const std::unordered_map<std::string, Binder> r = {
        REG(correlate_f32),    REG(correlate_f64),    REG(decompose_sn_f32), REG(decompose_sv_f32),
        REG(decompose_gn_f32), REG(decompose_gv_f32), REG(decompose_sn_f64), REG(decompose_sv_f64),
        REG(decompose_gn_f64), REG(decompose_gv_f64), REG(spectrum_f32),     REG(spectrum_f64),     REG(spectrum4_f32),    REG(spectrum4_f64),
        REG(peaks_f32),        REG(peaks_f64),        REG(eigh_f32),         REG(eigh_f64),     REG(eigh_narrow_f32), REG(eigh_narrow_f64),
        REG(form_h_f32),       REG(form_h_f64),       REG(correlate_phat_f32), REG(correlate_phat_f64), REG(coherence_f64),
        REG(count_sources),
    };
    return r;
}

void run_block(unsigned nthreads, size_t smem_bytes) {
    BlockState& B = g_block;
    B.fibers.resize(nthreads);
    const unsigned nwarps = (nthreads + 31) / 32;
    B.warps.assign(nwarps, WarpState{});
    for (unsigned w = 0; w < nwarps; ++w) B.warps[w].live = (int)std::min(32u, nthreads - 32 * w);
    B.arrived = 0;
    B.live = (int)nthreads;
    B.gen = 0;
    B.or_acc[0] = B.or_acc[1] = 0;
    B.smem.assign(smem_bytes + 16, 0xFF);
    for (unsigned t = 0; t < nthreads; ++t) {
        Fiber& f = B.fibers[t];
        if (!f.stack) f.stack = static_cast<char*>(std::malloc(kStack));
        f.done = false;
        f.st.tid = emu_dim3{t % emu_block_dim.x, (t / emu_block_dim.x) % emu_block_dim.y,
                            t / (emu_block_dim.x * emu_block_dim.y)};
        f.st.lane = (int)(t % 32);
        f.st.warp = (int)(t / 32);
        f.st.wgen = 0;
        getcontext(&f.ctx);
        f.ctx.uc_stack.ss_sp = f.stack;
        f.ctx.uc_stack.ss_size = kStack;
        f.ctx.uc_link = &B.sched;
        makecontext(&f.ctx, fiber_main, 0);
    }
    while (B.live > 0) {
        for (unsigned t = 0; t < nthreads; ++t) {
            Fiber& f = B.fibers[t];
            if (f.done) continue;
            g_fiber = &f;
            emu_cur = &f.st;
            swapcontext(&B.sched, &f.ctx);
        }
    }
}

}  // namespace

unsigned char* emu_dyn_smem() {
    uintptr_t p = reinterpret_cast<uintptr_t>(g_block.smem.data());
    p = (p + 15) & ~uintptr_t(15);
    return reinterpret_cast<unsigned char*>(p);
}

int emu_block_barrier(int v) {
    BlockState& B = g_block;
    const unsigned long g = B.gen;
    B.or_acc[g & 1] |= v;
    B.arrived += 1;
    if (B.arrived == B.live) {
        complete_block_barrier();
    } else {
        while (B.gen == g) yield_to_scheduler();
    }
    return B.result[g & 1];
}

void emu_warp_barrier() {
    WarpState& w = g_block.warps[emu_cur->warp];
    const unsigned long g = w.gen;
    w.arrived += 1;
    if (w.arrived == w.live) {
        complete_warp_barrier(w);
    } else {
        while (w.gen == g) yield_to_scheduler();
    }
    emu_cur->wgen += 1;
}

uint64_t* emu_warp_slots(int buf) { return g_block.warps[emu_cur->warp].slots[buf]; }

extern "C" int emu_launch(const char* name, unsigned gx, unsigned gy, unsigned gz, unsigned bx, unsigned by,
                          unsigned bz, unsigned smem, void** params) {
    // One launch at a time: the block state and `__shared__` statics are process-global.
    static std::mutex mu;
    std::lock_guard<std::mutex> lock(mu);
    const auto& r = registry();
    auto it = r.find(name);
    if (it == r.end()) return -1;
    const std::function<void()> body = it->second(params);
    emu_grid_dim = emu_dim3{gx, gy, gz};
    emu_block_dim = emu_dim3{bx, by, bz};
    g_block.body = &body;
    for (unsigned z = 0; z < gz; ++z)
        for (unsigned y = 0; y < gy; ++y)
            for (unsigned x = 0; x < gx; ++x) {
                emu_block_idx = emu_dim3{x, y, z};
                run_block(bx * by * bz, smem);
            }
    return 0;
}
