"""The update half of a training step on the device: the chain rule from the renderer's parameters to the raw fields,
the gradient statistics densification reads, a selective Adam and the packing of the new values into the renderer's
layout, all on Dr.Jit arrays of the variant in force (LLVM or CUDA), so that between two structure changes nothing of
a set goes to the host and back.

The host (numpy) :class:`glint_mi.model.gaussians.GaussianSet`, :class:`glint_mi.training.optim.Adam` and
:class:`glint_mi.training.strategy.Strategy` stay the record: densification, resets, checkpoints and saving read them
after :meth:`DeviceUpdate.pull`, and a set whose rows changed on the host is sent back with
:meth:`DeviceUpdate.load`.

The arithmetic is :func:`glint_mi.training.optim.raw_gradients` followed by
:meth:`glint_mi.training.optim.Adam.step`, operation by operation in the reference's precision (float64 where numpy
computes in float64, float32 where it does): on LLVM the two are equal bit for bit, on CUDA (fast-math float32
division and square root) to float32 rounding (tests/test_device_step.py). Which one a run uses is the config's
``update`` (device | host).

Every field is one flat array of N x C values (row-major, as the host array's memory); per-row quantities (the
touched rows, the step counts) are gathered by ``i // C``. Values that change every step (the position learning
rate, the SH degree) are opaque, so the kernels compile once per set size.
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

from glint_mi.model.gaussians import MIN_SHELL_FACTOR, NORMAL_MIN_LENGTH, GaussianSet
from glint_mi.training.optim import RAW_FIELDS


def _index(n: int):
    return dr.arange(mi.UInt32, n)


def _cols(gset: GaussianSet) -> dict[str, int]:
    return {f: int(np.prod(getattr(gset, f).shape[1:], dtype=np.int64)) for f in RAW_FIELDS}


class _Set:
    """One set's device state: fields, Adam moments (m, v, per-row step counts n per field), densification sums."""

    def __init__(self, gset: GaussianSet):
        self.n = len(gset)
        self.cols = _cols(gset)
        self.k = gset.sh.shape[1]
        self.value = {f: mi.Float(np.ascontiguousarray(getattr(gset, f), np.float32).ravel()) for f in RAW_FIELDS}
        self.m = {f: dr.zeros(mi.Float, self.n * c) for f, c in self.cols.items()}
        self.v = {f: dr.zeros(mi.Float, self.n * c) for f, c in self.cols.items()}
        self.steps = {f: dr.zeros(mi.Float64, self.n) for f in RAW_FIELDS}
        self.grad_sum = dr.zeros(mi.Float64, self.n)
        self.count = dr.zeros(mi.Float64, self.n)
        self.bad = mi.UInt32(0)
        self.stepped = self.accumulated = False  # whether the device has moments / statistics the host lacks

    def col(self, f: str, i, k: int):
        """Column k of field f at rows i."""
        return dr.gather(mi.Float, self.value[f], i * self.cols[f] + k)


