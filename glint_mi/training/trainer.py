"""The staged GLINT optimisation (glint-method.md sections 3-5) on ray patches, with resumable runs.

The trainer runs the loop; :mod:`glint_mi.training.builder` assembles the run it loops over and
:mod:`glint_mi.training.outputs` writes it. One iteration: draw ``patches`` p x p patches across training views ->
``integrator.trace`` (primal) -> the objective's terms (:mod:`glint_mi.training.objective`) on Dr.Jit leaves of the
traced buffers -> their adjoints -> ``integrator.backward`` (path replay, constant memory) ->
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
import signal
import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

import glint_mi.training.objective as objective
from glint_mi.config import TrainConfig
from glint_mi.model.render import floats
from glint_mi.runs import load_run_dataset
from glint_mi.scene import OptimScene
import glint_mi.training.builder as builder
import glint_mi.training.outputs as outputs
from glint_mi.training.optim import raw_gradients

if TYPE_CHECKING:
    from glint_mi.data import Dataset
    from glint_mi.model.gaussians import GaussianSet



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


def position_rate(c, it: int) -> float:
    """The position learning rate at iteration ``it`` as a multiple of ``lr_position``: log-linear from 1 to
    ``lr_position_final / lr_position`` at ``lr_position_until`` of the run, held there after (3DGS's schedule when
    it is 1.0)."""
    frac = min(it / max(c.iterations - 1, 1) / c.lr_position_until, 1.0)
    return float(np.exp((1 - frac) * np.log(c.lr_position) + frac * np.log(c.lr_position_final)) / c.lr_position)


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
        self.prior_floor = 0.0  # the falling normal prior's last share (builder: prior_decay_ref)
        self.prior_weight: dict = {}  # prior term -> its factor through the run (builder: prior_weight_ref)
        self.rng = np.random.default_rng(cfg.seed)
        self.stop_requested = False
        # phase(name) -> context manager around each part of a step; benchmarks/profile_step.py times them
        self.phase = lambda name: contextlib.nullcontext()
        builder.assemble(self, resume)

    # ------------------------------------------------------------ set-up
    @property
    def env(self):
        """Ref-GS's directional grid (channel-major flat log-radiance; training/refgs.py), None without one."""
        return next((part.values for part in self.parts if part.name == "refgs"), None)

    @property
    def epoch(self) -> float:
        """Rays traced so far per training pixel."""
        return self.it * self.cfg.rays_per_iteration() / self.train_pixels

    def _push(self, roles=None):
        """Send the sets' current values (and sizes) to the renderer; a `data` change rebuilds that set's BVH, so
        only ``roles`` (default all) are sent, packed as each shape was made (its opacity shells included)."""
        import drjit as dr
        from glint_mi.model.shapes import info, pack, param_keys

        for role, gs in self.sets.items():
            if roles is not None and role not in roles:
                continue
            shape = self.integ.sets[role].shape
            if self.dev is not None:  # packed on the device from its values (update: device)
                meta = info(shape)
                arrays = self.dev.pack(role, meta.min_shell_ratio, meta.opacity_shells, meta.extent, meta.normals)
                dr.eval(*arrays.values())
                # Mitsuba builds a set's BVH from the host memory of `data` without waiting for the LLVM kernels
                # that write it (measured: wrong hits, a different loss every run with traversal bvh)
                dr.sync_thread()
            else:
                arrays = {k: floats(v.ravel()) for k, v in pack(shape, gs).items()}
            for k in param_keys(shape):
                key = f"{role}.{k}"
                self.params[key] = arrays[k]
                dr.enable_grad(self.params[key])
        self.params.update()

    def sync(self) -> None:
        """Bring the host's sets, Adam moments and densification statistics up to date with the device's (update:
        device; a no-op when nothing changed since): before anything on the host reads or changes them. With
        normal_source: axis the sets' normals (unused in training) are set to their rotations' axes, so that what is
        saved (the .ply's nx, ny, nz, checkpoints) is the normal the model renders with."""
        if self.dev is not None and self._host_stale:
            for role, gs in self.sets.items():
                if role in self.dev.sets:
                    self.dev.pull(role, gs, self.strategy)
            self._host_stale = False
        if self.cfg.normal_source == "axis":
            from glint_mi.model.gaussians import axis_normals

            for gs in self.sets.values():
                gs.normals = axis_normals(gs.quats_wxyz).astype(np.float32)

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
        if c.secondary_until < 1.0 and on(c.secondary_until):
            trained -= {"transmission", "reflection"}  # traced (they still shape the image), no longer fitted
        has_t = "transmission" in traced
        gt_masks = c.trans_masks in ("gt", "prior")  # masks given from outside (TSGS)
        st = {"traced": traced, "trained": trained, "name": "warm-up" if traced == {"interface"} and not on(c.warmup)
                else ("refine" if "interface" not in trained else "joint"),
                "depth": c.w_depth > 0 and "depth" in self.bank.has,
                "sfm_depth": c.w_sfm_depth > 0 and self.bank.sfm_depth is not None,
                "normal": c.w_normal > 0 and "normal" in self.bank.has and (on(c.normal_from)
                                                                           or c.normal_early == "unmasked"),
                "normal_masked": on(c.normal_from),
                # prior_decay < 1: the prior terms' weight, 1 until then, linearly to prior_floor at the last
                # iteration (0, or the normal prior's share from its agreement with SfM: prior_decay_ref)
                "prior_scale": 1.0 if c.prior_decay >= 1.0 else self.prior_floor + (1.0 - self.prior_floor) *
                min(1.0, max(0.0, (c.iterations - it) / max(1, c.iterations - c.at(c.prior_decay)))),
                # prior term -> factor (prior_weight_ref; absent: 1), from prior_weight_from of the run
                "prior_weight": self.prior_weight if on(c.prior_weight_from) else {},
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
        for term in objective.TERMS:  # a term without a rule above: on while weighted, from its schedule field
            starts = term.starts is None or on(getattr(c, term.starts))
            st.setdefault(term.name, getattr(c, term.weight) > 0 and starts)
        return st

    def bank_now(self):
        """The ray bank this iteration draws from: a coarser one early with ``coarse_to_fine``, else the run's."""
        for until, bank in getattr(self, "coarse", ()):
            if self.it < until:
                return bank
        return self.bank

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
            b = self.bank_now().sample_device(self.rng, c.patches, c.patch)
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
            terms, adjoints, stats = objective.batch_objective(c.losses, b, out, st, ray, fwd, len(self.bank.views),
                                                               self.extent, read=read)
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
                row.update(objective.read_values(dev))

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
        lr_pos = position_rate(c, self.it)
        for part in self.parts:  # a method's own parameters (Ref-GS's grid)
            part.step(self)
        if self.dev is not None:
            return self._update_device(st, lr_pos)
        for role in list(self.sets):
            gs = self.sets[role]
            pk = self._param_keys(role)
            grads = {k: np.array(dr.grad(self.params[f"{role}.{k}"]), np.float64) for k in pk}
            for k in pk:
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

    def _param_keys(self, role: str) -> tuple[str, ...]:
        """The renderer's parameters of ``role``'s shape (``normals`` with normal_source: attribute)."""
        from glint_mi.model.shapes import param_keys

        return param_keys(self.integ.sets[role].shape)

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
            pk = self._param_keys(role)
            keys = [f"{role}.{k}" for k in pk]
            grads = {k: dr.grad(self.params[key]) for k, key in zip(pk, keys)}
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
        return outputs.eval_options(self.cfg, self.ds.root)

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

    # ------------------------------------------------------ persistence (glint_mi.training.outputs)
    def evaluate_now(self) -> dict:
        """Test-view metrics of the current model recorded against iteration, epoch and training seconds
        (``convergence.csv``; ``eval_every``)."""
        return outputs.evaluate_now(self)

    def save_checkpoint(self) -> Path:
        return outputs.save_checkpoint(self)

    def _write_log(self):
        outputs.write_log(self)

    def save_model(self) -> Path:
        """model/<role>.ply (3DGS + specular/transparency) and model/scene.xml renderable by Mitsuba."""
        return outputs.save_model(self)

    def _lrs(self):
        return builder.learning_rates(self)
