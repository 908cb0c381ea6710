"""What the glint integrator's passes share: one Gaussian set as the integrator sees it (:class:`GaussianSetRef`)
and the accumulators of one alpha-compositing pass (:class:`Composite`, a Dr.Jit struct of the variant in force)."""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

import glint_mi.native as native

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
        self.normals = meta.normals  # normal_source: attribute
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
        origin enters every shell that contains the origin. A width-1 array reduced on the device (nothing read
        back), so kernels do not recompile when it changes."""
        params = mi.traverse(self.shape)
        data = dr.detach(mi.Float(params["data"]))
        self._extent = float(params["extent"])
        n = dr.width(data) // 10
        if n:
            i = dr.arange(mi.UInt32, n * 3)
            scale = dr.max(dr.gather(mi.Float, data, (i // 3) * 10 + 3 + i % 3))
            self.reach = mi.Float(2.0 * self._extent * scale * (1.0 + 1e-3) + 1e-6)
            dr.make_opaque(self.reach)
        else:
            self.reach = dr.opaque(mi.Float, 1e-6)
        self._data = data  # the native traversal reads it on the host when it next builds (native())
        self._shells_stale = True

    def native(self, engine: str = "embree"):
        """The set's shells in a k-buffer traversal's structure, brought up to date on first use after a change:
        ``engine`` embree (:class:`glint_mi.native.ShellSet`), shellbvh (our own BVH: :class:`BvhShellSet` on the
        host, :class:`glint_mi.native.cuda.CudaShellSet` under a CUDA variant). A set's first build is static (a
        trained model being rendered); once it has changed it is taken for a training set: rebuilt refittable, then
        refitted while its size stays the same (exact: the same lists), with a full rebuild every REBUILD_EVERY
        refits and whenever the size changes."""
        shells = getattr(self, "_shells", None)
        if shells is not None and self._engine != engine:
            shells = self._shells = None
        if shells is not None and not self._shells_stale:
            return shells
        device = engine == "shellbvh" and not (mi.variant() or "").startswith("llvm")
        data = self._data if device else np.array(self._data, np.float64).reshape(-1, 10)
        if (shells is not None and shells.dynamic and len(shells) == dr.width(self._data) // 10
                and shells.extent == self._extent and self._refits < self.REBUILD_EVERY):
            shells.refit(_cupy(data) if device else data)
            self._refits += 1
        else:
            dynamic = shells is not None and self.REBUILD_EVERY > 0
            if device:
                from glint_mi.native import cuda
                self._shells = cuda.CudaShellSet(np.array(self._data, np.float32).reshape(-1, 10), self._extent,
                                                 dynamic=dynamic)
            else:
                kind = native.BvhShellSet if engine == "shellbvh" else native.ShellSet
                self._shells = kind(data, self._extent, dynamic=dynamic)
            self._refits = 0
        self._engine = engine
        self._shells_stale = False
        return self._shells


def _cupy(x):
    """A Dr.Jit CUDA array as a CuPy array (DLPack, no copy), once Dr.Jit's stream has written it."""
    import cupy
    dr.eval(x)
    dr.sync_thread()
    return cupy.from_dlpack(x)


# 2DGS's depth distortion maps each hit's depth into [0, 1) as an NDC depth with these planes (its rasteriser's
# near and far plane) before it weighs the spread of the hits along a ray
DIST_NEAR, DIST_FAR = 0.2, 100.0


