"""How much a densify step lifts the training loss: for each densify step of a finished (or running) run, the mean
training loss (``log.csv``'s ``total``) over the ``--window`` iterations after the step against the mean over the
``--window`` iterations up to it. Steps within ``--window`` iterations of an opacity reset are left out (a reset lifts
the loss on its own). The steps come from ``report.json``'s ``events`` (``what``: ``densify`` / ``reset``).

Used for the forty-eighth session's split arm (``docs/results/coarse_to_fine``, "A split that keeps its parent's
footprint"): the rise at the first step and its mean over the steps, per run.

    .venv/bin/python benchmarks/densify_bump.py RUN [RUN ...] [--window 10]
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import numpy as np


def densify_rises(run: Path, window: int = 10) -> list[tuple[int, float, float]]:
    """[(step iteration, mean loss before, mean loss after)] for each densify step not within ``window`` of a reset
    and with logged iterations on both sides."""
    with open(run / "log.csv") as fh:
        rows = list(csv.DictReader(fh))
    it = np.array([int(r["iteration"]) for r in rows])
    loss = np.array([float(r["total"]) for r in rows])
    events = json.loads((run / "report.json").read_text())["events"]
    steps = sorted({e["iteration"] for e in events if e.get("what") == "densify"})
    resets = [e["iteration"] for e in events if e.get("what") == "reset"]
    out = []
    for s in steps:
        if any(abs(s - r) <= window for r in resets):
            continue
        before, after = loss[(it > s - window) & (it <= s)], loss[(it > s) & (it <= s + window)]
        if len(before) and len(after):
            out.append((s, float(before.mean()), float(after.mean())))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", type=Path)
    ap.add_argument("--window", type=int, default=10)
    args = ap.parse_args(argv)
    print("| run | steps | first step: loss before -> after | mean rise over the steps |")
    print("|---|---|---|---|")
    for run in args.runs:
        for f in ("log.csv", "report.json"):
            if not (run / f).exists():
                print(f"{run}: no {f} (a run folder of python -m glint_mi.optimize or the benchmark)", file=sys.stderr)
                return 2
        rises = densify_rises(run, args.window)
        if not rises:
            print(f"| {run} | 0 | - | - |")
            continue
        s, b, a = rises[0]
        mean = 100 * np.mean([a_ / b_ - 1 for _, b_, a_ in rises])
        print(f"| {run} | {len(rises)} | {s}: {b:.3f} -> {a:.3f} ({100 * (a / b - 1):+.0f} %) | {mean:+.1f} % |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
