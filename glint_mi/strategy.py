"""Optimiser and densification for Gaussian sets whose size changes during training.

Parameters live in :class:`glint_mi.gaussians.GaussianSet` (raw, numpy float64): the renderer sees their
activations (``to_mitsuba``), gradients come back in renderer space and :func:`raw_gradients` applies the chain rule.
:class:`Adam` keeps per-row moments; every structural change (clone, split, prune) goes through
:class:`Strategy`, which remaps the set, the Adam state and the gradient statistics with one index array, so the
three can never disagree (``index[i]`` = the old row new row ``i`` comes from, -1 for a row with fresh state).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from . import conventions as cv
from .gaussians import GaussianSet

RAW_FIELDS = ("means", "log_scales", "quats_wxyz", "logit_opacity", "sh", "logit_specular", "logit_transparency")


def raw_gradients(gset: GaussianSet, grads: dict[str, np.ndarray], kernel: str) -> dict[str, np.ndarray]:
    """Chain rule from the renderer's parameters (``to_mitsuba`` names) to the raw fields of ``gset``."""
    n = len(gset)
    a = gset.activated()
    data = grads["data"].reshape(n, 10)
    g_scale = grads["kernel_scales"].reshape(n, 3) * a["scales"]
    if kernel == "surfel":
        g_scale[:, 2] = 0.0  # the surfel's flat axis is not seen by the kernel
    q = gset.quats_wxyz
    qn_len = np.maximum(np.linalg.norm(q, axis=1, keepdims=True), 1e-12)
    qhat = q / qn_len
    g_q = cv.xyzw_to_wxyz(data[:, 6:10])
    g_q = (g_q - qhat * np.sum(qhat * g_q, axis=1, keepdims=True)) / qn_len
    dsig = lambda p: p * (1.0 - p)
    return {
        "means": data[:, :3].copy(),
        "log_scales": g_scale,
        "quats_wxyz": g_q,
        "logit_opacity": grads["opacities"].reshape(n) * dsig(a["opacity"]),
        "sh": grads["sh_coeffs"].reshape(gset.sh.shape),
        "logit_specular": grads["specular"].reshape(n) * dsig(a["specular"]),
        "logit_transparency": grads["transparency"].reshape(n) * dsig(a["transparency"]),
    }


