"""The sixty-ninth session's look (README, "What was decided, and where it departs from the declaration"): does the
part of the normal prior's error that repeats across views tell the rooms where cutting the consistency's pull
helped (7303, 9803) from those where it hurt (7301 and 7302 at x2)? Measured without ground truth.

At each SfM point on a planar neighbourhood (12 nearest points, planarity 0.05: RayBank.planar_prior_normals, the
features of RayBank.normal_prior_sfm_angles) tracked in >= 3 training views, with a normal prior at its pixel in each:
the mean over those views of the angle between the prior's normal and the plane (the per-view error), and the angle
between the views' mean normal and the plane (the error that repeats in every view: an error drawn independently
per view averages out of it).

    python docs/results/coarse_to_fine/consist69.py [--data73 /work/data73] [--data98 /work/data98_r] \\
        [--out consist69.md]
"""
import argparse
from pathlib import Path

import numpy as np

# (label, room folder under DATA73 or DATA98, what cutting the pull did there: coarse_to_fine, 68th-69th sessions)
ROOMS = (("7301 x1", "73:r7301/scene_7301", "helped at share 0.41 (+0.37 dB, two seeds)"),
         ("7302 x1", "73:r7302/scene_7302", "helped at 0.53 (+0.24)"),
         ("7303 x1", "73:r7303/scene_7303", "helped at 0.14 (+0.56, depth under its priors)"),
         ("9801", "98:r9801/scene_9801", "neutral at 0.22 (-0.04, AbsRel +7 %)"),
         ("9802", "98:r9802/scene_9802", "neutral at 0.20 (-0.01)"),
         ("9803", "98:r9803/scene_9803", "helped at 0.28 (+0.28)"),
         ("7301 x1.25", "73:levels_7301/realistic_e1.25/scene_7301", "hurt at 0.28 (-0.39, AbsRel +22 %)"),
         ("7302 x1.25", "73:levels_7302/realistic_e1.25/scene_7302", "helped a little at 0.39 (+0.16, AbsRel -8 %)"),
         ("7301 x2", "73:levels_7301/realistic_e2.0/scene_7301", "hurt at 0.12 (-0.32, AbsRel +28 %)"),
         ("7302 x2", "73:levels_7302/realistic_e2.0/scene_7302", "hurt at 0.20 (glass lost: t IoU 0.59 -> 0.36)"),
         ("7301 v1 x2", "73:levels_7301/realistic-v1_e2.0/scene_7301",
          "hurt the geometry at 0.13 (+0.11 dB, AbsRel +16 %)"),
         ("7302 v1 x2", "73:levels_7302/realistic-v1_e2.0/scene_7302",
          "hurt the geometry at 0.12 (+0.50 dB, glass normals +20 deg)"))


def angles(root: Path, k: int = 12, planarity: float = 0.05, min_views: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Per SfM point tracked in >= min_views views: (mean per-view angle, angle of the views' mean normal), deg."""
    from glint_mi.data import load_dataset
    from glint_mi.training.batch import RayBank

    ds = load_dataset(root, downscale=2)  # the 40-epoch runs' 96 x 54
    bank = RayBank(ds.train_views, ds.root, use_priors=True)
    seen: dict[int, list] = {}
    planes: dict[int, np.ndarray] = {}
    # the features normal_prior_sfm_angles measures, grouped by their SfM point
    for _, _, _, j, n, plane in bank.planar_prior_normals(ds.observations(), ds.points, k, planarity):
        for jj, v, p in zip(j, n, plane):
            seen.setdefault(int(jj), []).append(v / np.linalg.norm(v))
            planes[int(jj)] = p
    per_view, common = [], []
    for jj, vs in seen.items():
        if len(vs) < min_views:
            continue
        V, p = np.array(vs), planes[jj]
        V = V * np.sign(V @ p)[:, None]  # unoriented: each view's normal on the plane normal's side
        per_view.append(np.degrees(np.arccos(np.clip(np.abs(V @ p), 0, 1))).mean())
        m = V.mean(0)
        common.append(np.degrees(np.arccos(np.clip(abs(m @ p) / np.linalg.norm(m), 0, 1))))
    return np.array(per_view), np.array(common)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data73", type=Path, default=Path("/work/data73"))
    ap.add_argument("--data98", type=Path, default=Path("/work/data98_r"))
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("consist69.md"))
    a = ap.parse_args()
    lines = ["`python docs/results/coarse_to_fine/consist69.py` (96 x 54, training views; no ground truth read)", "",
             "| room-level | points in >= 3 views | per-view angle (deg) | the views' mean normal's angle | ratio | "
             "cutting the pull |", "|---|---|---|---|---|---|"]
    for label, where, effect in ROOMS:
        base, rel = where.split(":")
        pv, cm = angles((a.data73 if base == "73" else a.data98) / rel)
        lines.append(f"| {label} | {len(pv)} | {pv.mean():.1f} | {cm.mean():.1f} | {cm.mean() / pv.mean():.2f} | "
                     f"{effect} |")
        print(lines[-1], flush=True)
    a.out.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
