"""Opacity shells against full shells, and both against the hit budget: render time and error on a trained run.

A Gaussian's BVH shell is 3.33 sigma, where an *opaque* Gaussian's alpha falls below the 1/255 compositing cut-off.
With ``opacity_shells`` (default) a fainter Gaussian's shell ends where its own alpha reaches the cut-off, so the
integrator no longer pays BVH hits, or hits of the ``max_hits`` budget, for Gaussians it skips anyway. What changes
besides speed: the compositing order (shell entry) follows the smaller shells, and the hit budget reaches deeper.

This script renders the test views of one trained run four ways - full / opacity shells x the run's hit budget /
a budget so large that it never binds - and prints time, the metrics, and each render's difference from the
budget-free full-shell render (the model with no approximation but the compositing order):

    .venv/bin/python benchmarks/bench_shells.py --run RUN_DIR [--views 6] [--free-hits 1024]

RUN_DIR is a run folder with checkpoint.npz and config.json (e.g. a benchmark's runs/<scene>/glint). Writes
benchmarks/results/shells_<name>.md.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import glint_mi  # noqa: E402

glint_mi.set_variant()

from glint_mi.config import TrainConfig  # noqa: E402
from glint_mi.evaluate import evaluate  # noqa: E402
from glint_mi.training.trainer import Trainer  # noqa: E402

METRICS = ("psnr", "normal_mae", "absrel", "t_iou", "t_off_glass")


def difference(a: list[np.ndarray], b: list[np.ndarray]) -> dict:
    """PSNR between two sets of linear renders, mean |diff| and the share of pixels off by > 1/255 (max channel)."""
    err = np.concatenate([np.abs(x - y).max(-1).ravel() for x, y in zip(a, b)])
    mse = np.mean([np.mean((x - y) ** 2) for x, y in zip(a, b)])
    return {"psnr_between": float(-10 * np.log10(max(mse, 1e-20))), "mean_abs": float(err.mean()),
            "pixels_off": float(np.mean(err > 1 / 255))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", required=True, type=Path)
    ap.add_argument("--views", type=int, default=6, help="first N test views")
    ap.add_argument("--free-hits", type=int, default=1024, help="a hit budget that does not bind")
    ap.add_argument("--name", help="results name (default: the run folder's parent's name)")
    args = ap.parse_args(argv)
    base = TrainConfig.load(args.run / "config.json")
    rows, renders = [], {}
    for shells in (False, True):
        for hits in (base.max_hits, args.free_hits):
            cfg = base.replace(opacity_shells=shells, max_hits=hits)
            tr = Trainer(args.run, cfg, resume=True, log=lambda *a, **k: None)
            views = tr.ds.test_views[:args.views]
            res = evaluate(tr.integ_for_eval(), views, write=False)
            key = ("opacity" if shells else "full", hits)
            renders[key] = [res["renders"][v.name]["rgb"] for v in views]
            rows.append({"shells": key[0], "max_hits": hits, "s_per_view": 1 / res["fps"],
                         **{m: res["metrics"].get(m, float("nan")) for m in METRICS}})
            print(f"{key}: {rows[-1]['s_per_view']:.2f} s per view", flush=True)
    ref = renders[("full", args.free_hits)]
    for r in rows:
        r.update(difference(renders[(r["shells"], r["max_hits"])], ref))
    name = args.name or args.run.parent.name
    lines = [f"### {name}: {args.run} (iteration {tr.it}), first {len(views)} test views, "
             f"{views[0].width} x {views[0].height}", "",
             "| shells | max_hits | s / view | x full, budget | " + " | ".join(METRICS)
             + " | PSNR to full, no budget | mean abs diff | pixels off > 1/255 |",
             "|" + "---|" * (7 + len(METRICS))]
    t0 = rows[0]["s_per_view"]
    for r in rows:
        lines.append(f"| {r['shells']} | {r['max_hits']} | {r['s_per_view']:.2f} | {r['s_per_view'] / t0:.2f} | "
                     + " | ".join(f"{r[m]:.4g}" for m in METRICS)
                     + (f" | {r['psnr_between']:.1f} dB" if r["psnr_between"] < 150 else " | (itself)")
                     + f" | {r['mean_abs']:.2e} | {100 * r['pixels_off']:.1f} % |")
    text = "\n".join(lines) + "\n"
    print(text)
    out = ROOT / "benchmarks" / "results" / f"shells_{name}.md"
    out.write_text(text)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
