// A k-buffer query's rays and how a batch of them is run: one trace per active ray, the rays handed out in blocks to
// Dr.Jit's own worker threads (its nanothread pool): after a Dr.Jit kernel those workers spin for a while, and threads
// of our own would share the cores with them (measured: 2 threads of our own ran no faster than 1 inside a training
// step). Shared by the Embree k-buffer (kbuffer.cpp) and the shell BVH's host query (shellbvh.cpp). Host code only.
#pragma once

#include <nanothread/nanothread.h>

#include <algorithm>
#include <cstdint>

namespace glint_native {

// The rays of one query: which are active, and where each one's count goes (the entries themselves are written by
// the trace, which holds the query's other arrays).
struct RayBatch {
    int nrays;
    const uint8_t *active;
    uint32_t *out_count;
};

constexpr int BLOCK = 64;  // rays per work unit: small enough to balance dark and busy parts of an image

template <class Trace> struct Job {
    const RayBatch *w;
    const Trace *trace;
};

template <class Trace> void run_rays(const RayBatch &w, const Trace &trace, int r0, int r1) {
    for (int r = r0; r < r1; ++r)
        w.out_count[r] = w.active[r] ? (uint32_t) trace(r) : 0u;
}

template <class Trace> void run_block(uint32_t index, void *payload) {
    const Job<Trace> &job = *(const Job<Trace> *) payload;
    int r0 = (int) index * BLOCK;
    run_rays(*job.w, *job.trace, r0, std::min(job.w->nrays, r0 + BLOCK));
}

// trace(r) lists active ray r's entries and returns their count; an inactive ray's count is 0. nthreads <= 1: on the
// calling thread; else on the pool (its own size, Dr.Jit's thread count; nullptr: the default pool, the one its LLVM
// backend launches kernels on).
template <class Trace> void run(const RayBatch &w, const Trace &trace, int nthreads) {
    if (nthreads <= 1 || w.nrays <= BLOCK) {
        run_rays(w, trace, 0, w.nrays);
        return;
    }
    Job<Trace> job{&w, &trace};
    uint32_t blocks = (uint32_t) ((w.nrays + BLOCK - 1) / BLOCK);
    Task *task = task_submit_dep(nullptr, nullptr, 0, blocks, run_block<Trace>, &job, sizeof(job), nullptr, 1);
    task_wait_and_release(task);
}

}  // namespace glint_native
