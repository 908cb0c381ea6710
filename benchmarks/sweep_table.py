"""A sweep's table (issue 66, ``docs/results/prior_sweep``): each level of a swept setting as benchmark output
folders, each run named ``LABEL`` (a method, or ``METHOD+SUFFIX`` for a folder trained with extra settings), one row
per level and run with the mean over the rooms it finished, and the rooms it used.

Each ``LEVEL=FOLDER[:SUFFIX][,FOLDER[:SUFFIX]...]`` gives the folders of one level; a run of method M in a folder
given with ``:SUFFIX`` is labelled ``M+SUFFIX`` (``see_1.0_priorphoto:pp`` -> ``glint+pp``). Runs are read as
``benchmarks/converge_table.py`` reads them (finished evaluations only).

    .venv/bin/python benchmarks/sweep_table.py 1.0=R/see_1.0,R/see_1.0_cuephoto:cue,R/see_1.0_priorphoto:pp \\
        0.6=R/see_0.6 --rooms scene_7301,scene_7302 --out docs/results/prior_sweep/see_through.md
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from converge_table import read_runs  # noqa: E402

COLUMNS = (("psnr", "PSNR", 2), ("psnr_glass", "on glass", 2), ("psnr_off_glass", "off glass", 2),
           ("normal_mae", "normal MAE", 1), ("absrel", "AbsRel", 3), ("normal_mae_glass", "glass normals", 1),
           ("t_iou", "t IoU", 2))


def gather(specs: list[str], rooms: list[str] | None, missing: list | None = None) -> dict:
    """{level: {label: {room: row}}} over every ``LEVEL=FOLDER[:SUFFIX],...`` spec (seed 0). A folder that does not
    exist yet (a sweep still running) is appended to ``missing`` when given, else refused."""
    out: dict = {}
    for spec in specs:
        level, _, folders = spec.partition("=")
        if not level or not folders:
            raise SystemExit(f"error: {spec!r}: give LEVEL=FOLDER[:SUFFIX][,FOLDER[:SUFFIX]...]")
        for item in folders.split(","):
            folder, _, suffix = item.partition(":")
            if missing is not None and not Path(folder).exists():
                missing.append(folder)
                continue
            for r in read_runs(Path(folder)):
                if r["seed"] != 0 or (rooms and r["scene"] not in rooms):
                    continue
                label = r["method"] + (f"+{suffix}" if suffix else "")
                out.setdefault(level, {}).setdefault(label, {}).setdefault(r["scene"], r)
    return out


def table(data: dict, by_room: bool = False) -> str:
    """The mean over each run's rooms (``rooms`` says how many: compare runs of equal counts), or with ``by_room``
    one row per room."""
    head = "| level | run | rooms | " + " | ".join(name for _, name, _ in COLUMNS) + " |"
    lines = [head, "|---|---|---|" + "---|" * len(COLUMNS)]
    if by_room:
        data = {f"{level} {room}": {label: {room: rows[room]} for label, rows in runs.items() if room in rows}
                for level, runs in data.items() for room in sorted({r for rows in runs.values() for r in rows})}
    for level, runs in data.items():
        for label, by_room in sorted(runs.items()):
            cells = []
            for key, _, d in COLUMNS:
                vals = [by_room[s][key] for s in sorted(by_room) if math.isfinite(by_room[s][key])]
                cells.append(f"{sum(vals) / len(vals):.{d}f}" if vals else "-")
            lines.append(f"| {level} | {label} | {len(by_room)} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def floor_pairs(data: dict, key: str, reference: str = "priors") -> dict:
    """{label: [(level, room, reference's, run's), ...]}: each run's ``key`` beside the ``reference`` row's of its
    folder (the priors), per room and level; the reference's copies (``priors+SUFFIX``) are no run, and a level whose
    folders all carry a suffix takes its first copy as the reference."""
    out: dict = {}
    for level, runs in data.items():
        ref = runs.get(reference) or next((r for lab, r in sorted(runs.items())
                                           if lab.startswith(reference + "+")), {})
        for label, rows in sorted(runs.items()):
            if label == reference or label.startswith(reference + "+"):
                continue
            for room, row in sorted(rows.items()):
                if room in ref and math.isfinite(row[key]) and math.isfinite(ref[room][key]):
                    out.setdefault(label, []).append((level, room, ref[room][key], row[key]))
    return out


def floor_summary(data: dict, reference: str = "priors") -> str:
    """One line a run label: at how many room-levels its normal MAE and its AbsRel are at or under the ``reference``
    row's, and which are over (issue 66, item 3: GLINT at or under its priors at every level)."""
    lines = []
    by_key = {key: floor_pairs(data, key, reference) for key in ("normal_mae", "absrel")}
    for label in sorted({lab for pairs in by_key.values() for lab in pairs}):
        parts = []
        for key, name, d in (("normal_mae", "normals", 2), ("absrel", "AbsRel", 4)):
            pairs = by_key[key].get(label, [])
            over = [f"{level} {room} ({run:.{d}f} against {ref:.{d}f})" for level, room, ref, run in pairs
                    if run > ref]
            parts.append(f"{name} at or under in {len(pairs) - len(over)} of {len(pairs)}"
                         + (f", over at {'; '.join(over)}" if over else ""))
        lines.append(f"- `{label}` against `{reference}`: " + "; ".join(parts))
    return "\n".join(lines)


