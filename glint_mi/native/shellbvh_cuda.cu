// The shell BVH's k-buffer query on a CUDA device: one thread a ray, the traversal of shellbvh.h (the code the CPU
// runs in shellbvh.cpp, tested there against Embree). Compiled at run time with NVRTC by glint_mi.native.cuda (CuPy),
// or by nvcc for a check (tests/test_shellbvh.py). A ray's list is gathered in registers / local memory
// (K <= GLINT_CUDA_K) and written once.
#include "shellbvh.h"

#define GLINT_CUDA_K 32

extern "C" __global__ void glint_shell_query(const glint_bvh::Node *nodes, const uint32_t *order,
                                             const glint_bvh::Shell *shells, int nrays, const float *o,
                                             const float *d, const float *t_prev, const uint32_t *p_prev,
                                             const unsigned char *active, int K, uint32_t *out_p, float *out_t,
                                             uint32_t *out_count) {
    int r = blockIdx.x * blockDim.x + threadIdx.x;
    if (r >= nrays)
        return;
    if (!active[r] || K < 1 || K > GLINT_CUDA_K) {
        out_count[r] = 0;
        return;
    }
    float t[GLINT_CUDA_K];
    uint32_t p[GLINT_CUDA_K];
    const float oo[3] = {o[3 * r], o[3 * r + 1], o[3 * r + 2]}, dd[3] = {d[3 * r], d[3 * r + 1], d[3 * r + 2]};
    int c = glint_bvh::trace(nodes, order, shells, oo, dd, t_prev[r], p_prev[r], K, t, p);
    for (int i = 0; i < c; ++i) {
        out_t[(size_t) r * K + i] = t[i];
        out_p[(size_t) r * K + i] = p[i];
    }
    out_count[r] = (uint32_t) c;
}

// Refit on the device: new shells and boxes for the same Gaussians (data [n, 10], by prim) into their slots, then
// the nodes bottom-up, one launch a level from the deepest (the host lists each level's node ids).
extern "C" __global__ void glint_shell_fill(const float *data, const uint32_t *order, int n, float extent,
                                            glint_bvh::Shell *shells, float *lo, float *hi) {
    int j = blockIdx.x * blockDim.x + threadIdx.x;
    if (j >= n)
        return;
    glint_bvh::make_shell(data + 10 * (size_t) order[j], extent, shells[j], lo + 3 * (size_t) j, hi + 3 * (size_t) j);
}

extern "C" __global__ void glint_shell_refit_level(glint_bvh::Node *nodes, const float *lo, const float *hi,
                                                   const int *ids, int count) {
    int j = blockIdx.x * blockDim.x + threadIdx.x;
    if (j >= count)
        return;
    glint_bvh::Node &nd = nodes[ids[j]];
    float l[3] = {INFINITY, INFINITY, INFINITY}, h[3] = {-INFINITY, -INFINITY, -INFINITY};
    if (nd.count > 0) {
        for (int j = nd.index; j < nd.index + nd.count; ++j) {  // the leaf's slots
            for (int k = 0; k < 3; ++k) {
                l[k] = fminf(l[k], lo[3 * (size_t) j + k]);
                h[k] = fmaxf(h[k], hi[3 * (size_t) j + k]);
            }
        }
    } else {
        const glint_bvh::Node &a = nodes[nd.index], &b = nodes[nd.index + 1];
        for (int k = 0; k < 3; ++k) {
            l[k] = fminf(a.lo[k], b.lo[k]);
            h[k] = fmaxf(a.hi[k], b.hi[k]);
        }
    }
    for (int k = 0; k < 3; ++k) {
        nd.lo[k] = l[k];
        nd.hi[k] = h[k];
    }
}
