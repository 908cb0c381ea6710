"""Which depth a method reports for a pixel (its evaluation and meshing depth), as each baseline's release renders it.

- ``expected``: sum_i w_i z_i / sum_i w_i, the interface's alpha-weighted depth (GLINT, 3DGS, PGSR here, EnvGS).
- ``median``: 2DGS with ``depth_ratio 1`` (its Tanks and Temples and DTU setting): the depth of the last Gaussian
  composited while the transmittance is above 0.5; where it never falls to 0.5 the expected depth is kept (2DGS keeps
  the last Gaussian's; such pixels hold less than half an opaque surface).
- ``first_surface``: TSGS's depth (``render_depth`` of its release, with its defaults). A pixel its transparency mask
  calls opaque (mask <= 0.5) takes the median rule above; a transparent pixel takes the densest depth window: the
  composited Gaussians sorted by depth, only those within the first ``end`` (0.2) of accumulated weight, every run of
  them spanning at most ``window`` (0.03, in metres here) in depth, and the run of largest weight gives its
  weighted mean depth. A pixel whose final transmittance is above 0.98 has depth 0 (background).
"""
from __future__ import annotations

import numpy as np

RULES = ("expected", "median", "first_surface")
TSGS = dict(window=0.03, start=0.0, end=0.2, observe_t=0.5, bg_t=0.98, binary=0.5)


def interface_hits(integ, ray, forward, hit_list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per ray, the interface pass's composited Gaussians in order: (alpha [n, K], planar depth [n, K], count [n]),
    from the pass's stored hit list (``trace(..., record=True)["hit_lists"][0]``), each kernel evaluated again exactly
    as the pass evaluated it."""
    import drjit as dr
    import mitsuba as mi

    listed, count = hit_list
    count = np.array(count, np.int64)
    n, k = len(count), integ.max_hits
    rows, cols = np.nonzero(np.arange(k)[None, :] < count[:, None])
    alpha, depth = np.zeros((n, k)), np.zeros((n, k))
    if len(rows):
        prims = np.array(listed, np.uint32).reshape(n, k)[rows, cols]
        r = mi.UInt32(rows.astype(np.uint32))
        o = dr.gather(mi.Point3f, mi.Point3f(ray.o), r)
        d = dr.gather(mi.Vector3f, mi.Vector3f(ray.d), r)
        fwd = mi.Vector3f(forward) if dr.width(forward) == 1 else dr.gather(mi.Vector3f, mi.Vector3f(forward), r)
        with dr.suspend_grad():
            a, t, *_ = integ._eval_kernel(integ.active_set("interface"), mi.UInt32(prims), o, d, mi.Bool(True))
            z = t * dr.dot(d, fwd)
            dr.eval(a, z)
        alpha[rows, cols], depth[rows, cols] = np.array(a, np.float64), np.array(z, np.float64)
    return alpha, depth, count


def _median(alpha, depth, observe_t):
    """Depth of the last hit composited while T > observe_t, and whether T fell to observe_t (per ray)."""
    T_before = np.cumprod(np.c_[np.ones(len(alpha)), 1.0 - alpha[:, :-1]], axis=1)
    seen = (T_before > observe_t) & (alpha > 0)
    last = np.where(seen.any(1), seen.shape[1] - 1 - np.argmax(seen[:, ::-1], axis=1), -1)
    med = np.where(last >= 0, depth[np.arange(len(depth)), np.maximum(last, 0)], 0.0)
    return med, np.prod(1.0 - alpha, axis=1) <= observe_t


def median_depth(median_distance, z, expected) -> np.ndarray:
    """2DGS's median depth (depth_ratio 1) per ray from the interface pass's median composite (the distance where T
    falls to 0.5, 0 where it never does) and each ray's planar factor ``z``; the expected depth where T never falls."""
    return np.where(median_distance > 0, median_distance * z, expected)


def first_surface_depth(alpha, depth, transparent, window=0.03, start=0.0, end=0.2, observe_t=0.5, bg_t=0.98,
                        binary=0.5) -> np.ndarray:
    """TSGS's first-surface depth per ray (see the module docstring); ``transparent`` = its mask in [0, 1]."""
    med, _ = _median(alpha, depth, observe_t)
    T_before = np.cumprod(np.c_[np.ones(len(alpha)), 1.0 - alpha[:, :-1]], axis=1)
    w = alpha * T_before
    out = med.copy()
    for r in np.nonzero(np.asarray(transparent) > binary)[0]:
        keep = alpha[r] > 0
        d, wr = depth[r][keep], w[r][keep]
        if not len(d):
            out[r] = 0.0
            continue
        order = np.argsort(d, kind="stable")
        d, wr = d[order], wr[order]
        acc = np.r_[0.0, np.cumsum(wr)]
        above = np.nonzero(acc[1:] > start)[0]
        if not len(above):
            out[r] = 0.0
            continue
        lo = above[0]
        past = np.nonzero(acc[1:] > end)[0]
        hi = past[0] if len(past) else len(d) - 1
        best, best_w = lo, -1.0
        for s in range(lo, hi + 1):
            e = s + int(np.searchsorted(d[s:hi + 1], d[s] + window, side="right")) - 1
            ws = acc[e + 1] - acc[s]
            if ws > best_w:
                best, best_w, best_e = s, ws, e
        out[r] = float(np.sum(d[best:best_e + 1] * wr[best:best_e + 1]) / max(best_w, 1e-30))
    out[np.prod(1.0 - alpha, axis=1) > bg_t] = 0.0
    return out
