"""How much of each native k-buffer list the compositing uses, on a trained run (issue 25).

Renders a run's first test views as ``python -m glint_mi.evaluate`` does and counts, per Gaussian set, the entries
the native traversal listed against the hits the compositing loops consumed before their stopping rule (T below the
pass's bound, or the hit budget). What is listed and never composited is the most an exact "end the list where
compositing stops" could save in callbacks (docs/performance.md).

    .venv/bin/python benchmarks/list_use.py RUN [--views 2]
"""
from __future__ import annotations

import argparse
import importlib
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import glint_mi  # noqa: E402

glint_mi.set_variant()


def count_lists(run: Path, views: int = 2) -> dict:
    """{role: {"listed", "composited", "rounds"}} over the first ``views`` test views of a finished run."""
    import drjit as dr

    from glint_mi import native
    from glint_mi.evaluate import evaluate, load_model, load_run
    from glint_mi.evaluate import eval_options

    march = importlib.import_module("glint_mi_plugins.glint_march").GaussianPasses
    _, ds, cfg, _ = load_run(run)
    integ = load_model(run, cfg)
    if not integ.kbuffer:
        raise SystemExit(f"{run}: the native k-buffer traversal is unavailable here: {native.why_not_here()} "
                         f"(it needs an LLVM variant and the library: python -m glint_mi.native)")
    stats: dict[str, dict] = {}
    role = [None]
    query0, march0 = native.ShellSet.query, march._march_kbuffer

    def query(self, *a, **k):
        prims, ts, cnt = query0(self, *a, **k)
        s = stats.setdefault(role[0], {"listed": 0, "composited": 0, "rounds": 0})
        s["listed"] += int(cnt.sum())
        s["rounds"] += 1
        return prims, ts, cnt

    def counted(self, gs, *a, **k):
        role[0] = gs.role
        out = march0(self, gs, *a, **k)
        hits = dr.sum(out[1])  # the hits each ray composited (UInt32, one entry)
        stats.setdefault(gs.role, {"listed": 0, "composited": 0, "rounds": 0})["composited"] += int(hits[0])
        return out

    native.ShellSet.query, march._march_kbuffer = query, counted
    try:
        evaluate(integ, ds.test_views[:views], write=False, **eval_options(cfg, ds.root))
    finally:
        native.ShellSet.query, march._march_kbuffer = query0, march0
    return stats


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path, help="a finished run folder (config.json and model/)")
    ap.add_argument("--views", type=int, default=2, help="how many test views to render")
    args = ap.parse_args(argv)
    stats = count_lists(args.run, args.views)
    print("| set | query rounds | listed | composited | used |\n|---|---|---|---|---|")
    tot = [0, 0]
    for r, s in stats.items():
        tot[0] += s["listed"]
        tot[1] += s["composited"]
        used = s["composited"] / max(1, s["listed"])
        print(f"| {r} | {s['rounds']} | {s['listed']} | {s['composited']} | {used:.3f} |")
    print(f"| all | | {tot[0]} | {tot[1]} | {tot[1] / max(1, tot[0]):.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
