"""Speed / accuracy trade, measured side by side in one run (issue 5): what do I give up for speed?

Trains variants of one configuration on one generated room (same data, seed and preset) - training budget
(iterations, rays per iteration), number of Gaussians, SH degree, components, first vs second order - and measures
the first-order glass model (glint mesh mode) against Mitsuba's `path` at several spp versus a high-spp reference.
Writes CSV, a markdown table with the Pareto front marked, and a plot (train time vs PSNR / normal MAE / AbsRel).

    .venv/bin/python benchmarks/bench_tradeoff.py --data scenes/glass_room --preset quick --out benchmarks/results/tradeoff
    .venv/bin/python benchmarks/bench_tradeoff.py --tiny            # a minute-scale smoke run
Resolution: `train 1/2 res` trains on 2 x 2 box-averaged photos and priors (same rays per iteration), evaluated at
full resolution. `--no-glass-data` adds the components question on the same room without its glass
(`python -m glint_mi.dataset make DIR --no-glass`). Variants whose configuration equals one already trained (the
base appears in several groups) reuse that run ("trained as" column).
"""
from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import glint_mi  # noqa: E402

glint_mi.set_variant()

from glint_mi.scene import scene_xml  # noqa: E402
from glint_mi.tradeoff import GRID, NO_GLASS, mesh_reference_trade, pareto, run_variants  # noqa: E402

NO_GLASS_GROUP = "components (no glass)"  # another room: its own Pareto front
KEYS = ("trained_as", "psnr", "normal_mae", "absrel", "t_iou", "train_s", "fps")


def plot(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 3, figsize=(13, 3.6))
    for a, (q, better) in zip(ax, (("psnr", True), ("normal_mae", False), ("absrel", False))):
        groups = sorted({r["group"] for r in rows})
        for g in groups:
            sel = [r for r in rows if r["group"] == g]
            a.scatter([r["train_s"] for r in sel], [r[q] for r in sel], label=g, s=18)
            for r in sel:
                a.annotate(r["variant"], (r["train_s"], r[q]), fontsize=6)
        same = [r for r in rows if r["group"] != NO_GLASS_GROUP]  # the front: one scene only
        front = [r for r, f in zip(same, pareto(same, quality=q, higher_is_better=better)) if f]
        front.sort(key=lambda r: r["train_s"])
        a.plot([r["train_s"] for r in front], [r[q] for r in front], "k--", lw=0.8, label="Pareto front")
        a.set_xlabel("train time (s, 2 CPU cores)"), a.set_ylabel(q)
    ax[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=ROOT / "scenes" / "glass_room", help="a generated scene folder")
    ap.add_argument("--preset", default="quick", choices=["tiny", "quick", "bench"])
    ap.add_argument("--no-glass-data", type=Path, help="the same room without glass (components question)")
    ap.add_argument("--groups", default=",".join(GRID), help=f"comma list of {list(GRID)}")
    ap.add_argument("--iterations", type=int, help="base iterations (default: the preset's)")
    ap.add_argument("--spps", default="4,16,64,256", help="spp of the mesh-mode vs path comparison")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "tradeoff")
    ap.add_argument("--tiny", action="store_true", help="smoke run: tiny preset, 30 iterations, two groups")
    args = ap.parse_args(argv)
    if args.tiny:
        args.preset, args.iterations, args.groups, args.spps = "tiny", 30, "budget,resolution", "2,8"
    args.out.mkdir(parents=True, exist_ok=True)
    xml = args.out / "scene.xml"
    xml.write_text(scene_xml(args.data))
    base = {"iterations": args.iterations, "epochs": 0.0} if args.iterations else {}
    rows, seen = [], {}
    for g in [x for x in args.groups.split(",") if x]:
        if g not in GRID:
            ap.error(f"unknown group '{g}'; use a comma list of {list(GRID)}")
        for r in run_variants(xml, args.out / "runs" / g, GRID[g], args.preset, seen=seen, **base):
            rows.append({"group": g, **r})
    if args.no_glass_data:
        xml_ng = args.out / "scene_no_glass.xml"
        xml_ng.write_text(scene_xml(args.no_glass_data))
        for r in run_variants(xml_ng, args.out / "runs" / "no_glass", NO_GLASS, args.preset, seen=seen, **base):
            rows.append({"group": NO_GLASS_GROUP, **r})
    glass_rows = [r for r in rows if r["group"] != NO_GLASS_GROUP]
    front = pareto(glass_rows) + pareto(rows[len(glass_rows):])  # each room its own front
    with open(args.out / "training.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=["group", "variant", *KEYS, "pareto"], extrasaction="ignore")
        w.writeheader()
        for r, p in zip(rows, front):
            w.writerow({**{k: (f"{r[k]:.6g}" if isinstance(r.get(k), float) else r.get(k)) for k in
                           ("group", "variant", *KEYS)}, "pareto": p})
    lines = ["| group | variant | " + " | ".join(KEYS) + " | Pareto (time vs PSNR) |",
             "|---|---|" + "---|" * (len(KEYS) + 1)]
    fmt = lambda v: v if isinstance(v, str) else "-" if v is None or v != v else f"{v:.4g}"
    for r, p in zip(rows, front):
        lines.append(f"| {r['group']} | {r['variant']} | " + " | ".join(fmt(r.get(k)) for k in KEYS)
                     + f" | {'yes' if p else ''} |")
    mesh = mesh_reference_trade(tuple(int(s) for s in args.spps.split(",")))
    with open(args.out / "mesh_vs_path.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=["renderer", "max_depth", "spp", "seconds", "rel_error"])
        w.writeheader()
        w.writerows(mesh)
    lines += ["", "| renderer | max_depth | spp | seconds | mean rel. error vs 1024-spp path (max_depth 64) |",
              "|---|---|---|---|---|"]
    lines += [f"| {m['renderer']} | {m['max_depth']} | {m['spp']} | {m['seconds']:.3f} | {m['rel_error']:.4f} |"
              for m in mesh]
    text = "\n".join(lines) + "\n"
    (args.out / "tradeoff.md").write_text(text)
    plot(rows, args.out / "tradeoff.png")
    print(text)
    print(f"wrote {args.out}/training.csv, mesh_vs_path.csv, tradeoff.md, tradeoff.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
