"""Speed / accuracy trade, measured side by side in one run (issues 5 and 25): what do I give up for speed?

Trains variants of one configuration on one or more generated rooms and seeds (same data, seed and preset per
pair) - training budget (iterations, rays per iteration), number of Gaussians, SH degree, components, first vs
second order, training resolution, hit budget - and measures the first-order glass model (glint mesh mode) against
Mitsuba's `path` at several spp versus a high-spp reference. Writes `training.csv` (one row per room, seed and
variant), `tradeoff.md` (per variant: the mean over rooms and seeds, its spread, and the change against the base
configuration trained on the same room with the same seed; Pareto front of the means marked) and `tradeoff.png`
(PSNR, normal MAE and t IoU against training minutes and against render frames per second, Pareto fronts dashed).

    .venv/bin/python benchmarks/bench_tradeoff.py --data data/unseen/scene_7101 data/unseen/scene_7103 --seeds 2 \
        --preset bench --groups budget,resolution --variants "rays x2,train 1/2 res" --no-mesh --out OUT
    .venv/bin/python benchmarks/bench_tradeoff.py --tiny            # a minute-scale smoke run
    .venv/bin/python benchmarks/bench_tradeoff.py --from-csv OUT   # table and plot again from OUT/training.csv
Every (room, seed) trains the base configuration first (variant "base"); a variant whose configuration equals one
already trained (the base appears in several groups) reuses that run ("trained as" column). Resumable: a finished
run is read back, an interrupted one resumes from its checkpoint. Resolution: `train 1/2 res` trains on 2 x 2
box-averaged photos and priors (same rays per iteration), evaluated at full resolution. `--no-glass-data` adds the
components question on the same room without its glass (`python -m glint_mi.dataset make DIR --no-glass`).
Training times are only comparable between rows trained under the same load (say how many ran side by side).
"""
from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import glint_mi  # noqa: E402

glint_mi.set_variant()

from glint_mi.scene import scene_xml  # noqa: E402
from glint_mi.tradeoff import (GRID, NO_GLASS, as_number, mesh_reference_trade, pareto,  # noqa: E402
                                          run_variants, summarise)

NO_GLASS_GROUP = "components (no glass)"  # another room: its own Pareto front
KEYS = ("room", "seed", "trained_as", "psnr", "ssim", "normal_mae", "absrel", "t_iou", "train_s", "fps")
QUALITY = (("psnr", "PSNR (dB)", True), ("normal_mae", "normal MAE (deg)", False), ("t_iou", "t IoU", True))


