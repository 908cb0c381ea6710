"""``python -m glint_mi.optimize scene.xml``: train GLINT on a dataset, then evaluate on its test views.

    python -m glint_mi.optimize scene.xml --preset quick --out runs/room      # new run
    python -m glint_mi.optimize --resume runs/room                           # continue exactly (Ctrl-C saves)
    python -m glint_mi.optimize scene.xml --set losses.w_trans=0 --set model.components=all  # any field, by path
    python -m glint_mi.optimize scene.xml --method 3dgs                       # a baseline (glint_mi.methods)

Prints a metrics table at the end; everything is written under ``--out`` (see glint_mi.training.trainer).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from glint_mi.config import DEFAULT_VARIANT, PRESETS, VARIANTS, ConfigError, TrainConfig, flatten


def parse_sets(items) -> dict:
    """``--set FIELD=VALUE`` flags as {FIELD: value}; a field given twice with two values is refused (the later one
    silently won before), as ``flatten`` refuses a field named twice through its layer's path."""
    out = {}
    for it in items or []:
        if "=" not in it:
            raise ConfigError(f"--set {it!r}: use FIELD=VALUE (a JSON value or a string).")
        k, v = it.split("=", 1)
        try:
            v = json.loads(v)
        except json.JSONDecodeError:
            pass
        if k in out and repr(out[k]) != repr(v):  # repr: 1, 1.0 and true are three values, though equal in Python
            raise ConfigError(f"--set: '{k}' is given twice ({out[k]!r} and {v!r}); keep one.")
        out[k] = v
    return out


