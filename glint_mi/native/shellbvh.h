// glint shell BVH: the k-buffer traversal written once, for the host C++ compiler and for CUDA (nvcc or NVRTC).
//
// Per ray, one traversal lists the next K bounding-shell entries of a Gaussian set after (t_prev, p_prev), sorted by
// (t, prim), shells that hold the origin first (their entry lies behind it, t < 0); once the buffer is full, the far
// limit shrinks to the K-th entry and boxes beyond it are culled. The same semantics, the same float64 shell
// arithmetic and so the same lists as the Embree k-buffer of kbuffer.cpp (which calls shell_entry below), on a BVH
// of our own: flat nodes, children stored after their parent (a refit walks the nodes backwards), leaves holding a
// range of slots (the shells stored in the tree's order, `order` giving each slot's prim id). The tree is built on
// the host (sb_build in shellbvh.cpp); only the nodes, the order and the shells travel to a device, and the lists it returns do not depend on the tree, only how fast
// they are found.
//
// Device code here: no std::, no recursion, no allocation; a fixed stack of GLINT_BVH_STACK nodes (the build caps
// the depth below it).
#pragma once

#if defined(__CUDACC__)
#define GLINT_HD __host__ __device__ __forceinline__
#else
#define GLINT_HD inline
#endif

#if defined(__CUDACC_RTC__)  // NVRTC: no system headers (its math functions are built in)
typedef unsigned int uint32_t;
typedef int int32_t;
#ifndef INFINITY
#define INFINITY __int_as_float(0x7f800000)
#endif
#else
#include <stdint.h>
#include <math.h>
#endif

#define GLINT_BVH_STACK 64

namespace glint_bvh {

struct Shell {          // one Gaussian's bounding shell: world -> unit sphere is m (c - x)
    double c[3];
    double m[9];        // rows of R^T / s
};

struct Node {           // 32 bytes
    float lo[3];
    int32_t index;      // interior: its first child (the second is index + 1); leaf: its first slot in `order`
    float hi[3];
    int32_t count;      // 0: interior; > 0: a leaf of `count` prims
};

// Shell and float32 box of one Gaussian from its 10 floats (centre, shell scales / extent, x y z w quaternion).
GLINT_HD void make_shell(const float *e, float extent, Shell &q, float lo[3], float hi[3]) {
    double x = e[6], y = e[7], z = e[8], w = e[9];
    double nq = sqrt(x * x + y * y + z * z + w * w);
    if (nq > 1e-12) { x /= nq; y /= nq; z /= nq; w /= nq; } else { x = y = z = 0; w = 1; }
    double R[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)},
                      {2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)},
                      {2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)}};
    double s[3];
    for (int k = 0; k < 3; ++k) {
        double v = (double) e[3 + k] * extent;
        s[k] = v > 1e-30 ? v : 1e-30;
    }
    for (int k = 0; k < 3; ++k) {
        q.c[k] = e[k];
        for (int j = 0; j < 3; ++j)
            q.m[3 * k + j] = R[j][k] / s[k];  // (R^T)[k][j] / s[k]
        double h = sqrt(R[k][0] * R[k][0] * s[0] * s[0] + R[k][1] * R[k][1] * s[1] * s[1] +
                        R[k][2] * R[k][2] * s[2] * s[2]);
        h = h * (1.0 + 1e-5) + 1e-6 * (1.0 + fabs((double) e[k]));  // float32 boxes hold the shell
        lo[k] = (float) (e[k] - h);
        hi[k] = (float) (e[k] + h);
    }
}

// Entry and exit of a ray at a shell, in float64 then rounded; false when it misses (or the shell is degenerate).
GLINT_HD bool shell_entry(const Shell &q, const float o[3], const float d[3], float &tn, float &tf) {
    double oc[3] = {(double) o[0] - q.c[0], (double) o[1] - q.c[1], (double) o[2] - q.c[2]};
    double dv[3] = {d[0], d[1], d[2]};
    double ol[3], dl[3];
    for (int r = 0; r < 3; ++r) {
        ol[r] = q.m[3 * r] * oc[0] + q.m[3 * r + 1] * oc[1] + q.m[3 * r + 2] * oc[2];
        dl[r] = q.m[3 * r] * dv[0] + q.m[3 * r + 1] * dv[1] + q.m[3 * r + 2] * dv[2];
    }
    double a = dl[0] * dl[0] + dl[1] * dl[1] + dl[2] * dl[2];
    double b = ol[0] * dl[0] + ol[1] * dl[1] + ol[2] * dl[2];
    // b^2 - a c without the cancellation of a distant origin: a (1 - |ol - (b / a) dl|^2)
    double pc[3] = {ol[0] - b / a * dl[0], ol[1] - b / a * dl[1], ol[2] - b / a * dl[2]};
    double disc = a * (1.0 - (pc[0] * pc[0] + pc[1] * pc[1] + pc[2] * pc[2]));
    if (!(disc > 0.0) || !(a > 0.0))
        return false;
    double sq = sqrt(disc);
    tn = (float) ((-b - sq) / a);
    tf = (float) ((-b + sq) / a);
    return true;
}