class Composite:
    """Accumulators of one alpha-compositing pass: sums over hits of w_i * (c, 1, t, n, beta, tau, m, m^2), with
    m the hit's NDC-mapped distance (2DGS's depth distortion: sum_{i<j} w_i w_j (m_i - m_j)^2 = A M2 - M^2), and
    Med, the distance of the hit at which the transmittance falls to 0.5 (2DGS's median depth; 0 where it never
    does). Med is a sum of delta_i t_i with delta_i from the detached transmittance: it depends on the hits' positions,
    not on their alphas, so the replay does not scale it (:meth:`scaled`).

    A Dr.Jit struct, so it can be loop state; arithmetic is field-wise.
    """

    DRJIT_STRUCT = {"C": mi.Color3f, "A": mi.Float, "Dt": mi.Float, "N": mi.Vector3f, "B": mi.Float, "Tau": mi.Float,
                    "M": mi.Float, "M2": mi.Float, "Med": mi.Float}
    FIELDS = tuple(DRJIT_STRUCT)

    def __init__(self, C=None, A=None, Dt=None, N=None, B=None, Tau=None, M=None, M2=None, Med=None):
        self.C = mi.Color3f(0.0) if C is None else C
        self.A = mi.Float(0.0) if A is None else A
        self.Dt = mi.Float(0.0) if Dt is None else Dt
        self.N = mi.Vector3f(0.0) if N is None else N
        self.B = mi.Float(0.0) if B is None else B
        self.Tau = mi.Float(0.0) if Tau is None else Tau
        self.M = mi.Float(0.0) if M is None else M
        self.M2 = mi.Float(0.0) if M2 is None else M2
        self.Med = mi.Float(0.0) if Med is None else Med

    @staticmethod
    def of_hit(w, t, n, c, beta, tau, median=None):
        """One hit's terms: weight w = T alpha, distance t, ...; ``median`` (bool) marks the hit at which the
        transmittance falls to 0.5."""
        m = ndc_depth(t)
        med = mi.Float(0.0) if median is None else dr.select(median, t, 0.0)
        return Composite(w * c, mi.Float(w), w * t, w * n, w * beta, w * tau, w * m, w * m * m, med)

    def map(self, fn, other=None):
        if other is None:
            return Composite(*(fn(getattr(self, f)) for f in self.FIELDS))
        return Composite(*(fn(getattr(self, f), getattr(other, f)) for f in self.FIELDS))

    def __add__(self, other):
        return self.map(lambda a, b: a + b, other)

    def __sub__(self, other):
        return self.map(lambda a, b: a - b, other)

    def scaled(self, s):
        """Every alpha-weighted sum times ``s`` (what lies behind a hit, as its alpha changes); Med is not one."""
        out = self.map(lambda a: a * s)
        out.Med = self.Med
        return out

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
                + self.B * other.B + self.Tau * other.Tau + self.M * other.M + self.M2 * other.M2
                + self.Med * other.Med)

    @property
    def depth(self):  # expected distance along the ray
        return dr.select(self.A > 0, self.Dt / dr.maximum(self.A, 1e-12), 0.0)

    @property
    def distortion(self):  # 2DGS: sum_{i<j} w_i w_j (m_i - m_j)^2
        return self.A * self.M2 - self.M * self.M

    @property
    def normal(self):  # normalised, 0 where nothing was hit
        n = dr.norm(self.N)
        return dr.select(n > 1e-12, self.N / dr.maximum(n, 1e-12), mi.Vector3f(0.0))


def ndc_depth(t):
    """2DGS's mapping of a distance into [0, 1): far / (far - near) (1 - near / t), 0 in front of the near plane."""
    return DIST_FAR / (DIST_FAR - DIST_NEAR) * (1.0 - DIST_NEAR / dr.maximum(t, DIST_NEAR))


def _ray_epsilon(p):
    """Origin offset after a hit: ~8 float32 ulps of the coordinates, at least 1e-6 m (stable from 1e-3 to 1e4 m)."""
    return dr.maximum(1e-6, dr.max(dr.abs(p)) * 1e-6)


def _widen(x, n: int):
    """``x`` (a Dr.Jit array or struct) with ``n`` entries: a width-1 value is broadcast."""
    if dr.width(x) == n:
        return x
    return dr.gather(type(x), x, dr.zeros(mi.UInt32, n))
