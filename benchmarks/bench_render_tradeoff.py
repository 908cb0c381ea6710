"""Render speed against accuracy on trained runs, measured side by side in one run (issue 25): what does a faster
render of a trained model give up?

Each trained run is rendered on its test views, at its training resolution, with render-time variants of the same
model: the hit budget per ray and pass (``max_hits``), the integrator's per-ray ``components: auto`` (reflection
only where k_s > 0.05, transmission where k_t > 1e-3; the skipped weight goes to the diffuse term) and fixed subsets
of the sets. The base is the exact first-order model at the run's own budget (``components: all``), as
``python -m glint_mi.evaluate`` renders it. Nothing is retrained. Variants are rendered in turn for each run and the
whole list is repeated ``--reps`` times (fps: the median), so a machine's load drifts over all of them alike.

    .venv/bin/python benchmarks/bench_render_tradeoff.py --runs OUT/runs --method glint --out benchmarks/results/render_tradeoff
    .venv/bin/python benchmarks/bench_render_tradeoff.py RUN [RUN ...] --out DIR

Writes ``render_tradeoff.csv`` (one row per run and variant), ``render_tradeoff.md`` (means over the runs, change
against the base, the Pareto front of fps against PSNR) and ``render_tradeoff.png``.
"""
from __future__ import annotations

import argparse
import csv
import statistics
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import glint_mi  # noqa: E402

glint_mi.set_variant()

from glint_mi.evaluate import evaluate, load_model, load_run  # noqa: E402
from glint_mi.tradeoff import pareto  # noqa: E402
from glint_mi.evaluate import eval_options  # noqa: E402

# (name, max_hits or None for the run's own, components, traversal)
VARIANTS = [("base (run's budget, all sets)", None, "all", "kbuffer"),
            ("max_hits 128", 128, "all", "kbuffer"),
            ("max_hits 64", 64, "all", "kbuffer"),
            ("max_hits 32", 32, "all", "kbuffer"),
            ("components auto", None, "auto", "kbuffer"),
            ("components auto, max_hits 64", 64, "auto", "kbuffer"),
            ("no reflection set", None, "interface,transmission", "kbuffer"),
            ("interface alone", None, "interface", "kbuffer"),
            ("Mitsuba's BVH queries (traversal bvh: the CUDA path)", None, "all", "bvh")]
QUALITY = ("psnr", "ssim", "normal_mae", "absrel", "t_iou")


def find_runs(runs_dir: Path, method: str) -> list[Path]:
    """The finished runs of ``method`` (all seeds) in a benchmark's runs folder (``ROOM/METHOD[@seedN]``)."""
    out = sorted(p for p in runs_dir.glob(f"*/{method}") if (p / "model").is_dir())
    out += sorted(p for p in runs_dir.glob(f"*/{method}@seed*") if (p / "model").is_dir())
    return out


def measure(run: Path, variants, reps: int) -> list[dict]:
    """Every variant rendered in turn, ``reps`` times; with more than one, the first is a warm-up (fps from the
    others)."""
    rows = []
    fps = {v[0]: [] for v in variants}
    metrics = {}
    _, ds, cfg, _ = load_run(run)  # the dataset once; each variant builds its integrator from the run's sets
    opts = eval_options(cfg, ds.root)
    for rep in range(reps):
        for name, hits, comps, traversal in variants:
            integ = load_model(run, cfg, max_hits=hits, components=comps)
            if traversal == "bvh":
                integ.kbuffer = False  # Mitsuba's queries, as on CUDA (the same image model)
            res = evaluate(integ, ds.test_views, write=False, **opts)
            if rep > 0 or reps == 1:
                fps[name].append(res["fps"])
            metrics[name] = res["metrics"]  # the same images every repetition (deterministic renders)
            if rep == 0:
                print(f"  {run.parent.name}/{run.name} {name}: {res['fps']:.2f} fps, PSNR {res['metrics']['psnr']:.2f}",
                      flush=True)
            budget = cfg.max_hits if hits is None else hits
            if rep == reps - 1:
                rows.append({"run": f"{run.parent.name}/{run.name}", "variant": name, "max_hits": budget,
                             "components": comps, "traversal": traversal, "fps": statistics.median(fps[name]),
                             **{k: metrics[name].get(k, float("nan")) for k in QUALITY}})
    return rows