def floor_plot(data: dict, path: Path, reference: str = "priors") -> dict:
    """Each run's normal MAE and AbsRel against the ``reference`` row's (the priors), one point per room and level,
    with the diagonal: a point above it ends worse than its priors (issue 66, item 3). Returns the points plotted,
    {column: {label: [(reference's, run's), ...]}}."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4.6))
    marks = "osD^vP*X"
    points: dict = {}
    for ax, (key, name) in zip(axes, (("normal_mae", "normal MAE (deg)"), ("absrel", "AbsRel"))):
        lo, hi = math.inf, -math.inf
        for j, (label, pairs) in enumerate(sorted(floor_pairs(data, key, reference).items())):
            xs, ys = [p[2] for p in pairs], [p[3] for p in pairs]
            points.setdefault(key, {})[label] = list(zip(xs, ys))
            ax.scatter(xs, ys, marker=marks[j % len(marks)], s=40, label=label, alpha=0.8)
            lo, hi = min(lo, *xs, *ys), max(hi, *xs, *ys)
        if math.isfinite(lo):
            pad = 0.05 * (hi - lo)
            ax.plot([lo - pad, hi + pad], [lo - pad, hi + pad], "k--", lw=1, label="= the priors'")
        ax.set_xlabel(f"the priors' {name}")
        ax.set_ylabel(f"the run's {name}")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle("Each run against its priors (one point per room and level; above the line: worse)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return points


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("levels", nargs="+", help="LEVEL=FOLDER[:SUFFIX][,FOLDER[:SUFFIX]...]")
    ap.add_argument("--rooms", default="", help="comma-separated scene folders to read (default: all)")
    ap.add_argument("--by-room", action="store_true", help="one row per room instead of the mean")
    ap.add_argument("--out", type=Path, default=None, help="also write the table here (markdown)")
    ap.add_argument("--floor-plot", type=Path, default=None,
                    help="also plot each run's normal MAE and AbsRel against the priors row's (PNG)")
    a = ap.parse_args(argv)
    rooms = [r for r in a.rooms.split(",") if r] or None
    missing: list = []
    data = gather(a.levels, rooms, missing)
    text = (f"`python benchmarks/sweep_table.py {' '.join(a.levels)}`" + (f" (rooms {a.rooms})" if rooms else "")
            + "; seed 0, the mean over the rooms each run finished"
            + (f"; not yet run: {', '.join(missing)}" if missing else "") + "\n\n" + table(data, a.by_room))
    summary = floor_summary(data)  # each run against its folder's priors row, where it has one
    if summary:
        text += "\n\n" + summary
    print(text)
    if a.out:
        a.out.write_text(text + "\n")
    if a.floor_plot:
        floor_plot(data, a.floor_plot)
    return 0


if __name__ == "__main__":
    sys.exit(main())
