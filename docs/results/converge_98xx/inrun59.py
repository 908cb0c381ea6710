"""The position-rate probe (the fifty-ninth session): GLINT at the converged preset for 120 epochs with the position
learning rate reaching its final value at half the run (`lr_position_until=0.5`), against the 60- and 120-epoch runs
of the same room and seed and the fifty-seventh session's two probes (sets frozen from epoch 60). Prints the test
views' metrics at each run's end (PSNR all / glass / off, normals, AbsRel) and each run's in-run PSNR at epochs
56-60 and at its end, and writes inrun59.png (the in-run test PSNR against the epoch) beside this file. A run that
has no metrics.json (stopped before its end) is read at its last in-run evaluation and marked so.
    python docs/results/converge_98xx/inrun59.py"""
import csv
import json
from pathlib import Path

HERE = Path(__file__).parent
RUNS = {"60 epochs": "s54_d54", "120 epochs": "s55_e120|s56_e120",
        "120, position rate final from 60": "s59_lr58",
        "120, T and R frozen from 60": "s57_secondary", "120, interface frozen from 60": "s57_refine"}
CASES = ((9802, 0), (9803, 1))
COLS = (("psnr", "all"), ("psnr_glass", "on the glass"), ("psnr_off_glass", "off the glass"))


def run_dir(groups: str, room: int, seed: int) -> Path | None:
    name = "glint" + (f"@seed{seed}" if seed else "")
    for g in groups.split("|"):
        d = HERE / "groups" / g / "runs" / f"scene_{room}" / name
        if d.is_dir():
            return d
    return None


def curve(run: Path) -> list[dict]:
    with open(run / "convergence.csv") as f:
        return [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]


def end(run: Path) -> tuple[dict, str]:
    """The run's end metrics (metrics.json), else its last in-run evaluation marked as such."""
    m = run / "metrics.json"
    if m.exists():
        return json.loads(m.read_text())["metrics"], "end"
    last = curve(run)[-1]
    return last, f"stopped, epoch {last['epoch']:.0f}"


def main() -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(CASES), len(COLS), figsize=(13, 7), squeeze=False)
    print("| room, seed | run | PSNR all / glass / off (test views) | normals | AbsRel | in-run glass, epochs 56-60 |")
    print("|---|---|---|---|---|---|")
    for ri, (room, seed) in enumerate(CASES):
        for li, (label, groups) in enumerate(RUNS.items()):
            run = run_dir(groups, room, seed)
            if run is None:
                continue
            met, how = end(run)
            rows = curve(run)
            near60 = [r for r in rows if 55.5 <= r["epoch"] <= 60.5]
            g60 = ", ".join(f"{r['psnr_glass']:.2f} (e{r['epoch']:.0f})" for r in near60) or "-"
            print(f"| {room}, {seed} | {label} ({how}) | {met['psnr']:.2f} / {met['psnr_glass']:.2f} / "
                  f"{met['psnr_off_glass']:.2f} | {met['normal_mae']:.2f} | {met['absrel']:.4f} | {g60} |")
            for ci, (k, name) in enumerate(COLS):
                ax = axes[ri][ci]
                ax.plot([r["epoch"] for r in rows], [r[k] for r in rows], "-o", ms=3, color=f"C{li}", label=label)
                ax.set_title(f"scene_{room}, seed {seed}: {name}")
        axes[ri][0].set_ylabel("test PSNR (dB)")
    for ax in axes[-1]:
        ax.set_xlabel("epoch")
    for ax in axes.flat:  # the opacity resets' dips are far below: show the upper range
        lo, hi = ax.get_ylim()
        ax.set_ylim(max(lo, hi - 6), hi)
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(HERE / "inrun59.png", dpi=90)


if __name__ == "__main__":
    main()