def summarise(rows: list[dict], variants) -> list[dict]:
    """Per variant, the mean over runs, and the mean change against each run's base."""
    base_name = variants[0][0]
    base = {r["run"]: r for r in rows if r["variant"] == base_name}
    out = []
    for name, _, comps, _ in variants:
        sel = [r for r in rows if r["variant"] == name]
        mean = lambda k, sel=sel: statistics.fmean(r[k] for r in sel if r[k] == r[k]) if any(
            r[k] == r[k] for r in sel) else float("nan")
        s = {"variant": name, "components": comps, "runs": len(sel), **{k: mean(k) for k in ("fps", *QUALITY)}}
        s["speed_x"] = statistics.fmean(r["fps"] / base[r["run"]]["fps"] for r in sel)
        s["d_psnr"] = statistics.fmean(r["psnr"] - base[r["run"]]["psnr"] for r in sel)
        s["s_per_frame"] = 1.0 / s["fps"]
        out.append(s)
    for s, p in zip(out, pareto(out, cost="s_per_frame", quality="psnr")):
        s["pareto"] = p
    return out


def markdown(summary: list[dict], runs: list[str]) -> str:
    f = lambda v, d=2: "-" if v != v else f"{v:.{d}f}"
    lines = [f"Mean over {len(runs)} runs ({', '.join(runs)}); fps at the training resolution, the median of the "
             f"repetitions after a warm-up; speed x and PSNR change against each run's base, averaged.", "",
             "| variant | fps | speed x | PSNR | PSNR change | SSIM | normal MAE | AbsRel | t IoU | Pareto (fps vs PSNR) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for s in summary:
        lines.append(f"| {s['variant']} | {f(s['fps'])} | {f(s['speed_x'])} | {f(s['psnr'])} | {s['d_psnr']:+.2f} | "
                     f"{f(s['ssim'], 3)} | {f(s['normal_mae'], 1)} | {f(s['absrel'], 3)} | {f(s['t_iou'])} | "
                     f"{'yes' if s['pareto'] else ''} |")
    return "\n".join(lines) + "\n"


def plot(summary: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 3, figsize=(13, 3.6))
    for a, q in zip(ax, ("psnr", "ssim", "t_iou")):  # normal MAE and AbsRel come from the interface pass alone
        a.scatter([s["fps"] for s in summary], [s[q] for s in summary], s=20)
        for s in summary:
            a.annotate(s["variant"], (s["fps"], s[q]), fontsize=6)
        front = sorted((s for s in summary if s["pareto"]), key=lambda s: s["fps"])
        if q == "psnr":
            a.plot([s["fps"] for s in front], [s[q] for s in front], "k--", lw=0.8, label="Pareto front (PSNR)")
            a.legend(fontsize=7)
        a.set_xlabel("render fps (2 CPU cores)"), a.set_ylabel(q)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="*", type=Path, help="finished run folders")
    ap.add_argument("--runs-dir", type=Path, help="a benchmark's runs folder (ROOM/METHOD[@seedN])")
    ap.add_argument("--method", default="glint", help="with --runs-dir: the method whose runs to render")
    ap.add_argument("--reps", type=int, default=3, help="repetitions of the whole variant list (the first a warm-up; "
                    "fps: the median of the others)")
    ap.add_argument("--variants", help="comma list of variant numbers to keep (0 = the base, always kept)")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "render_tradeoff")
    ap.add_argument("--from-csv", action="store_true", help="render nothing: summarise and plot OUT/render_tradeoff.csv")
    args = ap.parse_args(argv)
    variants = VARIANTS
    if args.variants:
        keep = {0} | {int(i) for i in args.variants.split(",")}
        variants = [v for i, v in enumerate(VARIANTS) if i in keep]
    if args.from_csv:
        with open(args.out / "render_tradeoff.csv") as fh:
            rows = [{k: (v if k in ("run", "variant", "components", "traversal") else float(v)) for k, v in r.items()}
                    for r in csv.DictReader(fh)]
        return report(rows, [v for v in variants if any(r["variant"] == v[0] for r in rows)], args.out)
    runs = list(args.runs) + (find_runs(args.runs_dir, args.method) if args.runs_dir else [])
    if not runs:
        ap.error("no runs: give run folders, or --runs-dir with finished runs of --method")
    for r in runs:
        if not (r / "model").is_dir() or not (r / "config.json").exists():
            ap.error(f"{r}: not a finished run (needs config.json and model/)")
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    for r in runs:
        print(f"{r}:", flush=True)
        rows += measure(r, variants, args.reps)
    with open(args.out / "render_tradeoff.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    return report(rows, variants, args.out)


def report(rows: list[dict], variants, out: Path) -> int:
    summary = summarise(rows, variants)
    text = markdown(summary, sorted({r["run"] for r in rows}))
    (out / "render_tradeoff.md").write_text(text)
    plot(summary, out / "render_tradeoff.png")
    print(text)
    print(f"wrote {out}/render_tradeoff.csv, render_tradeoff.md, render_tradeoff.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
