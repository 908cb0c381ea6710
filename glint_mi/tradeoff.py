"""The speed / accuracy trade: train variants of one configuration side by side and measure time against quality.

:func:`run_variants` trains each named set of overrides on one scene (same seed, same data) and returns rows with
train seconds, FPS and the metrics; :func:`pareto` marks the rows no other row beats on both time and quality;
:func:`mesh_reference_trade` measures the first-order glass model (mesh mode) and Mitsuba's ``path`` at several spp
against a high-spp ``path`` reference. ``benchmarks/bench_tradeoff.py`` runs the full grid and notebook 5 plots it.
"""
from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path

import numpy as np

# name -> TrainConfig overrides on top of the preset; the groups are the user's questions
GRID = {
    "budget": {"iters x0.5": {"iterations_scale": 0.5}, "iters x1": {}, "iters x2": {"iterations_scale": 2.0},
               "rays x0.5": {"patches_scale": 0.5}, "rays x2": {"patches_scale": 2.0}},
    "gaussians": {"max 1k": {"max_gaussians": 1000}, "max 4k": {"max_gaussians": 4000},
                  "max 16k": {"max_gaussians": 16000}},
    "sh": {"SH 0": {"sh_degree": 0}, "SH 1": {"sh_degree": 1}, "SH 2": {"sh_degree": 2}},
    "components": {"interface": {"components": "interface"},
                   "+ reflection": {"components": "interface,reflection"},
                   "+ transmission": {"components": "interface,transmission"},
                   "all three": {"components": "all"}, "auto": {"components": "auto"}},
    "order": {"first order": {"max_order": 1, "components": "all"},
              "max_order 2": {"max_order": 2, "components": "all"}},
    # rays per iteration stay the same; each ray then covers a 2 x 2 block (evaluation at full resolution); with an
    # epochs budget the half-resolution run gets a quarter of the iterations (the same rays per training pixel)
    "resolution": {"train 1/1 res": {}, "train 1/2 res": {"downscale": 2, "eval_full": True}},
    # the hit budget per ray and pass: 64 was the default until a trained model was found to learn its cut
    # (docs/performance.md, "The hit budget"); 256 is the default
    "hits": {"64 hits": {"max_hits": 64}, "128 hits": {"max_hits": 128}, "256 hits": {"max_hits": 256}},
}
# the components question on a room WITHOUT glass (same room, `python -m glint_mi.dataset make --no-glass`)
NO_GLASS = {"interface": {"components": "interface"}, "all three": {"components": "all"}, "auto": {"components": "auto"}}


def _overrides(cfg_base, ov: dict) -> dict:
    ov = dict(ov)
    out = {}
    if "iterations_scale" in ov:  # scales the budget: epochs where the preset has them, else iterations
        scale = ov.pop("iterations_scale")
        if cfg_base.epochs > 0:
            out["epochs"] = cfg_base.epochs * scale
        else:
            out["iterations"] = max(1, int(round(cfg_base.iterations * scale)))
    if "patches_scale" in ov:
        out["patches"] = max(1, int(round(cfg_base.patches * ov.pop("patches_scale"))))
    out.update(ov)
    return out


def run_variants(scene_xml: Path, out: Path, variants: dict[str, dict], preset: str = "tiny", log=print,
                 seen: dict | None = None, **base) -> list[dict]:
    """Train every variant (resumable: a finished one is read back) and return one row per variant.

    ``seen`` (shared across calls on the same scene) maps a resolved configuration to its result: a variant equal
    to one already trained (e.g. "iters x1" and "SH 1" are both the base) is reported from that run, not retrained.
    """
    from glint_mi.config import TrainConfig
    from glint_mi.evaluate import evaluate
    from glint_mi.runs import finished_metrics, train_unless_done
    from glint_mi.scene import read_scene
    from glint_mi.training.trainer import Trainer

    rows = []
    base_cfg = TrainConfig.for_preset(preset, **base)
    seen = {} if seen is None else seen
    for name, ov in variants.items():
        run = Path(out) / name.replace(" ", "_").replace("+", "plus").replace("/", "_")
        cfg = TrainConfig.for_preset(preset, **{**base, **_overrides(base_cfg, ov)})
        key = (str(scene_xml), json.dumps(dataclasses.asdict(cfg), sort_keys=True))
        res, trained_as = seen.get(key, (None, name))
        if res is None:
            res = finished_metrics(run)
        if res is None:
            if (run / "checkpoint.npz").exists():
                tr = Trainer(run, cfg, resume=True, log=lambda *a: None)
            else:
                tr = Trainer(run, cfg, scene=read_scene(scene_xml), log=lambda *a: None)
            r = train_unless_done(tr)
            res = evaluate(tr.integ_for_eval(), tr.eval_views(), run, r["train_s"], **tr.eval_options())
            res = {k: v for k, v in res.items() if k not in ("per_view", "renders")}
            log(f"{name}: {r['train_s']:.0f} s, PSNR {res['metrics']['psnr']:.2f}")
        seen[key] = (res, trained_as)
        rows.append({"variant": name, "trained_as": trained_as, **res["metrics"]})
    return rows


