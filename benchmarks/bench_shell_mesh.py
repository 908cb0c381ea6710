"""Custom-primitive shells against triangle shells: the traversal alone, on a trained run (issue 43, item 3).

The integrator's ``bvh`` traversal queries each set's Mitsuba ``ellipsoids`` shape: one custom primitive per
Gaussian, whose shell test runs as software (an Embree user geometry on LLVM, an OptiX intersection program on a
GPU). Mitsuba's ``ellipsoidsmesh`` holds the same ``data`` record as 20 triangles per Gaussian (an icosahedron around
the shell, back faces culled, so a ray reports a shell's entry only), which a GPU's ray-tracing cores intersect in
hardware. Whether that pays depends on the machine, so this script measures it and changes nothing in the
integrator: for every set of a trained run, the rays of one view walk both shapes the way the integrator's walk does
(closest entry, a small step past it, each Gaussian once), no kernel evaluated, and it prints

- the walk's time on each shape (the best of ``--reps`` after one that compiles), and the ratio;
- the entries per ray on each (the polyhedron encloses the shell, so it is entered by more rays: more hits);
- how many of the exact shells' entries (the first ``--keep`` per ray) the triangle walk also lists, and in the
  same order (the integrator composites in entry order, so order is what would change the image).

    .venv/bin/python benchmarks/bench_shell_mesh.py --run out/demo/run [--res 480x270] [--reps 3]
    GLINT_VARIANT=cuda_ad_rgb python benchmarks/bench_shell_mesh.py --run RUN --out DIR

Writes DIR/shell_mesh_<name>.md (default DIR: benchmarks/results).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import glint_mi  # noqa: E402

glint_mi.set_variant()
import drjit as dr  # noqa: E402
import mitsuba as mi  # noqa: E402

from glint_mi.machine import summary  # noqa: E402

TRIANGLES = 20  # Mitsuba's ellipsoidsmesh: an icosahedron per ellipsoid (checked against face_count below)


def triangle_scene(shape):
    """A scene holding Mitsuba's ``ellipsoidsmesh`` made from the same ``data`` and ``extent`` as ``shape`` (an
    ``ellipsoids`` shape of the integrator)."""
    p = mi.traverse(shape)
    data = mi.Float(p["data"])
    n = dr.width(data) // 10
    rec = np.asarray(data).reshape(n, 10)
    mesh = mi.load_dict({"type": "ellipsoidsmesh", "extent": float(p["extent"]),
                         "centers": mi.TensorXf(np.ascontiguousarray(rec[:, :3])),
                         "scales": mi.TensorXf(np.ascontiguousarray(rec[:, 3:6])),
                         "quaternions": mi.TensorXf(np.ascontiguousarray(rec[:, 6:]))})
    if mesh.face_count() != TRIANGLES * n:
        raise RuntimeError(f"ellipsoidsmesh made {mesh.face_count()} triangles for {n} ellipsoids, "
                           f"not {TRIANGLES} each: this script's prim_index mapping does not hold")
    return mi.load_dict({"type": "scene", "shells": mesh}), n


@dr.syntax
def walk(scene, o, d, per: int, keep: int, max_hits: int):
    """The integrator's walk without its kernels: closest shell entry, a step past it, each Gaussian once (the last
    two remembered); lists the first ``keep`` Gaussians entered per ray."""
    from glint_mi_plugins.glint_composite import _ray_epsilon

    n = dr.width(o)
    listed = dr.full(mi.UInt32, 0xFFFFFFFF, n * keep)
    slot = dr.arange(mi.UInt32, n) * keep
    hits = mi.UInt32(0)
    last0, last1 = mi.UInt32(0xFFFFFFFF), mi.UInt32(0xFFFFFFFF)
    step = mi.Float(1.0)
    active = mi.Bool(True)
    while dr.hint(active, exclude=[listed, slot]):
        pi = scene.ray_intersect_preliminary(mi.Ray3f(o, d), coherent=False, active=active)
        hit = active & pi.is_valid()
        prim = pi.prim_index // per
        p = o + d * pi.t
        new = hit & (prim != last0) & (prim != last1)
        dr.scatter(listed, prim, slot + hits, new & (hits < keep))
        o = dr.select(hit, p + d * (_ray_epsilon(p) * step), o)
        step = dr.select(hit & ~new, step * 4.0, 1.0)
        last1 = dr.select(new, last0, last1)
        last0 = dr.select(new, prim, last0)
        hits += mi.UInt32(dr.select(new, 1, 0))
        active = hit & (hits < max_hits)
    return hits, listed


def timed_walk(scene, ray, per, keep, max_hits, reps):
    best, out = float("inf"), None
    for i in range(reps + 1):  # the first compiles
        dr.sync_thread()
        t0 = time.perf_counter()
        out = walk(scene, mi.Point3f(ray.o), mi.Vector3f(ray.d), per, keep, max_hits)
        dr.eval(*out)
        dr.sync_thread()
        if i:
            best = min(best, time.perf_counter() - t0)
    hits, listed = out
    return best, np.asarray(hits), np.asarray(listed).reshape(-1, keep)


def agreement(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """Of the entries listed in ``a`` (exact shells): the share also in ``b``'s list of the same ray, and the share
    at the same position."""
    valid = a != 0xFFFFFFFF
    same_pos = (a == b) & valid
    inb = np.zeros_like(valid)
    for j in range(b.shape[1]):  # membership per ray, column by column (keep is small)
        inb |= (a == b[:, j:j + 1]) & valid
    n = max(int(valid.sum()), 1)
    return float(inb.sum()) / n, float(same_pos.sum()) / n


def main(argv=None) -> int:
    from glint_mi.evaluate import load_model, load_run
    from profile_step import view_rays

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--run", required=True, type=Path, help="a trained run folder (model/ and config.json)")
    ap.add_argument("--res", default="480x270", help="the view's rays, WxH (default: the paper's 480x270)")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--keep", type=int, default=16, help="entries per ray compared between the two walks")
    ap.add_argument("--max-hits", type=int, default=256)
    ap.add_argument("--name", help="results name (default: the run folder's parent's name)")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results")
    args = ap.parse_args(argv)
    w, h = (int(v) for v in args.res.split("x"))
    _, ds, cfg, _ = load_run(args.run)
    integ = load_model(args.run, cfg)
    view = (ds.test_views or ds.train_views)[0]
    ray, _ = view_rays(view, w, h)
    name = args.name or args.run.resolve().parent.name
    lines = [f"### Shell traversal: custom primitives (ellipsoids) against triangles (ellipsoidsmesh), {name}", "",
             f"{w} x {h} rays of view {view.name}, the walk alone (no kernels), best of {args.reps}. "
             f"Machine: {summary()}.", "",
             "| set | Gaussians | ellipsoids ms | triangles ms | x (ellipsoids / triangles) | entries / ray "
             "(ellipsoids, triangles) | exact entries listed by triangles | at the same position |",
             "|---|---|---|---|---|---|---|---|"]
    from glint_mi_plugins.glint_gaussians import info

    for role, ref in integ.sets.items():
        if info(ref.shape).empty:  # a set the run dropped: one invisible placeholder
            continue
        tri_scene, n = triangle_scene(ref.shape)
        t_e, h_e, l_e = timed_walk(ref.bvh_scene(), ray, 1, args.keep, args.max_hits, args.reps)
        t_t, h_t, l_t = timed_walk(tri_scene, ray, TRIANGLES, args.keep, args.max_hits, args.reps)
        shared, same = agreement(l_e, l_t)
        lines.append(f"| {role} | {n} | {1e3 * t_e:.1f} | {1e3 * t_t:.1f} | {t_e / t_t:.2f} | "
                     f"{h_e.mean():.1f}, {h_t.mean():.1f} | {100 * shared:.1f} % | {100 * same:.1f} % |")
    text = "\n".join(lines + [""])
    print(text)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / f"shell_mesh_{name}.md").write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
