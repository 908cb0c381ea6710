"""GLINT at the converged preset inside runs of 60, 120 and 240 epochs (the fifty-eighth session's 240-epoch runs,
stopped at epochs 155-169 for time, resumed from their checkpoints to their end by the fifty-ninth): test PSNR on every pixel, on the glass and off it against the epoch, seed 0, the curve
rooms. Prints the table and writes inrun58.png beside this file.
    python docs/results/converge_98xx/inrun58.py"""
import csv
from pathlib import Path

HERE = Path(__file__).parent
RUNS = {"60 epochs": "s54_d54", "120 epochs": "s55_e120", "240 epochs": "s59_e240"}
COLS = (("psnr", "all"), ("psnr_glass", "on the glass"), ("psnr_off_glass", "off the glass"))


def curve(group: str, room: int) -> list[dict]:
    with open(HERE / "groups" / group / "runs" / f"scene_{room}" / "glint" / "convergence.csv") as f:
        return [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]


def main() -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rooms = (9801, 9802)
    fig, axes = plt.subplots(len(rooms), len(COLS), figsize=(13, 7), squeeze=False)
    for ri, room in enumerate(rooms):
        for li, (label, group) in enumerate(RUNS.items()):
            rows = curve(group, room)
            print(f"scene_{room}, {label}: " + "; ".join(
                f"e{r['epoch']:.0f} {r['psnr']:.2f}/{r['psnr_glass']:.2f}/{r['psnr_off_glass']:.2f}" for r in rows))
            for ci, (k, name) in enumerate(COLS):
                ax = axes[ri][ci]
                ax.plot([r["epoch"] for r in rows], [r[k] for r in rows], "-o", ms=3, color=f"C{li}", label=label)
                ax.set_title(f"scene_{room}: {name}")
        axes[ri][0].set_ylabel("test PSNR (dB)")
    for ax in axes[-1]:
        ax.set_xlabel("epoch")
    for ax in axes.flat:  # the opacity resets' dips are far below: show the upper range
        lo, hi = ax.get_ylim()
        ax.set_ylim(max(lo, hi - 6), hi)
    axes[0][0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(HERE / "inrun58.png", dpi=90)


if __name__ == "__main__":
    main()