def build_config(args, scene_settings: dict | None = None, scene_path=None, note=None) -> TrainConfig:
    """The run's config from its sources, each setting from one place: the preset and variant give defaults, the
    method fixes its own fields; the --config file, the flags (--iterations, --seed) and --set override those (each
    override of a method's field or of the --config file is said, in one line to stderr); the scene XML's settings
    (components, max_order, kernel, grid_n, grid_k) are taken as they are, and any other source giving a different
    value for one of them is refused, naming both."""
    from glint_mi.methods import METHODS, config_for

    note = note or (lambda m: print(f"note: {m}", file=sys.stderr))
    method = getattr(args, "method", None) or "glint"
    if method not in METHODS:
        raise ConfigError(f"--method {method}: unknown; use one of {sorted(METHODS)}.")
    sources: list[tuple[str, dict]] = []  # (name, values by bare field name), later ones override earlier ones
    sources.append((f"method {method}", flatten(METHODS[method].overrides)))
    if args.config:
        TrainConfig.load(args.config)  # validates, with errors naming the file
        # as written: the migrations are for a run folder's complete config.json (they fill in what an older run
        # used where a key is absent), not for a file that gives a few fields
        sources.append((f"--config {args.config}", flatten(json.loads(args.config.read_text()))))
    flags = {}
    if args.iterations is not None:
        if args.iterations < 1:
            raise ConfigError(f"--iterations {args.iterations}: give a positive iteration count, or leave it out for "
                              f"the preset's budget (its epochs).")
        flags["iterations"], flags["epochs"] = args.iterations, 0.0
    if args.seed is not None:
        flags["seed"] = args.seed
    sources.append(("the command line", {**flags, **flatten(parse_sets(args.set), "--set")}))
    values, where = {}, {}
    for name, vals in sources:
        for k, v in vals.items():
            if k in values and values[k] != v and k not in ("epochs",):
                note(f"{name} sets {k} = {v!r} over {where[k]}'s {values[k]!r}")
            values[k], where[k] = v, name
    for k, v in (scene_settings or {}).items():
        if k in values and values[k] != v:
            tag = "string" if isinstance(v, str) else "integer"
            raise ConfigError(f"{scene_path or 'the scene XML'} states {k} = {v!r} but {where[k]} gives {values[k]!r}; "
                              f"a setting is given in one place: remove the <{tag} name=\"{k}\"> line from the XML, "
                              f"or drop the other.")
        values[k] = v
    fixed = {}
    for key, flag in (("preset", args.preset), ("variant", args.variant)):
        given = values.pop(key, None)
        if flag and given is not None and given != flag:
            raise ConfigError(f"--{key} {flag} but {where[key]} says {key} {given!r}; give one of them.")
        fixed[key] = flag or given
    preset = fixed["preset"] or "quick"
    variant = fixed["variant"] or DEFAULT_VARIANT
    for k, v in flatten(METHODS[method].at.get(preset, {})).items():  # the method's fields at this preset: over its
        if k not in values or where[k] == f"method {method}":        # own, under --config and the command line
            values[k], where[k] = v, f"method {method} at preset {preset}"
        elif values[k] != v and k != "epochs":  # said, as any override of a method's field is
            note(f"{where[k]} sets {k} = {values[k]!r} over method {method} at preset {preset}'s {v!r}")
    return config_for("glint", preset, variant, **values)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m glint_mi.optimize", description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("scene", nargs="?", type=Path, help="optimisation scene XML (python -m glint_mi.scene)")
    ap.add_argument("--out", type=Path, help="run folder (default runs/<scene folder name>)")
    ap.add_argument("--resume", type=Path, metavar="RUN", help="continue the run in this folder")
    ap.add_argument("--preset", choices=sorted(PRESETS), help="size preset (default quick)")
    ap.add_argument("--variant", choices=sorted(VARIANTS),
                    help="schedule: glint_mi (default: the supplement's without the refine stage), supplement, release")
    ap.add_argument("--method", default="glint",
                    help="a method of the comparison (glint_mi.methods: glint, 3dgs, 2dgs, ...; default glint)")
    ap.add_argument("--config", type=Path, help="JSON of TrainConfig fields")
    ap.add_argument("--iterations", type=int, help="a fixed iteration count instead of the preset's epochs budget")
    ap.add_argument("--seed", type=int)
    ap.add_argument("--set", action="append", metavar="LAYER.FIELD=VALUE",
                    help="override a config field by its path (losses.w_normal=0.1) or bare name (w_normal=0.1)")
    ap.add_argument("--no-eval", action="store_true", help="skip the test-view evaluation at the end")
    ap.add_argument("--no-progress", action="store_true")
    args = ap.parse_args(argv)

    from glint_mi.evaluation import metrics as M
    from glint_mi.data import DatasetError
    from glint_mi.data.priors import PriorError
    from glint_mi.model.gaussians import GaussianDataError
    from glint_mi.scene import SceneError, read_scene
    from glint_mi.runs import RunError, check_run_folder, undo_new_run
    from glint_mi import VariantError
    from glint_mi.training.trainer import Trainer

    run = None
    try:
        if args.resume:
            ignored = [flag for flag, given in (("a scene XML", args.scene), ("--out", args.out),
                                                ("--preset", args.preset), ("--variant", args.variant),
                                                ("--method", args.method != "glint"), ("--config", args.config),
                                                ("--iterations", args.iterations is not None),
                                                ("--seed", args.seed is not None), ("--set", args.set)) if given]
            if ignored:
                raise RunError(f"--resume {args.resume} continues the run as its config.json says; "
                               f"{', '.join(ignored)} would not be read: drop {'it' if len(ignored) == 1 else 'them'}, "
                               f"or start a new run with --out to train with other settings.")
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
            cfg = build_config(args, spec.settings, spec.path)
            with undo_new_run(run):  # a set-up that fails or is interrupted leaves no half-made run folder
                trainer = Trainer(run, cfg, scene=spec)
    except (ConfigError, SceneError, DatasetError, PriorError, GaussianDataError, RunError, VariantError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("\ninterrupted during set-up: nothing was trained" + (f"; {run} is as it was" if run else ""),
              file=sys.stderr)
        return 130
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