class DeviceUpdate:
    """Chain rule, selective Adam and packing for the trainer's sets on the device (see the module docstring).

    ``lrs``: the Adam's per-field learning rates (``sh`` the DC rate, ``sh_rest`` the others), ``kernel``: surfel or
    gaussian (a surfel's third scale gets no gradient), ``extent``: the scene extent the densification statistic is
    scaled by."""

    def __init__(self, adam, kernel: str, extent: float):
        self.adam, self.kernel, self.extent = adam, kernel, float(extent)
        self.sets: dict[str, _Set] = {}

    # ------------------------------------------------------------ host <-> device
    def load(self, role: str, gset: GaussianSet, strategy=None) -> None:
        """Send a set, its Adam moments and its gradient statistics (when the strategy holds them) to the device."""
        s = _Set(gset)
        if role in self.sets:  # the count of zeroed gradient entries runs on across reloads
            s.bad = self.sets[role].bad
        st = self.adam.state.get(role)
        if st is not None:
            for f in RAW_FIELDS:
                m, v, n = st[f]
                s.m[f], s.v[f] = mi.Float(m.astype(np.float32).ravel()), mi.Float(v.astype(np.float32).ravel())
                s.steps[f] = mi.Float64(np.asarray(n, np.float64))
            s.stepped = True
        if strategy is not None and role in strategy.grad_sum and len(strategy.grad_sum[role]) == s.n:
            s.grad_sum = mi.Float64(np.asarray(strategy.grad_sum[role], np.float64))
            s.count = mi.Float64(np.asarray(strategy.count[role], np.float64))
            s.accumulated = True
        self.sets[role] = s

    def pull(self, role: str, gset: GaussianSet, strategy=None) -> None:
        """Write the device's values into ``gset`` (in place), the moments into the Adam's state and the gradient
        statistics into the strategy."""
        s = self.sets[role]
        dr.eval(*s.value.values(), *s.m.values(), *s.v.values(), *s.steps.values(), s.grad_sum, s.count)
        for f in RAW_FIELDS:
            shape = getattr(gset, f).shape
            setattr(gset, f, np.array(s.value[f], np.float32).reshape(shape))
        if s.stepped:
            self.adam.state[role] = {f: (np.array(s.m[f], np.float32).reshape(getattr(gset, f).shape),
                                         np.array(s.v[f], np.float32).reshape(getattr(gset, f).shape),
                                         np.array(s.steps[f], np.float64)) for f in RAW_FIELDS}
        if strategy is not None and s.accumulated:
            strategy.grad_sum[role] = np.array(s.grad_sum, np.float64)
            strategy.count[role] = np.array(s.count, np.float64)

    # ------------------------------------------------------------------- the step
    def gradients(self, role: str, grads: dict, sh_degree, zero: set[str]) -> dict:
        """:func:`glint_mi.training.optim.raw_gradients` on the device (float64, the reference's operations in its
        order), then the SH bands above ``sh_degree`` (an opaque UInt32) and the ``zero`` fields set to 0, and
        non-finite entries zeroed (counted in the set's ``bad``). Float64 arrays, one per raw field (``normals`` only
        when ``grads`` has them: normal_source attribute)."""
        F64 = mi.Float64
        s = self.sets[role]
        n = s.n
        data = F64(grads["data"])
        out = {}
        i = _index(n * 3)
        row, k = i // 3, i % 3
        out["means"] = dr.gather(F64, data, row * 10 + k)
        g_scale = F64(grads["kernel_scales"]) * dr.exp(F64(s.value["log_scales"]))
        if self.kernel == "surfel":
            g_scale = dr.select(k == 2, 0.0, g_scale)  # the surfel's flat axis is not seen by the kernel
        out["log_scales"] = g_scale
        i = _index(n * 4)
        row, j = i // 4, i % 4
        q = [s.col("quats_wxyz", row, c) for c in range(4)]  # float32, as the reference's norm
        qlen = dr.maximum(dr.sqrt(((q[0] * q[0] + q[1] * q[1]) + q[2] * q[2]) + q[3] * q[3]), 1e-12)
        qhat = [F64(qc / qlen) for qc in q]
        g = [dr.gather(F64, data, row * 10 + 6 + (c + 3) % 4) for c in range(4)]  # (x,y,z,w) -> (w,x,y,z)
        dot = ((qhat[0] * g[0] + qhat[1] * g[1]) + qhat[2] * g[2]) + qhat[3] * g[3]
        qj = F64(dr.gather(mi.Float, s.value["quats_wxyz"], i) / qlen)  # float32 q / |q|, as the reference
        gj = dr.gather(F64, data, row * 10 + 6 + (j + 3) % 4)
        out["quats_wxyz"] = (gj - qj * dot) / F64(qlen)
        if "normals" in grads:  # normal_source: attribute; the reference's n / |n| (|n| in float32, as its norm)
            i = _index(n * 3)
            row = i // 3
            nv = [s.col("normals", row, c) for c in range(3)]
            nlen = dr.maximum(dr.sqrt((nv[0] * nv[0] + nv[1] * nv[1]) + nv[2] * nv[2]), NORMAL_MIN_LENGTH)
            nhat = [F64(nc / nlen) for nc in nv]
            gn = F64(grads["normals"])
            g = [dr.gather(F64, gn, row * 3 + c) for c in range(3)]
            dot = (nhat[0] * g[0] + nhat[1] * g[1]) + nhat[2] * g[2]
            nj = F64(dr.gather(mi.Float, s.value["normals"], i) / nlen)
            out["normals"] = (gn - nj * dot) / F64(nlen)
        for f, key in (("logit_opacity", "opacities"), ("logit_specular", "specular"),
                       ("logit_transparency", "transparency")):
            p = 1.0 / (1.0 + dr.exp(-F64(s.value[f])))
            out[f] = F64(grads[key]) * (p * (1.0 - p))
        col = _index(n * s.k * 3) % (s.k * 3)
        band = (sh_degree + 1) * (sh_degree + 1) * 3
        out["sh"] = dr.select(col >= band, 0.0, F64(grads["sh_coeffs"]))
        for f in zero:
            out[f] = dr.zeros(F64, n * s.cols[f])
        bad = mi.UInt32(0)
        for f in out:
            finite = dr.isfinite(out[f])
            bad += mi.UInt32(dr.count(~finite))
            out[f] = dr.select(finite, out[f], 0.0)
        s.bad = s.bad + bad
        return out

    def rows(self, role: str, g: dict):
        """Per row: (seen, touched, position gradient): a gradient on the opacity or the position (what the
        densification statistic counts), and also on the DC colour (the rows selective Adam steps)."""
        F64 = mi.Float64
        s = self.sets[role]
        r = _index(s.n)
        means = [dr.gather(F64, g["means"], r * 3 + k) for k in range(3)]
        seen = (g["logit_opacity"] != 0) | (means[0] != 0) | (means[1] != 0) | (means[2] != 0)
        sh_row = s.k * 3
        touched = seen
        for c in range(3):
            touched |= dr.gather(F64, g["sh"], r * sh_row + c) != 0
        return seen, touched, means

    def accumulate(self, role: str, seen, means) -> None:
        """The densification statistic (Strategy.accumulate): |dL/d position| x extent, and the steps that saw it."""
        s = self.sets[role]
        s.grad_sum = s.grad_sum + dr.sqrt((means[0] * means[0] + means[1] * means[1]) + means[2] * means[2]) \
            * self.extent
        s.count = s.count + dr.select(seen, 1.0, 0.0)
        s.accumulated = True

    def step(self, role: str, g: dict, touched, lr_scale: dict | None = None) -> None:
        """Adam on the rows ``touched`` (all rows when the Adam is dense); ``lr_scale`` values may be opaque
        Float64 scalars. Adam.step's arithmetic: the moments updated in float64 (their decay in float32) and stored
        in float32, the step in float64, rounded before it is subtracted in float32."""
        F64 = mi.Float64
        a, s = self.adam, self.sets[role]
        if not a.selective:
            touched = dr.full(mi.Bool, True, s.n)
        scale = lr_scale or {}
        for f in RAW_FIELDS:
            if f not in g:  # a field the renderer does not read (normals under normal_source: axis): not stepped
                continue
            c = s.cols[f]
            i = _index(s.n * c)
            row = i // c
            t = dr.gather(mi.Bool, touched, row)
            ns = dr.gather(F64, s.steps[f], row) + 1.0
            c1 = 1.0 - dr.power(F64(a.b1), ns)
            c2 = 1.0 - dr.power(F64(a.b2), ns)
            gf = g[f]
            # numpy multiplies the float32 moments by the Python-float betas in float32 (NEP 50), the rest in float64
            m = mi.Float(F64(a.b1 * s.m[f]) + (1.0 - a.b1) * gf)
            v = mi.Float(F64(a.b2 * s.v[f]) + ((1.0 - a.b2) * gf) * gf)
            direction = (F64(m) / c1) / (dr.sqrt(F64(v) / c2) + a.eps)
            if f == "sh":
                lr = dr.select(i % c < 3, F64(a.lrs["sh"]), F64(a.lrs["sh_rest"])) * scale.get("sh", 1.0)
            else:
                lr = a.lrs[f] * scale.get(f, 1.0)
            s.value[f] = dr.select(t, s.value[f] - mi.Float(lr * direction), s.value[f])
            s.m[f] = dr.select(t, m, s.m[f])
            s.v[f] = dr.select(t, v, s.v[f])
            s.steps[f] = dr.select(touched, s.steps[f] + 1.0, s.steps[f])
        s.stepped = True

    def schedule(self, role: str) -> None:
        s = self.sets[role]
        dr.schedule(*s.value.values(), *s.m.values(), *s.v.values(), *s.steps.values(), s.grad_sum, s.count, s.bad)

    # ------------------------------------------------------------------ packing
    def pack(self, role: str, min_shell_ratio: float, opacity_shells: bool, extent: float,
             normals: bool = False) -> dict:
        """:meth:`glint_mi.model.gaussians.GaussianSet.to_mitsuba` on the device (float64, rounded to float32 at the
        end, as the reference): the ``glint_gaussians`` parameters (flat float32 Dr.Jit arrays) of the set's values."""
        F64 = mi.Float64
        s = self.sets[role]
        n = s.n
        sig = lambda x: 1.0 / (1.0 + dr.exp(-F64(x)))
        i = _index(n * 10)
        r, c = i // 10, i % 10  # data is built element by element: column c of row r
        ks = [dr.exp(F64(s.col("log_scales", r, k))) for k in range(3)]
        smax = dr.maximum(ks[0], ks[1]) if self.kernel == "surfel" else dr.maximum(dr.maximum(ks[0], ks[1]), ks[2])
        factor = F64(1.0)
        if opacity_shells:
            o = dr.clip(sig(s.col("logit_opacity", r, 0)), 1e-300, 1.0)
            r2 = extent * extent + 2.0 * dr.log(o)
            factor = dr.clip(dr.sqrt(dr.maximum(r2, 0.0)) / extent, MIN_SHELL_FACTOR, 1.0)
        q = [F64(s.col("quats_wxyz", r, (k + 1) % 4)) for k in range(4)]  # (x, y, z, w)
        qn = dr.sqrt(((q[0] * q[0] + q[1] * q[1]) + q[2] * q[2]) + q[3] * q[3])
        ok = qn > 1e-12
        q = [dr.select(ok, x / dr.maximum(qn, 1e-30), 1.0 if k == 3 else 0.0) for k, x in enumerate(q)]
        shell = [dr.maximum(x, min_shell_ratio * smax) * factor for x in ks]
        columns = [F64(s.col("means", r, k)) for k in range(3)] + shell + q
        data = columns[-1]
        for k in range(8, -1, -1):
            data = dr.select(c == k, columns[k], data)
        out = {"data": mi.Float(data), "kernel_scales": mi.Float(dr.exp(F64(s.value["log_scales"]))),
               "opacities": mi.Float(sig(s.value["logit_opacity"])), "sh_coeffs": mi.Float(s.value["sh"]),
               "specular": mi.Float(sig(s.value["logit_specular"])),
               "transparency": mi.Float(sig(s.value["logit_transparency"]))}
        if normals:  # unit_normals: n / max(|n|, NORMAL_MIN_LENGTH)
            i = _index(n * 3)
            r = i // 3
            nv = [F64(s.col("normals", r, c)) for c in range(3)]
            nlen = dr.maximum(dr.sqrt((nv[0] * nv[0] + nv[1] * nv[1]) + nv[2] * nv[2]), NORMAL_MIN_LENGTH)
            out["normals"] = mi.Float(F64(s.value["normals"]) / nlen)
        return out

    def read_bad(self) -> dict[str, int]:
        """Non-finite gradient entries zeroed so far, per set (reads back)."""
        return {role: int(s.bad[0]) for role, s in self.sets.items()}
