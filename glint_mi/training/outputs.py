"""What a run writes besides its training state's arithmetic: the checkpoint (everything to continue exactly),
log.csv and report.json, the trained model (model/<role>.ply and a renderable scene.xml, curves.png) and the
convergence evaluations (convergence.csv)."""
from __future__ import annotations

import csv
import dataclasses
import io
import json
from pathlib import Path

import numpy as np

from glint_mi.config import LOSS_NAMES
from glint_mi.data.cameras import Camera, sensor_xml
from glint_mi.evaluation import metrics as M
from glint_mi.evaluation.plots import training_curves
from glint_mi.evaluation.renders import eval_options, evaluate
from glint_mi.model.files import integrator_props, model_xml, shape_props
from glint_mi.runs import atomic_write_bytes, atomic_write_text
from glint_mi.training.optim import RAW_FIELDS

__all__ = ["eval_options", "evaluate_now", "save_checkpoint", "write_log", "save_model"]  # eval_options: the trainer's


def evaluate_now(tr) -> dict:
    """Test-view metrics of the current model (no files but ``convergence.csv``), recorded against iteration,
    epoch and training seconds: the convergence curve (``eval_every``)."""

    m = evaluate(tr.integ_for_eval(), tr.eval_views(), write=False, **tr.eval_options())["metrics"]
    row = {"iteration": tr.it, "epoch": tr.epoch,
           "train_s": tr.elapsed, "gaussians": sum(len(tr.sets[r]) for r in tr.kept()),
           **{k: m.get(k, float("nan")) for k in M.METRICS}}
    tr.report.setdefault("convergence", [])
    if not any(r["iteration"] == tr.it for r in tr.report["convergence"]):
        tr.report["convergence"].append(row)
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(row))
    w.writeheader()
    w.writerows(tr.report["convergence"])
    atomic_write_text(tr.run_dir / "convergence.csv", buf.getvalue())
    return row

def save_checkpoint(tr) -> Path:
    tr.settle()
    tr.sync()
    arrays = {"iteration": np.array(tr.it), "elapsed": np.array(tr.elapsed), "extent": np.array(tr.extent),
              "bounds": np.stack(tr.bounds), "rng": np.array(json.dumps(tr.rng.bit_generator.state)),
              "strategy_rng": np.array(json.dumps(tr.strategy.rng.bit_generator.state)),
              "dropped": np.array(json.dumps(tr.dropped)), "report": np.array(json.dumps(tr.report)),
              "history": np.array(json.dumps(tr.history))}
    for role, gs in tr.sets.items():
        for f in RAW_FIELDS:
            arrays[f"set/{role}/{f}"] = getattr(gs, f)
    if tr.cfg.depth_align == "image" and tr.bank.depth_affine is not None:  # refitted from the model
        arrays["depth_affine"] = tr.bank.depth_affine
    arrays.update({f"adam/{k}": v for k, v in tr.adam.state_dict().items()})
    for part in tr.parts:  # a method's own parameters (Ref-GS's grid)
        arrays.update(part.state())
    arrays.update({f"strategy/{k}": v for k, v in tr.strategy.state_dict().items()})
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    path = tr.run_dir / "checkpoint.npz"
    atomic_write_bytes(path, buf.getvalue())
    write_log(tr)
    return path

def write_log(tr):
    tr.settle()
    rows = tr.history
    if rows:
        keys = ["iteration", "stage", *LOSS_NAMES, "rays_per_s", "gaussians", "share_reflection",
                "share_transmission", "mask_t", "gap_behind", "gap_front", "gain_reflection",
                "gain_transmission", "budget_full"]
        buf = io.StringIO()
        w = csv.DictWriter(buf, fieldnames=keys, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
        atomic_write_text(tr.run_dir / "log.csv", buf.getvalue())
    rep = dict(tr.report)
    rep["events"] = [dataclasses.asdict(e) for e in tr.strategy.events]
    rep["dropped"] = tr.dropped
    rep["sizes"] = {r: len(tr.sets[r]) for r in tr.kept()}
    atomic_write_text(tr.run_dir / "report.json", json.dumps(rep, indent=1))

def save_model(tr) -> Path:
    """model/<role>.ply (3DGS + specular/transparency) and model/scene.xml renderable by Mitsuba."""
    tr.sync()
    model = tr.run_dir / "model"
    model.mkdir(exist_ok=True)
    sets = tr.active_sets()
    for role, gs in sets.items():
        gs.save_ply(model / f"{role}.ply")
    for role in set(tr.sets) - set(sets):
        (model / f"{role}.ply").unlink(missing_ok=True)
    v = (tr.ds.test_views or tr.ds.train_views)[0]

    for part in tr.parts:  # a method's own model files (Ref-GS's grid: env.npy)
        part.save(tr, model)
    props = {"dataset": str(tr.ds.root.resolve()),
             **integrator_props(tr.cfg.render, components="all", env_file="env.npy")}
    xml = model_xml(props, list(sets), shape_props(tr.cfg), sensor_xml(Camera.from_view(v), 1),
                    f"trained by glint_mi ({tr.it} iterations); render with mitsuba or python -m "
                    f"glint_mi.evaluate")
    atomic_write_text(model / "scene.xml", xml)
    write_log(tr)
    if tr.history:

        training_curves(tr.history, tr.run_dir / "curves.png")
    return model
