"""GLINT at the converged preset against `3dgs` (growth) at the same budgets, on the glass and off it.

Each method at its own stopping point (the headline) compares GLINT at 120 epochs with `3dgs` at 60; this table
reads both at 60 and at 120 epochs, room by room and seed by seed, from the groups named below (benchmark folders,
read by `benchmarks/converge_table.py`'s `read_runs`; the means, wins and standard error by its `compare`). Missing
runs are left out and said.

    python docs/results/converge_98xx/same_budget.py [--extra 3dgs:120=FOLDER ...] [--out FILE.md]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[2] / "benchmarks"))
from converge_table import compare, read_runs  # noqa: E402

G = HERE / "groups"
ROOMS = ("9801", "9802", "9803", "9804")
KEYS = ("psnr", "psnr_glass", "psnr_off_glass")
# (method, epochs) -> the groups holding its runs (seed 0 and seed 1 may sit in different groups)
GROUPS = {("glint", 60): [G / "s54_d54"], ("glint", 120): [G / "s55_e120", G / "s56_e120"],
          ("3dgs", 60): [G / "e60_grow", G / "e60_grow_s1"], ("3dgs", 120): [G / "e120_grow_b", G / "s57_3dgs120"]}


def runs(method: str, epochs: int) -> dict:
    """{(scene, seed): run row} of ``method`` in its groups at ``epochs`` (a run found twice: the first group's)."""
    found = {}
    for g in GROUPS[(method, epochs)]:
        for r in read_runs(g):
            if r["method"] == method:
                found.setdefault((r["scene"], r["seed"]), r)
    return found


def table() -> str:
    lines = ["| epochs | room, seed | GLINT: all / glass / off | `3dgs`: all / glass / off | GLINT - `3dgs`: all / "
             "glass / off |", "|---|---|---|---|---|"]
    missing = []
    fmt = lambda r: " / ".join(f"{r[k]:.2f}" for k in KEYS)  # noqa: E731
    for ep in (60, 120):
        a, b = runs("glint", ep), runs("3dgs", ep)
        for room in ROOMS:
            for seed in (0, 1):
                key = (f"scene_{room}", seed)
                if key not in a or key not in b:
                    missing.append(f"{ep} epochs, {room} seed {seed}: " + ", ".join(
                        m for m, x in (("glint", a), ("3dgs", b)) if key not in x))
                    continue
                lines.append(f"| {ep} | {room}, {seed} | {fmt(a[key])} | {fmt(b[key])} | "
                             + " / ".join(f"{a[key][k] - b[key][k]:+.2f}" for k in KEYS) + " |")
        c = compare(list(a.values()), list(b.values()))
        if c is not None:
            lines.append(f"| {ep} | **mean of {c['n']}** (GLINT higher in {c['wins']}; on the glass "
                         f"{c['wins_glass']}) | | | **" + " / ".join(f"{c['mean'][k]:+.2f}" for k in KEYS)
                         + f"** (SE {c['se']:.2f}) |")
    text = "\n".join(lines) + "\n"
    if missing:
        text += "\nLeft out (no run): " + "; ".join(missing) + "\n"
    return text


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--extra", action="append", default=[],
                    help="METHOD:EPOCHS=FOLDER, a benchmark folder added to that method's groups at that budget")
    ap.add_argument("--out", type=Path)
    args = ap.parse_args(argv)
    for e in args.extra:
        try:
            key, folder = e.split("=", 1)
            method, ep = key.split(":")
            GROUPS[(method, int(ep))].append(Path(folder))
        except (ValueError, KeyError):
            raise SystemExit(f"--extra {e!r}: write METHOD:EPOCHS=FOLDER with METHOD:EPOCHS one of "
                             f"{', '.join(f'{m}:{x}' for m, x in GROUPS)}")
    text = table()
    print(text)
    if args.out:
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