class Adam:
    """Adam over the raw fields of several sets; learning rates per field (``sh`` has dc / rest rates).

    ``selective`` (default): only the rows of Gaussians that got a gradient in this batch update their moments and
    take a step, with per-row bias correction. With ray batches a Gaussian is hit in a few % of the iterations;
    dense Adam decays its first moment between hits and its steps shrink by that factor (measured: opacities reset
    to 0.01 did not recover in 1000 iterations). This is the "sparse / selective Adam" of fast 3DGS trainers.
    """

    NATIVE = True  # the step in glint_mi.native where it builds (the same numbers); False: numpy only

    def __init__(self, lrs: dict[str, float], eps: float = 1e-15, betas=(0.9, 0.999), selective: bool = True):
        self.lrs, self.eps, self.b1, self.b2, self.selective = dict(lrs), eps, betas[0], betas[1], selective
        self.state: dict[str, dict] = {}

    def _state(self, role, gset):
        st = self.state.get(role)
        if st is None:
            st = {f: (np.zeros_like(getattr(gset, f)), np.zeros_like(getattr(gset, f)), np.zeros(len(gset)))
                  for f in RAW_FIELDS}
            self.state[role] = st
        return st

    def step(self, role: str, gset: GaussianSet, grads: dict[str, np.ndarray], lr_scale: dict | None = None,
             rows: np.ndarray | None = None) -> None:
        """One step; ``rows`` (bool [N]) = the Gaussians touched by this batch (selective mode; all if None).

        The touched rows are gathered once per field, updated in those copies and scattered back: the same
        arithmetic as indexing every moment with the mask (bit for bit), a third of the time."""
        st = self._state(role, gset)
        full = rows is None or not self.selective
        idx = None if full else np.flatnonzero(rows)
        if idx is not None and not len(idx):
            return
        take = (lambda a: a) if full else (lambda a: a[idx])
        scale = lr_scale or {}
        for f in RAW_FIELDS:
            m, v, n = st[f]
            if self.NATIVE and self._native_step(f, getattr(gset, f), m, v, n, grads[f], idx, scale):
                continue
            ns = take(n) + 1
            ms, vs, step = self._direction(take(grads[f]), take(m), take(v), ns)
            if full:
                n[:], m[:], v[:] = ns, ms, vs
            else:
                n[idx], m[idx], v[idx] = ns, ms, vs
            lr = self._lr(f, scale, step.shape[1] if step.ndim > 1 else 1)
            value = getattr(gset, f)
            if full:
                value -= (lr * step).astype(value.dtype)
            else:
                value[idx] = take(value) - (lr * step).astype(value.dtype)

    def _direction(self, g, m, v, ns):
        """Adam's new moments after ``ns`` steps (kept in the moments' dtype - float32 means rounded as stored) and
        its bias-corrected step, for rows of gradient ``g``."""
        ms = (self.b1 * m + (1.0 - self.b1) * g).astype(m.dtype, copy=False)
        vs = (self.b2 * v + (1.0 - self.b2) * g * g).astype(v.dtype, copy=False)
        shape = (-1,) + (1,) * (g.ndim - 1)
        c1 = (1.0 - self.b1 ** ns).reshape(shape)
        c2 = (1.0 - self.b2 ** ns).reshape(shape)
        return ms, vs, (ms / c1) / (np.sqrt(vs / c2) + self.eps)

    def step_array(self, value: np.ndarray, grad: np.ndarray, state: tuple, lr: float) -> None:
        """Dense Adam on one free array outside the sets (``refgs``'s directional grid, which every ray reads), in
        place; ``state`` = (m, v, n) with n one step count for the whole array."""
        m, v, n = state
        n += 1
        if self.NATIVE:  # one row of len(value) columns in glint_mi.native: the arithmetic below, bit for bit
            from . import native
            row = lambda a: a.reshape(1, -1)
            if native.adam_rows(row(value), row(m), row(v), row(np.ascontiguousarray(grad, np.float64)),
                                np.zeros(1, np.int64), 1.0 - self.b1 ** n, 1.0 - self.b2 ** n, lr, self.b1, self.b2,
                                self.eps):
                return
        m[:], v[:], step = self._direction(grad, m, v, n)
        value -= (lr * step).astype(value.dtype)

    def _lr(self, f: str, scale: dict, cols: int):
        """Field f's learning rate: a scalar, or for ``sh`` one per coefficient, [1, cols, 1] (dc, then the rest)."""
        if f != "sh":
            return self.lrs[f] * scale.get(f, 1.0)
        lr = np.full((1, cols, 1), self.lrs["sh_rest"] * scale.get("sh", 1.0))
        lr[:, 0] = self.lrs["sh"] * scale.get("sh", 1.0)
        return lr

    def _native_step(self, f, value, m, v, n, grad, idx, scale) -> bool:
        """One field's step in glint_mi.native (the arithmetic below, bit for bit, one pass over the touched rows);
        False when the library or the arrays' layout does not allow it (float32 fields and moments, float64
        C-contiguous gradients; otherwise the numpy code runs instead)."""
        from . import native
        rows = np.arange(len(value)) if idx is None else idx
        ns = n[rows] + 1
        c1, c2 = 1.0 - self.b1 ** ns, 1.0 - self.b2 ** ns
        lr = self._lr(f, scale, value.shape[1] if value.ndim > 1 else 1)
        if not native.adam_rows(value, m, v, grad, rows, c1, c2, lr, self.b1, self.b2, self.eps):  # float64 grads
            return False
        n[rows] = ns
        return True

    def step_masked(self, role: str, gset: GaussianSet, grads: dict[str, np.ndarray], lr_scale: dict | None = None,
                    rows: np.ndarray | None = None) -> None:
        """:meth:`step` written row mask by row mask: the reference it is tested against bit for bit
        (tests/test_train.py) and the 'before' of benchmarks/profile_step.py --ab."""
        st = self._state(role, gset)
        sel = np.ones(len(gset), bool) if (rows is None or not self.selective) else rows
        if not sel.any():
            return
        for f in RAW_FIELDS:
            g = grads[f][sel]
            m, v, n = st[f]
            n[sel] += 1
            m[sel] = self.b1 * m[sel] + (1.0 - self.b1) * g
            v[sel] = self.b2 * v[sel] + (1.0 - self.b2) * g * g
            shape = (-1,) + (1,) * (g.ndim - 1)
            c1 = (1.0 - self.b1 ** n[sel]).reshape(shape)
            c2 = (1.0 - self.b2 ** n[sel]).reshape(shape)
            step = (m[sel] / c1) / (np.sqrt(v[sel] / c2) + self.eps)
            lr = self._lr(f, lr_scale or {}, step.shape[1] if step.ndim > 1 else 1)
            value = getattr(gset, f)
            value[sel] -= (lr * step).astype(value.dtype)

    def remap(self, role: str, index: np.ndarray) -> None:
        st = self.state.get(role)
        if st is None:
            return
        keep = index >= 0
        for f in RAW_FIELDS:
            new = []
            for arr in st[f]:
                out = np.zeros((len(index),) + arr.shape[1:], arr.dtype)
                out[keep] = arr[index[keep]]
                new.append(out)
            st[f] = tuple(new)

    def reset_field(self, role: str, field: str) -> None:
        st = self.state.get(role)
        if st is not None:
            st[field] = tuple(np.zeros_like(a) for a in st[field])

    def state_dict(self) -> dict:
        out = {}
        for role, st in self.state.items():
            for f in RAW_FIELDS:
                out[f"{role}/{f}/m"], out[f"{role}/{f}/v"], out[f"{role}/{f}/n"] = st[f]
        return out

    def load_state_dict(self, arrays: dict) -> None:
        self.state = {}
        roles = {k.split("/")[0] for k in arrays}
        for role in roles:
            self.state[role] = {f: tuple(arrays[f"{role}/{f}/{x}"].copy() for x in "mvn") for f in RAW_FIELDS}


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

    def __init__(self, cfg, extent: float, rng: np.random.Generator):
        self.cfg, self.extent, self.rng = cfg, float(extent), rng
        self.grad_sum: dict[str, np.ndarray] = {}
        self.count: dict[str, np.ndarray] = {}
        self.events: list[Event] = []
        self.resets = 0
        self.last_reset = -10 ** 9

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
        the same 131k rays in batches of 1k to 64k: the interface's median 9.4e-4 -> 7.9e-5). A fraction of a
        median of the same step's statistics does not depend on that scale: the sets' medians kept their ratio
        within 20 % over that range. Call before the step's first densify_and_prune (which resets its set's
        statistics)."""
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
        smax = a["scales"][:, :2].max(1) if cfg.kernel == "surfel" else a["scales"].max(1)
        room = max(0, cfg.max_gaussians - n - others)
        seen = self.count[role] > 0
        top = np.quantile(g[seen], 1.0 - cfg.densify_top) if seen.any() else np.inf
        # Right after an opacity reset (to 0.01) every Gaussian is below a paper-style threshold (0.05): for half a
        # reset interval at most 3DGS's 0.005 applies, so that opacities can recover before they are judged.
        grace = it - self.last_reset < max(1, cfg.every(cfg.reset_every) // 2) if cfg.reset_every > 0 else False
        thresh = min(cfg.prune_opacity, 0.005) if grace else cfg.prune_opacity
        alive = a["opacity"] >= thresh  # a Gaussian about to be pruned is not densified
        floor = self.floor() if floor is None else floor
        cand = np.flatnonzero(seen & alive & (g >= max(floor, top)))
        if len(cand) > room:  # the budget goes to the largest gradients
            cand = cand[np.argsort(-g[cand])[:room]]
        small = smax[cand] <= cfg.percent_dense * self.extent
        clone, split = cand[small], cand[~small]
        # split: two children sampled from the parent, scales / 1.6 (3DGS); the parent is removed
        rot = _rotation_matrices(a["quats_xyzw"][split])
        sc = a["scales"][split].copy()
        if cfg.kernel == "surfel":
            sc[:, 2] = 0.0
        children = []
        for _ in range(2):
            local = self.rng.normal(size=(len(split), 3)) * sc
            child = gset.subset(split)
            child.means = a["means"][split] + np.einsum("nij,nj->ni", rot, local)
            child.log_scales = gset.log_scales[split] - np.log(1.6)
            children.append(child)
        # prune: low opacity, too large (after the first reset), and split parents
        drop = ~alive
        if prune_large:
            drop |= smax > cfg.prune_scale * self.extent
        drop[split] = True
        keep = np.flatnonzero(~drop)
        parts = [gset.subset(keep), gset.subset(clone)] + children
        index = np.concatenate([keep, clone, np.full(2 * len(split), -1)])
        if len(index) == 0:  # never leave a set empty: keep its most opaque Gaussian
            best = np.array([int(np.argmax(a["opacity"]))])
            parts, index = [gset.subset(best)], best
        new = GaussianSet.concatenate(parts)
        self.events.append(Event(it, role, len(clone), len(split), int(drop.sum()) - len(split), len(new)))
        return self.apply(role, gset, index, new, adam)

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
        out = {"resets": np.array(self.resets), "last_reset": np.array(self.last_reset)}
        for role in self.grad_sum:
            out[f"{role}/grad_sum"], out[f"{role}/count"] = self.grad_sum[role], self.count[role]
        return out

    def load_state_dict(self, arrays: dict) -> None:
        self.resets = int(arrays.get("resets", 0))
        self.last_reset = int(arrays.get("last_reset", -10 ** 9))
        for key, v in arrays.items():
            if key.endswith("/grad_sum"):
                role = key.split("/")[0]
                self.grad_sum[role], self.count[role] = v.copy(), arrays[f"{role}/count"].copy()


def _rotation_matrices(q_xyzw: np.ndarray) -> np.ndarray:
    x, y, z, w = q_xyzw.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
    ], 1)