def plot(summ, path):
    """Means over rooms and seeds with min-max bars, against training minutes (top) and render fps (bottom)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 3, figsize=(14, 7.4))
    groups = list(dict.fromkeys(r["group"] for r in summ))
    colours = {g: f"C{i}" for i, g in enumerate(groups)}
    for row, (cost, label, scale) in enumerate((("train_s", "training minutes (2 CPU cores)", 1 / 60),
                                                ("fps", "render frames per second (evaluation)", 1.0))):
        for a, (q, qlabel, better) in zip(ax[row], QUALITY):
            for r in summ:
                if r[q] != r[q]:
                    continue
                x = r[cost] * scale
                a.errorbar(x, r[q], yerr=[[r[q] - r[q + "_min"]], [r[q + "_max"] - r[q]]], fmt="o", ms=4,
                           color=colours[r["group"]], ecolor=colours[r["group"]], alpha=0.8, elinewidth=0.8,
                           label=r["group"])
                a.annotate(r["variant"], (x, r[q]), fontsize=6, xytext=(3, 2), textcoords="offset points")
            higher_cost_better = cost == "fps"  # fps: more is better, so the front runs the other way
            same = [r for r in summ if r["group"] != NO_GLASS_GROUP and r[q] == r[q]]
            flip = [{**r, cost: -r[cost]} for r in same] if higher_cost_better else same
            front = [r for r, f in zip(same, pareto(flip, cost=cost, quality=q, higher_is_better=better)) if f]
            front.sort(key=lambda r: r[cost])
            a.plot([r[cost] * scale for r in front], [r[q] for r in front], "k--", lw=0.8, label="Pareto front")
            a.set_xlabel(label), a.set_ylabel(qlabel)
    h, l = ax[0][0].get_legend_handles_labels()
    keep = dict(zip(l, h))
    ax[0][0].legend(keep.values(), keep.keys(), fontsize=7)
    fig.suptitle("mean over rooms and seeds; bars: min-max", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _fmt(v, nd=4):
    return v if isinstance(v, str) else "-" if v is None or v != v else f"{v:.{nd}g}"


def write_outputs(rows, out: Path, mesh=None) -> str:
    """tradeoff.md and tradeoff.png from the per-run rows (those of training.csv); returns the markdown."""
    rows = [r for r in rows if r.get("trained_as", r["variant"]) == r["variant"]]  # a reused run: its own row
    summ = summarise(rows)
    flags = pareto([r for r in summ if r["group"] != NO_GLASS_GROUP])
    front = {(r["group"], r["variant"]) for r, f in zip([r for r in summ if r["group"] != NO_GLASS_GROUP], flags)
             if f}
    rooms = sorted({r["room"] for r in rows})
    seeds = sorted({int(r["seed"]) for r in rows})
    lines = [f"Rooms: {', '.join(rooms)}; seeds: {', '.join(map(str, seeds))}. Per variant: the mean over the runs "
             "(min-max), and the change against `base` trained on the same room with the same seed (mean, min-max).",
             "",
             "| group | variant | runs | PSNR | d PSNR | normal MAE | d normal | AbsRel | t IoU | d t IoU | train min "
             "| x base time | fps | Pareto (time vs PSNR) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    base_t = {(r["room"], r["seed"]): as_number(r["train_s"]) for r in rows if r["variant"] == "base"}
    for s in summ:
        ratio = [as_number(r["train_s"]) / base_t[(r["room"], r["seed"])] for r in rows
                 if (r["group"], r["variant"]) == (s["group"], s["variant"]) and (r["room"], r["seed"]) in base_t]
        rng = lambda q, nd=4: (f"{_fmt(s[q], nd)} ({_fmt(s[q + '_min'], nd)} to {_fmt(s[q + '_max'], nd)})"
                               if s["runs"] > 1 and s[q] == s[q] else _fmt(s[q], nd))
        lines.append(
            f"| {s['group']} | {s['variant']} | {s['runs']} | {rng('psnr')} | {rng('d_psnr', 2)} | "
            f"{rng('normal_mae', 3)} | {rng('d_normal_mae', 2)} | {_fmt(s['absrel'], 3)} | {_fmt(s['t_iou'], 2)} | "
            f"{rng('d_t_iou', 2)} | {_fmt(s['train_s'] / 60, 3)} | {_fmt(float(np.mean(ratio)) if ratio else None, 3)}"
            f" | {_fmt(s['fps'], 3)} | {'yes' if (s['group'], s['variant']) in front else ''} |")
    if mesh:
        lines += ["", "| renderer | max_depth | spp | seconds | mean rel. error vs 1024-spp path (max_depth 64) |",
                  "|---|---|---|---|---|"]
        lines += [f"| {m['renderer']} | {m['max_depth']} | {m['spp']} | {m['seconds']:.3f} | {m['rel_error']:.4f} |"
                  for m in mesh]
    text = "\n".join(lines) + "\n"
    (out / "tradeoff.md").write_text(text)
    plot(summ, out / "tradeoff.png")
    return text


def _room_name(data: Path) -> str:
    return Path(data).resolve().name


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, nargs="+", default=[ROOT / "scenes" / "glass_room"],
                    help="one or more generated scene folders (rooms)")
    ap.add_argument("--seeds", type=int, default=1, help="seeds 0..N-1 per room")
    ap.add_argument("--preset", default="quick", choices=["tiny", "quick", "bench"])
    ap.add_argument("--no-glass-data", type=Path, help="the same room without glass (components question)")
    ap.add_argument("--groups", default=",".join(GRID), help=f"comma list of {list(GRID)}")
    ap.add_argument("--variants", help="comma list: only these variants of the groups (the base always runs)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="override on every variant (e.g. eval_every=1000)")
    ap.add_argument("--iterations", type=int, help="base iterations (default: the preset's)")
    ap.add_argument("--spps", default="4,16,64,256", help="spp of the mesh-mode vs path comparison")
    ap.add_argument("--no-mesh", action="store_true", help="skip the mesh-mode vs path comparison")
    ap.add_argument("--from-csv", action="store_true", help="only re-make tradeoff.md and the plot from training.csv")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "tradeoff")
    ap.add_argument("--tiny", action="store_true", help="smoke run: tiny preset, 30 iterations, two groups")
    args = ap.parse_args(argv)
    if args.from_csv:
        rows = list(csv.DictReader(open(args.out / "training.csv")))
        print(write_outputs(rows, args.out))
        return 0
    if args.tiny:
        args.preset, args.iterations, args.groups, args.spps = "tiny", 30, "budget,resolution", "2,8"
    groups = [x for x in args.groups.split(",") if x]
    for g in groups:
        if g not in GRID:
            ap.error(f"unknown group '{g}'; use a comma list of {list(GRID)}")
    wanted = None
    if args.variants:
        wanted = {v.strip() for v in args.variants.split(",") if v.strip()}
        known = {v for g in groups for v in GRID[g]}
        if wanted - known:
            ap.error(f"--variants: {sorted(wanted - known)} not in the groups {groups} (they have {sorted(known)})")
    from glint_mi.optimize import parse_sets

    extra = parse_sets(args.set)
    args.out.mkdir(parents=True, exist_ok=True)
    base = {"iterations": args.iterations, "epochs": 0.0} if args.iterations else {}
    base.update(extra)
    rows, seen = [], {}
    rooms = [(d, _room_name(d)) for d in args.data]
    if len({n for _, n in rooms}) != len(rooms):
        ap.error("--data: two rooms share a folder name; the runs are kept by that name")
    xmls = {}
    for data, room in rooms + ([(args.no_glass_data, _room_name(args.no_glass_data))] if args.no_glass_data else []):
        xmls[room] = args.out / "scenes" / f"{room}.xml"
        xmls[room].parent.mkdir(parents=True, exist_ok=True)
        xmls[room].write_text(scene_xml(data))
    for seed in range(args.seeds):
        for data, room in rooms:
            xml = xmls[room]
            runs = args.out / "runs" / room / f"seed{seed}"
            todo = [("base", {"base": {}})] + [
                (g, {k: v for k, v in GRID[g].items() if wanted is None or k in wanted}) for g in groups]
            for g, variants in todo:
                for r in run_variants(xml, runs / g if g != "base" else runs, variants, args.preset, seen=seen,
                                      seed=seed, **base):
                    rows.append({"group": g, "room": room, "seed": seed, **r})
            if args.no_glass_data:
                ng = _room_name(args.no_glass_data)
                for r in run_variants(xmls[ng], args.out / "runs" / ng / f"seed{seed}", NO_GLASS, args.preset,
                                      seen=seen, seed=seed, **base):
                    rows.append({"group": NO_GLASS_GROUP, "room": ng, "seed": seed, **r})
    with open(args.out / "training.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=["group", "variant", *KEYS], extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{r[k]:.6g}" if isinstance(r.get(k), float) else r.get(k)) for k in
                        ("group", "variant", *KEYS)})
    mesh = None if args.no_mesh else mesh_reference_trade(tuple(int(s) for s in args.spps.split(",")))
    if mesh:
        with open(args.out / "mesh_vs_path.csv", "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=["renderer", "max_depth", "spp", "seconds", "rel_error"])
            w.writeheader()
            w.writerows(mesh)
    print(write_outputs(rows, args.out, mesh))
    print(f"wrote {args.out}/training.csv, tradeoff.md, tradeoff.png" + ("" if args.no_mesh else ", mesh_vs_path.csv"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
