"""``python -m glint_mi.crosscheck SCENE``: Mitsuba ground truth against Blender Cycles on the same scene.

Needs ``SCENE/cycles/`` from ``python -m glint_mi.dataset cycles SCENE``. Per view: RGB mean relative difference
(|C - M| / mean M, next to Cycles' own noise: the same view rendered with two seeds), depth agreement (median
relative difference, share of pixels within 1 %), normal agreement (mean angle, normals made to face the camera)
and glass-mask agreement (IoU). Writes ``SCENE/crosscheck/report.json`` and ``<view>.png`` (Mitsuba | Cycles |
difference x4 | depth difference | mask) and prints a table.

Known, expected differences: both are unbiased path tracers of the same radiance model, but Mitsuba's
``thindielectric`` is mapped to a Fresnel mix of sharp reflection and straight transmission in Cycles (no
thin-sheet BSDF there), ``roughplastic`` to a Principled BSDF (a different microfacet/diffuse coupling), Cycles'
pixel filter is a 1 px Gaussian vs Mitsuba's box; light units agree for mesh emitters and the world (radiance).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from glint_mi.evaluation.metrics import angles_deg


def compare_view(mi_gt: dict, cy: dict, cy_seed1: dict | None, c2w: np.ndarray) -> dict:
    m, c = mi_gt["rgb"], cy["rgb"]
    denom = max(float(m.mean()), 1e-9)
    glass = mi_gt["glass"] > 0.5
    diff = np.abs(c - m).mean(-1)
    out = {"rgb_rel_diff": float(diff.mean() / denom),
           "rgb_rel_diff_glass": float(diff[glass].mean() / max(float(m[glass].mean()), 1e-9)) if glass.any()
           else float("nan"),
           "rgb_rel_diff_other": float(diff[~glass].mean() / max(float(m[~glass].mean()), 1e-9)) if (~glass).any()
           else float("nan"),
           "rgb_mean_ratio": float(c.mean() / denom)}
    if cy_seed1 is not None:  # two independent estimates: |a - b| = sqrt(2) x one estimate's noise (mean abs)
        dn = np.abs(cy_seed1["rgb"] - c).mean(-1) / np.sqrt(2)
        out["cycles_noise_rel"] = float(dn.mean() / denom)
        if glass.any():
            out["cycles_noise_rel_glass"] = float(dn[glass].mean() / max(float(m[glass].mean()), 1e-9))
    zm, zc = mi_gt["depth"], cy["depth"]
    valid = (zm > 0) & (zc > 0)
    rel = np.abs(zc[valid] - zm[valid]) / zm[valid]
    out["depth_median_rel_diff"] = float(np.median(rel)) if valid.any() else float("nan")
    out["depth_within_1pct"] = float(np.mean(rel < 0.01)) if valid.any() else float("nan")
    fwd = c2w[:3, 2]
    ys, xs = np.mgrid[0:zm.shape[0], 0:zm.shape[1]]
    nm, nc = mi_gt["normal"], cy["normal"]
    ok = valid & (np.linalg.norm(nm, axis=-1) > 0.5) & (np.linalg.norm(nc, axis=-1) > 0.5)
    # face both towards the camera (the forward axis is a fine proxy for the ray at these fields of view)
    flip = lambda n: np.where((np.sum(n * fwd, -1) > 0)[..., None], -n, n)
    ang = angles_deg(flip(nm)[ok], flip(nc)[ok])
    out["normal_mean_angle_deg"] = float(ang.mean()) if ok.any() else float("nan")
    gm, gc = mi_gt["glass"] > 0.5, cy["glass"] > 0.5
    union = np.sum(gm | gc)
    out["glass_iou"] = float(np.sum(gm & gc) / union) if union else float("nan")
    return out


def side_by_side(mi_gt: dict, cy: dict, path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from glint_mi.conventions import linear_to_srgb

    zm, zc = mi_gt["depth"], cy["depth"]
    dz = np.where((zm > 0) & (zc > 0), np.abs(zc - zm) / np.maximum(zm, 1e-9), 0)
    panels = [(linear_to_srgb(mi_gt["rgb"]), "Mitsuba (GT)"), (linear_to_srgb(cy["rgb"]), "Cycles"),
              (np.clip(4 * np.abs(cy["rgb"] - mi_gt["rgb"]).mean(-1), 0, 1), "|diff| x4"),
              (np.clip(dz * 10, 0, 1), "depth rel. diff x10"),
              (np.stack([mi_gt["glass"], cy["glass"], np.zeros_like(cy["glass"])], -1), "glass: Mi red, Cy green")]
    fig, ax = plt.subplots(1, len(panels), figsize=(2.6 * len(panels), 1.9))
    for a, (img, t) in zip(ax, panels):
        a.imshow(np.clip(img, 0, 1), cmap="magma" if img.ndim == 2 else None, vmin=0, vmax=1)
        a.set_title(t, fontsize=8)
        a.axis("off")
    fig.suptitle(title, fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def crosscheck(scene_dir: Path) -> dict:
    from glint_mi.data import load_dataset
    from glint_mi.dataset.cycles_render import read_cycles_exr
    from glint_mi.runs import atomic_write_text

    scene_dir = Path(scene_dir)
    cdir = scene_dir / "cycles"
    if not (cdir / "meta.json").exists():
        raise FileNotFoundError(f"{cdir}: no Cycles renders; run `python -m glint_mi.dataset cycles {scene_dir}`.")
    meta = json.loads((cdir / "meta.json").read_text())
    ds = load_dataset(scene_dir, check_images=False)
    out_dir = scene_dir / "crosscheck"
    out_dir.mkdir(exist_ok=True)
    per_view = {}
    for name in meta["views"]:
        v = ds.view(name)
        gt = v.load_gt()
        cy = read_cycles_exr(cdir / f"{name}.exr")
        s1 = cdir / f"{name}.seed1.exr"
        per_view[name] = compare_view(gt, cy, read_cycles_exr(s1) if s1.exists() else None, v.c2w)
        side_by_side(gt, cy, out_dir / f"{name}.png", f"{scene_dir.name} {name}: rel. diff "
                     f"{per_view[name]['rgb_rel_diff']:.3f}")
    keys = sorted({k for d in per_view.values() for k in d})
    mean = {k: float(np.nanmean([d.get(k, np.nan) for d in per_view.values()])) for k in keys}
    gen = json.loads((scene_dir / "meta.json").read_text()) if (scene_dir / "meta.json").exists() else {}
    report = {"scene": str(scene_dir), "cycles": meta, "mitsuba_spp": gen.get("preset", {}).get("spp"),
              "mean": mean, "per_view": per_view,
              "known_differences": __doc__.split("Known, expected differences:")[1].strip()}
    atomic_write_text(out_dir / "report.json", json.dumps(report, indent=1))
    return report


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m glint_mi.crosscheck", description=__doc__.split("\n")[0])
    ap.add_argument("scene", type=Path)
    args = ap.parse_args(argv)
    try:
        rep = crosscheck(args.scene)
    except FileNotFoundError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    keys = ["rgb_rel_diff", "rgb_rel_diff_glass", "rgb_rel_diff_other", "cycles_noise_rel",
            "cycles_noise_rel_glass", "rgb_mean_ratio", "depth_median_rel_diff", "depth_within_1pct",
            "normal_mean_angle_deg", "glass_iou"]
    print("| view | " + " | ".join(keys) + " |\n|---|" + "---|" * len(keys))
    fmt = lambda v: "-" if v is None or v != v else f"{v:.4g}"
    for name, d in {**rep["per_view"], "mean": rep["mean"]}.items():
        print(f"| {name} | " + " | ".join(fmt(d.get(k)) for k in keys) + " |")
    print(f"wrote {args.scene}/crosscheck/report.json and one side-by-side PNG per view")
    return 0


if __name__ == "__main__":
    sys.exit(main())