def pareto(rows: list[dict], cost: str = "train_s", quality: str = "psnr", higher_is_better: bool = True):
    """Flags rows on the Pareto front (no other row is at least as cheap and strictly better, or cheaper and
    at least as good)."""
    sign = 1.0 if higher_is_better else -1.0
    flags = []
    for r in rows:
        dominated = any(o is not r and o[cost] <= r[cost] and sign * o[quality] >= sign * r[quality]
                        and (o[cost] < r[cost] or sign * o[quality] > sign * r[quality]) for o in rows)
        flags.append(not dominated)
    return flags


def mesh_reference_trade(spps=(4, 16, 64), ref_spp: int = 1024, width: int = 48, height: int = 36,
                         depths=(3, 6, 64)) -> list[dict]:
    """Error vs a ``ref_spp`` path-traced reference (max_depth 64) and warm time, for ``path`` at every spp and
    ``max_depth`` in ``depths``, and for the first-order mesh mode at every spp."""
    import mitsuba as mi

    from glint_mi.model.mesh_room import glass_room_dict
    from glint_mi.model.render import render_buffers

    ref = np.array(mi.render(mi.load_dict(glass_room_dict({"type": "path", "max_depth": 64}, True, width, height,
                                                          ref_spp)), seed=99))
    rows = []
    for spp in spps:
        for name, integ in [("path", {"type": "path", "max_depth": d}) for d in depths] + [
                ("glint mesh mode", {"type": "glint", "max_depth": 64})]:
            scene = mi.load_dict(glass_room_dict(integ, True, width, height, spp))
            render_buffers(scene, spp=spp, seed=1)  # warm-up: compile (the spp is part of the kernel)
            t0 = time.perf_counter()
            img = render_buffers(scene, spp=spp, seed=3)["rgb"]  # a render always names its spp: mi.render(spp=k)
            #                                                      leaves the sensor's sampler at k
            dt = time.perf_counter() - t0
            err = float(np.abs(img - ref).mean() / ref.mean())
            rows.append({"renderer": name, "max_depth": integ["max_depth"], "spp": spp, "seconds": dt,
                         "rel_error": err})
    return rows


def summarise(rows: list[dict], base: str = "base",
              keys=("psnr", "ssim", "normal_mae", "absrel", "t_iou", "train_s", "fps")) -> list[dict]:
    """One row per (group, variant) over every (room, seed) it was trained on: the mean and min/max of ``keys``,
    and the change against ``base`` trained on the same room with the same seed (paired: the room-to-room spread,
    which dwarfs most variants' effect, cancels). A variant without a base on its room (another room, e.g. the
    glass-free twin) has no deltas."""
    by_run = {(r["room"], r["seed"]): r for r in rows if r["variant"] == base}
    out, order = {}, []
    for r in rows:
        k = (r["group"], r["variant"])
        if k not in out:
            out[k] = []
            order.append(k)
        out[k].append(r)
    summ = []
    for k in order:
        sel = out[k]
        s = {"group": k[0], "variant": k[1], "runs": len(sel)}
        for q in keys:
            s.update(_spread(q, [as_number(r.get(q)) for r in sel]))
            s.update(_spread("d_" + q, [as_number(r.get(q)) - as_number(by_run[(r["room"], r["seed"])].get(q))
                                        for r in sel if (r["room"], r["seed"]) in by_run]))
        summ.append(s)
    return summ


def _spread(name: str, values: list[float]) -> dict:
    """{name, name_min, name_max}: mean, min and max of the finite values (nan when there are none)."""
    v = np.array(values, float)
    v = v[np.isfinite(v)]
    if not len(v):
        return {name: float("nan"), name + "_min": float("nan"), name + "_max": float("nan")}
    return {name: float(v.mean()), name + "_min": float(v.min()), name + "_max": float(v.max())}


def as_number(v) -> float:
    """A CSV cell or a metric as a float (nan when it is none)."""
    try:
        return float(v)
    except (TypeError, ValueError):
        return float("nan")