// The k-buffer's rule for one shell entry (tn, tf) of prim `pid`: kept when its exit lies ahead of the origin and it
// comes after (t_prev, p_prev); inserted in (t, prim) order into t[0..count), the K-th dropped. Returns the count.
GLINT_HD int insert_entry(float tn, float tf, uint32_t pid, float t_prev, uint32_t p_prev, int K, int count,
                          float *t, uint32_t *p) {
    if (!(tf > 0.f))
        return count;
    if (!(tn > t_prev || (tn == t_prev && pid > p_prev)))
        return count;
    if (count == K && !(tn < t[K - 1] || (tn == t[K - 1] && pid < p[K - 1])))
        return count;
    int i = count < K ? count++ : K - 1;
    while (i > 0 && (t[i - 1] > tn || (t[i - 1] == tn && p[i - 1] > pid))) {
        t[i] = t[i - 1];
        p[i] = p[i - 1];
        --i;
    }
    t[i] = tn;
    p[i] = pid;
    return count;
}

// Slab test of a ray (origin o, 1 / direction inv, every component finite) against a box over [t0, t1]: the entry,
// or +inf when it misses. A direction component of 0 has inv = +-1e30: a ray in a face's plane keeps the box.
GLINT_HD float box_entry(const Node &n, const float o[3], const float inv[3], float t0, float t1) {
    for (int k = 0; k < 3; ++k) {
        float a = (n.lo[k] - o[k]) * inv[k], b = (n.hi[k] - o[k]) * inv[k];
        float lo = a < b ? a : b, hi = a < b ? b : a;  // (compiled to min/max instructions; a NaN is ignored)
        t0 = lo > t0 ? lo : t0;
        t1 = hi < t1 ? hi : t1;
    }
    // float rounding of the slab products: a margin of a few ulps (t0 >= 0 here; boxes hold their shells with one)
    return t0 <= t1 * (1.0f + 1e-6f) ? t0 : INFINITY;
}

// One ray: the next (up to) K entries after (t_prev, p_prev) into t, p; returns their count. Leaves hold slots of
// `shells` (stored in the tree's order, so a leaf's shells lie together); `order` maps a slot to its prim id.
GLINT_HD int trace(const Node *nodes, const uint32_t *order, const Shell *shells, const float o[3], const float d[3],
                   float t_prev, uint32_t p_prev, int K, float *t, uint32_t *p) {
    float inv[3];
    for (int k = 0; k < 3; ++k) {
        float a = d[k];
        float m = a < 0 ? -a : a;
        inv[k] = (a < 0 ? -1.0f : 1.0f) / (m > 1e-30f ? m : 1e-30f);
    }
    const float tnear = t_prev > 0.f ? t_prev : 0.f;
    const float after = nextafterf(tnear, INFINITY);
    float tfar = INFINITY;
    int count = 0;
    int stack[GLINT_BVH_STACK];
    float stack_t[GLINT_BVH_STACK];  // the box entry a node was pushed with (the far limit only shrinks)
    int sp = 0;
    if (box_entry(nodes[0], o, inv, tnear, tfar) == INFINITY)
        return 0;
    int node = 0;
    while (true) {
        const Node &nd = nodes[node];
        if (nd.count > 0) {
            for (int j = nd.index; j < nd.index + nd.count; ++j) {
                float tn, tf;
                if (shell_entry(shells[j], o, d, tn, tf)) {
                    count = insert_entry(tn, tf, order[j], t_prev, p_prev, K, count, t, p);
                    if (count == K)  // boxes entered beyond the K-th entry cannot hold a nearer one
                        tfar = t[K - 1] > after ? t[K - 1] : after;
                }
            }
        } else {
            int a = nd.index, b = nd.index + 1;
            float ta = box_entry(nodes[a], o, inv, tnear, tfar), tb = box_entry(nodes[b], o, inv, tnear, tfar);
            if (tb < ta) {
                int s = a; a = b; b = s;
                float u = ta; ta = tb; tb = u;
            }
            if (ta != INFINITY) {
                if (tb != INFINITY && sp < GLINT_BVH_STACK) {
                    stack[sp] = b;
                    stack_t[sp++] = tb;
                }
                node = a;
                continue;
            }
        }
        // pop the next box still in front of the far limit (it may have shrunk since the box was pushed)
        node = -1;
        while (sp > 0) {
            --sp;
            if (stack_t[sp] <= tfar * (1.0f + 1e-6f)) {
                node = stack[sp];
                break;
            }
        }
        if (node < 0)
            return count;
    }
}

}  // namespace glint_bvh
