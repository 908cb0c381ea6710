// glint k-buffer traversal: per ray, the K nearest bounding-shell entries of a Gaussian set in one BVH traversal.
//
// Mitsuba's ray_intersect_preliminary returns one hit per query, from the BVH root, and never reports a shell that
// holds the ray origin. Here the shells are Embree user geometry (Embree as shipped in the mitsuba wheel): the
// intersection callback records every shell entry after the last one composited into a sorted per-ray buffer of K
// and rejects it, so one traversal yields the next K entries in order; once the buffer is full the ray's tfar
// shrinks to the K-th entry and boxes beyond it are culled. A shell around the origin has its entry behind it
// (t < 0) and is listed first, so no walk back is needed. The ray/ellipsoid quadratic is solved in double. The shell,
// its quadratic and the buffer's insertion rule are shellbvh.h's, which our own BVH (shellbvh.cpp, and on a device
// shellbvh_cuda.cu) uses too: both list the same entries.
// Rays are handed out in blocks to Dr.Jit's own worker threads (raybatch.h).
// Built by `python -m glint_mi.native` (make does it); used by plugins/glint_integrator.py (traversal=kbuffer).
#include "shellbvh.h"

#include "raybatch.h"

#include <embree3/rtcore.h>
#include <cmath>
#include <cstdint>
#include <vector>
#include <algorithm>
#include <limits>

RTC_NAMESPACE_USE

namespace {

struct Prim {
    glint_bvh::Shell s;  // world -> unit sphere
    float lo[3], hi[3];
};

struct Set {
    RTCScene scene;
    RTCGeometry geom;
    std::vector<Prim> prims;
};

struct Ctx {
    RTCIntersectContext ctx;
    const Prim *prims;
    int K;
    int count;
    float *t;
    uint32_t *p;
    float t_prev;
    uint32_t p_prev;
    float tnear;
};

void bounds_fn(const RTCBoundsFunctionArguments *args) {
    const Set *set = (const Set *) args->geometryUserPtr;
    const Prim &q = set->prims[args->primID];
    RTCBounds *b = args->bounds_o;
    b->lower_x = q.lo[0]; b->lower_y = q.lo[1]; b->lower_z = q.lo[2];
    b->upper_x = q.hi[0]; b->upper_y = q.hi[1]; b->upper_z = q.hi[2];
}

void intersect_fn(const RTCIntersectFunctionNArguments *args) {
    if (!args->valid[0])
        return;
    Ctx *cx = (Ctx *) args->context;
    RTCRayHit *rh = (RTCRayHit *) args->rayhit;
    RTCRay &ray = rh->ray;
    const uint32_t pid = args->primID;
    const float o[3] = {ray.org_x, ray.org_y, ray.org_z}, d[3] = {ray.dir_x, ray.dir_y, ray.dir_z};
    float tn, tf;
    if (!glint_bvh::shell_entry(cx->prims[pid].s, o, d, tn, tf))
        return;
    const int K = cx->K;
    cx->count = glint_bvh::insert_entry(tn, tf, pid, cx->t_prev, cx->p_prev, K, cx->count, cx->t, cx->p);
    if (cx->count == K) {  // boxes entered beyond the K-th entry cannot hold a nearer one
        ray.tfar = std::max(cx->t[K - 1], std::nextafter(cx->tnear, std::numeric_limits<float>::infinity()));
        rh->hit.geomID = args->geomID;
        rh->hit.primID = pid;
    }
}

RTCDevice device() {  // one per process (a device per set rebuilt after every training push cost its set-up)
    static RTCDevice dev = rtcNewDevice("threads=1");
    return dev;
}

}  // namespace

