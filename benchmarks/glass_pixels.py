"""Where the glass is missed: a finished run's geometry on the ground-truth glass pixels, split by its own
transparency (issue 24).

Reads what ``python -m glint_mi.evaluate`` (or the benchmark) saved in ``RUN/renders/<view>.exr`` - nothing is
rendered - and the dataset's ground truth and normal prior. For the glass pixels of the test views, split into
those the run marks transparent (t > 0.5, what t IoU counts) and the rest, it prints the normal error (degrees, as
``normal_mae``), the prior's normal error on the same pixels, and where the run's depth lies against the pane's:
the median of depth / true depth and the share more than 10 % behind the pane (the interface on the surface seen
through the glass, as a see-through prior has it).

``--off-glass`` reads the other pixels (valid ground truth, not glass) the same way: where a prior term costs the
photometric fit, whether the run's normals there are still under the prior's.

    .venv/bin/python benchmarks/glass_pixels.py RUN [RUN ...] [--off-glass]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

SUBSETS = ("all", "t>0.5", "t<=0.5")


def glass_split(pixels: dict) -> dict:
    """Summary of concatenated glass pixels ``{"normal", "prior", "gt_normal" [N,3], "depth", "gt_depth", "t" [N]}``:
    per subset (all, t > 0.5, t <= 0.5) the share of the glass pixels, the mean normal error of the run and of the
    prior, the median depth / true depth and the share of pixels more than 10 % behind the pane."""
    from glint_mi.evaluation.metrics import angles_deg as angles

    t = pixels["t"]
    err = angles(pixels["normal"], pixels["gt_normal"])
    prior_ok = np.linalg.norm(pixels["prior"], axis=-1) > 0.5
    perr = np.where(prior_ok, angles(pixels["prior"], pixels["gt_normal"]), np.nan)
    ratio = np.where(pixels["gt_depth"] > 0, pixels["depth"] / np.maximum(pixels["gt_depth"], 1e-12), np.nan)
    out = {}
    for name, m in zip(SUBSETS, (np.ones_like(t, bool), t > 0.5, t <= 0.5)):
        r = ratio[m][np.isfinite(ratio[m])]
        p = perr[m][np.isfinite(perr[m])]
        out[name] = {"share": float(m.mean()) if len(t) else float("nan"),
                     "normal": float(err[m].mean()) if m.any() else float("nan"),
                     "prior_normal": float(p.mean()) if len(p) else float("nan"),
                     "depth_ratio": float(np.median(r)) if len(r) else float("nan"),
                     "behind": float(np.mean(r > 1.1)) if len(r) else float("nan")}
    return out


def run_pixels(run: Path, off_glass: bool = False) -> dict:
    """The glass pixels (``off_glass``: the valid pixels that are not glass) of a finished run's test views (its
    saved renders), concatenated."""
    from glint_mi.training.batch import RayBank
    from glint_mi.config import TrainConfig
    from glint_mi.data.exr import read_gt_exr
    from glint_mi.runs import RunError, load_run_dataset

    cfg = TrainConfig.load(run / "config.json")
    ds = load_run_dataset(run, cfg, full=cfg.eval_full)
    views = ds.test_views
    bank = RayBank(views, ds.root)
    acc = {k: [] for k in ("normal", "prior", "gt_normal", "depth", "gt_depth", "t")}
    for i, v in enumerate(views):
        exr = run / "renders" / f"{v.name}.exr"
        if not exr.exists():
            raise RunError(f"{exr}: missing; evaluate the run first (python -m glint_mi.evaluate {run})")
        gt = v.load_gt()
        if gt is None:
            raise RunError(f"{v.gt_path or v.name}: no ground truth; glass pixels need a generated dataset")
        ch = read_gt_exr(exr)
        g = ((gt["glass"] <= 0.5) if off_glass else (gt["glass"] > 0.5)) & (gt["depth"] > 0)
        prior = bank.prior_normals_world(i)
        acc["normal"].append(np.stack([ch["N.X"], ch["N.Y"], ch["N.Z"]], -1)[g])
        acc["prior"].append(prior[g])
        acc["gt_normal"].append(gt["normal"][g])
        acc["depth"].append(ch["Z"][g])
        acc["gt_depth"].append(gt["depth"][g])
        acc["t"].append(ch["T"][g])
    return {k: np.concatenate(v) for k, v in acc.items()}


def table(rows: list[tuple[str, dict]], pixels: str = "glass pixels") -> str:
    lines = [f"| run | {pixels} | share | normal error | prior's normal error | depth / true depth "
             "| behind the pane |",
             "|---|---|---|---|---|---|---|"]
    for name, s in rows:
        for sub in SUBSETS:
            x = s[sub]
            lines.append(f"| {name} | {sub} | {x['share']:.2f} | {x['normal']:.1f} | {x['prior_normal']:.1f} | "
                         f"{x['depth_ratio']:.2f} | {x['behind']:.2f} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("runs", nargs="+", type=Path, help="finished run folders (with renders/)")
    ap.add_argument("--off-glass", action="store_true", help="the pixels off the glass instead")
    a = ap.parse_args(argv)
    rows = []
    for run in a.runs:
        rows.append((f"{run.parent.name}/{run.name}", glass_split(run_pixels(run, a.off_glass))))
    print(table(rows, "off-glass pixels" if a.off_glass else "glass pixels"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
