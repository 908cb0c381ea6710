"""A finished run's depth on the views it trained on, against the depth priors it read there.

The benchmark's ``priors`` row scores each *test* view's own prior, which the run never reads; a run can end over
that row because the test views' priors happen to be better than the training views' (the error model draws them
independently), or under it while being over the priors it was given. This renders the run at each training view
(the run's resolution and depth rule) and scores it, and the prior of the same view aligned as GLINT's loss aligns
it (``glint_mi.benchmark.aligned_prior_depth``: scale and shift fitted to the SfM points the view sees), against
the ground truth: AbsRel over every valid pixel, on the glass and off it, and the views where the run is worse.
Views with too few SfM points for the fit are left out (the priors row would fit those to the ground truth).

``--photo`` scores the photometric fit instead: the run's PSNR at the training views (every pixel, on the glass,
off it: the benchmark's own per-view metrics) beside its test views' (the run's ``metrics.json``), so a fit the test
views do not share shows as a gap that grows with epochs.

    .venv/bin/python benchmarks/train_view_depth.py RUN [RUN ...] [--photo] [--out FILE.md]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

KEYS = ("absrel", "absrel_glass", "absrel_off_glass")


def depth_errors(pred: np.ndarray, gt: dict, prior: np.ndarray) -> dict:
    """AbsRel of ``pred`` against ``gt["depth"]`` over the pixels where both the ground truth and ``prior`` are
    valid, on the glass (``gt["glass"]`` > 0.5) and off it (NaN where a part has no pixel)."""
    from glint_mi.evaluation.metrics import absrel

    valid = (gt["depth"] > 0) & (prior > 0)
    glass = gt["glass"] > 0.5
    return {"absrel": absrel(pred, gt["depth"], valid), "absrel_glass": absrel(pred, gt["depth"], valid & glass),
            "absrel_off_glass": absrel(pred, gt["depth"], valid & ~glass)}


def train_view_depth(run: Path, progress=None) -> dict:
    """{"views": [{"view", "run": {KEYS}, "prior": {KEYS}}], "left_out": [view names without an SfM fit],
    "run": {KEYS: mean}, "prior": {KEYS: mean}, "worse": views where the run's AbsRel is higher}."""
    from glint_mi.benchmark import aligned_prior_depth
    from glint_mi.evaluation.renders import load_run, render_view
    from glint_mi.training.batch import RayBank

    integ, ds, cfg, _ = load_run(run)
    if cfg.eval_depth == "first_surface":
        raise SystemExit(f"{run}: eval_depth first_surface reads each view's glass mask; this tool renders the "
                         f"expected or median depth only (a TSGS run: not supported)")
    bank = RayBank(ds.train_views, ds.root)
    if "depth" not in bank.has:
        raise SystemExit(f"{run}: its dataset ({ds.root}) has no depth priors to compare with")
    bank.align_depth_priors(ds.points)
    rows, left_out = [], []
    for i, v in enumerate(ds.train_views):
        gt = v.load_gt()
        if gt is None:
            raise SystemExit(f"{run}: training view {v.name} has no ground truth ({ds.root}); a generated room "
                             f"has it, a capture does not")
        prior, fitted = aligned_prior_depth(bank, i, gt["depth"])
        if fitted:
            left_out.append(v.name)
            continue
        depth = render_view(integ, v, depth_rule=cfg.eval_depth)["depth"]
        depth = depth[..., 0] if depth.ndim == 3 else depth
        rows.append({"view": v.name, "run": depth_errors(depth, gt, prior), "prior": depth_errors(prior, gt, prior)})
        if progress:
            progress(i + 1, len(ds.train_views))
    mean = lambda who, k: float(np.nanmean([r[who][k] for r in rows])) if rows else float("nan")  # noqa: E731
    return {"views": rows, "left_out": left_out, "run": {k: mean("run", k) for k in KEYS},
            "prior": {k: mean("prior", k) for k in KEYS},
            "worse": sum(r["run"]["absrel"] > r["prior"]["absrel"] for r in rows)}


PHOTO = ("psnr", "psnr_glass", "psnr_off_glass")


def train_view_photo(run: Path) -> dict:
    """{"train": {PHOTO: mean over the training views}, "test": {PHOTO: the run's metrics.json}, "views": n}: the
    training views go through the evaluation's own loop (``evaluate``, nothing written)."""
    import json

    from glint_mi.evaluation.renders import evaluate, load_run

    integ, ds, cfg, _ = load_run(run)
    test = json.loads((Path(run) / "metrics.json").read_text())["metrics"]
    bare = [v.name for v in ds.train_views if v.gt_path is None]
    if bare:
        raise SystemExit(f"{run}: training view(s) {', '.join(bare[:3])} have no ground truth ({ds.root}); a "
                         f"generated room has it, a capture does not")
    ev = evaluate(integ, ds.train_views, write=False)
    return {"train": {k: ev["metrics"][k] for k in PHOTO}, "test": {k: float(test[k]) for k in PHOTO},
            "views": ev["views_done"]}


def photo_table(results: list[tuple[str, dict]]) -> str:
    lines = ["| run | training views | PSNR all: training / test views | on the glass | off it | gap on / off the "
             "glass |", "|---|---|---|---|---|---|"]
    for name, r in results:
        cells = [f"{r['train'][k]:.2f} / {r['test'][k]:.2f}" for k in PHOTO]
        gap = [r["train"][k] - r["test"][k] for k in PHOTO[1:]]
        lines.append(f"| {name} | {r['views']} | " + " | ".join(cells) + f" | {gap[0]:.2f} / {gap[1]:.2f} |")
    return "\n".join(lines) + "\n"


def table(results: list[tuple[str, dict]]) -> str:
    lines = ["| run | training views | AbsRel: run / its priors | on the glass | off it | views where the run is "
             "worse |", "|---|---|---|---|---|---|"]
    for name, r in results:
        cells = [f"{r['run'][k]:.4f} / {r['prior'][k]:.4f}" for k in KEYS]
        lines.append(f"| {name} | {len(r['views'])} ({len(r['left_out'])} without an SfM fit) | " + " | ".join(cells)
                     + f" | {r['worse']} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", type=Path, help="finished run folders (RUN/model, RUN/config.json)")
    ap.add_argument("--photo", action="store_true", help="the photometric fit at the training views against the "
                    "test views' instead of the depth against the priors")
    ap.add_argument("--out", type=Path, help="also write the table here (markdown)")
    args = ap.parse_args(argv)
    import glint_mi

    glint_mi.set_variant()
    results = []
    for run in args.runs:
        print(f"{run} ...", file=sys.stderr, flush=True)
        results.append((str(run), train_view_photo(run) if args.photo else train_view_depth(run)))
    text = photo_table(results) if args.photo else table(results)
    print(text)
    if args.out:
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
