"""The staged GLINT optimisation (glint-method.md sections 3-5) on ray patches, with resumable runs.

One iteration: draw ``patches`` p x p patches across training views -> ``integrator.trace`` (primal) -> losses on Dr.Jit
leaves of the traced buffers -> their adjoints -> ``integrator.backward`` (path replay, constant memory) ->
renderer-space gradients -> chain rule to raw parameters (:func:`glint_mi.training.optim.raw_gradients`) -> Adam
(numpy). Structural changes (densify, prune, resets, dropping a set) go through
:class:`glint_mi.training.strategy.Strategy`.

A run folder holds ``config.json``, ``checkpoint.npz`` (atomic; everything to continue exactly, RNG included),
``log.csv`` (losses per logged iteration), ``report.json`` (initialisation, component decisions and why,
densification events) and, at the end, ``model/`` (3DGS .ply per set + a renderable ``scene.xml``) and the
evaluation of :mod:`glint_mi.evaluate`.
"""
from __future__ import annotations

import contextlib
import csv
import dataclasses
import io
import json
import signal
import time
from pathlib import Path

import numpy as np

from glint_mi import conventions as cv
from glint_mi.training import losses as L
from glint_mi.training.components import ComponentsPolicy
from glint_mi.training.inputs import training_inputs
from glint_mi.config import LOSS_NAMES, TrainConfig
from glint_mi.data import Dataset, DatasetError, load_dataset
from glint_mi.evaluation.renders import eval_options
from glint_mi.model.examples import gaussian_scene_dict
from glint_mi.model.gaussians import GaussianSet
from glint_mi.model.files import TRAINING_AOVS, integrator_props, model_xml, shape_props
from glint_mi.model.render import floats
from glint_mi.runs import RunError, atomic_write_bytes, atomic_write_text, hold_run, load_run_dataset, read_checkpoint
from glint_mi.scene import OptimScene, check_settings, initial_sets, read_scene
from glint_mi.training.optim import RAW_FIELDS, Adam, raw_gradients
from glint_mi.training.strategy import Strategy

PARAM_KEYS = ("data", "kernel_scales", "opacities", "sh_coeffs", "specular", "transparency")


BUDGET_WARN = 0.02  # share of the interface's rays that may spend the whole hit budget before the run warns


def budget_full(out: dict, max_hits: int, read: bool = True):
    """Share of the batch's interface rays that composited ``max_hits`` hits (cut short with transmittance left:
    the model then learns the cut), read from the forward's stored hit list; NaN when nothing was recorded. Exact for
    the k-buffer traversal (its list count is its hit count); a lower bound for ``traversal: bvh``, whose budget also
    counts a shell reported twice by the float32 test, which is listed once. Reduced on the device: ``read=False``
    returns the width-1 Dr.Jit array, scheduled for the next evaluation."""
    import drjit as dr
    import mitsuba as mi

    lists = out.get("hit_lists")
    if not lists or lists[0] is None:
        return float("nan")
    count = lists[0][1]
    share = mi.Float(dr.count(count >= max_hits)) / dr.width(count)
    if read:
        return float(share[0])
    dr.schedule(share)
    return share


def check_patch(cfg, ds) -> None:
    """Refuse a patch that does not fit in a training view (a large downscale leaves small images), before the run
    folder is made."""
    from glint_mi.config import ConfigError

    small = min(ds.train_views, key=lambda v: min(v.width, v.height))
    if cfg.patch > min(small.width, small.height):
        raise ConfigError(f"'patch' = {cfg.patch}: a {cfg.patch} x {cfg.patch} patch does not fit in training view "
                          f"'{small.name}' ({small.width} x {small.height} at downscale {cfg.downscale}); use "
                          f"--set patch={max(3, min(small.width, small.height))} or a smaller downscale.")


