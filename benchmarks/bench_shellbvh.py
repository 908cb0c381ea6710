"""The k-buffer traversal's engines side by side, on the same shells and rays (issue 65): Embree's (``kbuffer``, the
CPU default), the shell BVH on the host (``shellbvh`` under LLVM: the code a device runs) and, where CuPy and a CUDA
device are present, the shell BVH on the device. Per set size: build and refit ms, then for each buffer size K the
first round's query (every ray's next K entries) in ms and million rays/s, entries listed a ray, and whether the lists
equal Embree's (prims, t and counts; the device's are copied back to compare).

Shells: the display case's three sets (``scenes/display_case``) replicated with jitter to the size asked, or random
sets; rays: a camera's view of them at --res.

    .venv/bin/python benchmarks/bench_shellbvh.py [--sizes 10000,100000,200000] [--res 480x270] [--k 16,32]
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from glint_mi import native
from glint_mi.native import cuda

ROOT = Path(__file__).resolve().parents[1]
NO = 0xFFFFFFFF


def shells(n: int, seed: int = 0):
    """n shells like a trained room's: the display case's Gaussians, replicated with jitter (or random if absent)."""
    from glint_mi.model.gaussians import SHELL_EXTENT, GaussianSet
    rng = np.random.default_rng(seed)
    parts = []
    for name in ("interface", "reflection", "transmission"):
        path = ROOT / "scenes" / "display_case" / f"{name}.ply"
        if path.exists():
            parts.append(GaussianSet.load_ply(path).to_mitsuba()["data"])
    base = np.concatenate(parts) if parts else None
    if base is None:
        base = np.zeros((1000, 10), np.float32)
        base[:, :3], base[:, 3:6] = rng.uniform(-1, 1, (1000, 3)), rng.uniform(0.02, 0.1, (1000, 3))
        base[:, 6:10] = Rotation.random(1000, random_state=seed).as_quat()
    idx = rng.integers(0, len(base), n)
    data = base[idx].copy()
    span = data[:, :3].max(0) - data[:, :3].min(0)
    data[:, :3] += rng.normal(0, 0.01, (n, 3)) * span
    data[:, 3:6] *= np.sqrt(len(base) / n) if n > len(base) else 1.0  # keep the depth complexity of the base
    return data.astype(np.float32), SHELL_EXTENT


def rays(data, w: int, h: int):
    """A pinhole camera 2.5 scene sizes away looking at the set's centre."""
    lo, hi = data[:, :3].min(0), data[:, :3].max(0)
    c, size = (lo + hi) / 2, float(np.linalg.norm(hi - lo))
    eye = c + np.array([0.3, -1.0, 0.4]) / np.linalg.norm([0.3, -1.0, 0.4]) * 1.2 * size
    f = (c - eye) / np.linalg.norm(c - eye)
    r = np.cross(f, [0, 0, 1.0])
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    x, y = np.meshgrid((np.arange(w) + 0.5) / w * 2 - 1, ((np.arange(h) + 0.5) / h * 2 - 1) * h / w)
    d = f[None] + 0.55 * (x.reshape(-1, 1) * r[None] - y.reshape(-1, 1) * u[None])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return np.tile(eye, (w * h, 1)).astype(np.float32), d.astype(np.float32)


def timed(fn, reps: int = 3):
    fn()
    ts = []
    for _ in range(reps):
        t = time.perf_counter()
        out = fn()
        ts.append(time.perf_counter() - t)
    return 1e3 * float(np.median(ts)), out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="10000,100000,200000")
    ap.add_argument("--res", default="480x270")
    ap.add_argument("--k", default="16,32")
    ap.add_argument("--threads", type=int, default=0, help="host threads (0: Dr.Jit's pool size)")
    ap.add_argument("--json", help="also write the rows here")
    args = ap.parse_args()
    import drjit as dr  # the pool the host queries run on
    threads = args.threads or dr.thread_count()
    w, h = (int(v) for v in args.res.split("x"))
    device = not cuda.why_not()
    print(f"host threads {threads}; device: {'yes' if device else 'no (' + cuda.why_not() + ')'}")
    rows = []
    for n in (int(s) for s in args.sizes.split(",")):
        data, extent = shells(n)
        o, d = rays(data, w, h)
        m = len(o)
        first = (np.full(m, -np.inf, np.float32), np.full(m, NO, np.uint32), np.ones(m, bool))
        engines = {"embree": lambda: native.ShellSet(data, extent, dynamic=True),
                   "shellbvh host": lambda: native.BvhShellSet(data, extent, dynamic=True)}
        if device:
            engines["shellbvh device"] = lambda: cuda.CudaShellSet(data, extent, dynamic=True)
        ref = {}
        for name, make in engines.items():
            build_ms, s = timed(make, reps=1)
            moved = data.copy()
            moved[:, :3] += 1e-4
            refit_ms, _ = timed(lambda: s.refit(moved), reps=3)
            s.refit(data)
            for k in (int(v) for v in args.k.split(",")):
                if name == "shellbvh device":
                    import cupy as cp
                    args_ = tuple(cp.asarray(a) for a in (o, d, *first))

                    def q():
                        r = s.query(*args_[:5], k)
                        cp.cuda.runtime.deviceSynchronize()
                        return r
                else:
                    def q():
                        return s.query(o, d, *first, k, threads)
                ms, (p, t, c) = timed(q)
                if name == "shellbvh device":
                    p, t, c = (cp.asnumpy(a) for a in (p, t, c))
                if name == "embree":
                    ref[k] = (p.copy(), t.copy(), c.copy())
                    same = "-"
                else:
                    mask = np.arange(k)[None] < ref[k][2][:, None]
                    same = "yes" if ((c == ref[k][2]).all() and (p[mask] == ref[k][0][mask]).all()
                                     and (t[mask] == ref[k][1][mask]).all()) else "NO"
                rows.append(dict(gaussians=n, engine=name, k=k, rays=m, build_ms=build_ms, refit_ms=refit_ms,
                                 query_ms=ms, mrays_s=m / ms / 1e3, entries=float(c.mean()), same=same))
    print(f"\n| Gaussians | engine | K | build ms | refit ms | query ms ({w} x {h} rays) | M rays/s | entries / ray | "
          f"same lists as Embree |\n|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['gaussians']} | {r['engine']} | {r['k']} | {r['build_ms']:.1f} | {r['refit_ms']:.1f} | "
              f"{r['query_ms']:.1f} | {r['mrays_s']:.2f} | {r['entries']:.1f} | {r['same']} |")
    by = {(r["gaussians"], r["engine"], r["k"]): r for r in rows}
    print("\nquery time against Embree's (same rays, same K):")
    for (n, e, k), r in by.items():
        if e != "embree":
            print(f"  {n} Gaussians, K={k}, {e}: {r['query_ms'] / by[(n, 'embree', k)]['query_ms']:.2f}x")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
