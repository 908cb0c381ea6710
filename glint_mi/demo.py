"""`make demo`: render the bundled display-case scene with the glint integrator and write its buffers.

The optimisation CLI (`python -m glint_mi.optimize`) is not available yet; until it lands, the demo shows the image
model on the bundled scene: RGB, depth, normal, transparency and the interface / reflection / transmission
decomposition, saved as PNG (a contact sheet) and EXR, with timings.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import glint_mi

SCENE = Path(__file__).resolve().parent.parent / "scenes" / "display_case" / "scene.xml"


def contact_sheet(buffers: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from glint_mi.plots import show_buffers

    fig = show_buffers(buffers)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", nargs="?", default=str(SCENE), help="scene XML with the glint integrator")
    ap.add_argument("--out", default="out/demo", help="output folder")
    ap.add_argument("--spp", type=int, default=4)
    args = ap.parse_args(argv)

    import mitsuba as mi

    from glint_mi.render import render_buffers

    glint_mi.set_variant()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    scene = glint_mi.load_file(args.scene)
    t1 = time.perf_counter()
    buffers = render_buffers(scene, spp=args.spp)
    t2 = time.perf_counter()
    buffers = render_buffers(scene, spp=args.spp, seed=1)
    t3 = time.perf_counter()
    contact_sheet(buffers, out / "buffers.png")
    for name, x in buffers.items():
        mi.Bitmap(np.ascontiguousarray(x, dtype=np.float32)).write(str(out / f"{name}.exr"))
    integ = scene.integrator()
    print(f"scene      {args.scene}\nintegrator {integ.to_string()}")
    print(f"load {t1 - t0:.2f} s | first render (compiles kernels) {t2 - t1:.2f} s | warm render {t3 - t2:.3f} s "
          f"at {buffers['rgb'].shape[1]}x{buffers['rgb'].shape[0]}, {args.spp} spp")
    for name in ("transparency", "alpha"):
        if name in buffers:
            print(f"mean {name:12s} {float(buffers[name].mean()):.3f}")
    print(f"wrote {out}/buffers.png and one EXR per buffer")
    print("note: the optimisation (python -m glint_mi.optimize) is not yet available; this demo shows the image model.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
