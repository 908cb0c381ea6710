"""Densification for Gaussian sets whose size changes during training.

Every structural change (clone, split, prune) goes through :class:`Strategy`, which remaps the set, the Adam state
(:class:`glint_mi.training.optim.Adam`) and the gradient statistics with one index array, so the three can never
disagree (``index[i]`` = the old row new row ``i`` comes from, -1 for a row with fresh state).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from glint_mi import conventions as cv
from glint_mi.model.gaussians import GaussianSet


@dataclasses.dataclass
class Event:
    iteration: int
    role: str
    cloned: int = 0
    split: int = 0
    pruned: int = 0
    size: int = 0
    what: str = "densify"


class Strategy:
    """Clone / split on accumulated positional gradient, prune by opacity and size, opacity and tau resets."""

    def __init__(self, densify, extent: float, rng: np.random.Generator, kernel: str = "surfel",
                 iterations: int = 1):
        """``densify``: the config's densify layer; ``kernel`` and ``iterations`` (the run's length, which the
        schedule's fractions are of) from the model and run layers (:meth:`for_config` takes all three)."""
        self.cfg, self.extent, self.rng = densify, float(extent), rng
        self.kernel, self.iterations = kernel, int(iterations)
        self.grad_sum: dict[str, np.ndarray] = {}
        self.count: dict[str, np.ndarray] = {}
        self.events: list[Event] = []
        self.resets = 0
        self.last_reset = -10 ** 9
        self.start_count: int | None = None  # every set's Gaussians at the first densify step (cap_schedule)

    @classmethod
    def for_config(cls, cfg, extent: float, rng: np.random.Generator) -> "Strategy":
        """The strategy of a run configured as ``cfg`` (a TrainConfig)."""
        return cls(cfg.densify, extent, rng, kernel=cfg.kernel, iterations=cfg.iterations)

    # ------------------------------------------------------------- schedule
    def at(self, fraction: float) -> int:
        """The iteration at ``fraction`` of the run (as TrainConfig.at)."""
        return int(round(fraction * self.iterations))

    def every(self, fraction: float) -> int:
        return max(1, int(round(fraction * self.iterations)))

    def densifying(self, it: int) -> bool:
        """Whether iteration ``it``'s gradients feed the densification statistic."""
        c = self.cfg
        return self.at(c.densify_from) <= it < self.at(self.grow_until())

    def grow_until(self) -> float:
        """The fraction of the run where densification ends: ``grow_until``, or ``densify_until`` where that is -1
        (the opacity resets stop at ``densify_until`` either way)."""
        c = self.cfg
        return c.densify_until if c.grow_until == -1 else c.grow_until

    def cap(self, it: int) -> int:
        """The Gaussian budget (every set together) at iteration ``it``: ``max_gaussians`` (``cap_schedule:
        fixed``, or before the first densify step), or (``linear``) the count at the first densify step plus the
        share of the rest that the growth window has run by ``it``: ``max_gaussians`` at its end."""
        c = self.cfg
        if c.cap_schedule == "fixed" or self.start_count is None or self.start_count >= c.max_gaussians:
            return c.max_gaussians
        a, b = self.at(c.densify_from), self.at(self.grow_until())
        p = min(1.0, max(0.0, (it - a) / max(1, b - a)))
        return int(round(self.start_count + p * (c.max_gaussians - self.start_count)))

    def due(self, it: int) -> tuple[bool, bool]:
        """(densify, reset): what the structure step after iteration ``it`` does."""
        c, nxt = self.cfg, it + 1
        reset = c.reset_every > 0 and nxt < self.at(c.densify_until) and nxt % self.every(c.reset_every) == 0
        densify = self.densifying(it) and nxt % self.every(c.densify_every) == 0 and nxt > self.at(c.densify_from)
        return densify, reset

    def step_post(self, it: int, sets: dict[str, GaussianSet], roles: list[str], adam, sizes: dict[str, int],
                  densify: bool, reset: bool) -> None:
        """The structure step after iteration ``it`` on the sets ``roles`` (in place in ``sets``): densify and prune
        with one floor for every set (from the interface's statistics), then the opacity / transparency resets.
        ``sizes``: every kept set's size (the Gaussian budget counts them together)."""
        nxt = it + 1
        if densify:
            if self.start_count is None:
                self.start_count = sum(sizes.values())
            floor = self.floor()
            for role in roles:
                others = sum(n for r, n in sizes.items() if r != role)
                sets[role] = self.densify_and_prune(nxt, role, sets[role], adam, prune_large=self.resets > 0,
                                                    others=others, floor=floor)
                sizes[role] = len(sets[role])
        if reset:
            for role in roles:
                fields = ("logit_opacity", "logit_transparency") if role == "interface" else ("logit_opacity",)
                self.reset(nxt, role, sets[role], adam, fields)

    # ---------------------------------------------------------------- stats
    def accumulate(self, role: str, n: int, g_means: np.ndarray, g_opacity: np.ndarray) -> None:
        if role not in self.grad_sum or len(self.grad_sum[role]) != n:
            self.grad_sum[role], self.count[role] = np.zeros(n), np.zeros(n)
        seen = (np.abs(g_opacity) > 0) | (np.abs(g_means).sum(1) > 0)
        self.grad_sum[role] += np.linalg.norm(g_means, axis=1) * self.extent
        self.count[role] += seen

    def mean_grad(self, role: str) -> np.ndarray:
        return self.grad_sum[role] / np.maximum(self.count[role], 1)

    def floor(self) -> float:
        """The densification floor for this densification step: ``densify_grad_rel`` x the median statistic of the
        interface's Gaussians (of the first set with statistics where there is no interface), and at least
        ``densify_grad``. The statistic (mean |dL/d position| over the steps that saw a Gaussian, with the loss a
        mean over the batch's rays) falls as the batch grows: a Gaussian seen by one ray of B gets 1/B of its
        gradient, and more rays pulling it different ways cancel (measured on the bundled room at iteration 240,
        the same 131k rays in batches of 1k to 64k: the interface's median 9.4e-4 -> 7.9e-5, 12x). A fraction of a
        median of the same step's statistics follows that scale: over the same range the transmission set's median
        stayed within 3 % of the interface's and the reflection set's rose from 0.008 to 0.011 of it (1.5x). Call
        before the step's first densify_and_prune (which resets its set's statistics)."""
        ref = next((r for r in ("interface", *self.grad_sum) if r in self.grad_sum and (self.count[r] > 0).any()),
                   None)
        if ref is None:
            return float(self.cfg.densify_grad)
        g = self.mean_grad(ref)[self.count[ref] > 0]
        return max(float(self.cfg.densify_grad), float(self.cfg.densify_grad_rel) * float(np.median(g)))

    # ------------------------------------------------------------- changes
    def apply(self, role: str, gset: GaussianSet, index: np.ndarray, new: GaussianSet, adam) -> GaussianSet:
        """Replace ``gset`` by ``new`` whose rows come from ``index`` (-1 = fresh) and keep everything aligned."""
        adam.remap(role, index)
        for d in (self.grad_sum, self.count):
            if role in d:
                d[role] = np.zeros(len(index))  # statistics restart after every change (as in 3DGS)
        return new

    def densify_and_prune(self, it: int, role: str, gset: GaussianSet, adam, prune_large: bool,
                          others: int = 0, floor: float | None = None) -> GaussianSet:
        """Clone / split / prune one set; ``others`` Gaussians of the method's other sets share its budget
        (``max_gaussians`` counts every set together); ``floor``: the step's densification floor (default
        :meth:`floor` now)."""
        cfg, n = self.cfg, len(gset)
        if n == 0 or role not in self.grad_sum:
            return gset
        a = gset.activated()
        g = self.mean_grad(role)
        smax = a["scales"][:, :2].max(1) if self.kernel == "surfel" else a["scales"].max(1)
        room = max(0, self.cap(it) - n - others)
        seen = self.count[role] > 0
        top = np.quantile(g[seen], 1.0 - cfg.densify_top) if seen.any() else np.inf
        # Right after an opacity reset (to 0.01) every Gaussian is below a paper-style threshold (0.05): for half a
        # reset interval at most 3DGS's 0.005 applies, so that opacities can recover before they are judged.
        grace = it - self.last_reset < max(1, self.every(cfg.reset_every) // 2) if cfg.reset_every > 0 else False
        thresh = min(cfg.prune_opacity, 0.005) if grace else cfg.prune_opacity
        alive = a["opacity"] >= thresh  # a Gaussian about to be pruned is not densified
        floor = self.floor() if floor is None else floor
        cand = np.flatnonzero(seen & alive & (g >= max(floor, top)))
        if len(cand) > room:  # the budget goes to the largest gradients
            cand = cand[np.argsort(-g[cand])[:room]]
        small = smax[cand] <= cfg.percent_dense * self.extent
        clone, split = cand[small], cand[~small]
        children = self._split_children(gset, a, split)  # the parent is removed below
        # prune: low opacity, too large (after the first reset), and split parents
        drop = ~alive
        if prune_large:
            drop |= smax > cfg.prune_scale * self.extent
        drop[split] = True
        keep = np.flatnonzero(~drop)
        parts = [gset.subset(keep), gset.subset(clone)] + children
        if cfg.clone_opacity == "shared" and len(clone):  # a clone and its kept parent share the parent's coverage
            kept = np.isin(clone, keep)  # a parent pruned as too large leaves its clone its opacity
            shared = cv.logit(1.0 - np.sqrt(1.0 - a["opacity"][clone[kept]])).astype(gset.logit_opacity.dtype)
            parts[0].logit_opacity[np.searchsorted(keep, clone[kept])] = shared  # keep is sorted: the parents' rows
            parts[1].logit_opacity[kept] = shared
        index = np.concatenate([keep, clone, np.full(2 * len(split), -1)])
        if len(index) == 0:  # never leave a set empty: keep its most opaque Gaussian
            best = np.array([int(np.argmax(a["opacity"]))])
            parts, index = [gset.subset(best)], best
        new = GaussianSet.concatenate(parts)
        self.events.append(Event(it, role, len(clone), len(split), int(drop.sum()) - len(split), len(new)))
        return self.apply(role, gset, index, new, adam)

    def _split_children(self, gset: GaussianSet, a: dict, split: np.ndarray) -> list[GaussianSet]:
        """The two children of each split parent (``split_mode``). ``sample`` (3DGS): drawn from the parent's
        Gaussian (a surfel's in its plane), scales / 1.6, opacity kept. ``axis``: at mean +- (sqrt(3)/2) s e, with s
        the parent's largest scale (a surfel's largest in-plane one) and e that axis, whose scale is halved; the
        other scales and the opacity are kept. The pair's mixture then has the parent's mean and covariance (s^2 / 4
        + 3 s^2 / 4 = s^2 along e) and, where the opacities add (low opacity), its integrated opacity (two halves)."""
        rot = cv.rotation_matrices_xyzw(a["quats_xyzw"][split])
        sc = a["scales"][split].copy()
        if self.kernel == "surfel":
            sc[:, 2] = 0.0
        children = []
        if self.cfg.split_mode == "axis":
            rows = np.arange(len(split))
            k = np.argmax(sc, axis=1)  # a surfel's normal scale is 0 here: its largest in-plane axis
            offset = (np.sqrt(3.0) / 2.0) * sc[rows, k][:, None] * rot[rows, :, k]
            log_scales = gset.log_scales[split].copy()
            log_scales[rows, k] -= np.log(2.0)
            for sign in (1.0, -1.0):
                child = gset.subset(split)
                child.means = (a["means"][split] + sign * offset).astype(gset.means.dtype)
                child.log_scales = log_scales.copy()
                children.append(child)
            return children
        for _ in range(2):
            local = self.rng.normal(size=(len(split), 3)) * sc
            child = gset.subset(split)
            child.means = a["means"][split] + np.einsum("nij,nj->ni", rot, local)
            child.log_scales = gset.log_scales[split] - np.log(1.6)
            children.append(child)
        return children

    def reset(self, it: int, role: str, gset: GaussianSet, adam, fields=("logit_opacity", "logit_transparency")):
        """Opacity and transparency reset to <= 0.01 (the logits are clamped; the moments restart)."""
        cap = cv.logit(0.01)
        for f in fields:
            v = getattr(gset, f)
            np.minimum(v, cap, out=v)
            adam.reset_field(role, f)
        self.resets += 1
        self.last_reset = it
        self.events.append(Event(it, role, size=len(gset), what="reset"))

    def state_dict(self) -> dict:
        out = {"resets": np.array(self.resets), "last_reset": np.array(self.last_reset),
               "start_count": np.array(-1 if self.start_count is None else self.start_count)}
        for role in self.grad_sum:
            out[f"{role}/grad_sum"], out[f"{role}/count"] = self.grad_sum[role], self.count[role]
        return out

    def load_state_dict(self, arrays: dict) -> None:
        self.resets = int(arrays.get("resets", 0))
        self.last_reset = int(arrays.get("last_reset", -10 ** 9))
        start = int(arrays.get("start_count", -1))
        self.start_count = None if start < 0 else start
        for key, v in arrays.items():
            if key.endswith("/grad_sum"):
                role = key.split("/")[0]
                self.grad_sum[role], self.count[role] = v.copy(), arrays[f"{role}/count"].copy()
