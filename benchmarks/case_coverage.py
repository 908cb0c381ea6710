"""How much of the view the glass case fills, per seed, from the generator's layout alone: nothing is rendered.

For each seed it builds the room and the camera arc exactly as ``python -m glint_mi.dataset make`` would (same
draws; the arc depends on the number of views, so pass the one you will generate with) and prints the mean share of
the image covered by the case's bounding box (its eight corners projected, the box clipped to the image), the
distance from the first camera to the case's centre and the case's size. It is how a tuning room is chosen to
resemble a kind of room (a case that fills the view, one seen from afar) without looking at any render or result.

    .venv/bin/python benchmarks/case_coverage.py 7301 7302 7303 [--views 48] [--range 7304 7340] [--min 0.6]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def case_coverage(seed: int, views: int = 48, width: int = 192, height: int = 108) -> dict:
    """Mean share of the image the case's bounding box covers over the arc's views, the first camera's distance to
    the case centre (m) and the case's size (m)."""
    from glint_mi.dataset.trajectory import trajectory
    from glint_mi.dataset.room import build_room

    room = build_room(seed)
    cams = trajectory(room, views, width, height, seed)
    lo, hi = np.asarray(room.case_lo, float), np.asarray(room.case_hi, float)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    shares = []
    for cam in cams:
        w2c = np.linalg.inv(cam.c2w)
        p = corners @ w2c[:3, :3].T + w2c[:3, 3]
        if (p[:, 2] <= 1e-3).any():          # a corner behind the camera: the case fills the view
            shares.append(1.0)
            continue
        u = cam.fx * p[:, 0] / p[:, 2] + cam.cx
        v = cam.fy * p[:, 1] / p[:, 2] + cam.cy
        du = np.clip(u.max(), 0, width) - np.clip(u.min(), 0, width)
        dv = np.clip(v.max(), 0, height) - np.clip(v.min(), 0, height)
        shares.append(du * dv / (width * height))
    return {"seed": seed, "coverage": float(np.mean(shares)),
            "distance": float(np.linalg.norm(cams[0].c2w[:3, 3] - room.case_center)), "size": (hi - lo).tolist()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("seeds", nargs="*", type=int)
    ap.add_argument("--range", nargs=2, type=int, metavar=("FIRST", "LAST"), help="also every seed FIRST..LAST")
    ap.add_argument("--views", type=int, default=48)
    ap.add_argument("--min", type=float, default=0.0, help="print only seeds whose coverage is at least this")
    a = ap.parse_args(argv)
    seeds = list(a.seeds) + (list(range(a.range[0], a.range[1] + 1)) if a.range else [])
    if not seeds:
        ap.error("give seeds or --range FIRST LAST")
    print(f"{'seed':>6} {'coverage':>8} {'distance':>8}  case size (m)")
    for s in seeds:
        try:
            r = case_coverage(s, a.views)
        except RuntimeError as e:            # no camera arc fits the room
            print(f"{s:>6} {'-':>8} {'-':>8}  {e}")
            continue
        if r["coverage"] >= a.min:
            print(f"{s:>6} {r['coverage']:8.2f} {r['distance']:8.2f}  " + " x ".join(f"{x:.2f}" for x in r["size"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
