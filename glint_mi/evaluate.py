"""Evaluate a trained run: ``python -m glint_mi.evaluate RUN`` renders the test views and recomputes the metrics.

Writes ``RUN/metrics.json`` (means, FPS, train time, machine), ``RUN/per_view/<view>.json``, and per test view
``RUN/renders/<view>_{rgb,depth,normal,t,cI,cR,cT}.png`` plus one ``<view>.exr`` with every buffer (linear
floats: R G B, Z, N.X N.Y N.Z, T, cI.*, cR.*, cT.*).
"""
from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

from . import metrics as M
from .batch import pixel_rays
from .data import View
from .render import floats

CHUNK = 1 << 16


def render_view(integ, view: View, need_direct: bool = False) -> dict[str, np.ndarray]:
    """Every buffer of one view as [H, W, C] numpy (rays through pixel centres, chunks of 65k rays)."""
    import drjit as dr
    import mitsuba as mi

    d = pixel_rays(view).astype(np.float32)
    o = view.c2w[:3, 3].astype(np.float32)
    f = view.c2w[:3, 2].astype(np.float32)
    fwd = mi.Vector3f(*[float(x) for x in f])
    bufs: dict[str, list] = {}
    for s in range(0, len(d), CHUNK):
        dd = d[s:s + CHUNK]
        ray = mi.Ray3f(mi.Point3f(*floats(np.broadcast_to(o, dd.shape))), mi.Vector3f(*floats(dd)))
        out = integ.trace(ray, mi.Bool(True), need={"trans_direct"} if need_direct else set(), forward=fwd)
        vals = {"rgb": out["rgb"], "depth": out["depth"], "normal": out["normal"], "transparency": out["transparency"],
                "interface": out["interface"], "reflection": out["reflection"], "transmission": out["transmission"],
                "alpha": out["alpha"]}
        if need_direct:
            vals["trans_rgb"], vals["trans_depth"] = out["trans_direct"][0], out["trans_direct"][1]
        dr.eval(vals)
        for k, v in vals.items():
            a = np.array(v)
            a = a.T if a.ndim == 2 else a[:, None]
            bufs.setdefault(k, []).append(np.broadcast_to(a, (len(dd), a.shape[1])))  # unused passes are width 1
    out = {}
    for k, v in bufs.items():
        arr = np.concatenate(v).reshape(view.height, view.width, -1)
        out[k] = arr[..., 0] if arr.shape[-1] == 1 else arr
    return out


def _png(path: Path, img: np.ndarray) -> None:
    from PIL import Image

    Image.fromarray((np.clip(img, 0, 1) * 255 + 0.5).astype(np.uint8)).save(path)


def save_renders(folder: Path, name: str, b: dict) -> None:
    import OpenEXR

    folder.mkdir(parents=True, exist_ok=True)
    depth = b["depth"]
    valid = depth > 0
    dn = np.zeros_like(depth)
    if valid.any():
        lo, hi = np.percentile(depth[valid], [1, 99])
        dn[valid] = 1.0 - np.clip((depth[valid] - lo) / max(hi - lo, 1e-9), 0, 1) * 0.9
    _png(folder / f"{name}_rgb.png", b["rgb"])
    _png(folder / f"{name}_depth.png", dn)
    _png(folder / f"{name}_normal.png", b["normal"] * 0.5 + 0.5)
    _png(folder / f"{name}_t.png", b["transparency"])
    for key, short in (("interface", "cI"), ("reflection", "cR"), ("transmission", "cT")):
        _png(folder / f"{name}_{short}.png", b[key])
    ch = {"R": b["rgb"][..., 0], "G": b["rgb"][..., 1], "B": b["rgb"][..., 2], "Z": depth,
          "N.X": b["normal"][..., 0], "N.Y": b["normal"][..., 1], "N.Z": b["normal"][..., 2], "T": b["transparency"]}
    for key, short in (("interface", "cI"), ("reflection", "cR"), ("transmission", "cT")):
        for i, c in enumerate("RGB"):
            ch[f"{short}.{c}"] = b[key][..., i]
    ch = {k: np.ascontiguousarray(v, np.float32) for k, v in ch.items()}
    tmp = folder / f"{name}.exr.partial.exr"
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, ch) as f:
        f.write(str(tmp))
    tmp.replace(folder / f"{name}.exr")


def machine() -> str:
    import os

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, {platform.system()}, Dr.Jit LLVM"


def evaluate(integ, views: list[View], out_dir: Path | None = None, train_s: float | None = None,
             write: bool = True) -> dict:
    """Metrics of ``integ`` (a glint integrator holding trained sets) on ``views``; FPS after a warm-up render."""
    from .train import atomic_write_text

    per_view, renders = {}, {}
    render_view(integ, views[0])  # warm-up: kernels compiled here are not counted in the FPS
    t0 = time.perf_counter()
    for v in views:
        renders[v.name] = render_view(integ, v)
    fps = len(views) / max(time.perf_counter() - t0, 1e-9)
    for v in views:
        b = renders[v.name]
        per_view[v.name] = M.view_metrics(b, v.load_gt(), v.load_image())
    result = {"metrics": M.mean_metrics(list(per_view.values())), "fps": fps, "train_s": train_s,
              "resolution": [views[0].width, views[0].height], "views": [v.name for v in views],
              "machine": machine()}
    result["metrics"].update(fps=fps, train_s=train_s)
    if write and out_dir is not None:
        out_dir = Path(out_dir)
        for v in views:
            save_renders(out_dir / "renders", v.name, renders[v.name])
            (out_dir / "per_view").mkdir(exist_ok=True)
            atomic_write_text(out_dir / "per_view" / f"{v.name}.json", json.dumps(per_view[v.name], indent=1))
        atomic_write_text(out_dir / "metrics.json", json.dumps(result, indent=1))
    result["per_view"] = per_view
    result["renders"] = renders
    return result


def load_run(run: str | Path):
    """(integrator, dataset, config, train_s) of a finished run folder (its ``model/``)."""
    import glint_mi

    from .config import TrainConfig
    from .data import load_dataset
    from .gaussians import GaussianSet
    from .examples import gaussian_scene_dict
    from .train import RunError

    run = Path(run)
    model = run / "model"
    if not (run / "config.json").exists() or not model.exists():
        raise RunError(f"{run}: not a finished run (needs config.json and model/); train with "
                       f"`python -m glint_mi.optimize scene.xml --out {run}`.")
    cfg = TrainConfig.load(run / "config.json")
    info = json.loads((run / "run.json").read_text())
    ds = load_dataset(info["dataset"])
    glint_mi.set_variant()
    import mitsuba as mi

    from .conventions import ROLES

    sets = {r: GaussianSet.load_ply(model / f"{r}.ply") for r in ROLES if (model / f"{r}.ply").exists()}
    scene = mi.load_dict(gaussian_scene_dict(sets, cfg.kernel, cfg.opacity_shells, components="all",
                                             max_order=cfg.max_order, max_hits=cfg.max_hits, blend=cfg.blend))
    ckpt = run / "checkpoint.npz"
    train_s = float(np.load(ckpt)["elapsed"]) if ckpt.exists() else None
    return scene.integrator(), ds, cfg, train_s


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m glint_mi.evaluate", description=__doc__.split("\n")[0])
    ap.add_argument("run", type=Path)
    args = ap.parse_args(argv)
    from .data import DatasetError
    from .train import RunError

    try:
        integ, ds, cfg, train_s = load_run(args.run)
    except (RunError, DatasetError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    res = evaluate(integ, ds.test_views, args.run, train_s)
    print(M.table({args.run.name: res["metrics"]}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
