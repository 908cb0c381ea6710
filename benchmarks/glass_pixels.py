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

``--reflection`` prints, on and off the glass, how much of each pixel the reflection set makes: the weight k_s
solved per pixel by least squares from the saved buffers (rgb = (1 - k_s) base + k_s c_R with base = (1 - t) c_I
+ t c_T, the image model of glint-method.md section 2), its mean, median and share over 0.1, and the share of the
pixels' energy that k_s c_R carries (the fit's residual is printed against the signal).

    .venv/bin/python benchmarks/glass_pixels.py RUN [RUN ...] [--off-glass | --reflection]
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


def run_dataset(run: Path):
    """The dataset a finished run was trained on, as its config reads it (evaluation size)."""
    from glint_mi.config import TrainConfig
    from glint_mi.runs import load_run_dataset

    cfg = TrainConfig.load(run / "config.json")
    return load_run_dataset(run, cfg, full=cfg.eval_full)


def saved_view(run: Path, view) -> tuple[dict, dict]:
    """A test view's saved render buffers (what ``python -m glint_mi.evaluate`` wrote in ``RUN/renders/<view>.exr``)
    and its ground truth; refused, naming the fix, when either is missing."""
    from glint_mi.data.exr import read_gt_exr
    from glint_mi.runs import RunError

    exr = run / "renders" / f"{view.name}.exr"
    if not exr.exists():
        raise RunError(f"{exr}: missing; evaluate the run first (python -m glint_mi.evaluate {run})")
    gt = view.load_gt()
    if gt is None:
        raise RunError(f"{view.gt_path or view.name}: no ground truth; glass pixels need a generated dataset")
    return read_gt_exr(exr), gt


def run_pixels(run: Path, off_glass: bool = False) -> dict:
    """The glass pixels (``off_glass``: the valid pixels that are not glass) of a finished run's test views (its
    saved renders), concatenated."""
    from glint_mi.training.batch import RayBank

    ds = run_dataset(run)
    bank = RayBank(ds.test_views, ds.root)
    acc = {k: [] for k in ("normal", "prior", "gt_normal", "depth", "gt_depth", "t")}
    for i, v in enumerate(ds.test_views):
        ch, gt = saved_view(run, v)
        g = ((gt["glass"] <= 0.5) if off_glass else (gt["glass"] > 0.5)) & (gt["depth"] > 0)
        prior = bank.prior_normals_world(i)
        acc["normal"].append(np.stack([ch["N.X"], ch["N.Y"], ch["N.Z"]], -1)[g])
        acc["prior"].append(prior[g])
        acc["gt_normal"].append(gt["normal"][g])
        acc["depth"].append(ch["Z"][g])
        acc["gt_depth"].append(gt["depth"][g])
        acc["t"].append(ch["T"][g])
    return {k: np.concatenate(v) for k, v in acc.items()}


def solve_ks(rgb, c_i, c_r, c_t, t) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel ([..., 3] colours, [...] t): the k_s of rgb = (1 - k_s) base + k_s c_R, base = (1 - t) c_I + t c_T,
    by least squares over the three channels (NaN where c_R and base are too close to tell), and the residual."""
    base = (1.0 - t[..., None]) * c_i + t[..., None] * c_t
    a, b = rgb - base, c_r - base
    bb = (b * b).sum(-1)
    ks = np.where(bb > 1e-6, (a * b).sum(-1) / np.maximum(bb, 1e-12), np.nan)
    return ks, a - np.nan_to_num(ks)[..., None] * b


def reflection_share(run: Path) -> dict:
    """On the glass and off it (valid ground truth), over a finished run's test views: k_s's mean, median and share
    over 0.1 (pixels where it can be told), the share of the energy (sum of the mean channel) that k_s c_R carries,
    and the fit's residual RMS against the pixels' RMS."""
    from glint_mi.runs import RunError

    acc = {"glass": [], "off": []}
    for v in run_dataset(run).test_views:
        ch, gt = saved_view(run, v)
        for k in ("cR.R", "cI.R", "cT.R"):
            if k not in ch:
                raise RunError(f"{run / 'renders' / v.name}.exr: no '{k}' buffer; evaluate the run again with "
                               f"today's code")
        col = lambda p: np.stack([ch[f"{p}R"], ch[f"{p}G"], ch[f"{p}B"]], -1)
        rgb, c_r = col(""), col("cR.")
        ks, res = solve_ks(rgb, col("cI."), c_r, col("cT."), ch["T"])
        for name, m in (("glass", gt["glass"] > 0.5), ("off", gt["glass"] <= 0.5)):
            m = m & (gt["depth"] > 0)
            acc[name].append((ks[m], rgb[m], c_r[m], res[m]))
    out = {}
    for name, parts in acc.items():
        ks, rgb, c_r, res = (np.concatenate([p[i] for p in parts]) for i in range(4))
        told = np.isfinite(ks)
        k = ks[told]
        out[name] = {"pixels": int(len(ks)), "told": float(told.mean()) if len(ks) else float("nan"),
                     "mean": float(k.mean()) if len(k) else float("nan"),
                     "median": float(np.median(k)) if len(k) else float("nan"),
                     "over_0.1": float((k > 0.1).mean()) if len(k) else float("nan"),
                     "energy": float((np.nan_to_num(ks) * c_r.mean(-1)).sum() / max(rgb.mean(-1).sum(), 1e-12)),
                     "residual": float(np.sqrt((res ** 2).mean()) / max(np.sqrt((rgb ** 2).mean()), 1e-12))}
    return out


def reflection_table(rows: list[tuple[str, dict]]) -> str:
    lines = ["| run | pixels | k_s told | k_s mean | median | share > 0.1 | energy from k_s c_R | fit residual |",
             "|---|---|---|---|---|---|---|---|"]
    for name, s in rows:
        for sub, label in (("glass", "glass"), ("off", "off the glass")):
            x = s[sub]
            lines.append(f"| {name} | {label} ({x['pixels']}) | {x['told']:.2f} | {x['mean']:.3f} | {x['median']:.3f} "
                         f"| {x['over_0.1']:.2f} | {x['energy']:.3f} | {x['residual']:.3f} |")
    return "\n".join(lines)


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
    which = ap.add_mutually_exclusive_group()
    which.add_argument("--off-glass", action="store_true", help="the pixels off the glass instead")
    which.add_argument("--reflection", action="store_true", help="the reflection weight k_s on and off the glass")
    a = ap.parse_args(argv)
    if a.reflection:
        print(reflection_table([(f"{run.parent.name}/{run.name}", reflection_share(run)) for run in a.runs]))
        return 0
    rows = []
    for run in a.runs:
        rows.append((f"{run.parent.name}/{run.name}", glass_split(run_pixels(run, a.off_glass))))
    print(table(rows, "off-glass pixels" if a.off_glass else "glass pixels"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
