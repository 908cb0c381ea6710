"""Integrator speed, side by side in one run: glint vs Mitsuba's volprim_rf_basic on identical Gaussians.

Prints markdown tables (and writes CSV to benchmarks/results/) of forward and forward+backward time per ray for
1k/10k/50k Gaussians at two resolutions, the cost of each component, the no-glass scene in auto mode, the replay vs
plain-AD backward, and the peak memory of one gradient step (each in a fresh subprocess). Targets (issue 2):
interface-only / volprim <= 1.0, all three components <= 2.5x interface-only, no-glass auto <= 1.1x interface-only.
Dr.Jit's LLVM backend runs kernels asynchronously: every timing ends with dr.sync_thread().

    .venv/bin/python benchmarks/bench_integrator.py [--quick]
"""
from __future__ import annotations

import argparse
import csv
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import glint_mi

glint_mi.set_variant()
import drjit as dr  # noqa: E402
import mitsuba as mi  # noqa: E402

from glint_mi.model.gaussians import GaussianSet  # noqa: E402
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
            dr.sync_thread()
            dr.clear_grad(params[grad_key])
        else:
            dr.eval(img)
            dr.sync_thread()
        times.append(time.perf_counter() - t)
    return float(np.median(times[1:]))


def glint_scene(sets, res, kernel="ellipsoid", opacity_shells=True, **props):
    integ = {"type": "glint", "aovs": "depth", **props}
    for role, s in sets.items():
        integ[role] = make_shape(s, kernel=kernel, role=role, extent=3.0, opacity_shells=opacity_shells)
    return mi.load_dict({"type": "scene", "integrator": integ, "sensor": camera(*res)})


def volprim_scene(s, res):
    return mi.load_dict({"type": "scene", "sensor": camera(*res),
                         "integrator": {"type": "volprim_rf_basic", "srgb_primitives": False, "max_depth": 256},
                         "g": make_shape(s, kernel="ellipsoid", extent=3.0, opacity_shells=False)})  # no alpha floor


# volprim_rf_basic stops at transmittance 0.01 and has no alpha floor (so its shells are not shrunk by opacity: a
# faint Gaussian still counts out to the full shell); the paper (our default) stops at 1e-4
VOLPRIM_CUTOFFS = {"transmittance_min": 0.01, "alpha_min": 0.0, "alpha_max": 0.9999}


def three_sets(n: int) -> dict:
    """The glass scene's sets: the interface (glass in front), a reflected cloud and a transmitted one behind it."""
    trans = gaussians(n, 2, glass=False)
    trans.means[:, 2] += 1.0
    return {"interface": gaussians(n, 0), "reflection": gaussians(n, 1, glass=False), "transmission": trans}


def configs(n: int, res) -> dict:
    """name -> (scene, key of a differentiable parameter) for n Gaussians per set."""
    three = three_sets(n)
    base, refl, trans = three["interface"], three["reflection"], three["transmission"]
    noglass = gaussians(n, 0, glass=False)
    key = "integrator.interface.opacities"
    return {
        "volprim_rf_basic": lambda: (volprim_scene(base, res), "g.opacities"),
        "glint interface only, volprim's cut-offs": lambda: (glint_scene({"interface": base}, res,
                                                                          components="interface", opacity_shells=False,
                                                                          **VOLPRIM_CUTOFFS), key),
        "glint interface only": lambda: (glint_scene({"interface": base}, res, components="interface"), key),
        "glint + reflection": lambda: (glint_scene({"interface": base, "reflection": refl}, res, components="all"), key),
        "glint + transmission": lambda: (glint_scene({"interface": base, "transmission": trans}, res,
                                                     components="all"), key),
        "glint all three (all)": lambda: (glint_scene(three, res, components="all"), key),
        "glint all three (auto)": lambda: (glint_scene(three, res), key),
        "glint interface only, traversal=bvh (Mitsuba's queries)": lambda: (
            glint_scene({"interface": base}, res, components="interface", traversal="bvh"), key),
        "glint all three (all), traversal=bvh (Mitsuba's queries)": lambda: (
            glint_scene(three, res, components="all", traversal="bvh"), key),
        "glint all three (all), inside_origins off (Gaussians around origins unseen)": lambda: (
            glint_scene(three, res, components="all", inside_origins=False), key),
        "glint all three, gradient=ad": lambda: (glint_scene(three, res, components="all", gradient="ad"), key),
        "no glass, auto (t = 0: transmission set never traced)": lambda: (
            glint_scene({"interface": noglass, "transmission": trans}, res), key),
        "no glass, auto, + reflection set (beta = 0, Fresnel only)": lambda: (
            glint_scene({"interface": noglass, "transmission": trans, "reflection": refl}, res), key),
    }


