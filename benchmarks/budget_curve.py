"""Quality against training budget, gathered from benchmark folders trained at different budgets (issue 25).

Each ``EPOCHS=FOLDER[,FOLDER...]`` names ``python -m glint_mi.benchmark`` outputs (their ``results.csv``) trained
with that many epochs (a run found twice is taken from the first folder); rows are kept for the rooms and methods asked for, and each (method, epochs) is summarised over the
(room, seed) runs present: mean, min-max spread, and how many runs. A method's row at a budget only counts the
rooms it has at every budget listed, so the curve compares like with like.

    .venv/bin/python benchmarks/budget_curve.py 3=runs/e3 5=runs/e5 10=runs/unseen --rooms scene_7101,scene_7103 \
        --methods glint,3dgs --out docs/results/budget

Writes ``budget.csv`` (the runs used), ``budget.md`` (the summary) and ``budget.png`` (PSNR, normal MAE and t IoU
against epochs, one line per method, the runs as points).
"""
from __future__ import annotations

import argparse
import csv
import statistics
import sys
from pathlib import Path

QUALITY = ("psnr", "normal_mae", "absrel", "t_iou", "train_s")


def read(folder: Path) -> list[dict]:
    path = folder / "results.csv"
    if not path.exists():
        raise SystemExit(f"error: {path} not found (a python -m glint_mi.benchmark output folder holds it)")
    with open(path) as f:
        return list(csv.DictReader(f))


def gather(budgets: dict[float, list[Path]], rooms: set[str] | None, methods: list[str]) -> list[dict]:
    rows = []
    for epochs, folders in budgets.items():
        seen = set()
        for r in (r for folder in folders for r in read(folder)):
            key = (r["method"], r["scene"], r["seed"])
            if key in seen:
                continue
            seen.add(key)
            if r["method"] in methods and (rooms is None or r["scene"] in rooms):
                rows.append({"epochs": epochs, "method": r["method"], "scene": r["scene"], "seed": int(r["seed"]),
                             **{k: float(r[k]) if r.get(k) not in (None, "", "nan") else float("nan")
                                for k in QUALITY}})
    # like with like: per method, only the (room, seed) runs present at every budget
    out = []
    for m in methods:
        keys = [{(r["scene"], r["seed"]) for r in rows if r["method"] == m and r["epochs"] == e} for e in budgets]
        common = set.intersection(*keys) if keys else set()
        out += [r for r in rows if r["method"] == m and (r["scene"], r["seed"]) in common]
    return out


def summary(rows: list[dict], budgets, methods) -> list[dict]:
    out = []
    for m in methods:
        for e in sorted(budgets):
            sel = [r for r in rows if r["method"] == m and r["epochs"] == e]
            if not sel:
                continue
            s = {"method": m, "epochs": e, "runs": len(sel)}
            for k in QUALITY:
                v = [r[k] for r in sel if r[k] == r[k]]
                s[k] = statistics.fmean(v) if v else float("nan")
                s[k + "_lo"], s[k + "_hi"] = (min(v), max(v)) if v else (float("nan"),) * 2
            out.append(s)
    return out


def markdown(summ: list[dict]) -> str:
    f = lambda s, k, d: "-" if s[k] != s[k] else (f"{s[k]:.{d}f}" + (
        f" ({s[k + '_lo']:.{d}f}-{s[k + '_hi']:.{d}f})" if s["runs"] > 1 else ""))
    lines = ["| method | epochs | runs | PSNR (min-max) | normal MAE | AbsRel | t IoU | train s (shared machine) |",
             "|---|---|---|---|---|---|---|---|"]
    for s in summ:
        lines.append(f"| {s['method']} | {s['epochs']:g} | {s['runs']} | {f(s, 'psnr', 2)} | {f(s, 'normal_mae', 1)} | "
                     f"{f(s, 'absrel', 3)} | {f(s, 't_iou', 2)} | {s['train_s']:.0f} |")
    return "\n".join(lines) + "\n"


def plot(rows, summ, methods, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 3, figsize=(13, 3.6))
    for a, q in zip(ax, ("psnr", "normal_mae", "t_iou")):
        for m in methods:
            sel = [s for s in summ if s["method"] == m]
            a.plot([s["epochs"] for s in sel], [s[q] for s in sel], "-o", label=m, ms=4)
            pts = [r for r in rows if r["method"] == m]
            a.scatter([r["epochs"] for r in pts], [r[q] for r in pts], s=8, alpha=0.4)
        a.set_xscale("log"), a.set_xlabel("epochs (log)"), a.set_ylabel(q)
    ax[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("budgets", nargs="+", metavar="EPOCHS=FOLDER[,FOLDER]")
    ap.add_argument("--rooms", help="comma list of scene names (default: all)")
    ap.add_argument("--methods", default="glint,3dgs")
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)
    budgets = {}
    for b in args.budgets:
        e, _, folder = b.partition("=")
        try:
            budgets[float(e)] = [Path(x) for x in folder.split(",") if x]
        except ValueError:
            ap.error(f"'{b}': give EPOCHS=FOLDER, e.g. 10=runs/unseen")
    methods = [m for m in args.methods.split(",") if m]
    rooms = set(args.rooms.split(",")) if args.rooms else None
    rows = gather(budgets, rooms, methods)
    if not rows:
        ap.error("no runs in common: check --rooms and --methods against the folders' results.csv")
    summ = summary(rows, budgets, methods)
    args.out.mkdir(parents=True, exist_ok=True)
    with open(args.out / "budget.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    text = markdown(summ)
    (args.out / "budget.md").write_text(text)
    plot(rows, summ, methods, args.out / "budget.png")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
