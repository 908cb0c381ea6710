"""The sixty-eighth session's look at a per-pixel normal-prior weight (README, "A consistency term that moves only the
normals"): can the SfM points say WHERE the normal prior errs, not only how much on the mean?

At each tracked feature on a planar SfM neighbourhood (RayBank.normal_prior_sfm_angles, the angles
normal_prior_sfm_agreement summarises: 12 nearest points, planarity 0.05) the angle between its plane and the prior's
normal at its pixel is set beside the prior's true error there (ground truth read to score the idea, never by
training). Then each pixel takes its nearest feature's
inverse-variance weight min(1, (10 / angle)^2) within a radius (x image width), optionally only where its prior normal
is within GATE deg of the feature pixel's; the table gives the share of the weight cut on the pixels whose prior errs
by > 30 deg and on those where it errs by < 15 deg. A weight that localises the error cuts the first far more.

    python docs/results/coarse_to_fine/local68.py [--data /work/data73] [--rooms 7301,7302,7303] [--out local68.md]
"""
import argparse
from pathlib import Path

import numpy as np

BINS = ((0, 5), (5, 10), (10, 20), (20, 30), (30, 45), (45, 90))
RADII = (0.04, 0.08, 0.15, 0.3)
GATES = (None, 10, 20)


def room_tables(root: Path, ref: float = 10.0) -> tuple[list[str], list[str]]:
    from scipy.ndimage import distance_transform_edt

    from glint_mi.data import load_dataset
    from glint_mi.training.batch import RayBank

    ds = load_dataset(root, downscale=2)  # the 40-epoch runs' 96 x 54
    bank = RayBank(ds.train_views, ds.root, use_priors=True)
    sfm, true, cut = [], [], {}
    for i, (row, col, ang) in bank.normal_prior_sfm_angles(ds.observations(), ds.points).items():
        gt = bank.views[i].load_gt()
        npw = bank.prior_normals_world(i)
        h, w = npw.shape[:2]
        valid = (np.linalg.norm(npw, axis=-1) > 0.5) & (gt["depth"] > 0)
        nn = npw / np.maximum(np.linalg.norm(npw, axis=-1, keepdims=True), 1e-12)
        err = np.degrees(np.arccos(np.clip(np.abs((nn * gt["normal"]).sum(-1)), 0, 1)))
        ok = valid[row, col]  # where the ground truth scores the feature
        r, c, a = row[ok], col[ok], ang[ok]
        sfm.append(a)
        true.append(err[r, c])
        if not ok.any():
            continue
        seed = np.zeros((h, w), bool)
        seed[r, c] = True
        wmap = np.ones((h, w))
        wmap[r, c] = np.minimum(1.0, (ref / np.maximum(a, 1e-6)) ** 2)
        fn = np.zeros((h, w, 3))
        fn[r, c] = nn[r, c]
        d, (ri, ci) = distance_transform_edt(~seed, return_indices=True)
        bad, good = valid & (err > 30), valid & (err < 15)
        for rad in RADII:
            for gate in GATES:
                lab = d <= rad * w
                if gate is not None:
                    lab &= np.abs((nn * fn[ri, ci]).sum(-1)) >= np.cos(np.radians(gate))
                wp = np.where(lab, wmap[ri, ci], 1.0)
                acc = cut.setdefault((rad, gate), np.zeros(4))
                acc += ((1 - wp)[bad].sum(), bad.sum(), (1 - wp)[good].sum(), good.sum())
    sfm, true = np.concatenate(sfm), np.concatenate(true)
    head = [f"{len(sfm)} features; SfM angle mean {sfm.mean():.1f} deg, the prior's true error there "
            f"{true.mean():.1f}; correlation {np.corrcoef(sfm, true)[0, 1]:.2f}", "",
            "| SfM angle (deg) | features | true error, mean / median | share erring > 30 deg |", "|---|---|---|---|"]
    for lo, hi in BINS:
        m = (sfm >= lo) & (sfm < hi)
        if m.any():
            head.append(f"| {lo}-{hi} | {m.sum()} | {true[m].mean():.1f} / {np.median(true[m]):.1f} | "
                        f"{(true[m] > 30).mean():.2f} |")
    rows = ["| radius (x width) | gate (deg) | weight cut where the prior errs > 30 deg | where it errs < 15 deg |",
            "|---|---|---|---|"]
    for (rad, gate), (cb, nb_, cg, ng) in cut.items():
        rows.append(f"| {rad:.2f} | {gate if gate is not None else '-'} | {cb / max(nb_, 1):.3f} | "
                    f"{cg / max(ng, 1):.3f} |")
    return head, rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default="/work/data73")
    ap.add_argument("--rooms", default="7301,7302,7303")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    lines = [f"`python docs/results/coarse_to_fine/local68.py --rooms {args.rooms}` (96 x 54, training views)", ""]
    for room in args.rooms.split(","):
        head, rows = room_tables(Path(args.data) / f"r{room}" / f"scene_{room}")
        lines += [f"### {room}", "", *head, "", *rows, ""]
    text = "\n".join(lines)
    print(text)
    if args.out:
        Path(args.out).write_text(text)


if __name__ == "__main__":
    main()
