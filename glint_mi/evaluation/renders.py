"""A run's evaluation as a library (``python -m glint_mi.evaluate`` is its command): render views of trained sets,
write, as each view finishes, ``per_view/<view>.json``, ``renders/<view>_{rgb,depth,normal,t,cI,cR,cT}.png`` and one
``<view>.exr`` with every buffer (R G B and the components cI.*, cR.*, cT.* as linear light: the model's colours are
fitted to sRGB photos and converted; Z planar depth, N.X N.Y N.Z world normal, T transparency), then
``metrics.json`` (means, FPS, train time, machine); load a finished run's model. Training imports it for its
periodic evaluations, so it imports nothing from training.
"""
from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import numpy as np

from glint_mi.conventions import srgb_to_linear
from glint_mi.data import View
from glint_mi.data.rays import pixel_rays
from glint_mi.evaluation import metrics as M
from glint_mi.model.render import floats
from glint_mi.runs import atomic_write_text

CHUNK = 1 << 16


def render_view(integ, view: View, need_direct: bool = False, depth_rule: str = "expected",
                glass: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Every buffer of one view as [H, W, C] numpy (rays through pixel centres, chunks of 65k rays). ``depth``
    follows ``depth_rule`` (:mod:`glint_mi.evaluation.depth_rules`: expected, median, or first_surface with the view's
    transparency mask ``glass`` [H, W])."""
    import drjit as dr
    import mitsuba as mi

    from glint_mi.evaluation import depth_rules

    d = pixel_rays(view).astype(np.float32)
    o = view.c2w[:3, 3].astype(np.float32)
    f = view.c2w[:3, 2].astype(np.float32)
    fwd = mi.Vector3f(*[float(x) for x in f])
    bufs: dict[str, list] = {}
    for s in range(0, len(d), CHUNK):
        dd = d[s:s + CHUNK]
        ray = mi.Ray3f(mi.Point3f(*floats(np.broadcast_to(o, dd.shape))), mi.Vector3f(*floats(dd)))
        lists = depth_rule == "first_surface"
        out = integ.trace(ray, mi.Bool(True), need={"trans_direct"} if need_direct else set(), forward=fwd,
                          record=lists)
        depth = out["depth"]
        if depth_rule == "median":  # the interface pass's own median composite, as planar depth
            z = dd.astype(np.float64) @ f.astype(np.float64)
            depth = mi.Float(depth_rules.median_depth(np.array(out["median"], np.float64), z,
                                                      np.array(depth, np.float64)).astype(np.float32))
        elif lists:  # TSGS's rule reads the interface pass's composited Gaussians
            alpha, z, _ = depth_rules.interface_hits(integ, ray, fwd, out["hit_lists"][0])
            mask = np.zeros(len(dd)) if glass is None else glass.reshape(-1)[s:s + CHUNK]
            depth = mi.Float(depth_rules.first_surface_depth(alpha, z, mask, **depth_rules.TSGS).astype(np.float32))
        vals = {"rgb": out["rgb"], "depth": depth, "normal": out["normal"], "transparency": out["transparency"],
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
    # the model is fitted to sRGB photos, so its colours are sRGB-encoded values; an EXR holds linear light
    lin = lambda x: srgb_to_linear(np.clip(x, 0.0, None))
    rgb = lin(b["rgb"])
    ch = {"R": rgb[..., 0], "G": rgb[..., 1], "B": rgb[..., 2], "Z": depth,
          "N.X": b["normal"][..., 0], "N.Y": b["normal"][..., 1], "N.Z": b["normal"][..., 2], "T": b["transparency"]}
    for key, short in (("interface", "cI"), ("reflection", "cR"), ("transmission", "cT")):
        comp = lin(b[key])
        for i, c in enumerate("RGB"):
            ch[f"{short}.{c}"] = comp[..., i]
    ch = {k: np.ascontiguousarray(v, np.float32) for k, v in ch.items()}
    tmp = folder / f"{name}.exr.partial.exr"
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, ch) as f:
        f.write(str(tmp))
    tmp.replace(folder / f"{name}.exr")


def eval_options(cfg, root) -> dict:
    """``evaluate`` keywords for a run's config: its depth rule and, for first_surface, the masks it reads."""
    if cfg.eval_depth != "first_surface":
        return {"depth_rule": cfg.eval_depth}
    from glint_mi.data.priors import load_prior

    def glass_of(view):
        m = load_prior(root, view, "glass")
        if m is None:
            from glint_mi.data import DatasetError
            raise DatasetError(f"{root}: eval_depth = first_surface (TSGS) needs priors/glass/{view.name}.(npy|png|exr)"
                               f" for the test view '{view.name}' (the transparency mask its depth rule reads).")
        return m
    return {"depth_rule": "first_surface", "glass_of": glass_of}


PARTIAL = "evaluation_partial"  # where an evaluation writes until its last view is done


def evaluate(integ, views: list[View], out_dir: Path | None = None, train_s: float | None = None,
             write: bool = True, progress: bool = False, depth_rule: str = "expected", glass_of=None) -> dict:
    """Metrics of ``integ`` (a glint integrator holding trained sets) on ``views``, at the views' resolution; the
    depth each method reports by ``depth_rule`` (``glass_of(view)``: the view's transparency mask, for TSGS's
    first_surface rule).

    With ``write``, each view's renders, ``per_view/<view>.json`` and the metrics so far (``"views_done"``) are
    written to ``out_dir/evaluation_partial/`` as soon as it is done and moved into ``out_dir`` when every view is:
    a Ctrl-C keeps what is finished there and leaves the last complete evaluation as it was (the
    KeyboardInterrupt propagates). FPS counts the views after the first (whose
    render also compiles the kernels); with one view, that view is rendered a second time."""
    from tqdm.auto import tqdm

    out_dir = Path(out_dir) if (write and out_dir is not None) else None
    per_view, renders, seconds = {}, {}, []
    from glint_mi.machine import describe, summary

    dev = describe()
    res = {"resolution": [views[0].width, views[0].height], "machine": summary(dev), "variant": dev["variant"],
           "device": dev["device"], "train_s": train_s}

    def result(done_all: bool) -> dict:
        timed = seconds[1:] if len(seconds) > 1 else seconds
        fps = len(timed) / max(sum(timed), 1e-9) if timed else float("nan")
        r = {"metrics": {**M.mean_metrics(list(per_view.values())), "fps": fps, "train_s": train_s}, "fps": fps,
             **res, "views": list(per_view), "views_done": len(per_view), "views_total": len(views)}
        if not done_all:
            r["interrupted"] = True
        return r

    bar = tqdm(views, desc="evaluate", unit="view", disable=not progress, dynamic_ncols=True)
    final = out_dir
    if out_dir is not None:  # written here as views finish, moved into place when all are: an interruption keeps
        out_dir = final / PARTIAL  # the last complete evaluation (metrics.json, renders/, per_view/) as it was
        shutil.rmtree(out_dir, ignore_errors=True)
        out_dir.mkdir(parents=True)  # its presence says an evaluation is under way or was interrupted
    try:
        for v in bar:
            t0 = time.perf_counter()
            mask = glass_of(v) if glass_of is not None else None
            b = render_view(integ, v, depth_rule=depth_rule, glass=mask)
            seconds.append(time.perf_counter() - t0)
            if len(views) == 1:  # the first render compiled the kernels: time a second one
                t0 = time.perf_counter()
                b = render_view(integ, v, depth_rule=depth_rule, glass=mask)
                seconds.append(time.perf_counter() - t0)
            per_view[v.name] = M.view_metrics(b, v.load_gt(), v.load_image())
            renders[v.name] = b
            if out_dir is not None:
                save_renders(out_dir / "renders", v.name, b)
                (out_dir / "per_view").mkdir(parents=True, exist_ok=True)
                atomic_write_text(out_dir / "per_view" / f"{v.name}.json", json.dumps(per_view[v.name], indent=1))
                atomic_write_text(out_dir / "metrics.json", json.dumps(result(len(per_view) == len(views)), indent=1))
            bar.set_postfix(psnr=f"{per_view[v.name]['psnr']:.2f}", refresh=False)
    except KeyboardInterrupt:
        bar.close()
        if out_dir is not None:
            print(f"\nevaluation interrupted: {len(per_view)} of {len(views)} views kept in {out_dir}; "
                  f"{final}/metrics.json is still the last complete evaluation")
        raise
    bar.close()
    if out_dir is not None:
        atomic_write_text(out_dir / "metrics.json", json.dumps(result(True), indent=1))
        for sub in ("renders", "per_view"):
            shutil.rmtree(final / sub, ignore_errors=True)
            if (out_dir / sub).exists():
                (out_dir / sub).rename(final / sub)
        (out_dir / "metrics.json").replace(final / "metrics.json")
        shutil.rmtree(out_dir, ignore_errors=True)
    out = result(True)
    out["per_view"] = per_view
    out["renders"] = renders
    return out


def check_finished_run(run: Path) -> None:
    """Refuse a folder that holds no finished run (its config.json and model/)."""
    from glint_mi.runs import RunError

    if not (Path(run) / "config.json").exists() or not (Path(run) / "model").exists():
        raise RunError(f"{run}: not a finished run (needs config.json and model/); train with "
                       f"`python -m glint_mi.optimize scene.xml --out {run}`.")


def load_run(run: str | Path, full: bool = False, max_hits: int | None = None, components: str = "all"):
    """(integrator, dataset, config, train_s) of a finished run folder (its ``model/``); the dataset at the
    training resolution, or with ``full`` at its full resolution; ``max_hits`` and ``components`` as in
    :func:`load_model`."""
    from glint_mi.config import TrainConfig
    from glint_mi.runs import load_run_dataset, read_checkpoint

    run = Path(run)
    check_finished_run(run)
    cfg = TrainConfig.load(run / "config.json")
    ds = load_run_dataset(run, cfg, full=full or cfg.eval_full)
    ckpt = run / "checkpoint.npz"
    train_s = float(read_checkpoint(ckpt, keys=("elapsed",))["elapsed"]) if ckpt.exists() else None
    return load_model(run, cfg, max_hits, components), ds, cfg, train_s


def load_model(run: str | Path, cfg, max_hits: int | None = None, components: str = "all"):
    """The glint integrator holding a finished run's trained sets (``RUN/model/*.ply``), configured as ``cfg`` (the
    run's) except for ``max_hits`` (replaces the run's hit budget) and ``components`` (``all``: the exact
    first-order model; ``auto`` or a comma list of sets trade accuracy for speed, see
    ``benchmarks/bench_render_tradeoff.py``)."""
    import glint_mi

    from glint_mi.conventions import ROLES
    from glint_mi.model.examples import gaussian_scene_dict
    from glint_mi.model.gaussians import GaussianSet
    from glint_mi.model.files import integrator_props, shape_props

    glint_mi.set_variant()
    import mitsuba as mi

    model = Path(run) / "model"
    sets = {r: GaussianSet.load_ply(model / f"{r}.ply") for r in ROLES if (model / f"{r}.ply").exists()}
    if cfg.blend == "refgs" and not (model / "env.npy").exists():  # Ref-GS's directional grid, beside the sets
        from glint_mi.runs import RunError

        raise RunError(f"{model / 'env.npy'}: a refgs model needs its directional grid; the run did not "
                       f"finish saving its model - resume it with `python -m glint_mi.optimize --resume {run}`.")
    props = integrator_props(cfg.render, components=components, max_hits=max_hits,
                             env_file=str((model / "env.npy").resolve()))
    with glint_mi.deferred_interrupt():  # a Ctrl-C inside the plugins' C++ callbacks prints a traceback
        scene = mi.load_dict(gaussian_scene_dict(sets, **shape_props(cfg), **props))
    return scene.integrator()
