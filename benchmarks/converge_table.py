"""Every method where it stops gaining (issue 66): quality against budget (epochs) and capacity (how far
densification lets the sets grow), the point where each method has stopped gaining, and the table at those points.

Each ``EPOCHS:CAPACITY=FOLDER[,FOLDER...]`` names ``python -m glint_mi.benchmark`` outputs trained with that many
epochs at that capacity level (a label: ``default``, ``grow``, ``wide``, ordered as given by ``--capacities``). A
method's curve uses the ``--curve-rooms`` it has at every point, seed 0. A method has *stopped gaining* at the
smallest (epochs, capacity) whose mean PSNR is within ``--tol`` dB (0.2) of the next doubling of the epochs and of
the next capacity level, where those were run; a point flat in epochs whose next capacity was not run is taken
as undecided in capacity; if every doubling run still gains, it says so and takes the best point.
The converged table then gives each method at its point over every room and seed found there. ``--only
METHOD=FOLDER,...`` reads a method from those folders alone (its runs elsewhere, e.g. at a former default, left out).

    .venv/bin/python benchmarks/converge_table.py 60:grow=E60 120:grow=E120A,E120B 240:grow=E240 120:default=D120 \\
        --curve-rooms scene_9801,scene_9802 --out docs/results/converge_98xx

Writes ``curves.csv`` (every run used), ``curves.md`` (the curve means and each method's point), ``converged.md``
(the table: PSNR overall, on the glass and off it, normals, AbsRel, t IoU, Gaussians, train minutes; GLINT's
difference to each method), ``curves.png`` (PSNR against epochs and against Gaussians) and ``inrun.png`` (each run's
own test curve, ``eval_every``).
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import statistics
from pathlib import Path

KEYS = ("psnr", "psnr_glass", "psnr_off_glass", "normal_mae", "normal_mae_glass", "absrel", "absrel_glass", "t_iou",
        "train_s", "gaussians")


def _f(v) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return float("nan")


def read_runs(folder: Path) -> list[dict]:
    """The finished runs of a benchmark folder: each ``runs/<scene>/<method>[@seed<k>]`` with a ``metrics.json`` (so a
    benchmark still running is read as far as it got), else its ``results.csv``; each with its Gaussians at the end
    (``report.json``)."""
    out = []
    runs = folder / "runs"
    if runs.is_dir():
        for m in sorted(runs.glob("*/*/metrics.json")):
            run = m.parent
            method, _, seed = run.name.partition("@seed")
            met = json.loads(m.read_text())["metrics"]
            rep = run / "report.json"
            g = float(sum(json.loads(rep.read_text()).get("sizes", {}).values())) if rep.exists() else math.nan
            out.append({"method": method, "scene": run.parent.name, "seed": int(seed or 0),
                        **{k: _f(met.get(k)) for k in KEYS if k != "gaussians"}, "gaussians": g, "run": str(run)})
        return out
    path = folder / "results.csv"
    if not path.exists():
        raise SystemExit(f"error: {folder} holds neither runs/*/*/metrics.json nor results.csv (a python -m "
                         f"glint_mi.benchmark output folder)")
    with open(path) as f:
        for r in csv.DictReader(f):
            out.append({"method": r["method"], "scene": r["scene"], "seed": int(r["seed"]),
                        **{k: _f(r.get(k)) for k in KEYS}, "run": ""})
    return out


def parse_only(specs: list[str]) -> dict[str, set[Path]]:
    """``--only METHOD=FOLDER[,FOLDER...]`` (repeatable) -> {method: resolved folders}."""
    only: dict[str, set[Path]] = {}
    for spec in specs:
        method, _, folders = spec.partition("=")
        if not method or not folders:
            raise SystemExit(f"error: --only {spec!r}: give METHOD=FOLDER[,FOLDER...]")
        only.setdefault(method, set()).update(Path(f).resolve() for f in folders.split(","))
    return only


def gather(specs: list[str], only: dict[str, set[Path]] | None = None) -> list[dict]:
    """Every run of the specs' folders with its point; ``only`` ({method: folders}) takes a method's runs from those
    folders alone (e.g. GLINT's current default, its runs of a former default in the same folders left out). A
    folder named in ``only`` but in no spec is refused: its runs would be silently missing."""
    only = only or {}
    named = {Path(f).resolve() for spec in specs for f in spec.partition("=")[2].split(",") if f}
    for m, fs in only.items():
        if fs - named:
            raise SystemExit(f"error: --only {m}: {', '.join(sorted(map(str, fs - named)))} is in no "
                             f"EPOCHS:CAPACITY=FOLDER spec; add it to the point its runs belong to")
    rows, seen = [], set()
    for spec in specs:
        point, _, folders = spec.partition("=")
        epochs, _, cap = point.partition(":")
        if not folders or not cap:
            raise SystemExit(f"error: {spec!r}: give EPOCHS:CAPACITY=FOLDER[,FOLDER...]")
        for folder in folders.split(","):
            here = Path(folder).resolve()
            for r in read_runs(Path(folder)):
                if r["method"] in only and here not in only[r["method"]]:
                    continue
                key = (float(epochs), cap, r["method"], r["scene"], r["seed"])
                if key not in seen:  # a run found twice is taken from the first folder
                    seen.add(key)
                    rows.append({"epochs": float(epochs), "capacity": cap, **r})
    return rows


def mean(rows, k):
    v = [r[k] for r in rows if r[k] == r[k]]
    return statistics.fmean(v) if v else math.nan


def curve_points(rows, method, rooms):
    """{(epochs, capacity): rows of seed 0 on the rooms present at every point of this method}."""
    mine = [r for r in rows if r["method"] == method and r["seed"] == 0 and r["scene"] in rooms]
    points = sorted({(r["epochs"], r["capacity"]) for r in mine})
    if not points:
        return {}
    common = set.intersection(*[{r["scene"] for r in mine if (r["epochs"], r["capacity"]) == p} for p in points])
    return {p: [r for r in mine if (r["epochs"], r["capacity"]) == p and r["scene"] in common] for p in points}


def stopped(points: dict, capacities: list[str], tol: float):
    """(epochs, capacity, note): the smallest point within tol of its next doubling and next capacity level. Without
    such a point: the smallest within tol of its next doubling whose next capacity was not run (undecided in
    capacity, said); else, when every doubling run gains, the largest budget run at the smallest capacity within tol
    of its next one (still gaining in epochs, stopped in capacity, said); else the best point, saying whether any
    doubling was run at all."""
    psnr = {p: mean(rs, "psnr") for p, rs in points.items()}
    order = sorted(points, key=lambda p: (p[0], capacities.index(p[1]) if p[1] in capacities else 99))
    flat_in_epochs = None  # the first point that stopped gaining in epochs, its next capacity not run
    for e, c in order:
        nxt_e = [p for p in points if p[1] == c and p[0] == 2 * e]
        ci = capacities.index(c) if c in capacities else -1
        nxt_c = [p for p in points if p[0] == e and ci >= 0 and ci + 1 < len(capacities) and p[1] == capacities[ci + 1]]
        last_cap = ci < 0 or ci + 1 >= len(capacities)
        if not nxt_e:
            continue
        if not nxt_c and not last_cap:  # both neighbours are needed (no larger capacity: the budget's)
            g = psnr[nxt_e[0]] - psnr[(e, c)]
            if g < tol and flat_in_epochs is None:
                flat_in_epochs = (e, c, f"undecided: x2 epochs {g:+.2f} dB, the next capacity "
                                        f"({capacities[ci + 1]}) not run")
            continue
        gains = [psnr[q] - psnr[(e, c)] for q in nxt_e + nxt_c]
        if all(g < tol for g in gains):
            return e, c, "stopped gaining: " + ", ".join(
                f"{'x2 epochs' if q[1] == c else q[1]} {g:+.2f} dB" for q, g in zip(nxt_e + nxt_c, gains))
    if flat_in_epochs is not None:
        return flat_in_epochs
    best = max(points, key=lambda p: psnr[p])
    decidable = any(q[1] == c and q[0] == 2 * e for e, c in points for q in points)
    if decidable:  # every doubling gains: at the largest budget run, the smallest capacity flat to its next one
        top = max(e for e, _ in points)
        for c in sorted({c for e, c in points if e == top and c in capacities}, key=capacities.index):
            i = capacities.index(c) + 1
            nxt = (top, capacities[i]) if i < len(capacities) else None
            if nxt in points and psnr[nxt] - psnr[(top, c)] < tol:
                return top, c, (f"still gaining in epochs; at the largest budget run the next capacity "
                                f"({nxt[1]}) {psnr[nxt] - psnr[(top, c)]:+.2f} dB")
    return best[0], best[1], ("still gaining at every point run: its best point taken" if decidable else
                              "undecided: no point has its next doubling run yet; its best point taken")


def compare(glint_rows, rows):
    """GLINT minus a method on the (room, seed) runs both have: the mean differences (PSNR overall, on and off the
    glass, normal MAE), how many runs GLINT is higher in (``wins``; on the glass: ``wins_glass``), the PSNR difference
    by seed ({seed: (mean, rooms)}) and the standard error of the mean PSNR difference (paired; nan with one pair).
    None without a common run."""
    g = {(r["scene"], r["seed"]): r for r in glint_rows}
    pairs = [(g[(r["scene"], r["seed"])], r) for r in rows if (r["scene"], r["seed"]) in g]
    if not pairs:
        return None
    d = {k: statistics.fmean([a[k] - b[k] for a, b in pairs if a[k] == a[k] and b[k] == b[k]] or [math.nan])
         for k in ("psnr", "psnr_glass", "psnr_off_glass", "normal_mae")}
    per_seed = {}
    for s_ in sorted({a["seed"] for a, _ in pairs}):
        v = [a["psnr"] - b["psnr"] for a, b in pairs if a["seed"] == s_]
        per_seed[s_] = (statistics.fmean(v), len(v))
    diffs = [a["psnr"] - b["psnr"] for a, b in pairs]
    se = statistics.stdev(diffs) / math.sqrt(len(diffs)) if len(diffs) > 1 else math.nan
    return {"n": len(pairs), "wins": sum(a["psnr"] > b["psnr"] for a, b in pairs),
            "wins_glass": sum(a["psnr_glass"] > b["psnr_glass"] for a, b in pairs), "mean": d, "per_seed": per_seed,
            "se": se}


def seed_spread(rows) -> float:
    """Mean |PSNR(seed k) - PSNR(seed 0)| over the (room, seed k > 0) runs whose seed-0 run is there: how far one run
    of a room moves with the seed alone (nan without such a pair)."""
    s0 = {r["scene"]: r["psnr"] for r in rows if r["seed"] == 0}
    v = [abs(r["psnr"] - s0[r["scene"]]) for r in rows if r["seed"] != 0 and r["scene"] in s0]
    return statistics.fmean(v) if v else math.nan


def fmt(v, d):
    return "-" if v != v else f"{v:.{d}f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0], epilog=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("specs", nargs="+", metavar="EPOCHS:CAPACITY=FOLDER[,FOLDER...]")
    ap.add_argument("--methods", default="glint,glint-paper,3dgs-priors,3dgs,tsgs")
    ap.add_argument("--capacities", default="default,grow,wide", help="capacity labels, smallest first")
    ap.add_argument("--curve-rooms", default="", help="comma list of rooms for the curves (default: every room)")
    ap.add_argument("--tol", type=float, default=0.2)
    ap.add_argument("--priors", type=Path, help="a benchmark folder with the `priors` row (the prior maps scored): "
                                                "the table gains it, and GLINT's normals and AbsRel against it")
    ap.add_argument("--only", action="append", default=[], metavar="METHOD=FOLDER[,FOLDER...]",
                    help="take METHOD's runs from these folders alone (repeatable): e.g. GLINT at today's preset "
                         "when the other folders also hold its runs at a former one")
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    rows = gather(args.specs, parse_only(args.only))
    methods = [m for m in args.methods.split(",") if any(r["method"] == m for r in rows)]
    caps = args.capacities.split(",")
    rooms = set(args.curve_rooms.split(",")) if args.curve_rooms else {r["scene"] for r in rows}
    args.out.mkdir(parents=True, exist_ok=True)
    with open(args.out / "curves.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=["epochs", "capacity", "method", "scene", "seed", *KEYS], extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    md = [f"Curves on {', '.join(sorted(rooms))} (seed 0; a method's points use the rooms it has at all of them).",
          "", "| method | epochs | capacity | rooms | PSNR | on glass | off glass | normal MAE | AbsRel | t IoU | "
          "Gaussians | train min |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    chosen, curves = {}, {}
    for m in methods:
        pts = curve_points(rows, m, rooms)
        curves[m] = pts
        for (e, c), rs in sorted(pts.items(), key=lambda kv: (caps.index(kv[0][1]) if kv[0][1] in caps else 99,
                                                                kv[0][0])):
            md.append(f"| {m} | {e:g} | {c} | {len(rs)} | {fmt(mean(rs, 'psnr'), 2)} | {fmt(mean(rs, 'psnr_glass'), 2)} "
                      f"| {fmt(mean(rs, 'psnr_off_glass'), 2)} | {fmt(mean(rs, 'normal_mae'), 1)} | "
                      f"{fmt(mean(rs, 'absrel'), 3)} | {fmt(mean(rs, 't_iou'), 2)} | {fmt(mean(rs, 'gaussians'), 0)} | "
                      f"{fmt(mean(rs, 'train_s') / 60, 1)} |")
        if pts:
            chosen[m] = stopped(pts, caps, args.tol)
    md += ["", f"Where each method stopped gaining (within {args.tol} dB of twice the epochs and of the next capacity):",
           ""]
    md += [f"- **{m}**: {e:g} epochs, {c} ({note})" for m, (e, c, note) in chosen.items()]
    (args.out / "curves.md").write_text("\n".join(md) + "\n")
    # the converged table: each method at its point, every room and seed there
    table = ["| method | point | runs | PSNR (min-max) | on glass | off glass | normal MAE | on glass | AbsRel | "
             "on glass | t IoU | Gaussians | train min |", "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    at = {m: [r for r in rows if r["method"] == m and (r["epochs"], r["capacity"]) == chosen[m][:2]] for m in chosen}
    for m, rs in at.items():
        lo, hi = min(r["psnr"] for r in rs), max(r["psnr"] for r in rs)
        table.append(f"| {m} | {chosen[m][0]:g} epochs, {chosen[m][1]} | {len(rs)} | {fmt(mean(rs, 'psnr'), 2)} "
                     f"({lo:.2f}-{hi:.2f}) | {fmt(mean(rs, 'psnr_glass'), 2)} | {fmt(mean(rs, 'psnr_off_glass'), 2)} | "
                     f"{fmt(mean(rs, 'normal_mae'), 1)} | {fmt(mean(rs, 'normal_mae_glass'), 1)} | "
                     f"{fmt(mean(rs, 'absrel'), 3)} | {fmt(mean(rs, 'absrel_glass'), 3)} | {fmt(mean(rs, 't_iou'), 2)} | "
                     f"{fmt(mean(rs, 'gaussians'), 0)} | {fmt(mean(rs, 'train_s') / 60, 1)} |")
    if args.priors is not None:
        pri = {r["scene"]: r for r in read_runs(args.priors) if r["method"] == "priors"}
        rs = [pri[s_] for s_ in sorted({r["scene"] for r in rows}) if s_ in pri]
        if rs:
            table.append(f"| the priors themselves | - | {len(rs)} rooms | - | - | - | {fmt(mean(rs, 'normal_mae'), 1)} | "
                         f"{fmt(mean(rs, 'normal_mae_glass'), 1)} | {fmt(mean(rs, 'absrel'), 3)} | "
                         f"{fmt(mean(rs, 'absrel_glass'), 3)} | - | - | - |")
        if "glint" in at:
            pairs = [(r, pri[r["scene"]]) for r in at["glint"] if r["scene"] in pri]
            if pairs:
                ratio = lambda k: statistics.fmean(a[k] / b[k] for a, b in pairs if b[k] > 0)
                worse = [a["scene"] for a, b in pairs if a["normal_mae"] > b["normal_mae"] or a["absrel"] > b["absrel"]]
                table += ["", f"GLINT against its priors ({len(pairs)} runs): normals {ratio('normal_mae'):.2f}x, "
                          f"AbsRel {ratio('absrel'):.2f}x (mean of per-run ratios); worse than the priors in "
                          f"{', '.join(worse) if worse else 'none'}"]
    if "glint" in at:
        table += ["", "GLINT against each method at their points, on the (room, seed) runs both have (PSNR overall / "
                  "on glass / off glass, dB; normal MAE, deg):", ""]
        for m, rs in at.items():
            if m == "glint":
                continue
            c = compare(at["glint"], rs)
            if c is None:
                continue
            d = c["mean"]
            line = (f"- against {m} ({c['n']} runs, GLINT higher in {c['wins']}): {d['psnr']:+.2f} / "
                    f"{d['psnr_glass']:+.2f} / {d['psnr_off_glass']:+.2f} dB; normals {d['normal_mae']:+.1f} deg")
            if len(c["per_seed"]) > 1:
                line += ("; PSNR by seed " + ", ".join(f"{s_}: {v:+.2f} ({n} rooms)" for s_, (v, n) in
                                                        sorted(c["per_seed"].items()))
                         + f"; standard error {c['se']:.2f} dB")
            table.append(line)
        spread = [f"{m} {v:.2f}" for m, v in ((m, seed_spread(rs)) for m, rs in at.items()) if v == v]
        if spread:
            table += ["", "Run-to-run spread (mean |PSNR seed k - seed 0| over the rooms run with both, dB): "
                      + ", ".join(spread)]
    (args.out / "converged.md").write_text("\n".join(table) + "\n")
    print("\n".join(md) + "\n\n" + "\n".join(table))
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 4.5))
    styles = {"default": ":", "grow": "-", "wide": "--"}
    for i, (m, pts) in enumerate(curves.items()):
        col = f"C{i}"
        for c in caps:
            line = sorted((e, mean(rs, "psnr"), mean(rs, "gaussians")) for (e, cc), rs in pts.items() if cc == c)
            if line:
                a1.plot([x[0] for x in line], [x[1] for x in line], styles.get(c, "-"), color=col, marker="o",
                        label=f"{m} ({c})")
        byg = sorted((mean(rs, "gaussians"), mean(rs, "psnr")) for (e, cc), rs in pts.items() if e == chosen[m][0])
        if byg:
            a2.plot([x[0] for x in byg], [x[1] for x in byg], "-", color=col, marker="o", label=m)
    a1.set_xscale("log", base=2)
    a1.set_xlabel("epochs (rays per training pixel), 96 x 54")
    a1.set_ylabel("test PSNR (dB), mean of the curve rooms")
    a1.legend(fontsize=7)
    a2.set_xlabel("Gaussians at the end (capacity levels, at each method's chosen epochs)")
    a2.set_ylabel("test PSNR (dB)")
    a2.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(args.out / "curves.png", dpi=110)
    inrun_figure(rows, methods, rooms, args.out / "inrun.png")


def inrun_figure(rows, methods, rooms, path: Path) -> None:
    """Test PSNR and Gaussians against epochs inside each run (its convergence.csv, ``eval_every``), mean of the curve
    rooms at seed 0, one panel per (epochs, capacity) run length: where a run itself stops gaining. A curve inside a
    run is not a shorter run (the schedule's fractions scale with the run), so the budget curves above decide."""
    import matplotlib.pyplot as plt

    groups = sorted({(r["epochs"], r["capacity"]) for r in rows})
    fig, axes = plt.subplots(2, len(groups), figsize=(4.2 * len(groups), 6.5), squeeze=False)
    for gi, (e, c) in enumerate(groups):
        for i, m in enumerate(methods):
            curves = []
            for r in rows:
                f = Path(r["run"]) / "convergence.csv"
                if (r["method"], r["epochs"], r["capacity"], r["seed"]) == (m, e, c, 0) and r["scene"] in rooms \
                        and f.exists():
                    with open(f) as fh:
                        curves.append([(float(x["epoch"]), float(x["psnr"]), float(x["gaussians"]))
                                       for x in csv.DictReader(fh)])
            n = min((len(cv) for cv in curves), default=0)
            if not n:
                continue
            ep = [statistics.fmean(cv[j][0] for cv in curves) for j in range(n)]
            for row, k in ((0, 1), (1, 2)):
                axes[row][gi].plot(ep, [statistics.fmean(cv[j][k] for cv in curves) for j in range(n)], "-o",
                                   color=f"C{i}", ms=3, label=f"{m} ({len(curves)} rooms)")
        axes[0][gi].set_title(f"runs of {e:g} epochs, {c}")
        axes[1][gi].set_xlabel("epoch")
        axes[0][gi].legend(fontsize=7)
    axes[0][0].set_ylabel("test PSNR (dB)")
    axes[1][0].set_ylabel("Gaussians")
    fig.tight_layout()
    fig.savefig(path, dpi=100)


if __name__ == "__main__":
    main()
