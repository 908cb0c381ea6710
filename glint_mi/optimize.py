"""``python -m glint_mi.optimize scene.xml``: train GLINT on a dataset, then evaluate on its test views.

    python -m glint_mi.optimize scene.xml --preset quick --out runs/room      # new run
    python -m glint_mi.optimize --resume runs/room                           # continue exactly (Ctrl-C saves)
    python -m glint_mi.optimize scene.xml --set w_trans=0 --set components=all  # any TrainConfig field
    python -m glint_mi.optimize scene.xml --method 3dgs                       # a baseline (glint_mi.methods)

Prints a metrics table at the end; everything is written under ``--out`` (see glint_mi.training.trainer).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from glint_mi.config import DEFAULT_VARIANT, VARIANTS, ConfigError, TrainConfig


def parse_sets(items) -> dict:
    out = {}
    for it in items or []:
        if "=" not in it:
            raise ConfigError(f"--set {it!r}: use FIELD=VALUE (a JSON value or a string).")
        k, v = it.split("=", 1)
        try:
            out[k] = json.loads(v)
        except json.JSONDecodeError:
            out[k] = v
    return out


def build_config(args, scene_props: dict | None = None) -> TrainConfig:
    """Preset and variant, then the --config file, the scene XML's integrator properties, flags and --set."""
    values = {}
    if args.config:
        TrainConfig.load(args.config)  # validates, with errors naming the file
        values.update(json.loads(args.config.read_text()))
    from glint_mi.methods import METHODS

    method = getattr(args, "method", None) or "glint"
    for key in ("components", "max_order"):  # the scene's, unless the method fixes it (3dgs: the interface alone)
        if scene_props and key in scene_props and key not in METHODS.get(method, METHODS["glint"]).overrides:
            values[key] = scene_props[key]
    if args.iterations:
        values["iterations"], values["epochs"] = args.iterations, 0.0
    if args.seed is not None:
        values["seed"] = args.seed
    values.update(parse_sets(args.set))
    preset = args.preset or values.pop("preset", None) or "quick"
    variant = args.variant or values.pop("variant", None) or DEFAULT_VARIANT
    values.pop("preset", None), values.pop("variant", None)
    from glint_mi.methods import config_for

    return config_for(method, preset, variant, **values)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m glint_mi.optimize", description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("scene", nargs="?", type=Path, help="optimisation scene XML (python -m glint_mi.scene)")
    ap.add_argument("--out", type=Path, help="run folder (default runs/<scene folder name>)")
    ap.add_argument("--resume", type=Path, metavar="RUN", help="continue the run in this folder")
    ap.add_argument("--preset", choices=["tiny", "quick", "bench", "gpu"], help="size preset (default quick)")
    ap.add_argument("--variant", choices=sorted(VARIANTS),
                    help="schedule: glint_mi (default: the supplement's without the refine stage), supplement, release")
    ap.add_argument("--method", default="glint",
                    help="a method of the comparison (glint_mi.methods: glint, 3dgs, 2dgs, ...; default glint)")
    ap.add_argument("--config", type=Path, help="JSON of TrainConfig fields")
    ap.add_argument("--iterations", type=int, help="a fixed iteration count instead of the preset's epochs budget")
    ap.add_argument("--seed", type=int)
    ap.add_argument("--set", action="append", metavar="FIELD=VALUE", help="override a TrainConfig field")
    ap.add_argument("--no-eval", action="store_true", help="skip the test-view evaluation at the end")
    ap.add_argument("--no-progress", action="store_true")
    args = ap.parse_args(argv)

    from glint_mi.evaluation import metrics as M
    from glint_mi.data import DatasetError
    from glint_mi.data.priors import PriorError
    from glint_mi.model.gaussians import GaussianDataError
    from glint_mi.scene import SceneError, read_scene
    from glint_mi.runs import RunError, check_run_folder
    from glint_mi.training.trainer import Trainer

    try:
        if args.resume:
            run = args.resume
            if not (run / "config.json").exists():
                raise RunError(f"{run}/config.json: missing; --resume needs a run folder made by glint_mi.optimize.")
            cfg = TrainConfig.load(run / "config.json")
            trainer = Trainer(run, cfg, resume=True)
        else:
            if args.scene is None:
                ap.error("give a scene XML or --resume RUN")
            run = args.out or Path("runs") / args.scene.resolve().parent.name
            check_run_folder(run)  # before the dataset is read
            spec = read_scene(args.scene)
            cfg = build_config(args, spec.integrator)
            trainer = Trainer(run, cfg, scene=spec)
    except (ConfigError, SceneError, DatasetError, PriorError, GaussianDataError, RunError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    for role, what in trainer.report["init"].items():
        if role in trainer.sets:  # a set dropped before training was said so, with why, when it was dropped
            print(f"init {role}: {what}")
    if trainer.report.get("priors_derived_from_ground_truth"):
        print("note: the priors were derived from ground truth (priors/PRIORS.json); results are labelled so")
    try:
        res = trainer.train(progress=not args.no_progress)
    except KeyboardInterrupt:
        return 130
    if trainer.report["components"]:  # each decision was logged with its reason when taken: a summary only
        print("components: " + ", ".join(f"{'kept' if d['kept'] else 'dropped'} {role}"
                                         for role, d in trainer.report["components"].items())
              + f" (why: above, and in {run}/report.json)")
    print(f"trained {res['iterations']} iterations in {res['train_s']:.1f} s -> {run}")
    if not args.no_eval and trainer.ds.test_views:
        from glint_mi.evaluate import evaluate

        try:
            out = evaluate(trainer.integ_for_eval(), trainer.eval_views(), run, res["train_s"],
                           progress=not args.no_progress, **trainer.eval_options())
        except KeyboardInterrupt:
            print(f"the model is saved in {run}/model; finish the evaluation with `python -m glint_mi.evaluate {run}`")
            return 130
        print(M.table({run.name: out["metrics"]}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
