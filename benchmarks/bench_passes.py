"""Where each pass's time goes, on bench_integrator's glass scene (issue 11's <= 2.5x target).

On the same rays, one run, each pass of the forward (camera -> interface set; reflection set from x_I along the
mirror direction; transmission set from x_I along d) timed as it runs and as the traversal alone (the same shells
found, no kernel evaluated), for three traversals: the native k-buffer (the default where it is built), Mitsuba's
BVH queries with the walk back behind the origin (``traversal: bvh``), and without the walk back (inside_origins
off: Gaussians around the origin unseen); its hits per ray (Mitsuba's queries also count a shell reported twice at its entry) and the share of SIMD lanes busy (mean hits / mean over
packets of their slowest ray: a symbolic loop runs a packet until its last ray is done); and for Mitsuba's queries,
two orderings of the same rays: the camera rays shuffled (how much ray coherence is worth to its packet traversal)
and the reflection rays sorted by direction octant then Morton order of x_I (the best of the sortings tried). Every
timing is a median of 3 after a warm-up, ending with dr.sync_thread().

    .venv/bin/python benchmarks/bench_passes.py [--gaussians 10000] [--res 128x96]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_integrator as B  # noqa: E402  (sets the variant)

import drjit as dr  # noqa: E402
import mitsuba as mi  # noqa: E402

from glint_mi import native  # noqa: E402
from glint_mi.model.render import camera_rays  # noqa: E402


def _np3(v) -> np.ndarray:
    a = np.array(v)
    return a.T if a.ndim == 2 and a.shape[0] == 3 else a


def morton(x: np.ndarray, bits: int = 8) -> np.ndarray:
    """Interleaved-bit (Morton) code of points quantised to 2^bits per axis of their bounding box."""
    q = ((x - x.min(0)) / (np.ptp(x, 0) + 1e-9) * (2 ** bits - 1)).astype(np.uint64)
    code = np.zeros(len(x), np.uint64)
    for b in range(bits):
        for k in range(3):
            code |= ((q[:, k] >> np.uint64(b)) & np.uint64(1)) << np.uint64(3 * b + k)
    return code


def lane_efficiency(hits: np.ndarray, lanes: int) -> float:
    """Share of lanes busy when packets of ``lanes`` consecutive rays loop until their slowest ray is done."""
    h = np.asarray(hits, np.float64)
    h = np.concatenate([h, np.zeros((-len(h)) % lanes)]).reshape(-1, lanes)
    return float(h.sum() / max(h.max(axis=1).sum() * lanes, 1.0))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--gaussians", type=int, default=10000)
    ap.add_argument("--res", default="128x96")
    args = ap.parse_args()
    w, h = (int(v) for v in args.res.split("x"))
    sets = B.three_sets(args.gaussians)
    rows = []
    traversals = {"kbuffer": {"traversal": "kbuffer"}, "bvh": {"traversal": "bvh"},
                  "bvh, no walk back": {"traversal": "bvh", "inside_origins": False}}
    if native.why_not_here():  # not built, or a variant whose arrays are not in host memory (cuda)
        print(f"(no k-buffer rows: {native.why_not_here()})")
        traversals.pop("kbuffer")
    for label, props in traversals.items():
        scene = B.glint_scene(sets, (w, h), components="all", **props)
        integ, sensor = scene.integrator(), scene.sensors()[0]
        ray, _ = camera_rays(sensor, np.stack(np.unravel_index(np.arange(w * h), (h, w))[::-1], axis=1))
        o, d, active = mi.Point3f(ray.o) + 0.0 * ray.d, mi.Vector3f(ray.d), dr.full(mi.Bool, True, w * h)
        I = integ.march(integ.active_set("interface"), o, d, active)
        kd, ks, kt, do_r, do_t = integ._weights(I, d, active)
        x_i, d_r = integ._secondary(I, o, d)
        dr.eval(o, d, x_i, d_r, ks, kt, do_r, do_t)

        def timed(gs, o_, d_, a_, w_, **kw):
            times = []
            for _ in range(4):
                info = {}
                t = time.perf_counter()
                acc = integ.march(gs, o_, d_, a_, weight=w_, info=info, **kw)
                dr.eval(acc, info["hits"])
                dr.sync_thread()
                times.append(time.perf_counter() - t)
            return 1e3 * float(np.median(times[1:])), info["hits"]

        passes = {"camera": ("interface", o, d, active, None), "reflection": ("reflection", x_i, d_r, do_r, ks),
                  "transmission": ("transmission", x_i, d, do_t, kt)}
        for name, (role, o_, d_, a_, w_) in passes.items():
            gs = integ.active_set(role)
            ms, hits = timed(gs, o_, d_, a_, w_)
            trav, _ = timed(gs, o_, d_, a_, w_, budget=mi.UInt32(hits))
            hv, av = np.array(hits), np.array(a_).astype(bool)
            row = {"pass": name, "traversal": label, "ms": ms, "traversal_ms": trav,
                   "hits": float(hv[av].mean()), "lanes8": lane_efficiency(np.where(av, hv, 0), 8),
                   "lanes16": lane_efficiency(np.where(av, hv, 0), 16)}
            if label == "bvh" and name in ("camera", "reflection"):
                n = w * h
                if name == "camera":
                    perm, how = np.random.default_rng(0).permutation(n), "shuffled"
                else:
                    dn, xo = _np3(d_), _np3(o_)
                    octant = (dn[:, 0] > 0) * 4 + (dn[:, 1] > 0) * 2 + (dn[:, 2] > 0)
                    perm, how = np.lexsort((morton(xo), octant, ~av)), "sorted (octant, Morton of x_I)"
                pi = mi.UInt32(perm.astype(np.uint32))
                g = [dr.gather(type(v), v, pi) for v in (o_, d_, a_)]
                wg = None if w_ is None else dr.gather(mi.Float, w_, pi)
                dr.eval(g, wg)
                row["reordered"] = (how, timed(gs, *g, wg)[0])
            rows.append(row)
    print(f"\nbench_integrator's glass scene, {args.gaussians} Gaussians per set, {w}x{h} "
          f"(variant {mi.variant()})\n")
    print("| pass | traversal | ms | traversal only ms | hits / ray | lanes busy (8 / 16 wide) | same rays reordered |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        re = f"{r['reordered'][0]}: {r['reordered'][1]:.1f} ms" if "reordered" in r else ""
        print(f"| {r['pass']} | {r['traversal']} | {r['ms']:.1f} | {r['traversal_ms']:.1f} | "
              f"{r['hits']:.1f} | {r['lanes8']:.2f} / {r['lanes16']:.2f} | {re} |")
    print()
    for label in traversals:
        ms = {r["pass"]: r["ms"] for r in rows if r["traversal"] == label}
        print(f"{label}: sum of passes {sum(ms.values()):.1f} ms = {sum(ms.values()) / ms['camera']:.2f}x the camera pass")


if __name__ == "__main__":
    main()
