"""How fast a run's training steps went, from its ``log.csv`` alone (``rays_per_s`` per iteration: the step's rays
over its own time, without evaluation): the median rays/s over an iteration range and the steps' time summed, so
that runs started side by side (or stopped early) compare on the same iterations.

Used for the forty-ninth session's side-by-side start (``docs/results/converge_98xx``, "Where the 1.3x minutes
come from"): today's code with ``clone_opacity`` copy and shared, and the declared code, on the same room.

    .venv/bin/python benchmarks/step_rate.py RUN [RUN ...] [--from 300] [--to N] [--split 500]

``--to`` defaults to the last iteration every run reached; ``--split`` also sums the steps from that iteration on.
"""
from __future__ import annotations

import argparse
import csv
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def read_rates(run: Path) -> dict[int, tuple[float, float, int]]:
    """{iteration: (rays/s, loss, rays a step)} of a run's ``log.csv``; the rays a step (patches x patch^2) come from
    its ``config.json``, read as the trainer reads it (``TrainConfig.load``: old runs' configs migrated, a bad one
    refused)."""
    from glint_mi.config import TrainConfig

    cfg = TrainConfig.load(run / "config.json")
    rays = cfg.patches * cfg.patch ** 2
    out = {}
    with open(run / "log.csv") as fh:
        for r in csv.DictReader(fh):
            if r.get("rays_per_s"):
                out[int(r["iteration"])] = (float(r["rays_per_s"]), float(r["total"]), rays)
    return out


def summary(rates: dict, first: int, last: int, split: int | None = None) -> dict:
    """Median rays/s over iterations first..last, the steps' seconds summed from 0 to last (and from split to last),
    and the loss at last."""
    its = [i for i in rates if first <= i <= last]
    if not its:
        raise ValueError(f"no logged iteration in {first}..{last}")
    step_s = lambda a: sum(rates[i][2] / rates[i][0] for i in rates if a <= i <= last)
    return {"median_rays_per_s": statistics.median(rates[i][0] for i in its), "step_s": step_s(0),
            "step_s_split": step_s(split) if split is not None else None, "loss": rates[max(its)][1]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", type=Path)
    ap.add_argument("--from", dest="first", type=int, default=300)
    ap.add_argument("--to", dest="last", type=int, default=None)
    ap.add_argument("--split", type=int, default=500)
    args = ap.parse_args(argv)
    rates = {}
    for run in args.runs:
        for f in ("log.csv", "config.json"):
            if not (run / f).exists():
                print(f"{run}: no {f} (a run folder of python -m glint_mi.optimize or the benchmark)", file=sys.stderr)
                return 2
        rates[run] = read_rates(run)
        if not rates[run]:
            print(f"{run}/log.csv: no iteration with rays_per_s logged", file=sys.stderr)
            return 2
    last = args.last if args.last is not None else min(max(r) for r in rates.values())
    print(f"| run | median rays/s, iterations {args.first}-{last} | step time summed, 0-{last} | "
          f"{args.split}-{last} | loss at {last} |")
    print("|---|---|---|---|---|")
    for run, r in rates.items():
        try:
            s = summary(r, args.first, last, args.split)
        except ValueError as e:
            print(f"{run}/log.csv: {e}; give --from under the last iteration every run reached ({last})",
                  file=sys.stderr)
            return 2
        print(f"| {run} | {s['median_rays_per_s']:,.0f} | {s['step_s']:.0f} s | {s['step_s_split']:.0f} s | "
              f"{s['loss']:.4f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
