"""How right L_trans's SfM see-through cue is, against ground-truth glass (issue 24): nothing is trained.

For each dataset (with SfM tracks, a depth prior and ground-truth glass masks) it aligns the depth prior to the SfM
points and computes the cue exactly as a training run does (``RayBank.see_through_cue``), then counts over the
training pixels: the share of the glass pixels the cue labels "seen through" (+1) and "opaque" (-1), the same
shares off the glass, with ``--photo Q`` the shares above the photo-inconsistency's Q-quantile (where ``cue_photo``
drops opaque votes and ``prior_photo`` the priors), and what the SfM depth term keeps on the glass (tracked pixels whose feature lies more than
10 % behind the pane pull the interface behind it).

    .venv/bin/python benchmarks/cue_accuracy.py DATASET [DATASET ...] [--margin 0.05] [--radius 0.04] [--photo Q]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def cue_accuracy(root, margin: float = 0.05, radius: float = 0.04, observations=None, depth_affine=None,
                 votes: str = "view", point_share: float = 0.2, photo: float = 0.0) -> dict:
    """The cue's labels on and off the ground-truth glass of ``root``'s training views (shares of pixels).
    ``observations`` / ``depth_affine`` replace the dataset's SfM tracks / the SfM alignment (tests)."""
    from glint_mi.training.batch import RayBank
    from glint_mi.data import load_dataset

    ds = load_dataset(root)
    bank = RayBank(ds.train_views, ds.root, use_priors=True, glass_masks="gt")  # gt: the training views' glass
    if depth_affine is None:
        bank.align_depth_priors(ds.points, seed=0)
    else:
        bank.depth_affine = np.asarray(depth_affine, np.float64)
    obs = ds.observations() if observations is None else observations
    rep = bank.see_through_cue(obs, margin, radius, votes, point_share, photo)
    bank.set_sfm_depth(obs)
    glass = bank.glass > 0.5
    depth = np.concatenate([np.asarray(v.load_gt()["depth"]).reshape(-1) for v in ds.train_views])
    cue = bank.cue if bank.cue is not None else np.zeros(glass.size, np.int8)
    share = lambda m, sel: float(np.mean(m[sel])) if sel.any() else float("nan")
    z = bank.sfm_depth if bank.sfm_depth is not None else np.zeros(glass.size, np.float32)
    tracked = z > 0
    photo_above = {}
    if photo > 0:  # what prior_photo at the same q leaves without priors, on the glass and off it
        above = bank.photo_moving(photo)
        above = np.zeros(glass.size, bool) if above is None else above
        photo_above = {"photo_above_on_glass": share(above, glass), "photo_above_off_glass": share(above, ~glass)}
    return {"dataset": str(root), "glass_share": float(glass.mean()), **photo_above,
            "through_on_glass": share(cue == 1, glass), "opaque_on_glass": share(cue == -1, glass),
            "through_off_glass": share(cue == 1, ~glass), "opaque_off_glass": share(cue == -1, ~glass),
            "through_all": float(np.mean(cue == 1)), "opaque_all": float(np.mean(cue == -1)),
            "sfm_depth_glass_pixels": int((tracked & glass).sum()),
            "sfm_depth_behind_pane": int((tracked & glass & (z > 1.1 * depth)).sum()),
            "sfm_depth_other_pixels": int((tracked & ~glass).sum()), "report": rep}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("datasets", nargs="+", type=Path)
    ap.add_argument("--margin", type=float, default=0.05, help="the cue's margin (TrainConfig.cue_margin)")
    ap.add_argument("--radius", type=float, default=0.04, help="the cue's radius (TrainConfig.cue_radius)")
    ap.add_argument("--votes", choices=["view", "point"], default="view", help="TrainConfig.cue_votes")
    ap.add_argument("--point-share", type=float, default=0.2, help="TrainConfig.cue_point_share")
    ap.add_argument("--photo", type=float, default=0.0, help="TrainConfig.cue_photo (0: off)")
    a = ap.parse_args(argv)
    print(f"margin {a.margin}, radius {a.radius}, votes {a.votes}"
          + (f" (point share {a.point_share})" if a.votes == "point" else "")
          + (f", opaque votes dropped above the {a.photo:g} quantile of photo-inconsistency" if a.photo else "")
          + "; shares of training pixels\n")
    extra = " above q on glass | above q off glass |" if a.photo else ""
    print("| dataset | glass | +1 on glass | -1 on glass | +1 off glass | -1 off glass | SfM depth on glass "
          "(behind the pane) | SfM depth elsewhere |" + extra)
    print("|---|---|---|---|---|---|---|---|" + "---|---|" * bool(a.photo))
    for d in a.datasets:
        r = cue_accuracy(d, a.margin, a.radius, votes=a.votes, point_share=a.point_share, photo=a.photo)
        f = lambda x: "-" if not np.isfinite(x) else f"{x:.3f}"
        print(f"| {d} | {r['glass_share']:.3f} | {f(r['through_on_glass'])} | {f(r['opaque_on_glass'])} | "
              f"{f(r['through_off_glass'])} | {f(r['opaque_off_glass'])} | {r['sfm_depth_glass_pixels']} "
              f"({r['sfm_depth_behind_pane']}) | {r['sfm_depth_other_pixels']} |"
              + (f" {f(r['photo_above_on_glass'])} | {f(r['photo_above_off_glass'])} |" if a.photo else ""))


if __name__ == "__main__":
    main()
