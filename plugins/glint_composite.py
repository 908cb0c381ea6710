"""What the glint integrator's passes share: one Gaussian set as the integrator sees it (:class:`GaussianSetRef`)
and the accumulators of one alpha-compositing pass (:class:`Composite`, a Dr.Jit struct of the variant in force)."""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

from glint_mi import native

from . import glint_gaussians


class GaussianSetRef:
    """One set as the integrator sees it: its shape, kernel and the sub-scene holding its BVH."""

    REBUILD_EVERY = 100  # refits of the native shells between full rebuilds (a refitted tree slowly loosens); 0: a
    #                      static build after every change (as before refits; benchmarks/profile_step.py --ab)

    def __init__(self, role: str, shape):
        meta = glint_gaussians.info(shape)
        if meta.role is not None and meta.role != role:
            raise ValueError(f"glint: the shape nested as '{role}' declares role '{meta.role}'.")
        self.role, self.shape, self.kernel, self.empty = role, shape, meta.kernel, meta.empty
        self.scene = mi.load_dict({"type": "scene", "gaussians": shape})
        self.bvh_stale = False
        self.refresh()

    def bvh_scene(self):
        """The sub-scene whose Mitsuba BVH the ``bvh`` traversal queries, rebuilt first if the set changed since: the
        k-buffer traversal never uses it, so a training push does not pay for it (13 ms at 10k, 33 ms at 40k)."""
        if self.bvh_stale:
            self.scene.parameters_changed()
            self.bvh_stale = False
        return self.scene

    def refresh(self) -> None:
        """Recompute ``reach``, the longest shell diameter of the set (metres): a ray started that far behind its
        origin enters every shell that contains the origin. An opaque Dr.Jit scalar, so kernels do not recompile
        when it changes."""
        params = mi.traverse(self.shape)
        data = np.array(params["data"], np.float64).reshape(-1, 10)
        reach = 2.0 * float(params["extent"]) * float(data[:, 3:6].max(initial=0.0)) if len(data) else 0.0
        self.reach = dr.opaque(mi.Float, reach * (1.0 + 1e-3) + 1e-6)
        self._data, self._extent = data, float(params["extent"])
        self._shells_stale = True

    def native(self) -> "native.ShellSet":
        """The set's shells in the native k-buffer traversal's Embree scene, brought up to date on first use after a
        change. A set's first build is static (a trained model being rendered); once it has changed it is taken for
        a training set: rebuilt in Embree's refittable mode, then refitted while its size stays the same (exact: the
        same lists), with a full rebuild every REBUILD_EVERY refits and whenever the size changes."""
        shells = getattr(self, "_shells", None)
        if shells is not None and not self._shells_stale:
            return shells
        if (shells is not None and shells.dynamic and len(shells) == len(self._data)
                and shells.extent == self._extent and self._refits < self.REBUILD_EVERY):
            shells.refit(self._data)
            self._refits += 1
        else:
            self._shells = native.ShellSet(self._data, self._extent,
                                           dynamic=shells is not None and self.REBUILD_EVERY > 0)
            self._refits = 0
        self._shells_stale = False
        return self._shells


class Composite:
    """Accumulators of one alpha-compositing pass: sums over hits of w_i * (c, 1, t, n, beta, tau).

    A Dr.Jit struct, so it can be loop state; arithmetic is field-wise.
    """

    DRJIT_STRUCT = {"C": mi.Color3f, "A": mi.Float, "Dt": mi.Float, "N": mi.Vector3f, "B": mi.Float, "Tau": mi.Float}
    FIELDS = tuple(DRJIT_STRUCT)

    def __init__(self, C=None, A=None, Dt=None, N=None, B=None, Tau=None):
        self.C = mi.Color3f(0.0) if C is None else C
        self.A = mi.Float(0.0) if A is None else A
        self.Dt = mi.Float(0.0) if Dt is None else Dt
        self.N = mi.Vector3f(0.0) if N is None else N
        self.B = mi.Float(0.0) if B is None else B
        self.Tau = mi.Float(0.0) if Tau is None else Tau

    @staticmethod
    def of_hit(w, t, n, c, beta, tau):
        return Composite(w * c, mi.Float(w), w * t, w * n, w * beta, w * tau)

    def map(self, fn, other=None):
        if other is None:
            return Composite(*(fn(getattr(self, f)) for f in self.FIELDS))
        return Composite(*(fn(getattr(self, f), getattr(other, f)) for f in self.FIELDS))

    def __add__(self, other):
        return self.map(lambda a, b: a + b, other)

    def __sub__(self, other):
        return self.map(lambda a, b: a - b, other)

    def scaled(self, s):
        return self.map(lambda a: a * s)

    def detached(self):
        return self.map(dr.detach)

    def leaf(self):
        """A detached copy with gradients enabled (an AD input for the shading head)."""
        c = self.detached()
        for f in self.FIELDS:
            dr.enable_grad(getattr(c, f))
        return c

    def grad(self):
        return self.map(dr.grad)

    def dot(self, other):
        """sum over fields of <self.f, other.f> per ray (adjoint . value)."""
        return (dr.dot(self.C, other.C) + self.A * other.A + self.Dt * other.Dt + dr.dot(self.N, other.N)
                + self.B * other.B + self.Tau * other.Tau)

    @property
    def depth(self):  # expected distance along the ray
        return dr.select(self.A > 0, self.Dt / dr.maximum(self.A, 1e-12), 0.0)

    @property
    def normal(self):  # normalised, 0 where nothing was hit
        n = dr.norm(self.N)
        return dr.select(n > 1e-12, self.N / dr.maximum(n, 1e-12), mi.Vector3f(0.0))


def _ray_epsilon(p):
    """Origin offset after a hit: ~8 float32 ulps of the coordinates, at least 1e-6 m (stable from 1e-3 to 1e4 m)."""
    return dr.maximum(1e-6, dr.max(dr.abs(p)) * 1e-6)


def _widen(x, n: int):
    """``x`` (a Dr.Jit array or struct) with ``n`` entries: a width-1 value is broadcast."""
    if dr.width(x) == n:
        return x
    return dr.gather(type(x), x, dr.zeros(mi.UInt32, n))
