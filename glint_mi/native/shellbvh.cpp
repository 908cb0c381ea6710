// The host side of the shell BVH (shellbvh.h): build (binned SAH over the shells' boxes), refit, and the CPU query
// on Dr.Jit's thread pool. The same tree, as flat arrays (sb_export), is what a device traverses with the same
// header (shellbvh_cuda.cu).
#include "shellbvh.h"
#include "raybatch.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

using glint_bvh::Node;
using glint_bvh::Shell;

namespace {

constexpr int LEAF_MAX = 4;   // prims a leaf holds at most (a leaf test is one float64 quadratic a prim)
constexpr int BINS = 16;      // SAH bins per axis
constexpr int MAX_DEPTH = GLINT_BVH_STACK - 2;  // the traversal's stack holds one node a level

struct Bvh {
    std::vector<Shell> shells;      // in slot order (a leaf's shells together): slot j holds prim order[j]
    std::vector<float> lo, hi;      // [n, 3] boxes of the shells, by prim while building, then by slot
    std::vector<Node> nodes;
    std::vector<uint32_t> order;
    int depth = 0;
};

struct Box {
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    void grow(const float *l, const float *h) {
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], l[k]);
            hi[k] = std::max(hi[k], h[k]);
        }
    }
    void grow(const Box &b) { grow(b.lo, b.hi); }
    double area() const {
        if (!(hi[0] >= lo[0]))
            return 0.0;
        double x = hi[0] - lo[0], y = hi[1] - lo[1], z = hi[2] - lo[2];
        return x * y + y * z + z * x;
    }
};

int bin_of(float c, float c0, float scale) {  // a NaN centroid (a broken Gaussian, which no ray hits) goes to bin 0
    float f = (c - c0) * scale;
    return f >= 0.f ? std::min(BINS - 1, (int) f) : 0;
}

// The shells and boxes of n Gaussians: by prim (before a build: order empty), or by slot (a refit of a built tree).
void fill(Bvh &b, const float *data, int n, float extent) {
    b.shells.resize(n);
    b.lo.resize(3 * (size_t) n);
    b.hi.resize(3 * (size_t) n);
    const bool slots = b.order.size() == (size_t) n;
    for (int j = 0; j < n; ++j) {
        size_t i = slots ? b.order[j] : (size_t) j;
        glint_bvh::make_shell(data + 10 * i, extent, b.shells[j], &b.lo[3 * (size_t) j], &b.hi[3 * (size_t) j]);
    }
}

// Nodes [first, first + count) of order under node `at`; children are appended after it.
void build_node(Bvh &b, int at, int first, int count, int depth, std::vector<float> &cen) {
    b.depth = std::max(b.depth, depth);
    Box box, cbox;
    for (int i = first; i < first + count; ++i) {
        uint32_t p = b.order[i];
        box.grow(&b.lo[3 * (size_t) p], &b.hi[3 * (size_t) p]);
        cbox.grow(&cen[3 * (size_t) p], &cen[3 * (size_t) p]);
    }
    Node &nd = b.nodes[at];
    for (int k = 0; k < 3; ++k) {
        nd.lo[k] = box.lo[k];
        nd.hi[k] = box.hi[k];
    }
    if (count <= LEAF_MAX || depth >= MAX_DEPTH) {
        nd.index = first;
        nd.count = count;
        return;
    }
    // binned SAH over the centroids; the widest axis first, every axis tried
    double best = std::numeric_limits<double>::infinity();
    int best_axis = -1, best_bin = -1;
    for (int axis = 0; axis < 3; ++axis) {
        float c0 = cbox.lo[axis], c1 = cbox.hi[axis];
        if (!(c1 > c0))
            continue;
        Box bins[BINS];
        int cnt[BINS] = {0};
        float scale = BINS / (c1 - c0);
        for (int i = first; i < first + count; ++i) {
            uint32_t p = b.order[i];
            int k = bin_of(cen[3 * (size_t) p + axis], c0, scale);
            cnt[k]++;
            bins[k].grow(&b.lo[3 * (size_t) p], &b.hi[3 * (size_t) p]);
        }
        double right_area[BINS];
        int right_cnt[BINS];
        Box acc;
        int c = 0;
        for (int k = BINS - 1; k > 0; --k) {
            acc.grow(bins[k]);
            c += cnt[k];
            right_area[k] = acc.area();
            right_cnt[k] = c;
        }
        Box left;
        int lc = 0;
        for (int k = 0; k < BINS - 1; ++k) {
            left.grow(bins[k]);
            lc += cnt[k];
            if (lc == 0 || right_cnt[k + 1] == 0)
                continue;
            double cost = left.area() * lc + right_area[k + 1] * right_cnt[k + 1];
            if (cost < best) {
                best = cost;
                best_axis = axis;
                best_bin = k;
            }
        }
    }
    int mid;
    if (best_axis < 0) {  // every centroid in one point: split the range in two halves
        mid = first + count / 2;
    } else {
        float c0 = cbox.lo[best_axis], scale = BINS / (cbox.hi[best_axis] - c0);
        auto left_of = [&](uint32_t p) {
            return bin_of(cen[3 * (size_t) p + best_axis], c0, scale) <= best_bin;
        };
        mid = (int) (std::partition(b.order.begin() + first, b.order.begin() + first + count, left_of) -
                     b.order.begin());
        if (mid == first || mid == first + count)
            mid = first + count / 2;
    }
    int child = (int) b.nodes.size();
    b.nodes.resize(b.nodes.size() + 2);
    b.nodes[at].index = child;  // (nd may have moved with the resize)
    b.nodes[at].count = 0;
    build_node(b, child, first, mid - first, depth + 1, cen);
    build_node(b, child + 1, mid, first + count - mid, depth + 1, cen);
}

