"""Evaluate a trained run: ``python -m glint_mi.evaluate RUN`` renders the test views and recomputes the metrics.

Renders at the training resolution (``--full``: the dataset's full resolution) with a progress bar, and writes, as
each view finishes, ``RUN/per_view/<view>.json``, ``RUN/renders/<view>_{rgb,depth,normal,t,cI,cR,cT}.png`` and one
``<view>.exr`` with every buffer (R G B and the components cI.*, cR.*, cT.* as linear light: the model's colours are
fitted to sRGB photos and converted; Z planar depth, N.X N.Y N.Z world normal, T transparency), then
``RUN/metrics.json`` (means, FPS, train time, machine). Ctrl-C keeps the views already done. The functions are
:mod:`glint_mi.evaluation.renders`.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from glint_mi.evaluation import metrics as M
from glint_mi.evaluation.renders import (CHUNK, PARTIAL, check_finished_run, eval_options, evaluate, load_model,
                                         load_run, render_view, save_renders)

__all__ = ["CHUNK", "PARTIAL", "eval_options", "evaluate", "load_model", "load_run", "render_view", "save_renders",
           "main"]  # the library's names, where scripts of earlier sessions import them


def _resolution(folder: Path):
    """The resolution [W, H] of the complete evaluation in ``folder`` (None when there is none)."""
    p = folder / "metrics.json"
    return json.loads(p.read_text()).get("resolution") if p.exists() else None


HELD: list = []  # the run locks this process holds (the command's)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m glint_mi.evaluate", description=__doc__.split("\n")[0])
    ap.add_argument("run", type=Path)
    ap.add_argument("--full", action="store_true",
                    help="render the test views at the dataset's full resolution (default: the training one)")
    ap.add_argument("--max-hits", type=int, default=None, metavar="N",
                    help="render with a hit budget of N per ray and pass instead of the run's (a model trained with "
                         "a budget its rays spend has learnt the cut: compare); writes RUN/max_hits_N/, not the "
                         "run's own metrics")
    ap.add_argument("--no-progress", action="store_true")
    args = ap.parse_args(argv)
    if args.max_hits is not None and args.max_hits < 1:
        print(f"error: --max-hits {args.max_hits}: give a positive hit budget (the run's is in "
              f"{args.run}/config.json, max_hits)", file=sys.stderr)
        return 2
    from glint_mi.config import ConfigError
    from glint_mi.data import DatasetError
    from glint_mi import VariantError
    from glint_mi.runs import RunError, hold_run

    try:
        check_finished_run(args.run)  # before the lock, which would make the folder
        # one process at a time on a run: two evaluations would move their renders over each other's, and an
        # evaluation beside a resumed training would read a model that is being replaced
        HELD.append(hold_run(args.run))  # held until the process ends
        integ, ds, cfg, train_s = load_run(args.run, full=args.full, max_hits=args.max_hits)
    except (RunError, DatasetError, ConfigError, VariantError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"\ninterrupted before any view was rendered; {args.run} is as it was", file=sys.stderr)
        return 130
    try:
        out = args.run if args.max_hits is None else args.run / f"max_hits_{args.max_hits}"
        v0 = ds.test_views[0] if ds.test_views else None
        if args.full and v0 is not None and [v0.width, v0.height] != _resolution(out):
            out = out / f"eval_{v0.width}x{v0.height}"  # beside the run's own evaluation, never mixed with it
        res = evaluate(integ, ds.test_views, out, train_s, progress=not args.no_progress,
                       **eval_options(cfg, ds.root))
    except KeyboardInterrupt:
        print(f"\ninterrupted: {args.run}/metrics.json is still the last complete evaluation", file=sys.stderr)
        return 130
    except DatasetError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    name = args.run.name if args.max_hits is None else f"{args.run.name} (max_hits {args.max_hits})"
    print(M.table({name: res["metrics"]}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