extern "C" {

// The shells of n Gaussians into set->prims (their transforms and float32 boxes).
static void fill(Set *set, const float *data, int n, float extent) {
    set->prims.resize(n);
    for (int i = 0; i < n; ++i)
        glint_bvh::make_shell(data + 10 * (size_t) i, extent, set->prims[i].s, set->prims[i].lo, set->prims[i].hi);
}

// dynamic = 0: a BVH of medium quality, built once (rendering a trained model). dynamic = 1: a training set, whose
// Gaussians move a little every step: a two-level BVH of low quality whose primitives can be refitted in place
// (kb_refit, ~0.5 ms against ~6 ms for a build at 8.5k Gaussians; queries ~5 % slower).
void *kb_build(const float *data, int n, float extent, int dynamic) {
    Set *set = new Set();
    set->scene = rtcNewScene(device());
    fill(set, data, n, extent);
    RTCGeometry g = rtcNewGeometry(device(), RTC_GEOMETRY_TYPE_USER);
    rtcSetGeometryUserPrimitiveCount(g, n);
    rtcSetGeometryUserData(g, set);
    rtcSetGeometryBoundsFunction(g, bounds_fn, nullptr);
    rtcSetGeometryIntersectFunction(g, intersect_fn);
    if (dynamic)
        rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_REFIT);
    rtcCommitGeometry(g);
    rtcAttachGeometry(set->scene, g);
    set->geom = g;
    if (dynamic) {  // Embree reads a geometry's own quality only in the two-level (low quality) mode
        rtcSetSceneFlags(set->scene, RTC_SCENE_FLAG_DYNAMIC);
        rtcSetSceneBuildQuality(set->scene, RTC_BUILD_QUALITY_LOW);
    } else {
        rtcSetSceneBuildQuality(set->scene, RTC_BUILD_QUALITY_MEDIUM);
    }
    rtcCommitScene(set->scene);
    return set;
}

// New shells for the same n Gaussians of a dynamic set: the primitives are replaced and the BVH's boxes refitted
// (its tree kept). The lists a query returns do not depend on the tree, only how fast it finds them. Returns 0, or
// -1 (nothing changed) when n is not the set's size.
int kb_refit(void *h, const float *data, int n, float extent) {
    Set *set = (Set *) h;
    if ((size_t) n != set->prims.size())
        return -1;
    fill(set, data, n, extent);
    rtcCommitGeometry(set->geom);
    rtcCommitScene(set->scene);
    return 0;
}

void kb_free(void *h) {
    Set *set = (Set *) h;
    rtcReleaseGeometry(set->geom);
    rtcReleaseScene(set->scene);
    delete set;
}

}  // extern "C"

extern "C" {

// For each active ray: the K nearest shell entries (t, prim) after (t_prev, p_prev) among shells whose exit lies
// ahead of the origin (shells around the origin have t < 0). Sorted by (t, prim); count per ray.
void kb_query(void *h, int nrays, const float *o, const float *d, const float *t_prev, const uint32_t *p_prev,
              const uint8_t *active, int K, uint32_t *out_p, float *out_t, uint32_t *out_count, int nthreads) {
    const Set *set = (const Set *) h;
    const glint_native::RayBatch w{nrays, active, out_count};
    glint_native::run(w, [&](int r) {
        Ctx cx;
        rtcInitIntersectContext(&cx.ctx);
        cx.prims = set->prims.data();
        cx.K = K;
        cx.count = 0;
        cx.t = out_t + (size_t) r * K;
        cx.p = out_p + (size_t) r * K;
        cx.t_prev = t_prev[r];
        cx.p_prev = p_prev[r];
        RTCRayHit rh;
        rh.ray.org_x = o[3 * r]; rh.ray.org_y = o[3 * r + 1]; rh.ray.org_z = o[3 * r + 2];
        rh.ray.dir_x = d[3 * r]; rh.ray.dir_y = d[3 * r + 1]; rh.ray.dir_z = d[3 * r + 2];
        rh.ray.tnear = std::max(0.f, t_prev[r]);
        cx.tnear = rh.ray.tnear;
        rh.ray.tfar = std::numeric_limits<float>::infinity();
        rh.ray.mask = 0xFFFFFFFF;
        rh.ray.flags = 0;
        rh.ray.time = 0;
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(set->scene, &cx.ctx, &rh);
        return cx.count;
    }, nthreads);
}

}
