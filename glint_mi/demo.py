"""`make demo`: the main job on the bundled room with a glass case — train GLINT, evaluate, print the metrics.

Runs ``python -m glint_mi.optimize scenes/glass_room/optimize.xml --preset quick`` into ``out/demo/run`` (a previous
demo run there is replaced), then renders a contact sheet of the first test view (RGB, depth, normal,
transparency, interface / reflection / transmission) next to the ground truth, and prints the metrics table
(the priors of the bundled dataset are derived from its ground truth; the table says so).
"""
from __future__ import annotations

import argparse
import shutil
import sys
import time
from pathlib import Path

from glint_mi.config import PRESETS

ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "scenes" / "glass_room" / "optimize.xml"


def contact_sheet(run: Path, view, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from PIL import Image

    names = [("rgb", "GLINT"), ("depth", "depth"), ("normal", "normal"), ("t", "transparency t"),
             ("cI", "interface c_I"), ("cR", "reflection c_R"), ("cT", "transmission c_T")]
    fig, ax = plt.subplots(1, len(names) + 1, figsize=(2.4 * (len(names) + 1), 1.9))
    ax[0].imshow(view.load_image())
    ax[0].set_title("photo (test view)", fontsize=8)
    for a, (key, title) in zip(ax[1:], names):
        a.imshow(np.asarray(Image.open(run / "renders" / f"{view.name}_{key}.png")))
        a.set_title(title, fontsize=8)
    for a in ax:
        a.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", nargs="?", default=str(SCENE), help="optimisation scene XML")
    ap.add_argument("--out", default="out/demo", help="output folder")
    ap.add_argument("--preset", default="quick", choices=sorted(PRESETS))
    ap.add_argument("--iterations", type=int, help="override the preset's iterations")
    args = ap.parse_args(argv)

    from glint_mi import optimize

    out = Path(args.out)
    run = out / "run"
    if run.exists():
        shutil.rmtree(run)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    cli = [args.scene, "--preset", args.preset, "--out", str(run)]
    if args.iterations:
        cli += ["--iterations", str(args.iterations)]
    rc = optimize.main(cli)
    if rc != 0:
        return rc
    from glint_mi.config import TrainConfig
    from glint_mi.runs import load_run_dataset

    ds = load_run_dataset(run, TrainConfig.load(run / "config.json"))
    contact_sheet(run, ds.test_views[0], out / "buffers.png")
    print(f"demo done in {time.perf_counter() - t0:.0f} s: run folder {run} (metrics.json, renders/, model/, "
          f"curves.png), contact sheet {out / 'buffers.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