def memory_probe(name: str, n: int, res, what: str) -> None:
    """Child process: peak RSS (MB) of a fresh process that renders once (``fwd``) or takes one gradient step."""
    scene, key = configs(n, res)[name]()
    timed(scene, key if what == "grad" else None, reps=1)
    # VmHWM belongs to this process image (ru_maxrss would include the parent's peak, inherited over fork/exec)
    hwm = next(line for line in open("/proc/self/status") if line.startswith("VmHWM"))
    print(json.dumps({"peak_mb": int(hwm.split()[1]) / 1024}))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="1k/10k and one resolution (a smoke run)")
    ap.add_argument("--tiny", action="store_true", help="500 Gaussians at 32x24, no memory probes (used by the tests)")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"), help="folder for the CSV files")
    ap.add_argument("--memory-probe", nargs=4, metavar=("CONFIG", "N", "WxH", "WHAT"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.memory_probe:
        name, n, res, what = args.memory_probe
        return memory_probe(name, int(n), tuple(int(v) for v in res.split("x")), what)
    counts = [500] if args.tiny else [1000, 10000] if args.quick else [1000, 10000, 50000]
    resolutions = [(32, 24)] if args.tiny else [(128, 96)] if args.quick else [(128, 96), (256, 192)]
    from glint_mi.machine import describe

    dev = describe()
    rows = []
    for n in counts:
        for res in resolutions:
            rays = res[0] * res[1]
            cfg = configs(n, res)
            if n > 10000 or res[0] > 128 or args.tiny:  # the evaluated-loop reference is slow; one size shows it
                cfg.pop("glint all three, gradient=ad")
            for name, build in cfg.items():
                scene, key = build()
                fwd = timed(scene)
                bwd = timed(scene, key)
                rows.append({"gaussians": n, "resolution": f"{res[0]}x{res[1]}", "config": name,
                             "forward_ms": 1e3 * fwd, "fwd_ns_per_ray": 1e9 * fwd / rays,
                             "grad_ms": 1e3 * bwd, "grad_ns_per_ray": 1e9 * bwd / rays})
            ref = next(r for r in rows[-len(cfg):] if r["config"] == "glint interface only")
            for r in rows[-len(cfg):]:
                r.update(variant=dev["variant"], device=dev["device"])
                r["fwd_vs_interface"] = r["forward_ms"] / ref["forward_ms"]
                r["grad_vs_interface"] = r["grad_ms"] / ref["grad_ms"]
            print(f"done {n} Gaussians at {res}", flush=True)
    mem_rows = []
    for name in () if args.tiny else ("volprim_rf_basic", "glint interface only, volprim's cut-offs", "glint interface only",
                 "glint all three (all)", "glint all three, gradient=ad"):
        for n, res in ((10000, (128, 96)), (10000, (256, 192))):
            if "gradient=ad" in name and res[0] > 128:
                continue
            m = {}
            for what in ("fwd", "grad"):
                r = subprocess.run([sys.executable, __file__, "--memory-probe", name, str(n), f"{res[0]}x{res[1]}",
                                    what], capture_output=True, text=True, check=True)
                m[what] = json.loads(r.stdout.strip().splitlines()[-1])["peak_mb"]
            mem_rows.append({"config": name, "gaussians": n, "resolution": f"{res[0]}x{res[1]}",
                             "forward_peak_mb": m["fwd"], "gradient_peak_mb": m["grad"],
                             "gradient_extra_mb": m["grad"] - m["fwd"]})
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
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
    print("\n| config | Gaussians | res | peak RSS, forward (MB) | peak RSS, gradient step (MB) | extra (MB) |")
    print("|---|---|---|---|---|---|")
    for m in mem_rows:
        print(f"| {m['config']} | {m['gaussians']} | {m['resolution']} | {m['forward_peak_mb']:.0f} | "
              f"{m['gradient_peak_mb']:.0f} | {m['gradient_extra_mb']:.0f} |")
    if mem_rows:
        with open(out / "memory.csv", "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(mem_rows[0]))
            w.writeheader()
            w.writerows(mem_rows)
    print(f"\npeak RSS of the timing process: {peak_mb:.0f} MB  (variant {mi.variant()}, {os.cpu_count()} cores)")


if __name__ == "__main__":
    main()