class Trainer:
    def __init__(self, run_dir: str | Path, cfg: TrainConfig, scene: OptimScene | None = None,
                 dataset: Dataset | None = None, log=print, resume: bool = False):
        import glint_mi

        glint_mi.set_variant()  # $GLINT_VARIANT (e.g. cuda_ad_rgb) or llvm_ad_rgb
        self.run_dir, self.cfg, self.log = Path(run_dir), cfg, log
        if cfg.threads > 0:
            import drjit as dr
            import mitsuba as mi

            if mi.variant().startswith("llvm"):  # a GPU's atomics have no fixed order to restore
                dr.set_thread_count(cfg.threads)
        self.scene_spec = scene
        self.ds = dataset
        self.it = 0
        self.elapsed = 0.0
        self.history: list[dict] = []
        self._unread = 0  # history rows from here on may hold device values (settle)
        self._nonfinite_read: dict[str, int] = {}  # update: device's zeroed-gradient counts already reported
        self.report: dict = {"components": {}, "init": {}, "events": []}
        self.rng = np.random.default_rng(cfg.seed)
        self.stop_requested = False
        # phase(name) -> context manager around each part of a step; benchmarks/profile_step.py times them
        self.phase = lambda name: contextlib.nullcontext()
        if resume:
            self._load_checkpoint()
        else:
            self._fresh()
        from glint_mi.machine import describe

        self.report["machine"] = describe()  # where this run (its latest segment, when resumed) trained
        cfg = self.cfg
        if cfg.eval_depth == "first_surface":  # TSGS's depth reads each test view's mask: refuse before training
            glass_of = eval_options(cfg, self.ds.root)["glass_of"]
            for v in self.ds.test_views:
                glass_of(v)
        self.bank = training_inputs(self.ds, cfg, "transmission" in self.sets, self.report, self.log,
                                    getattr(self, "_resume_affine", None))  # set by _load_checkpoint only
        if not resume:
            self._glass_cue_check()
        from glint_mi.data.priors import priors_are_derived

        self.report["priors_derived_from_ground_truth"] = bool(priors_are_derived(self.ds.root))
        self._build()

    # ------------------------------------------------------------ set-up
    def _fresh(self):
        if self.scene_spec is None:
            raise RunError("a new run needs an optimisation scene (python -m glint_mi.scene DATASET > scene.xml).")
        if self.ds is None:
            self.ds = load_dataset(self.scene_spec.dataset, downscale=self.cfg.downscale,
                                   missing=self.scene_spec.missing, log=self.log)
            self.log(self.ds.summary())
        if not self.ds.train_views:
            raise DatasetError(f"{self.ds.root}: no training views (check split.json).")
        if self.cfg.priors == "all":  # before SfM and initialisation: a bad prior is found in seconds, not minutes
            from glint_mi.data.priors import PriorError, check_priors

            problems = check_priors(self.ds.root, self.ds.train_views)
            if problems:
                raise PriorError("\n".join(problems))
        check_settings(self.scene_spec, self.cfg)
        check_patch(self.cfg, self.ds)
        self._set_budget()
        sets, (lo, hi, extent), rep = initial_sets(self.scene_spec, self.ds, self.cfg, self.rng, self.log)
        roles = self.cfg.roles()
        self.sets = {r: s for r, s in sets.items() if r in roles}
        self.bounds = (lo, hi)
        self.extent = float(extent)
        self.report["init"] = {**rep, "extent": self.extent, "box": [lo.tolist(), hi.tolist()]}
        self.env = self.env_adam = None
        if self.cfg.blend == "refgs":
            self._refgs_start()
        self.adam = Adam(self._lrs(), eps=self.cfg.adam_eps, selective=self.cfg.adam == "selective")
        self.strategy = Strategy(self.cfg, self.extent, np.random.default_rng([self.cfg.seed, 1]))  # own stream
        self.components = ComponentsPolicy(self.cfg)
        self.report["components"] = self.components.decisions
        self._lock = hold_run(self.run_dir)  # before anything is written (creates the folder)
        self.cfg.save(self.run_dir / "config.json")
        atomic_write_text(self.run_dir / "run.json", json.dumps(
            {"scene": str(self.scene_spec.path), "dataset": str(self.ds.root), "dataset_options": self.ds.options,
             "dataset_notes": self.ds.notes, "sparse": str(self.ds.sparse) if self.ds.sparse else None,
             "tracks_distorted": self.ds.tracks_distorted}, indent=1))

    def _refgs_start(self):
        """Ref-GS's starting point: roughness 0.5 (its sigmoid(0); beta carries it), the albedo composited in linear
        space (the SfM colours converted, so the first image shows them), and the directional grid at its initial
        value (glint_env)."""
        from glint_mi_plugins.glint_env import DirectionalGrid

        gs = self.sets["interface"]
        gs.logit_specular[:] = 0.0
        colour = gs.sh[:, 0] * cv.SH_C0 + 0.5
        gs.sh[:, 0] = ((cv.srgb_to_linear(np.clip(colour, 0.0, 1.0)) - 0.5) / cv.SH_C0).astype(gs.sh.dtype)
        grid = DirectionalGrid(self.cfg.env_levels, init=float(np.log(self.cfg.env_init)))
        self.env = grid.data.copy()  # channel-major flat, as the integrator holds it
        self.env_adam = (np.zeros_like(self.env), np.zeros_like(self.env), np.zeros(1))

    def _env_step(self):
        """Dense Adam on the refgs grid (every ray reads it), then back to the integrator with gradients on."""
        grid = self.integ.env
        g = np.nan_to_num(grid.grad(), nan=0.0, posinf=0.0, neginf=0.0)
        grid.clear_grad()
        self.adam.step_array(self.env, g, self.env_adam, self.cfg.lr_env * self.cfg.lr_multiplier)
        self._push_env()

    def _push_env(self):
        grid = self.integ.env
        grid.data = self.env
        grid.enable_grad()

    def _set_budget(self):
        """epochs -> iterations from the training set's size (recomputed identically on resume)."""
        self.train_pixels = sum(v.width * v.height for v in self.ds.train_views)
        self.cfg = self.cfg.with_budget(self.train_pixels)

    @property
    def epoch(self) -> float:
        """Rays traced so far per training pixel."""
        return self.it * self.cfg.rays_per_iteration() / self.train_pixels

    def _lrs(self):
        c = self.cfg
        lrs = {"means": c.lr_position * self.extent, "log_scales": c.lr_scale, "quats_wxyz": c.lr_rotation,
               "logit_opacity": c.lr_opacity, "sh": c.lr_sh_dc, "sh_rest": c.lr_sh_rest,
               "logit_specular": c.lr_specular, "logit_transparency": c.lr_transparency}
        return {k: v * c.lr_multiplier for k, v in lrs.items()}

    def _build(self):
        """(Re)create the Mitsuba scene for the current sets (once per run; sizes change through traverse)."""
        import mitsuba as mi

        # the integrator traces every enabled set for every ray ("all"): its per-ray "auto" skipping folds a skipped
        # weight into k_d, which zeroes the gradient that would let beta (or tau) grow from its initial value
        props = integrator_props(self.cfg, components="all", aovs=TRAINING_AOVS)
        self.scene = mi.load_dict(gaussian_scene_dict(self.sets, **shape_props(self.cfg), **props))
        self.integ = self.scene.integrator()
        self.params = mi.traverse(self.integ)
        c = self.cfg
        rays = c.rays_per_iteration()
        if c.stored_hits and not self.integ.lists_fit(rays, c.stored_hits_mb):
            need = self.integ.lists_mb(rays)
            self.log(f"note: a batch's stored hit lists ({rays:,} rays x max_hits {c.max_hits}) need {need:,.0f} MiB, "
                     f"over stored_hits_mb {c.stored_hits_mb:g}: the replay re-traces every pass (on an H100 at 1M "
                     f"rays a step: 2.33 s a step against 1.20 s with the lists). Raise it: --set stored_hits_mb="
                     f"{int(need) + 1}")
        self.dev = None
        self._host_stale = False  # the device holds newer values than self.sets (update: device)
        if self.cfg.update == "device":
            from glint_mi.training.device_step import DeviceUpdate

            self.dev = DeviceUpdate(self.adam, self.cfg.kernel, self.extent)
            for role, gs in self.sets.items():
                self.dev.load(role, gs, self.strategy)
        self._push()
        if self.integ.env is not None:
            self._push_env()

    def _push(self, roles=None):
        """Send the sets' current values (and sizes) to the renderer; a `data` change rebuilds that set's BVH, so
        only ``roles`` (default all) are sent, packed as each shape was made (its opacity shells included)."""
        import drjit as dr
        from glint_mi.model.shapes import info, pack

        for role, gs in self.sets.items():
            if roles is not None and role not in roles:
                continue
            shape = self.integ.sets[role].shape
            if self.dev is not None:  # packed on the device from its values (update: device)
                meta = info(shape)
                arrays = self.dev.pack(role, meta.min_shell_ratio, meta.opacity_shells, meta.extent)
                dr.eval(*arrays.values())
                # Mitsuba builds a set's BVH from the host memory of `data` without waiting for the LLVM kernels
                # that write it (measured: wrong hits, a different loss every run with traversal bvh)
                dr.sync_thread()
            else:
                arrays = {k: floats(v.ravel()) for k, v in pack(shape, gs).items()}
            for k in PARAM_KEYS:
                key = f"{role}.{k}"
                self.params[key] = arrays[k]
                dr.enable_grad(self.params[key])
        self.params.update()

    def sync(self) -> None:
        """Bring the host's sets, Adam moments and densification statistics up to date with the device's (update:
        device; a no-op when nothing changed since): before anything on the host reads or changes them."""
        if self.dev is None or not self._host_stale:
            return
        for role, gs in self.sets.items():
            if role in self.dev.sets:
                self.dev.pull(role, gs, self.strategy)
        self._host_stale = False

    def _reload(self, roles) -> None:
        """Send the sets ``roles`` (changed on the host: densified, reset) back to the device."""
        if self.dev is not None:
            for role in roles:
                self.dev.load(role, self.sets[role], self.strategy)

    # ---------------------------------------------------------- schedule
    def stage(self, it: int | None = None) -> dict:
        """Which sets are traced and trained at iteration ``it``, which loss terms are on."""
        c, it = self.cfg, self.it if it is None else it
        on = lambda f: it >= c.at(f)
        traced = {"interface"}
        if "transmission" in self.sets and "transmission" not in self.dropped and on(max(c.warmup, c.transmission_from)):
            traced.add("transmission")
        if "reflection" in self.sets and "reflection" not in self.dropped and on(max(c.warmup, c.reflection_from)):
            traced.add("reflection")
        trained = set(traced)
        if c.refine_from < 1.0 and on(c.refine_from) and len(traced) > 1:
            trained.discard("interface")  # supplement: the interface is frozen in the refine stage
        has_t = "transmission" in traced
        gt_masks = c.trans_masks in ("gt", "prior")  # masks given from outside (TSGS)
        return {"traced": traced, "trained": trained, "name": "warm-up" if traced == {"interface"} and not on(c.warmup)
                else ("refine" if "interface" not in trained else "joint"),
                "depth": c.w_depth > 0 and "depth" in self.bank.has,
                "sfm_depth": c.w_sfm_depth > 0 and self.bank.sfm_depth is not None,
                "normal": c.w_normal > 0 and "normal" in self.bank.has and (on(c.normal_from)
                                                                           or c.normal_early == "unmasked"),
                "normal_masked": on(c.normal_from),
                # prior_decay < 1: the prior terms' weight, 1 until then, linearly to 0 at the last iteration
                "prior_scale": 1.0 if c.prior_decay >= 1.0 else
                min(1.0, max(0.0, (c.iterations - it) / max(1, c.iterations - c.at(c.prior_decay)))),
                "consistency": c.w_consistency > 0 and on(c.consistency_from),
                "distortion": c.w_dist > 0 and on(c.dist_from),
                "direct": has_t and c.w_direct > 0,
                "trans": (has_t or gt_masks) and c.w_trans > 0 and on(c.trans_from),
                "treg": has_t and c.w_treg > 0 and on(c.treg_from),
                "plausibility": has_t and c.w_plausibility > 0 and on(c.plausibility_from),
                # t_raise: masks, on L_trans's depth-gap masks, from the end of densification: until then the
                # opacity / tau resets clear what the photometric terms build, and their push lets t grow on the
                # glass in the first place. Off glass a blend of two fits of one surface (c_I, c_T) beats either,
                # so the photometric terms would use t as a mixing weight: a veil over the room
                "t_gate": (has_t and c.t_raise == "masks" and c.trans_masks == "depth_gap" and c.w_trans > 0
                           and on(max(c.trans_from, c.densify_until))),
                "sh_degree": min(c.sh_degree, it // c.every(c.sh_every))}

    def render_depth(self, flat: np.ndarray, vid: np.ndarray):
        """The interface's planar depth and accumulated alpha at training pixels (``flat`` rows of the bank, their
        view indices ``vid``), numpy, without gradient."""
        import drjit as dr
        import mitsuba as mi

        bank = self.bank
        ray = mi.Ray3f(mi.Point3f(*floats(bank.origins[vid])), mi.Vector3f(*floats(bank.dirs[flat])))
        with self.integ.tracing({"interface"}):
            out = self.integ.trace(ray, mi.Bool(True), forward=mi.Vector3f(*floats(bank.axes[vid, :, 2])))
            dr.eval(out["depth"], out["alpha"])
        return np.array(out["depth"], np.float64), np.array(out["alpha"], np.float64)

    # --------------------------------------------------------- one step
    def step(self, read: bool = True) -> dict:
        """One training step. Returns the loss terms and the batch's statistics: floats, or with ``read=False``
        width-1 Dr.Jit arrays that nothing reads back until :meth:`settle` (the training loop: one read per log)."""
        st = self.stage()
        with self.integ.tracing(st["traced"]):  # the stage's sets, for the forward and its replay
            return self._step(st, read)

    def _step(self, st: dict, read: bool) -> dict:
        import drjit as dr
        import mitsuba as mi

        c, phase = self.cfg, self.phase
        with phase("sample"):  # the draws in numpy (3 numbers a patch), the rays and targets gathered on the device
            b = self.bank.sample_device(self.rng, c.patches, c.patch)
            ray, fwd = mi.Ray3f(b.origin, b.direction), b.axes[2]
        need = {"trans_direct"} if "transmission" in st["traced"] else set()
        active = mi.Bool(True)
        with phase("forward"):
            # stored lists while they fit the cap (a batch of 1M rays would need 5 GB at 256 hits): else re-trace
            record = c.stored_hits and self.integ.lists_fit(dr.width(ray), c.stored_hits_mb)
            out = self.integ.trace(ray, active, need=need, forward=fwd, record=record)
            dr.eval(out["passes"], out.get("hit_lists"))
        full = budget_full(out, c.max_hits, read=read)
        with phase("objective"):
            terms, adjoints, stats = L.batch_objective(c, b, out, st, ray, fwd, len(self.bank.views), self.extent,
                                                       read=read)
        with phase("backward"):
            self.integ.backward(ray, active, out, adjoints, forward=fwd, t_raise=stats.pop("t_raise", None))
            dr.eval()  # run the replay now (the gradients are read next anyway): its time is the backward's
        with phase("update"):
            self._update(st)
        return {**terms, **stats, "budget_full": full}

    def settle(self, rows: list[dict] | None = None) -> None:
        """Read back the device values of ``rows`` (default: the history rows not read yet), in place, as floats:
        the training loop keeps a step's terms and statistics on the device until a log line, a checkpoint, the
        components decision or the end of the run needs them."""
        import drjit as dr

        if rows is None:
            rows, self._unread = self.history[self._unread:], len(self.history)
            if self.dev is not None:
                self._count_nonfinite()
        for row in rows:
            dev = {k: v for k, v in row.items() if isinstance(v, dr.ArrayBase)}
            if dev:
                row.update(L.read_values(dev))

    def _count_nonfinite(self):
        """update: device counts the non-finite gradient entries it zeroes on the device; read them here (the host
        update counts them as they happen)."""
        seen = self._nonfinite_read
        for role, total in self.dev.read_bad().items():
            delta = total - seen.get(role, 0)
            if delta <= 0:
                continue
            seen[role] = total
            counts = self.report.setdefault("nonfinite_gradients", {})
            first = not counts.get(role)
            counts[role] = counts.get(role, 0) + delta
            if first:
                self.log(f"by iteration {self.it}: {delta} non-finite gradient entries in the {role} set, zeroed "
                         f"(counted in report.json 'nonfinite_gradients')")

    def _update(self, st):
        import drjit as dr

        c = self.cfg
        frac = self.it / max(c.iterations - 1, 1)
        lr_pos = np.exp((1 - frac) * np.log(c.lr_position) + frac * np.log(c.lr_position_final)) / c.lr_position
        if self.env is not None:
            self._env_step()
        if self.dev is not None:
            return self._update_device(st, lr_pos)
        for role in list(self.sets):
            gs = self.sets[role]
            grads = {k: np.array(dr.grad(self.params[f"{role}.{k}"]), np.float64) for k in PARAM_KEYS}
            for k in PARAM_KEYS:
                dr.clear_grad(self.params[f"{role}.{k}"])
            if role not in st["trained"] or role not in st["traced"]:
                continue
            g = raw_gradients(gs, grads, c.kernel)
            g["sh"][:, (st["sh_degree"] + 1) ** 2:] = 0.0
            for f in self._frozen_fields(role):
                g[f][:] = 0.0
            bad = sum(int(np.count_nonzero(~np.isfinite(v))) for v in g.values())
            if bad:  # zeroed for this step, counted in the log and the report (a NaN would poison Adam's moments)
                for v in g.values():
                    np.nan_to_num(v, copy=False, nan=0.0, posinf=0.0, neginf=0.0)
                counts = self.report.setdefault("nonfinite_gradients", {})
                counts[role] = counts.get(role, 0) + bad
                if counts[role] == bad:
                    self.log(f"iteration {self.it}: {bad} non-finite gradient entries in the {role} set, zeroed "
                             f"(counted in report.json 'nonfinite_gradients')")
            if self.strategy.densifying(self.it):
                self.strategy.accumulate(role, len(gs), g["means"], g["logit_opacity"])
            touched = (g["logit_opacity"] != 0) | np.any(g["means"] != 0, axis=1) | np.any(g["sh"][:, 0] != 0, axis=1)
            self.adam.step(role, gs, g, {"means": lr_pos}, rows=touched)

    def _frozen_fields(self, role: str) -> set[str]:
        """The raw fields of ``role`` that get no gradient: beta and tau are interface attributes (the release's
        order 2 uses G_trans's beta); without a transmission set tau means nothing and keeps its initial value."""
        if role == "interface":
            return set() if "transmission" in self.sets else {"logit_transparency"}
        keep_beta = role == "transmission" and self.cfg.max_order == 2
        return {"logit_transparency"} if keep_beta else {"logit_transparency", "logit_specular"}

    def _update_device(self, st, lr_pos: float):
        """:meth:`_update` on the device (update: device): the same chain rule, zeroed fields, statistics and
        selective Adam on Dr.Jit arrays; the host's sets go stale until :meth:`sync`."""
        import drjit as dr
        import mitsuba as mi

        lr = {"means": dr.opaque(mi.Float64, lr_pos)}
        degree = dr.opaque(mi.UInt32, st["sh_degree"])
        for role in list(self.sets):
            keys = [f"{role}.{k}" for k in PARAM_KEYS]
            grads = {k: dr.grad(self.params[key]) for k, key in zip(PARAM_KEYS, keys)}
            for key in keys:
                dr.clear_grad(self.params[key])
            if role not in st["trained"] or role not in st["traced"]:
                continue
            g = self.dev.gradients(role, grads, degree, self._frozen_fields(role))
            dr.eval(*g.values())
            seen, touched, means = self.dev.rows(role, g)
            if self.strategy.densifying(self.it):
                self.dev.accumulate(role, seen, means)
            dr.eval(touched)
            self.dev.step(role, g, touched, lr)
            self.dev.schedule(role)
            self._host_stale = True


    # ---------------------------------------------------- structure steps
    def _structure(self, st):
        """Densify / prune / reset on their schedules and the components: auto decisions."""
        with self.phase("structure"):
            self._structure_now(st)
        with self.phase("bvh"):
            self._push(st["trained"])  # only trained sets change (Adam, densify, resets): others keep their BVH

    def _structure_now(self, st):
        c, it = self.cfg, self.it + 1
        if c.depth_align == "image" and "depth" in self.bank.has and it % c.every(c.depth_refit) == 0:
            self.bank.fit_depth_to_renders(self.render_depth)
        densify, reset = self.strategy.due(self.it)  # the strategy owns its schedule
        changed = sorted(st["trained"] & set(self.sets)) if densify or reset else []
        if changed:
            self.sync()
            sizes = {r: len(g) for r, g in self.active_sets().items()}
            self.strategy.step_post(self.it, self.sets, changed, self.adam, sizes, densify, reset)
        self._reload(changed)
        due = self.components.due(it, self.sets)
        if due:
            self.settle()  # the statistics of the steps not logged yet
        for role in due:
            keep, why = self.components.decide(role, self.history, self.sets)
            self.components.record(role, keep, it, why)
            self.log(f"components auto: {'keep' if keep else 'drop'} {role}: {why}")

    def _glass_cue_check(self) -> None:
        """Before training: drop the secondary sets where there is no glass cue (ComponentsPolicy.glass_cue_drops),
        before the scene is built (never given a BVH, traced or saved); a lone interface trains as 3DGS."""
        drops = self.components.glass_cue_drops(self.sets, "albedo" in self.bank.has, self.bank.cue is not None)
        for role, why in drops.items():
            self.components.record(role, False, 0, why)
            n = len(self.sets.pop(role))
            self.log(f"components auto: drop {role} (its {n} initial Gaussians discarded): {why}")
        profile = self.components.no_glass_profile() if drops else None
        if profile:
            self.cfg = dataclasses.replace(self.cfg, **profile)
            self.strategy.cfg = self.components.cfg = self.cfg
            self.cfg.save(self.run_dir / "config.json")
            self.report["no_glass"] = profile
            said = ", ".join(f"{k}={v}" for k, v in profile.items())
            self.log(f"no glass: the interface alone is trained as 3DGS ({said}; no_glass: 3dgs+sfm adds glint_mi's "
                     f"SfM depth term, glint keeps GLINT's surfels and weights)")

    @property
    def dropped(self) -> dict[str, str]:
        """The sets components: auto dropped (role -> why)."""
        return self.components.dropped

    # ------------------------------------------------------------- loop
    def train(self, progress: bool = True, until: int | None = None) -> dict:
        """Run to ``until`` (default: the end of the schedule; a notebook can advance in chunks). At the end the
        model is saved. Ctrl-C stops after the current iteration (a second Ctrl-C at once), saves a checkpoint and
        raises KeyboardInterrupt; ``--resume`` then continues exactly."""
        import sys

        from tqdm.auto import tqdm

        c = self.cfg
        until = c.iterations if until is None else min(until, c.iterations)
        start = time.perf_counter() - self.elapsed
        rays = c.patches * c.patch ** 2
        bar = tqdm(total=c.iterations, initial=self.it, disable=not progress, unit="it", dynamic_ncols=True,
                   mininterval=0.5 if sys.stderr.isatty() else 30.0)
        self.stop_requested = False

        def on_sigint(signum, frame):
            if self.stop_requested:
                raise KeyboardInterrupt
            self.stop_requested = True
            self.log("\nCtrl-C: stopping after this iteration (press again to stop at once)")

        old = signal.getsignal(signal.SIGINT)
        try:
            signal.signal(signal.SIGINT, on_sigint)
        except ValueError:  # not the main thread (e.g. some notebook runners): default handling
            old = None
        mid = hard = False
        try:
            while self.it < until and not self.stop_requested:
                mid = True
                t0 = time.perf_counter()
                st = self.stage()
                rec = self.step(read=False)
                self._structure(st)
                dt = time.perf_counter() - t0
                rec.update(iteration=self.it, stage=st["name"], rays_per_s=rays / max(dt, 1e-9),
                           gaussians=sum(len(s) for r, s in self.sets.items() if r not in self.dropped))
                self.history.append(rec)
                self.it += 1
                mid = False
                self.elapsed = time.perf_counter() - start
                bar.update(1)
                if self.it % c.log_every == 0 or self.it == c.iterations:
                    self.settle()
                    bar.set_postfix(epoch=f"{self.epoch:.1f}", loss=f"{rec['total']:.4f}",
                                    rays_s=f"{rec['rays_per_s']:.0f}",
                                    stage=st["name"], n=rec["gaussians"], refresh=False)
                if c.eval_every > 0 and self.it % c.eval_every == 0 and self.it < c.iterations:
                    t_eval = time.perf_counter()
                    self.evaluate_now()
                    start += time.perf_counter() - t_eval  # evaluation is not training time
                    self.elapsed = time.perf_counter() - start
                if self.it % c.checkpoint_every == 0 and self.it < c.iterations:
                    self.save_checkpoint()
        except KeyboardInterrupt:
            self.stop_requested, hard = True, mid
        finally:
            bar.close()
            if old is not None:
                signal.signal(signal.SIGINT, old)
        self.elapsed = time.perf_counter() - start
        if hard:  # stopped inside an iteration: its state is partial, keep the last consistent checkpoint
            done = int(np.load(self.run_dir / "checkpoint.npz")["iteration"]) if (
                self.run_dir / "checkpoint.npz").exists() else 0
            self.log(f"stopped inside iteration {self.it}; the last checkpoint (iteration {done}) is kept")
            raise KeyboardInterrupt
        self.save_checkpoint()
        if self.stop_requested:
            self.log(f"interrupted at iteration {self.it}: checkpoint saved; continue with "
                     f"`python -m glint_mi.optimize --resume {self.run_dir}`")
            raise KeyboardInterrupt
        if self.it >= c.iterations:
            self._check_budget()
            if c.eval_every > 0:
                self.evaluate_now()
            self.save_model()
        return {"iterations": self.it, "train_s": self.elapsed}

    def _check_budget(self):
        """report.json ``hit_budget``: how often the last tenth of the run ran out of hits; a warning above 2 %."""
        self.settle()
        tail = self.history[-max(1, len(self.history) // 10):]
        full = [r["budget_full"] for r in tail if np.isfinite(r.get("budget_full", np.nan))]
        if not full:
            return
        share = float(np.mean(full))
        self.report["hit_budget"] = {"max_hits": self.cfg.max_hits, "budget_full_last_tenth": share}
        if share > BUDGET_WARN:
            self.log(f"warning: {100 * share:.1f} % of the interface's rays spent the whole hit budget (max_hits "
                     f"{self.cfg.max_hits}) in the last tenth of the run: they are cut short and the model learns "
                     f"the cut; train again with --set max_hits={2 * self.cfg.max_hits}")

    def evaluate_now(self) -> dict:
        """Test-view metrics of the current model (no files but ``convergence.csv``), recorded against iteration,
        epoch and training seconds: the convergence curve (``eval_every``)."""
        from glint_mi.evaluation import metrics as M
        from glint_mi.evaluation.renders import evaluate

        m = evaluate(self.integ_for_eval(), self.eval_views(), write=False, **self.eval_options())["metrics"]
        row = {"iteration": self.it, "epoch": self.epoch,
               "train_s": self.elapsed, "gaussians": sum(len(self.sets[r]) for r in self.kept()),
               **{k: m.get(k, float("nan")) for k in M.METRICS}}
        self.report.setdefault("convergence", [])
        if not any(r["iteration"] == self.it for r in self.report["convergence"]):
            self.report["convergence"].append(row)
        buf = io.StringIO()
        w = csv.DictWriter(buf, fieldnames=list(row))
        w.writeheader()
        w.writerows(self.report["convergence"])
        atomic_write_text(self.run_dir / "convergence.csv", buf.getvalue())
        return row

    def eval_views(self):
        """The test views (the training views when there are none) at the training resolution, or at the
        dataset's full resolution with ``eval_full``."""
        if self.cfg.eval_full and self.cfg.downscale > 1:
            if getattr(self, "_full_ds", None) is None:
                self._full_ds = load_run_dataset(self.run_dir, self.cfg, full=True)
            ds = self._full_ds
        else:
            ds = self.ds
        return ds.test_views or ds.train_views

    def eval_options(self) -> dict:
        """How :func:`glint_mi.evaluate.evaluate` reads this method's depth: the config's ``eval_depth`` rule and,
        for TSGS's first_surface, each view's transparency mask (priors/glass)."""
        return eval_options(self.cfg, self.ds.root)

    def integ_for_eval(self):
        """The integrator with every kept set enabled (dropped sets stay out), for rendering and evaluation."""
        self.integ.select(self.kept())
        return self.integ

    # ------------------------------------------------------ persistence
    def kept(self) -> list[str]:
        """The sets not dropped by components: auto (names only: nothing is read from the device)."""
        return [r for r in self.sets if r not in self.dropped]

    def active_sets(self) -> dict[str, GaussianSet]:
        """The kept sets' parameters on the host (brought up to date from the device first)."""
        self.sync()
        return {r: s for r, s in self.sets.items() if r not in self.dropped}

    def save_checkpoint(self) -> Path:
        self.settle()
        self.sync()
        arrays = {"iteration": np.array(self.it), "elapsed": np.array(self.elapsed), "extent": np.array(self.extent),
                  "bounds": np.stack(self.bounds), "rng": np.array(json.dumps(self.rng.bit_generator.state)),
                  "strategy_rng": np.array(json.dumps(self.strategy.rng.bit_generator.state)),
                  "dropped": np.array(json.dumps(self.dropped)), "report": np.array(json.dumps(self.report)),
                  "history": np.array(json.dumps(self.history))}
        for role, gs in self.sets.items():
            for f in RAW_FIELDS:
                arrays[f"set/{role}/{f}"] = getattr(gs, f)
        if self.cfg.depth_align == "image" and self.bank.depth_affine is not None:  # refitted from the model
            arrays["depth_affine"] = self.bank.depth_affine
        arrays.update({f"adam/{k}": v for k, v in self.adam.state_dict().items()})
        if self.env is not None:
            arrays.update({"env": self.env, "env_adam/m": self.env_adam[0], "env_adam/v": self.env_adam[1],
                           "env_adam/n": self.env_adam[2]})
        arrays.update({f"strategy/{k}": v for k, v in self.strategy.state_dict().items()})
        buf = io.BytesIO()
        np.savez(buf, **arrays)
        path = self.run_dir / "checkpoint.npz"
        atomic_write_bytes(path, buf.getvalue())
        self._write_log()
        return path

    def _load_checkpoint(self):
        path = self.run_dir / "checkpoint.npz"
        if not self.run_dir.is_dir():
            raise RunError(f"{self.run_dir}: no such run folder; --resume needs a folder made by glint_mi.optimize.")
        # before the checkpoint is looked at: another process may be setting the run up or writing its checkpoint
        self._lock = hold_run(self.run_dir)
        if not path.exists():
            raise RunError(f"{path}: no checkpoint to resume (the run was stopped before its first checkpoint); "
                           f"start it again with `python -m glint_mi.optimize scene.xml --out {self.run_dir}` after "
                           f"removing the folder.")
        info = json.loads((self.run_dir / "run.json").read_text())
        self.scene_spec = read_scene(info["scene"]) if Path(info["scene"]).exists() else None
        if self.ds is None:
            self.ds = load_run_dataset(self.run_dir, self.cfg, log=self.log)
        self._set_budget()
        z = read_checkpoint(path)
        self.it, self.elapsed = int(z["iteration"]), float(z["elapsed"])
        self.extent = float(z["extent"])
        self.bounds = (z["bounds"][0], z["bounds"][1])
        self.rng.bit_generator.state = json.loads(str(z["rng"]))
        self.report = json.loads(str(z["report"]))
        if self.report.get("no_glass"):  # dropped before training: it trained as 3DGS, whatever config resumes it
            self.cfg = dataclasses.replace(self.cfg, **self.report["no_glass"])
        self.components = ComponentsPolicy(self.cfg)
        self.components.load_state_dict({"dropped": json.loads(str(z["dropped"])),
                                         "decisions": self.report.get("components", {})})
        self.report["components"] = self.components.decisions
        self.history = json.loads(str(z["history"]))
        self._resume_affine = z.get("depth_affine")
        roles = sorted({k.split("/")[1] for k in z if k.startswith("set/")}, key=cv.ROLES.index)
        self.sets = {r: GaussianSet(**{f: z[f"set/{r}/{f}"] for f in RAW_FIELDS}) for r in roles}
        self.adam = Adam(self._lrs(), eps=self.cfg.adam_eps, selective=self.cfg.adam == "selective")
        self.adam.load_state_dict({k[5:]: v for k, v in z.items() if k.startswith("adam/")})
        self.env = self.env_adam = None
        if "env" in z:
            self.env = z["env"].astype(np.float32)
            self.env_adam = (z["env_adam/m"].copy(), z["env_adam/v"].copy(), z["env_adam/n"].copy())
        srng = np.random.default_rng()
        srng.bit_generator.state = json.loads(str(z["strategy_rng"]))
        self.strategy = Strategy(self.cfg, self.extent, srng)
        self.strategy.load_state_dict({k[9:]: v for k, v in z.items() if k.startswith("strategy/")})
        self.log(f"resumed {self.run_dir} at iteration {self.it}")

    def _write_log(self):
        self.settle()
        rows = self.history
        if rows:
            keys = ["iteration", "stage", *LOSS_NAMES, "rays_per_s", "gaussians", "share_reflection",
                    "share_transmission", "mask_t", "gap_behind", "gap_front", "gain_reflection",
                    "gain_transmission", "budget_full"]
            buf = io.StringIO()
            w = csv.DictWriter(buf, fieldnames=keys, extrasaction="ignore")
            w.writeheader()
            w.writerows(rows)
            atomic_write_text(self.run_dir / "log.csv", buf.getvalue())
        rep = dict(self.report)
        rep["events"] = [dataclasses.asdict(e) for e in self.strategy.events]
        rep["dropped"] = self.dropped
        rep["sizes"] = {r: len(self.sets[r]) for r in self.kept()}
        atomic_write_text(self.run_dir / "report.json", json.dumps(rep, indent=1))

    def save_model(self) -> Path:
        """model/<role>.ply (3DGS + specular/transparency) and model/scene.xml renderable by Mitsuba."""
        model = self.run_dir / "model"
        model.mkdir(exist_ok=True)
        sets = self.active_sets()
        for role, gs in sets.items():
            gs.save_ply(model / f"{role}.ply")
        for role in set(self.sets) - set(sets):
            (model / f"{role}.ply").unlink(missing_ok=True)
        v = (self.ds.test_views or self.ds.train_views)[0]
        from glint_mi.data.cameras import Camera
        from glint_mi.data.cameras import sensor_xml

        if self.env is not None:  # refgs: the directional grid, [h, w, 3] log-radiance
            buf = io.BytesIO()
            np.save(buf, self.integ.env.numpy())  # what _push_env last sent: self.env as [h, w, 3]
            atomic_write_bytes(model / "env.npy", buf.getvalue())
        props = {"dataset": str(self.ds.root.resolve()),
                 **integrator_props(self.cfg, components="all", env_file="env.npy")}
        xml = model_xml(props, list(sets), shape_props(self.cfg), sensor_xml(Camera.from_view(v), 1),
                        f"trained by glint_mi ({self.it} iterations); render with mitsuba or python -m "
                        f"glint_mi.evaluate")
        atomic_write_text(model / "scene.xml", xml)
        self._write_log()
        if self.history:
            from glint_mi.evaluation.plots import training_curves

            training_curves(self.history, self.run_dir / "curves.png")
        return model
