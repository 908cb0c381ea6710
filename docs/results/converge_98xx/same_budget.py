"""GLINT at the converged preset against `3dgs` (growth) at the same budgets, on the glass and off it.

Each method at its own stopping point (the headline) compares GLINT at 120 epochs with `3dgs` at 60; this table
reads both at 60 and at 120 epochs, room by room and seed by seed, from the runs' `metrics.json` (the groups named
below, each a benchmark folder: RUNS/scene_ROOM/METHOD[@seedS]/metrics.json). Missing runs are left out and said.

    python docs/results/converge_98xx/same_budget.py [--extra 3dgs:120=FOLDER ...] [--out FILE.md]
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
G = HERE / "groups"
ROOMS = ("9801", "9802", "9803", "9804")
KEYS = ("psnr", "psnr_glass", "psnr_off_glass")
# (method, epochs) -> the groups holding its runs (seed 0 and seed 1 may sit in different groups)
GROUPS = {("glint", 60): [G / "s54_d54"], ("glint", 120): [G / "s55_e120", G / "s56_e120"],
          ("3dgs", 60): [G / "e60_grow", G / "e60_grow_s1"], ("3dgs", 120): [G / "e120_grow_b", G / "s57_3dgs120"]}


def find(method: str, epochs: int, room: str, seed: int) -> dict | None:
    name = method if seed == 0 else f"{method}@seed{seed}"
    for g in GROUPS[(method, epochs)]:
        f = g / "runs" / f"scene_{room}" / name / "metrics.json"
        if f.is_file():
            m = json.loads(f.read_text())["metrics"]
            return {k: float(m[k]) for k in KEYS}
    return None


def table() -> str:
    lines = ["| epochs | room, seed | GLINT: all / glass / off | `3dgs`: all / glass / off | GLINT - `3dgs`: all / "
             "glass / off |", "|---|---|---|---|---|"]
    missing = []
    for ep in (60, 120):
        diffs = []
        for room in ROOMS:
            for seed in (0, 1):
                a, b = find("glint", ep, room, seed), find("3dgs", ep, room, seed)
                if a is None or b is None:
                    missing.append(f"{ep} epochs, {room} seed {seed}: " + ", ".join(
                        m for m, x in (("glint", a), ("3dgs", b)) if x is None))
                    continue
                d = [a[k] - b[k] for k in KEYS]
                diffs.append(d)
                fmt = lambda r: " / ".join(f"{r[k]:.2f}" for k in KEYS)  # noqa: E731
                lines.append(f"| {ep} | {room}, {seed} | {fmt(a)} | {fmt(b)} | "
                             + " / ".join(f"{x:+.2f}" for x in d) + " |")
        if diffs:
            d = np.array(diffs)
            se = d.std(axis=0, ddof=1) / np.sqrt(len(d)) if len(d) > 1 else np.full(3, np.nan)
            lines.append(f"| {ep} | **mean of {len(d)}** (GLINT higher in {int((d[:, 0] > 0).sum())}; on the glass "
                         f"{int((d[:, 1] > 0).sum())}) | | | **" + " / ".join(f"{m:+.2f}" for m in d.mean(axis=0))
                         + f"** (SE " + " / ".join(f"{s:.2f}" for s in se) + ") |")
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
