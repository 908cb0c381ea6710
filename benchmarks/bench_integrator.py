"""Integrator speed, side by side in one run: glint vs Mitsuba's volprim_rf_basic on identical Gaussians.

Prints a markdown table (and writes CSV to benchmarks/results/) of forward and forward+backward time per ray for
1k/10k/50k Gaussians at two resolutions, the cost of each component, the no-glass scene in auto mode, and the peak
memory of a gradient step. Targets (issue 2): interface-only / volprim <= 1.0, all three components <= 2.5x
interface-only, no-glass auto <= 1.1x interface-only.

    .venv/bin/python benchmarks/bench_integrator.py [--quick]
"""
from __future__ import annotations

import argparse
import csv
import resource
import time
from pathlib import Path

import numpy as np

import glint_mi

glint_mi.set_variant()
import drjit as dr  # noqa: E402
import mitsuba as mi  # noqa: E402

from glint_mi.gaussians import GaussianSet  # noqa: E402
from glint_mi_plugins.glint_gaussians import make_shape  # noqa: E402


def gaussians(n, seed=0, glass=True):
    """A unit-ish scene: n Gaussians in a 2 x 2 x 1 slab; glass Gaussians (tau = 0.9) in front when ``glass``."""
    rng = np.random.default_rng(seed)
    means = rng.uniform(-1, 1, (n, 3)) * [1.2, 1.0, 0.5]
    scale = 0.6 * (4.0 / n) ** (1 / 3)
    return GaussianSet.from_activated(means, rng.uniform(0.5, 1.5, (n, 3)) * scale, rng.normal(size=(n, 4)),
                                      opacities=rng.uniform(0.3, 0.9, n), colors=rng.uniform(0, 1, (n, 3)),
                                      specular=rng.uniform(0, 0.2, n) if glass else 0.0,
                                      transparency=np.where(means[:, 2] < -0.2, 0.9, 0.0) if glass else 0.0)


def camera(w, h):
    return {"type": "perspective", "fov": 50,
            "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, -3.5], target=[0, 0, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"}},
            "sampler": {"type": "independent", "sample_count": 1}}


def timed(scene, grad_key=None, reps=3):
    """Median seconds of a forward render (or render + backward of a weighted sum when grad_key)."""
    params = mi.traverse(scene)
    if grad_key:
        dr.enable_grad(params[grad_key])
        params.update()
    times = []
    for i in range(reps + 1):  # the first call compiles the kernels
        t = time.perf_counter()
        img = mi.render(scene, params if grad_key else None, seed=i)
        if grad_key:
            dr.backward(dr.sum(img, axis=None))
            dr.eval(dr.grad(params[grad_key]))
            dr.clear_grad(params[grad_key])
        else:
            dr.eval(img)
        times.append(time.perf_counter() - t)
    return float(np.median(times[1:]))


def glint_scene(sets, res, kernel="ellipsoid", **props):
    integ = {"type": "glint", "aovs": "depth", **props}
    for role, s in sets.items():
        integ[role] = make_shape(s, kernel=kernel, role=role, extent=3.0)
    return mi.load_dict({"type": "scene", "integrator": integ, "sensor": camera(*res)})


def volprim_scene(s, res):
    return mi.load_dict({"type": "scene", "sensor": camera(*res),
                         "integrator": {"type": "volprim_rf_basic", "srgb_primitives": False, "max_depth": 256},
                         "g": make_shape(s, kernel="ellipsoid", extent=3.0)})


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="1k/10k and one resolution (a smoke run)")
    args = ap.parse_args()
    counts = [1000, 10000] if args.quick else [1000, 10000, 50000]
    resolutions = [(128, 96)] if args.quick else [(128, 96), (256, 192)]
    rows = []
    for n in counts:
        base = gaussians(n, 0)
        refl, trans = gaussians(n, 1, glass=False), gaussians(n, 2, glass=False)
        trans.means[:, 2] += 1.0
        noglass = gaussians(n, 0, glass=False)
        for res in resolutions:
            rays = res[0] * res[1]
            cfg = {
                "volprim_rf_basic": (volprim_scene(base, res), "g.opacities"),
                "glint interface only": (glint_scene({"interface": base}, res, components="interface"),
                                         "integrator.interface.opacities"),
                "glint + reflection": (glint_scene({"interface": base, "reflection": refl}, res, components="all"),
                                       "integrator.interface.opacities"),
                "glint + transmission": (glint_scene({"interface": base, "transmission": trans}, res, components="all"),
                                         "integrator.interface.opacities"),
                "glint all three (all)": (glint_scene({"interface": base, "reflection": refl, "transmission": trans}, res,
                                                      components="all"), "integrator.interface.opacities"),
                "glint all three (auto)": (glint_scene({"interface": base, "reflection": refl, "transmission": trans},
                                                       res), "integrator.interface.opacities"),
                "no glass, auto (interface + reflection sets)": (
                    glint_scene({"interface": noglass, "reflection": refl}, res), "integrator.interface.opacities"),
            }
            ref_f = ref_b = None
            for name, (scene, key) in cfg.items():
                fwd = timed(scene)
                bwd = timed(scene, key)
                if name == "glint interface only":
                    ref_f, ref_b = fwd, bwd
                rows.append({"gaussians": n, "resolution": f"{res[0]}x{res[1]}", "config": name,
                             "forward_ms": 1e3 * fwd, "fwd_ns_per_ray": 1e9 * fwd / rays,
                             "grad_ms": 1e3 * bwd, "grad_ns_per_ray": 1e9 * bwd / rays})
            for r in rows[-len(cfg):]:
                r["fwd_vs_interface"] = r["forward_ms"] / (1e3 * ref_f)
                r["grad_vs_interface"] = r["grad_ms"] / (1e3 * ref_b)
            print(f"done {n} Gaussians at {res}", flush=True)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    out = Path(__file__).parent / "results"
    out.mkdir(exist_ok=True)
    with open(out / "integrator.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print("\n| Gaussians | res | config | fwd ms | fwd ns/ray | x interface | fwd+grad ms | x interface |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['gaussians']} | {r['resolution']} | {r['config']} | {r['forward_ms']:.1f} | "
              f"{r['fwd_ns_per_ray']:.0f} | {r['fwd_vs_interface']:.2f} | {r['grad_ms']:.1f} | "
              f"{r['grad_vs_interface']:.2f} |")
    print(f"\npeak RSS of the whole run: {peak_mb:.0f} MB  (machine: {mi.variant()}, "
          f"{__import__('os').cpu_count()} cores)")


if __name__ == "__main__":
    main()
