"""The optimiser of Gaussian sets on the host: the chain rule from the renderer's parameters to the raw fields
(:func:`raw_gradients`) and Adam with per-row moments (:class:`Adam`).

Parameters live in :class:`glint_mi.model.gaussians.GaussianSet` (raw, numpy float32): the renderer sees their
activations (``to_mitsuba``), gradients come back in renderer space. ``update: device`` runs the same arithmetic on
Dr.Jit arrays (:mod:`glint_mi.training.device_step`); this module is its reference and the ``update: host`` path.
"""
from __future__ import annotations

import numpy as np

from glint_mi import conventions as cv
from glint_mi.model.gaussians import NORMAL_MIN_LENGTH, GaussianSet

RAW_FIELDS = ("means", "log_scales", "quats_wxyz", "logit_opacity", "sh", "logit_specular", "logit_transparency",
              "normals")


def raw_gradients(gset: GaussianSet, grads: dict[str, np.ndarray], kernel: str) -> dict[str, np.ndarray]:
    """Chain rule from the renderer's parameters (``to_mitsuba`` names) to the raw fields of ``gset``. Without a
    ``normals`` gradient (``normal_source: axis``) the result has no ``normals`` entry, and Adam leaves them be."""
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
    out = {
        "means": data[:, :3].copy(),
        "log_scales": g_scale,
        "quats_wxyz": g_q,
        "logit_opacity": grads["opacities"].reshape(n) * dsig(a["opacity"]),
        "sh": grads["sh_coeffs"].reshape(gset.sh.shape),
        "logit_specular": grads["specular"].reshape(n) * dsig(a["specular"]),
        "logit_transparency": grads["transparency"].reshape(n) * dsig(a["transparency"]),
    }
    if "normals" in grads:  # the renderer reads n / |n|: the gradient's part across the normal, over |n|
        nv = gset.normals  # float32, as the quaternions' norm above
        n_len = np.maximum(np.linalg.norm(nv, axis=1, keepdims=True), NORMAL_MIN_LENGTH)
        nhat = nv / n_len
        g_n = grads["normals"].reshape(n, 3)
        out["normals"] = (g_n - nhat * np.sum(nhat * g_n, axis=1, keepdims=True)) / n_len
    return out


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
        """One step; ``rows`` (bool [N]) = the Gaussians touched by this batch (selective mode; all if None). A
        field missing from ``grads`` is not stepped (its moments and step counts stay as they are).

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
            if f not in grads:  # a field the renderer does not read (normals under normal_source: axis)
                continue
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
            from glint_mi import native
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
        from glint_mi import native
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
            if f not in grads:
                continue
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
            st = self.state[role] = {}
            for f in RAW_FIELDS:
                if f == "normals" and f"{role}/{f}/m" not in arrays:  # a checkpoint from before the normal attribute
                    n = arrays[f"{role}/means/n"]
                    st[f] = (np.zeros((len(n), 3), np.float32), np.zeros((len(n), 3), np.float32), np.zeros_like(n))
                    continue
                st[f] = tuple(arrays[f"{role}/{f}/{x}"].copy() for x in "mvn")
