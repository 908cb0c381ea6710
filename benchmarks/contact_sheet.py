"""Where each Gaussian set goes in a trained run: one row per test view (photo, GLINT's image, depth, normal,
transparency t, the interface's colour c_I, the reflection c_R, the transmission c_T), from the run's evaluation
renders (``renders/<view>_<buffer>.png``), with each set's share of the image energy from its training log.

    .venv/bin/python benchmarks/contact_sheet.py RUN_FOLDER --out sheet.png [--views N]
"""
from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

BUFFERS = [("rgb", "GLINT"), ("depth", "depth"), ("normal", "normal"), ("t", "transparency t"),
           ("cI", "interface c_I"), ("cR", "reflection c_R"), ("cT", "transmission c_T")]


def energy_shares(run: Path, last: int = 50) -> dict:
    """Mean share of the image energy of the reflection and transmission sets, and L_trans's transparent-mask
    coverage, over the last ``last`` logged steps (log.csv)."""
    rows = list(csv.DictReader(open(run / "log.csv")))[-last:] if (run / "log.csv").exists() else []
    out = {}
    for key in ("share_reflection", "share_transmission", "mask_t"):
        vals = [float(r[key]) for r in rows if r.get(key) not in (None, "")]
        out[key] = float(np.mean(vals)) if vals else float("nan")
    return out


def contact_sheet(run: Path, out: Path, views: int | None = None, dpi: int = 110) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from PIL import Image

    from glint_mi.config import TrainConfig
    from glint_mi.runs import load_run_dataset

    ds = load_run_dataset(run, TrainConfig.load(run / "config.json"))
    test = [v for v in ds.test_views if (run / "renders" / f"{v.name}_rgb.png").exists()][:views]
    if not test:
        raise SystemExit(f"{run}/renders: no evaluation renders; run `python -m glint_mi.evaluate {run}` first.")
    cols = len(BUFFERS) + 1
    fig, ax = plt.subplots(len(test), cols, figsize=(1.9 * cols, 2.0 * len(test) * ds.test_views[0].height
                                                    / ds.test_views[0].width + 0.4), squeeze=False)
    for i, v in enumerate(test):
        ax[i, 0].imshow(v.load_image())
        ax[i, 0].set_title(f"photo {v.name[-8:]}", fontsize=7)
        for a, (key, title) in zip(ax[i, 1:], BUFFERS):
            p = run / "renders" / f"{v.name}_{key}.png"
            if p.exists():
                a.imshow(np.asarray(Image.open(p)))
            a.set_title(title, fontsize=7)
    for a in ax.ravel():
        a.axis("off")
    s = energy_shares(run)
    fig.suptitle(f"{run}: reflection {100 * s['share_reflection']:.1f} %, transmission "
                 f"{100 * s['share_transmission']:.1f} % of the image energy; L_trans transparent mask "
                 f"{100 * s['mask_t']:.1f} % of pixels (last 50 logged steps)", fontsize=7)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=dpi)
    plt.close(fig)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--views", type=int, default=None, help="at most this many test views")
    ap.add_argument("--dpi", type=int, default=110)
    a = ap.parse_args(argv)
    print(contact_sheet(a.run, a.out, a.views, a.dpi))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
