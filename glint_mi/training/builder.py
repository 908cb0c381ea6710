"""Assembling a run (the trainer runs the loop; this builds what it loops over): read the dataset and check it
against the config, initialise the sets or read them back from a checkpoint, set up Adam, the densification strategy
and the components policy, take the run folder's lock and write its config, prepare the training inputs, apply the
no-glass decision and build the Mitsuba scene. Each function fills the :class:`~glint_mi.training.trainer.Trainer`
it is given (the attributes it documents), so that a notebook still holds one object."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

import glint_mi.conventions as cv
from glint_mi.data import DatasetError, load_dataset
from glint_mi.evaluation.renders import eval_options
from glint_mi.model.examples import gaussian_scene_dict
from glint_mi.model.files import TRAINING_AOVS, integrator_props, shape_props
from glint_mi.model.gaussians import GaussianSet
from glint_mi.runs import RunError, atomic_write_text, hold_run, load_run_dataset, read_checkpoint
from glint_mi.scene import check_settings, initial_sets, read_scene
from glint_mi.training.components import ComponentsPolicy
from glint_mi.training.inputs import normal_prior_schedule, training_inputs
from glint_mi.training.optim import RAW_FIELDS, Adam
from glint_mi.training.refgs import DirectionalGridPart
from glint_mi.training.strategy import Strategy


# a method's own training parts (each says whether a config asks for it): Ref-GS's directional grid
PARTS = (DirectionalGridPart,)


def parts_for(cfg) -> list:
    """The parts a run configured as ``cfg`` trains beside its sets."""
    return [part() for part in PARTS if part.applies(cfg)]


def smallest_view(ds):
    """The training view with the shortest side (what a patch and coarse_to_fine's levels must fit)."""
    return min(ds.train_views, key=lambda v: min(v.width, v.height))


def check_patch(cfg, ds) -> None:
    """Refuse a patch that does not fit in a training view (a large downscale leaves small images), before the run
    folder is made."""
    from glint_mi.config import ConfigError

    small = smallest_view(ds)
    if cfg.patch > min(small.width, small.height):
        raise ConfigError(f"'patch' = {cfg.patch}: a {cfg.patch} x {cfg.patch} patch does not fit in training view "
                          f"'{small.name}' ({small.width} x {small.height} at downscale {cfg.downscale}); use "
                          f"--set patch={max(3, min(small.width, small.height))} or a smaller downscale.")
    for f, _ in cfg.coarse_levels(small.width, small.height)[0]:  # the dataset read at f x the downscale (floor)
        w, h = small.width // f, small.height // f
        if cfg.patch > min(w, h):
            raise ConfigError(f"'coarse_to_fine' = {cfg.coarse_to_fine!r}: at 1/{f} of the run's size training view "
                              f"'{small.name}' is {w} x {h}, smaller than a {cfg.patch} x {cfg.patch} patch: use a "
                              f"smaller factor or patch, or --set coarse_to_fine= (full size throughout; the bench "
                              f"preset sets it).")


def assemble(tr, resume: bool) -> None:
    """Everything a run needs before its first step, fresh or resumed: the dataset, the initial sets (or the
    checkpoint's), the optimiser, the densification strategy, the components policy, the run folder's lock and
    files, the training inputs (priors, the see-through cue), the no-glass decision and the Mitsuba scene."""
    if resume:
        load_checkpoint(tr)
    else:
        fresh(tr)
    from glint_mi.machine import describe

    tr.report["machine"] = describe()  # where this run (its latest segment, when resumed) trained
    cfg = tr.cfg
    if cfg.eval_depth == "first_surface":  # TSGS's depth reads each test view's mask: refuse before training
        glass_of = eval_options(cfg, tr.ds.root)["glass_of"]
        for v in tr.ds.test_views:
            glass_of(v)
    tr.bank = training_inputs(tr.ds, cfg, "transmission" in tr.sets, tr.report, tr.log,
                              getattr(tr, "_resume_affine", None))  # set by _load_checkpoint only
    tr.prior_floor, tr.prior_weight = normal_prior_schedule(tr.bank, tr.ds, cfg, tr.report, tr.log)
    coarse_banks(tr)
    if not resume:
        glass_cue_check(tr)  # may give the run the 3dgs profile (another kernel): the strategy is built after it
        tr.strategy = Strategy.for_config(tr.cfg, tr.extent, np.random.default_rng([tr.cfg.seed, 1]))  # own stream
    from glint_mi.data.priors import priors_are_derived

    tr.report["priors_derived_from_ground_truth"] = bool(priors_are_derived(tr.ds.root))
    build_scene(tr)


def fresh(tr):
    """A new run: the dataset read and checked (priors, the scene's settings, the patch size) before anything is
    written, the initial sets, Adam and the components policy; then the lock and config.json / run.json (tr: ds,
    sets, bounds, extent, report['init'], parts, adam, components). The strategy comes after the no-glass decision
    (:func:`assemble`)."""
    if tr.scene_spec is None:
        raise RunError("a new run needs an optimisation scene (python -m glint_mi.scene DATASET > scene.xml).")
    if tr.ds is None:
        tr.ds = load_dataset(tr.scene_spec.dataset, downscale=tr.cfg.downscale,
                             missing=tr.scene_spec.missing, log=tr.log)
        tr.log(tr.ds.summary())
    if not tr.ds.train_views:
        raise DatasetError(f"{tr.ds.root}: no training views (check split.json).")
    if tr.cfg.priors == "all":  # before SfM and initialisation: a bad prior is found in seconds, not minutes
        from glint_mi.data.priors import PriorError, check_priors

        problems = check_priors(tr.ds.root, tr.ds.train_views)
        if problems:
            raise PriorError("\n".join(problems))
    check_settings(tr.scene_spec, tr.cfg)
    check_patch(tr.cfg, tr.ds)
    set_budget(tr)
    sets, (lo, hi, extent), rep = initial_sets(tr.scene_spec, tr.ds, tr.cfg, tr.rng, tr.log)
    roles = tr.cfg.roles()
    tr.sets = {r: s for r, s in sets.items() if r in roles}
    tr.bounds = (lo, hi)
    tr.extent = float(extent)
    tr.report["init"] = {**rep, "extent": tr.extent, "box": [lo.tolist(), hi.tolist()]}
    tr.parts = parts_for(tr.cfg)
    for part in tr.parts:
        part.start(tr)
    tr.adam = Adam(learning_rates(tr), eps=tr.cfg.adam_eps, selective=tr.cfg.adam == "selective")
    tr.components = ComponentsPolicy(tr.cfg)
    tr.report["components"] = tr.components.decisions
    tr._lock = hold_run(tr.run_dir)  # before anything is written (creates the folder)
    tr.cfg.save(tr.run_dir / "config.json")
    atomic_write_text(tr.run_dir / "run.json", json.dumps(
        {"scene": str(tr.scene_spec.path), "dataset": str(tr.ds.root), "dataset_options": tr.ds.options,
         "dataset_notes": tr.ds.notes, "sparse": str(tr.ds.sparse) if tr.ds.sparse else None,
         "tracks_distorted": tr.ds.tracks_distorted}, indent=1))

def coarse_banks(tr) -> None:
    """``coarse_to_fine``: the ray banks the early iterations draw from (tr.coarse: [(until iteration, bank)],
    coarsest first; empty without it). Each is the run's dataset read at factor x its downscale, with the same SfM
    points and tracks, and its inputs prepared as the full-size bank's (priors aligned, the see-through cue, the SfM
    depth)."""
    tr.coarse = []
    tr.report.pop("coarse_to_fine", None)  # written afresh: a resumed run's report holds the last segment's list
    least = smallest_view(tr.ds)
    levels, left_out = tr.cfg.coarse_levels(least.width, least.height)
    if left_out:
        tr.report["coarse_to_fine_left_out"] = [{"factor": f, "size": [least.width // f, least.height // f]}
                                                for f in left_out]
        tr.log("coarse to fine: " + ", ".join(f"1/{f} size left out ({least.width // f} x {least.height // f}, "
                                              f"under coarse_min_side {tr.cfg.coarse_min_side})" for f in left_out))
    for f, until in levels:
        ds = load_dataset(tr.ds.root, **{**tr.ds.options, "downscale": tr.cfg.downscale * f})
        ds.points, ds.colors, ds.sparse, ds.tracks_distorted = (tr.ds.points, tr.ds.colors, tr.ds.sparse,
                                                                tr.ds.tracks_distorted)
        small = smallest_view(ds)  # checked against the patch before
        bank = training_inputs(ds, tr.cfg, "transmission" in tr.sets, {}, log=lambda *a: None)
        tr.coarse.append((int(round(until * tr.cfg.iterations)), bank))
        tr.report.setdefault("coarse_to_fine", []).append(
            {"factor": f, "until_iteration": tr.coarse[-1][0], "size": [small.width, small.height]})
    if tr.coarse:
        tr.log("coarse to fine: " + ", ".join(f"1/{f} size until iteration {it}" for (f, _), (it, _) in
                                              zip(levels, tr.coarse)))


def set_budget(tr):
    """epochs -> iterations from the training set's size (recomputed identically on resume)."""
    tr.train_pixels = sum(v.width * v.height for v in tr.ds.train_views)
    tr.cfg = tr.cfg.with_budget(tr.train_pixels)

def learning_rates(tr):
    c = tr.cfg
    lrs = {"means": c.lr_position * tr.extent, "log_scales": c.lr_scale, "quats_wxyz": c.lr_rotation,
           "logit_opacity": c.lr_opacity, "sh": c.lr_sh_dc, "sh_rest": c.lr_sh_rest,
           "logit_specular": c.lr_specular, "logit_transparency": c.lr_transparency, "normals": c.lr_normal}
    return {k: v * c.lr_multiplier for k, v in lrs.items()}

def build_scene(tr):
    """(Re)create the Mitsuba scene for the current sets (once per run; sizes change through traverse)."""
    import mitsuba as mi

    import glint_mi

    # the integrator traces every enabled set for every ray ("all"): its per-ray "auto" skipping folds a skipped
    # weight into k_d, which zeroes the gradient that would let beta (or tau) grow from its initial value
    props = integrator_props(tr.cfg.render, components="all", aovs=TRAINING_AOVS)
    with glint_mi.deferred_interrupt():  # a Ctrl-C inside the plugins' C++ callbacks prints a traceback
        tr.scene = mi.load_dict(gaussian_scene_dict(tr.sets, **shape_props(tr.cfg), **props))
    tr.integ = tr.scene.integrator()
    tr.params = mi.traverse(tr.integ)
    c = tr.cfg
    rays = c.rays_per_iteration()
    if c.stored_hits and not tr.integ.lists_fit(rays, c.stored_hits_mb):
        need = tr.integ.lists_mb(rays)
        tr.log(f"note: a batch's stored hit lists ({rays:,} rays x max_hits {c.max_hits}) need {need:,.0f} MiB, "
               f"over stored_hits_mb {c.stored_hits_mb:g}: the replay re-traces every pass (on an H100 at 1M "
               f"rays a step: 2.33 s a step against 1.20 s with the lists). Raise it: --set stored_hits_mb="
               f"{int(need) + 1}")
    tr.dev = None
    tr._host_stale = False  # the device holds newer values than tr.sets (update: device)
    if tr.cfg.update == "device":
        from glint_mi.training.device_step import DeviceUpdate

        tr.dev = DeviceUpdate(tr.adam, tr.cfg.kernel, tr.extent)
        for role, gs in tr.sets.items():
            tr.dev.load(role, gs, tr.strategy)
    tr._push()
    for part in tr.parts:
        part.push(tr)

def glass_cue_check(tr) -> None:
    """Before training: drop the secondary sets where there is no glass cue (ComponentsPolicy.glass_cue_drops),
    before the scene is built (never given a BVH, traced or saved); a lone interface trains as 3DGS."""
    drops = tr.components.glass_cue_drops(tr.sets, "albedo" in tr.bank.has, tr.bank.cue is not None)
    for role, why in drops.items():
        tr.components.record(role, False, 0, why)
        n = len(tr.sets.pop(role))
        tr.log(f"components auto: drop {role} (its {n} initial Gaussians discarded): {why}")
    profile = tr.components.no_glass_profile() if drops else None
    if profile:
        # the components policy reads none of the profile's fields (kernel, blend, weights), and the strategy is
        # built after this decision: nothing holds the former config
        tr.cfg = tr.cfg.replace(**profile)
        tr.cfg.save(tr.run_dir / "config.json")
        tr.report["no_glass"] = profile
        said = ", ".join(f"{k}={v}" for k, v in profile.items())
        tr.log(f"no glass: the interface alone is trained as 3DGS ({said}; no_glass: 3dgs+sfm adds glint_mi's "
               f"SfM depth term, glint keeps GLINT's surfels and weights)")

def load_checkpoint(tr):
    """A resumed run: the lock first (another process may be setting the run up), then everything the checkpoint
    holds, so that the run continues exactly."""
    path = tr.run_dir / "checkpoint.npz"
    if not tr.run_dir.is_dir():
        raise RunError(f"{tr.run_dir}: no such run folder; --resume needs a folder made by glint_mi.optimize.")
    # before the checkpoint is looked at: another process may be setting the run up or writing its checkpoint
    tr._lock = hold_run(tr.run_dir)
    if not path.exists():
        raise RunError(f"{path}: no checkpoint to resume (the run was stopped before its first checkpoint); "
                       f"start it again with `python -m glint_mi.optimize scene.xml --out {tr.run_dir}` after "
                       f"removing the folder.")
    info = json.loads((tr.run_dir / "run.json").read_text())
    tr.scene_spec = read_scene(info["scene"]) if Path(info["scene"]).exists() else None
    if tr.ds is None:
        tr.ds = load_run_dataset(tr.run_dir, tr.cfg, log=tr.log)
    set_budget(tr)
    z = read_checkpoint(path)
    tr.it, tr.elapsed = int(z["iteration"]), float(z["elapsed"])
    tr.extent = float(z["extent"])
    tr.bounds = (z["bounds"][0], z["bounds"][1])
    tr.rng.bit_generator.state = json.loads(str(z["rng"]))
    tr.report = json.loads(str(z["report"]))
    if tr.report.get("no_glass"):  # dropped before training: it trained as 3DGS, whatever config resumes it
        tr.cfg = tr.cfg.replace(**tr.report["no_glass"])
    tr.components = ComponentsPolicy(tr.cfg)
    tr.components.load_state_dict({"dropped": json.loads(str(z["dropped"])),
                                   "decisions": tr.report.get("components", {})})
    tr.report["components"] = tr.components.decisions
    tr.history = json.loads(str(z["history"]))
    tr._resume_affine = z.get("depth_affine")
    roles = sorted({k.split("/")[1] for k in z if k.startswith("set/")}, key=cv.ROLES.index)
    # a checkpoint from before the normal attribute has none: GaussianSet derives it from the rotation
    tr.sets = {r: GaussianSet(**{f: z[f"set/{r}/{f}"] for f in RAW_FIELDS if f"set/{r}/{f}" in z}) for r in roles}
    tr.adam = Adam(learning_rates(tr), eps=tr.cfg.adam_eps, selective=tr.cfg.adam == "selective")
    tr.adam.load_state_dict({k[5:]: v for k, v in z.items() if k.startswith("adam/")})
    tr.parts = parts_for(tr.cfg)
    for part in tr.parts:
        part.load(tr, z)
    srng = np.random.default_rng()
    srng.bit_generator.state = json.loads(str(z["strategy_rng"]))
    tr.strategy = Strategy.for_config(tr.cfg, tr.extent, srng)
    tr.strategy.load_state_dict({k[9:]: v for k, v in z.items() if k.startswith("strategy/")})
    tr.log(f"resumed {tr.run_dir} at iteration {tr.it}")

