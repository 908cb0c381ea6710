"""Ref-GS's directional appearance (Zhang et al., CVPR 2025) for the ``refgs`` blend of the ``glint`` integrator.

Ref-GS shades each pixel after compositing (deferred): the composited albedo a, roughness r and normal n give the
reflected direction w_o = reflect(d, n), a "spherical Mip-grid" is read at w_o with mip level r x L, and the pixel is

    C = srgb(clamp(a + s, 0, 1)),  s = exp(min(f(grid(w_o, r L)), 5)),

where its f is a small MLP that also reads per-Gaussian latent features. Here the grid holds RGB log-radiance and f
is the identity (no latent features, no MLP): the environment a rough or a mirror-like surface reflects, looked up
with the roughness's blur. The grid is a latitude-longitude map of 2^L x 2^(L+1) texels (latitude from the world
+z axis) with L mip levels made by 2 x 2 averaging of the level above, read bilinearly (wrapping in longitude) and
linearly between levels, as nvdiffrast's trilinear texture lookup that Ref-GS uses.

The grid's values are level 0 (``data``, numpy, channel-major). Its whole pyramid, every level, is one flat
``mi.Float`` (``mips``) made in numpy whenever level 0 is set: the lookup gathers from it, and it is the AD leaf of
the grid. The gradient of level 0 is the pyramid's transpose applied to the gradient of ``mips`` (:meth:`grad`; a
texel of level k averages 4^k texels of level 0), so the backward is one scatter per read rather than a kernel
chain through the levels. Gradients reach the roughness and the normal through AD (the integrator differentiates its
shading head with AD on the composites).
"""
from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi
import numpy as np

INIT_LOG_RADIANCE = math.log(0.001)  # the grid's initial value: s = 0.001 everywhere (TrainConfig.env_init)
MAX_LOG = 5.0  # Ref-GS clamps the MLP's output at 5 before exp


def srgb(x):
    """sRGB transfer of linear values in [0, 1] (Ref-GS's linear2srgb, clamping to [1e-10, 1] first)."""
    x = dr.clip(x, 1e-10, 1.0)
    return dr.select(x <= 0.0031308, 12.92 * x, 1.055 * dr.power(x, 1.0 / 2.4) - 0.055)