void build(Bvh &b) {
    int n = (int) b.shells.size();
    b.order.resize(n);
    for (int i = 0; i < n; ++i)
        b.order[i] = (uint32_t) i;
    std::vector<float> cen(3 * (size_t) n);
    for (size_t i = 0; i < cen.size(); ++i)
        cen[i] = 0.5f * (b.lo[i] + b.hi[i]);
    b.nodes.clear();
    b.nodes.reserve(2 * (size_t) std::max(n, 1));
    b.nodes.resize(1);
    b.depth = 0;
    if (n == 0) {  // an empty set: one node that sb_query never reads (it lists nothing without a traversal)
        Node &r = b.nodes[0];
        for (int k = 0; k < 3; ++k) {
            r.lo[k] = INFINITY;
            r.hi[k] = -INFINITY;
        }
        r.index = 0;
        r.count = 0;
        return;
    }
    build_node(b, 0, 0, n, 0, cen);
    std::vector<Shell> shells(n);  // into slot order: a leaf's shells together
    std::vector<float> lo(3 * (size_t) n), hi(3 * (size_t) n);
    for (int j = 0; j < n; ++j) {
        size_t i = b.order[j];
        shells[j] = b.shells[i];
        for (int k = 0; k < 3; ++k) {
            lo[3 * (size_t) j + k] = b.lo[3 * i + k];
            hi[3 * (size_t) j + k] = b.hi[3 * i + k];
        }
    }
    b.shells.swap(shells);
    b.lo.swap(lo);
    b.hi.swap(hi);
}

// New boxes for the same tree: children come after their parent, so walking the nodes backwards sees children first.
void refit(Bvh &b) {
    for (int i = (int) b.nodes.size() - 1; i >= 0; --i) {
        Node &nd = b.nodes[i];
        Box box;
        if (nd.count > 0) {
            for (int j = nd.index; j < nd.index + nd.count; ++j)
                box.grow(&b.lo[3 * (size_t) j], &b.hi[3 * (size_t) j]);
        } else if (b.shells.empty()) {
            continue;
        } else {  // an interior node
            const Node &l = b.nodes[nd.index], &r = b.nodes[nd.index + 1];
            box.grow(l.lo, l.hi);
            box.grow(r.lo, r.hi);
        }
        for (int k = 0; k < 3; ++k) {
            nd.lo[k] = box.lo[k];
            nd.hi[k] = box.hi[k];
        }
    }
}

}  // namespace

extern "C" {

// A BVH over the shells of n Gaussians (data [n, 10] as the ellipsoids shape holds it).
void *sb_build(const float *data, int n, float extent) {
    Bvh *b = new Bvh();
    fill(*b, data, n, extent);  // by prim (no order yet); build() puts them in slot order
    build(*b);
    return b;
}

// New shells for the same n Gaussians: the tree is kept, its boxes refitted. 0, or -1 (nothing changed) when n is
// not the set's size.
int sb_refit(void *h, const float *data, int n, float extent) {
    Bvh *b = (Bvh *) h;
    if ((size_t) n != b->shells.size())
        return -1;
    fill(*b, data, n, extent);
    refit(*b);
    return 0;
}

void sb_free(void *h) { delete (Bvh *) h; }

// Sizes of the flat arrays: nodes (each 32 bytes), order (n uint32), shells (n x 12 float64), and the tree's depth.
void sb_sizes(void *h, int64_t *out) {
    const Bvh *b = (const Bvh *) h;
    out[0] = (int64_t) b->nodes.size();
    out[1] = (int64_t) b->order.size();
    out[2] = (int64_t) b->shells.size();
    out[3] = b->depth;
}

// Copies of the flat arrays (for a device): nodes [sizes[0] x 32 bytes], order, shells [n x 12 float64] by slot.
void sb_export(void *h, void *nodes, uint32_t *order, double *shells) {
    const Bvh *b = (const Bvh *) h;
    std::memcpy(nodes, b->nodes.data(), b->nodes.size() * sizeof(Node));
    std::memcpy(order, b->order.data(), b->order.size() * sizeof(uint32_t));
    std::memcpy(shells, b->shells.data(), b->shells.size() * sizeof(Shell));
}

// As kb_query (kbuffer.cpp): per active ray the next K shell entries after (t_prev, p_prev), sorted by (t, prim).
void sb_query(void *h, int nrays, const float *o, const float *d, const float *t_prev, const uint32_t *p_prev,
              const uint8_t *active, int K, uint32_t *out_p, float *out_t, uint32_t *out_count, int nthreads) {
    const Bvh *b = (const Bvh *) h;
    if (b->shells.empty()) {  // (its one node is no tree to walk)
        std::memset(out_count, 0, sizeof(uint32_t) * (size_t) nrays);
        return;
    }
    const glint_native::RayBatch w{nrays, active, out_count};
    glint_native::run(w, [&](int r) {
        return glint_bvh::trace(b->nodes.data(), b->order.data(), b->shells.data(), o + 3 * (size_t) r,
                                d + 3 * (size_t) r, t_prev[r], p_prev[r], K, out_t + (size_t) r * K,
                                out_p + (size_t) r * K);
    }, nthreads);
}

}  // extern "C"