class DirectionalGrid:
    """RGB log-radiance over directions, ``levels`` mip levels of a 2^levels x 2^(levels+1) lat-long map."""

    def __init__(self, levels: int, values: np.ndarray | None = None, init: float = INIT_LOG_RADIANCE):
        if not 1 <= levels <= 10:
            raise ValueError(f"glint: 'env_levels' must be in 1..10 (got {levels}).")
        self.levels = int(levels)
        self.h, self.w = 2 ** self.levels, 2 ** (self.levels + 1)
        self.sizes = [(self.h >> k, self.w >> k) for k in range(self.levels)]
        starts = np.cumsum([0] + [3 * h * w for h, w in self.sizes])
        self.offsets = [int(x) for x in starts[:-1]]  # where level k begins in ``mips`` (channel-major inside)
        if values is None:
            values = np.full((self.h, self.w, 3), init, np.float32)
        self.set_numpy(values)

    @property
    def data(self) -> np.ndarray:
        """Level 0, channel-major flat float32 (3 h w), as a trained model's checkpoint holds it."""
        return self._data

    @data.setter
    def data(self, values) -> None:
        """Set level 0 (channel-major flat, numpy or mi.Float) and rebuild ``mips`` (no gradient on it)."""
        values = np.array(values, np.float32).reshape(-1)
        if values.size != 3 * self.h * self.w:
            raise ValueError(f"glint: the environment grid holds {3 * self.h * self.w} values for env_levels = "
                             f"{self.levels} (got {values.size}).")
        self._data = values
        chans = values.astype(np.float64).reshape(3, self.h, self.w)
        levels = [chans]
        for _ in range(1, self.levels):
            c = levels[-1]
            levels.append(0.25 * (c[:, 0::2, 0::2] + c[:, 0::2, 1::2] + c[:, 1::2, 0::2] + c[:, 1::2, 1::2]))
        self.mips = mi.Float(np.concatenate([x.ravel() for x in levels]).astype(np.float32))

    def numpy(self) -> np.ndarray:
        """[h, w, 3] log-radiance."""
        return self._data.reshape(3, self.h, self.w).transpose(1, 2, 0).copy()

    def set_numpy(self, values: np.ndarray) -> None:
        values = np.asarray(values, np.float32)
        if values.shape != (self.h, self.w, 3):
            raise ValueError(f"glint: the environment grid must be {self.h} x {self.w} x 3 for env_levels = "
                             f"{self.levels} (got {values.shape}).")
        self.data = np.ascontiguousarray(values.transpose(2, 0, 1)).ravel()  # channel-major

    def enable_grad(self) -> None:
        dr.enable_grad(self.mips)

    def grad(self) -> np.ndarray:
        """d/d(level 0) (channel-major flat, float64) of what was back-propagated into ``mips``: each level's
        gradient, coarsest first, spread over the 2 x 2 texels it averages (x 0.25) and added to the finer one's."""
        g = np.array(dr.grad(self.mips), np.float64)
        acc = None
        for k in range(self.levels - 1, -1, -1):
            h, w = self.sizes[k]
            gk = g[self.offsets[k]:self.offsets[k] + 3 * h * w].reshape(3, h, w)
            acc = gk if acc is None else gk + 0.25 * np.repeat(np.repeat(acc, 2, axis=1), 2, axis=2)
        return acc.ravel()

    def clear_grad(self) -> None:
        dr.clear_grad(self.mips)

    def lookup(self, direction, level):
        """Trilinear read at unit ``direction`` (world) and fractional mip ``level`` in [0, levels - 1]."""
        z = dr.clip(direction.z, -1.0 + 1e-6, 1.0 - 1e-6)
        u = dr.atan2(direction.y, direction.x) * (0.5 / dr.pi) + 0.5  # longitude in [0, 1]
        v = dr.acos(z) / dr.pi  # colatitude in [0, 1]
        level = dr.clip(level, 0.0, self.levels - 1.0)
        acc = mi.Color3f(0.0)
        for k, (h, w) in enumerate(self.sizes):
            wk = dr.maximum(0.0, 1.0 - dr.abs(level - k))
            xf, yf = u * w - 0.5, v * h - 0.5
            x0, y0 = dr.floor(xf), dr.floor(yf)
            fx, fy = xf - x0, yf - y0
            xi0 = mi.Int32(x0)
            xi0 = dr.select(xi0 < 0, xi0 + w, dr.select(xi0 >= w, xi0 - w, xi0))
            xi1 = dr.select(xi0 + 1 >= w, xi0 + 1 - w, xi0 + 1)
            yi0 = dr.clip(mi.Int32(y0), 0, h - 1)
            yi1 = dr.clip(mi.Int32(y0) + 1, 0, h - 1)
            idx = [(yi0 * w + xi0, (1 - fx) * (1 - fy)), (yi0 * w + xi1, fx * (1 - fy)),
                   (yi1 * w + xi0, (1 - fx) * fy), (yi1 * w + xi1, fx * fy)]
            val = [sum(dr.gather(mi.Float, self.mips, mi.UInt32(i + self.offsets[k] + c * h * w)) * wt
                       for i, wt in idx) for c in range(3)]
            acc += wk * mi.Color3f(*val)
        return acc

    def specular(self, direction, roughness):
        """Ref-GS's specular radiance s = exp(min(grid(w_o, r L), 5)) (f = identity here)."""
        return dr.exp(dr.minimum(self.lookup(direction, roughness * self.levels), MAX_LOG))


def reflect(d, n):
    """The mirror direction d - 2 (d . n) n (GLINT's reflection rays; Ref-GS's w_o = reflect(-d, n) in its
    convention)."""
    return d - 2.0 * dr.dot(d, n) * n


def refgs_shade(C, A, B, N, d, grid: DirectionalGrid, alpha_min: float = 0.05):
    """Ref-GS's deferred pixel: srgb(clamp(a + s, 0, 1)) where the composited alpha exceeds ``alpha_min`` (0 elsewhere,
    as its renderer leaves those pixels to the background); C = composited albedo, B = composited roughness, N =
    normalised composited normal (world), d = ray direction."""
    s = grid.specular(dr.normalize(reflect(d, N)), B)
    return dr.select(dr.detach(A) > alpha_min, srgb(C + s), 0.0)
