"""How the glint integrator walks one Gaussian set along rays (:class:`GaussianPasses`, its base class): the
kernel at a hit, front-to-back compositing with the paper's cut-offs, the two traversals (the native k-buffer rounds
of :mod:`glint_mi.native`; Mitsuba's BVH queries with a walk back behind the origin), stored hit lists, and the
constant-memory replay of a pass for reverse-mode gradients."""
from __future__ import annotations

import threading

import drjit as dr
import mitsuba as mi
import numpy as np

import glint_mi.conventions as cv
from glint_mi.native.cuda import MAX_K as DEVICE_K

from .glint_composite import Composite, GaussianSetRef, _ray_epsilon, _widen

KBUFFER_BYTES = 256 * 2 ** 20  # a k-buffer round's buffers, at most
# The k-buffer rounds' output arrays, kept between queries of the same shape (per thread, the two latest shapes):
# fresh arrays of a few megabytes cost their page faults on every query (~1.2 ms at 3072 rays x 256 entries, four
# queries a training step). Reuse is safe: a query runs after np.asarray of the rays, which waits for every task of
# the thread, the copy of the previous round's list into Dr.Jit included. REUSE_LISTS = False: new arrays each time.
# Only lists of at most KEEP_LIST_BYTES are kept (a training batch's are 6 MB; a full frame's would hold hundreds of MB
# after the render that needed them).
REUSE_LISTS = True
KEEP_LIST_BYTES = 64 * 2 ** 20
_lists = threading.local()


def _list_buffers(n: int, k: int):
    """(prims, t, count) arrays for a query of n rays and k entries: kept ones when REUSE_LISTS and they are at most
    KEEP_LIST_BYTES, else None (the query makes new ones)."""
    if not REUSE_LISTS or 8 * n * k > KEEP_LIST_BYTES:
        return None
    cache = getattr(_lists, "cache", None)
    if cache is None:
        cache = _lists.cache = {}
    key = (n, k)
    if key not in cache:
        while len(cache) >= 2:
            cache.pop(next(iter(cache)))
        cache[key] = (np.empty((n, k), np.uint32), np.empty((n, k), np.float32), np.empty(n, np.uint32))
    else:
        cache[key] = cache.pop(key)  # the latest last
    return cache[key]


class GaussianPasses(mi.ad.integrators.common.ADIntegrator):
    """One set's passes, the glint integrator's base (nanobind classes take one base, so the layers are a chain).
    Reads the integrator's settings: alpha_min, alpha_max, transmittance_min, max_hits, kbuffer, kbuffer_k,
    inside_origins."""

    def _eval_kernel(self, gs: GaussianSetRef, prim_index, o0, d, active):
        """Alpha, distance along the ray, facing normal and attributes of hit primitives (differentiable)."""
        shape = gs.shape
        si, e, center, rot = self._frame(gs, prim_index, active)
        s = mi.Vector3f(shape.eval_attribute_3("kernel_scales", si, active))
        opacity = shape.eval_attribute_1("opacities", si, active)

        ol = rot.T @ (o0 - center)  # ray in the kernel's local frame
        dl = rot.T @ d
        if gs.kernel == "surfel":
            ok = dr.abs(dl.z) > 1e-7
            t = dr.select(ok, -ol.z / dr.select(ok, dl.z, 1.0), 0.0)
            u = ol + t * dl
            sx, sy = dr.maximum(s.x, 1e-30), dr.maximum(s.y, 1e-30)
            power = dr.square(u.x / sx) + dr.square(u.y / sy)
            n_local = mi.Vector3f(0, 0, 1)
        else:
            sc = dr.maximum(s, 1e-30)
            ols, dls = ol / sc, dl / sc
            dd = dr.squared_norm(dls)
            ok = dd > 0
            t = dr.select(ok, -dr.dot(ols, dls) / dr.select(ok, dd, 1.0), 0.0)
            power = dr.squared_norm(ols + t * dls)
            zmin = (s.z <= s.x) & (s.z <= s.y)
            ymin = ~zmin & (s.y <= s.x)
            n_local = dr.select(zmin, mi.Vector3f(0, 0, 1), dr.select(ymin, mi.Vector3f(0, 1, 0), mi.Vector3f(1, 0, 0)))
        if gs.normals:  # normal_source: attribute - the set's own unit normals (packed normalised), not the axis
            n = mi.Vector3f(shape.eval_attribute_3("normals", si, active))
        else:
            n = rot @ n_local
        n = dr.select(dr.dot(n, d) > 0, -n, n)
        G = dr.exp(-0.5 * power)
        alpha = dr.minimum(opacity * G, self.alpha_max)
        ok &= active & (t > 0) & dr.isfinite(alpha) & (alpha >= self.alpha_min)
        alpha = dr.select(ok, alpha, 0.0)

        sh = shape.eval_attribute_x("sh_coeffs", si, active)
        degree = cv.sh_degree_from_coeffs(len(sh))
        basis = dr.sh_eval(d, degree)
        c = mi.Color3f(0.0)
        for k, y in enumerate(basis):
            c += y * mi.Color3f(sh[3 * k], sh[3 * k + 1], sh[3 * k + 2])
        c = dr.maximum(c + 0.5, 0.0)
        beta = shape.eval_attribute_1("specular", si, active) if shape.has_attribute("specular") else mi.Float(0)
        tau = shape.eval_attribute_1("transparency", si, active) if shape.has_attribute("transparency") else mi.Float(0)
        zero3 = mi.Vector3f(0.0)
        return (alpha, dr.select(ok, t, 0.0), dr.select(ok, n, zero3), dr.select(ok, c, mi.Color3f(0.0)),
                dr.select(ok, beta, 0.0), dr.select(ok, tau, 0.0))

    def march(self, gs: GaussianSetRef, o0, d, active, ad: bool = False, total: Composite = None,
              adjoint: Composite = None, ray_grad: bool = False, weight=None, budget=None, record: bool = False,
              hit_list=None, info: dict | None = None):
        """Front-to-back alpha compositing of one set along rays (o0, d).

        ``weight`` (per ray, primal) is how much of this pass reaches the pixel: the pass stops once
        weight * T < transmittance_min, the same bound on the missed radiance as the camera pass has.

        Forward (``adjoint`` None): returns the :class:`Composite`; with ``ad`` the loop is evaluated so that plain
        Dr.Jit AD runs through it (d and o0 may carry gradients).
        Replay (``adjoint`` given, ``total`` = the forward Composite): re-traces the same hits and back-propagates the
        adjoint of the totals into the set's parameters hit by hit, in constant memory. Returns the adjoints of
        the ray origin and direction (zero unless ``ray_grad``).

        Stored hit lists (exact, a speed-up of the replay): a forward with ``record`` also writes the Gaussians it
        composited, per ray in order, into ``info["list"]`` = (indices [rays x max_hits], count [rays]); a replay
        given that ``hit_list`` walks the list instead of re-running the BVH queries (same hits, same order, same
        arithmetic). Traversal is most of a training step (benchmarks/profile_step.py), the replay half of it.

        Profiling (benchmarks/profile_step.py): a pass given an ``info`` dict leaves its per-ray hit count there
        (``info["hits"]``; never on ``self``, which is loop state of Dr.Jit's symbolic loops);
        ``budget`` (per-ray hit counts) makes the pass a traversal only: the same BVH queries and stepping, stopped
        after ``budget`` hits, with no kernel evaluated (returns an empty Composite).
        """
        if adjoint is not None and hit_list is not None:
            return self._replay_list(gs, o0, d, active, total, adjoint, ray_grad, hit_list)
        listed = slot = None
        if record:
            n_rays = max(dr.width(active), dr.width(o0), dr.width(d))
            slot = dr.arange(mi.UInt32, n_rays) * self.max_hits
            listed = dr.zeros(mi.UInt32, n_rays * self.max_hits)
        march = self._march_kbuffer if (self.kbuffer and not ad) else self._march_bvh
        acc, hits, count = march(gs, o0, d, active, ad, total, adjoint, ray_grad, weight, budget, listed, slot)
        if march == self._march_bvh:
            # One kernel per set: every set is its own scene, and OptiX (cuda variants) takes one shader binding
            # table per kernel, dropping the queries of any other scene in it. So the pass is evaluated here (its
            # totals or ray adjoints, its hit list, and in a replay its gradients' scatters), before a later pass
            # of another set can join its kernel (tests/test_kernels.py). The k-buffer rounds are evaluated anyway.
            dr.eval(acc, hits, listed, count)
        if info is not None:
            info["hits"] = hits
            info["list"] = (listed, count) if record else None
        return acc

    def _t_stop(self, weight):
        """Per ray, the transmittance at which a pass stops: weight * T < transmittance_min (weight None: 1)."""
        if weight is None:
            return mi.Float(self.transmittance_min)
        return dr.minimum(self.transmittance_min / dr.maximum(dr.detach(weight), self.transmittance_min), 1.0)

    @dr.syntax
    def _march_bvh(self, gs, o0, d, active, ad, total, adjoint, ray_grad, weight, budget, listed, slot):
        replay = adjoint is not None
        t_stop = self._t_stop(weight)
        bvh = gs.bvh_scene()
        origin = mi.Point3f(dr.detach(o0))
        dd = mi.Vector3f(dr.detach(d))
        # Mitsuba's shell test never reports a shell that contains the ray origin: walk from one shell diameter
        # behind the origin, and of the shells entered before the origin keep those that contain it.
        o = origin - dd * gs.reach if self.inside_origins else mi.Point3f(origin)
        T = mi.Float(1.0)
        acc = Composite()
        d_o, d_d = mi.Vector3f(0.0), mi.Vector3f(0.0)
        hits = mi.UInt32(0)
        last0, last1 = mi.UInt32(0xFFFFFFFF), mi.UInt32(0xFFFFFFFF)
        count = mi.UInt32(0)
        step = mi.Float(1.0)
        active = mi.Bool(active)
        while dr.hint(active, mode="evaluated" if ad else "symbolic", label=f"glint {gs.role}",
                      exclude=[listed, slot]):  # a scatter target and a read-only index, not loop state
            pi = bvh.ray_intersect_preliminary(mi.Ray3f(o, dd), coherent=False, active=active)
            hit = active & pi.is_valid()
            p = o + dd * pi.t
            # Just past a shell entry the float32 shell test can report the same primitive again: each Gaussian
            # counts once per pass (the last two are remembered) and the step grows until the ray leaves the band.
            new = hit & (pi.prim_index != last0) & (pi.prim_index != last1)
            # entered behind the origin: counts only if the shell holds the origin (and then not on the hit budget
            # when it does not)
            relevant = mi.Bool(True)
            if self.inside_origins:
                behind = new & (dr.dot(p - origin, dd) < 0)
                relevant = ~behind | self._contains(gs, pi.prim_index, origin, behind)
            fresh = new & relevant
            if dr.hint(listed is not None, mode="scalar"):  # recording: no scatter in other kernels
                dr.scatter(listed, pi.prim_index, slot + count, fresh)
            count = count + mi.UInt32(dr.select(fresh, 1, 0))
            if budget is None:
                acc, alpha, g_o, g_d = self._hit(gs, pi.prim_index, o0, d, fresh, T, acc, total, adjoint, ray_grad)
                d_o += g_o
                d_d += g_d
                T *= 1.0 - alpha
            o = dr.select(hit, p + dd * (_ray_epsilon(p) * step), o)
            step = dr.select(hit & ~new, step * 4.0, 1.0)
            last1 = dr.select(new, last0, last1)
            last0 = dr.select(new, pi.prim_index, last0)
            hits += mi.UInt32(dr.select(relevant, 1, 0))
            active = hit & (T > t_stop) & (hits < (self.max_hits if budget is None else budget))
        return ((d_o, d_d) if replay else acc), hits, count

    def _march_kbuffer(self, gs, o0, d, active, ad, total, adjoint, ray_grad, weight, budget, listed, slot):
        """:meth:`_march_bvh` with a k-buffer traversal (``traversal``: kbuffer, Embree's; shellbvh, our own BVH, on the
        host or on a CUDA device): rounds of one traversal per ray that lists its next ``kbuffer_k`` shell entries in order (shells that hold the origin
        first: no walk back), each followed by a Dr.Jit loop that composites them with the same arithmetic and the
        same stopping rule (T <= t_stop or the hit budget). Rays still going after a full buffer take another round."""
        replay = adjoint is not None
        n = max(dr.width(x) for x in (active, o0, d))
        t_stop = self._t_stop(weight)
        origin, dd = _widen(mi.Point3f(dr.detach(o0)), n), _widen(mi.Vector3f(dr.detach(d)), n)
        active = _widen(mi.Bool(active), n)
        t_stop = _widen(t_stop, n)
        dr.eval(origin, dd, active, t_stop)
        # host arrays (numpy, LLVM) or device arrays (CuPy by DLPack, the shell BVH on a CUDA variant)
        shells = gs.native(self.kbuffer_engine)
        on_device = getattr(shells, "xp_name", "numpy") == "cupy"
        if on_device:
            import cupy as xp
            arr = lambda v, dtype=None: (xp.from_dlpack(mi.UInt32(dr.select(v, 1, 0))) != 0 if dtype is bool
                                         else xp.from_dlpack(v))
            k_cap = min(self.kbuffer_k, DEVICE_K)
        else:
            xp = np
            arr = lambda v, dtype=None: np.asarray(v, dtype=dtype)
            k_cap = self.kbuffer_k
        xyz = lambda v: xp.stack([arr(v.x), arr(v.y), arr(v.z)], axis=1)
        sync = (lambda: (dr.sync_thread(), xp.cuda.get_current_stream().synchronize())) if on_device else (
            lambda: None)  # Dr.Jit and CuPy launch on their own streams: each waits for the other's writes
        sync()
        O, D, go = xyz(origin), xyz(dd), arr(active, bool).copy()
        # a round holds 12 bytes per ray and entry (prims and t from the traversal, the prims again for Dr.Jit): at
        # most KBUFFER_BYTES (a 1080p frame lists 10 entries per round)
        k = min(k_cap, max(4, KBUFFER_BYTES // (12 * n)))
        T, acc = dr.full(mi.Float, 1.0, n), _widen(Composite(), n)
        d_o, d_d = dr.zeros(mi.Vector3f, n), dr.zeros(mi.Vector3f, n)
        hits = dr.zeros(mi.UInt32, n)  # every listed entry composited is one hit: the list count is the hit count
        t_prev, p_prev = xp.full(n, -np.inf, xp.float32), xp.full(n, 0xFFFFFFFF, xp.uint32)
        rows = xp.arange(n)
        while bool(go.any()):
            prims, ts, cnt = shells.query(O, D, t_prev, p_prev, go, k, dr.thread_count(),
                                          out=None if on_device else _list_buffers(n, k))
            sync()
            T, acc, d_o, d_d, hits, more = self._kbuffer_round(
                gs, mi.UInt32(prims.ravel()), mi.UInt32(cnt), k, o0, d, t_stop, total, adjoint, ray_grad, budget,
                listed, slot, T, acc, d_o, d_d, hits)
            dr.eval(T, acc, d_o, d_d, hits, more, listed)
            sync()
            last = xp.maximum(cnt.astype(xp.int64) - 1, 0)
            t_prev = xp.where(cnt > 0, ts[rows, last], t_prev)
            p_prev = xp.where(cnt > 0, prims[rows, last], p_prev)
            go &= (cnt == k) & arr(more, bool)
        return ((d_o, d_d) if replay else acc), hits, hits

    @dr.syntax
    def _kbuffer_round(self, gs, prims, cnt, k_max, o0, d, t_stop, total, adjoint, ray_grad, budget, listed, slot,
                       T, acc, d_o, d_d, hits):
        """Composite one round's listed entries (``prims`` [rays x k_max], ``cnt`` per ray) in order."""
        limit = self.max_hits if budget is None else budget
        base = dr.arange(mi.UInt32, dr.width(cnt)) * k_max
        k = mi.UInt32(0)
        active = (k < cnt) & (T > t_stop) & (hits < limit)
        while dr.hint(active, mode="symbolic", label=f"glint {gs.role} k-buffer", exclude=[listed, slot]):
            prim = dr.gather(mi.UInt32, prims, base + k, active)
            if dr.hint(listed is not None, mode="scalar"):  # recording: no scatter in other kernels
                dr.scatter(listed, prim, slot + hits, active)
            if budget is None:
                acc, alpha, g_o, g_d = self._hit(gs, prim, o0, d, active, T, acc, total, adjoint, ray_grad)
                d_o += g_o
                d_d += g_d
                T *= 1.0 - alpha
            hits += mi.UInt32(dr.select(active, 1, 0))
            k += 1
            active &= (k < cnt) & (T > t_stop) & (hits < limit)
        return T, acc, d_o, d_d, hits, (T > t_stop) & (hits < limit)

    @dr.syntax
    def _replay_list(self, gs: GaussianSetRef, o0, d, active, total, adjoint, ray_grad, hit_list):
        """The replay of :meth:`march` over a stored hit list (no BVH query); returns the ray adjoints."""
        listed, count = hit_list
        slot = dr.arange(mi.UInt32, dr.width(count)) * self.max_hits
        T = mi.Float(1.0)
        acc = Composite()
        d_o, d_d = mi.Vector3f(0.0), mi.Vector3f(0.0)
        k = mi.UInt32(0)
        active = mi.Bool(active) & (count > 0)
        while dr.hint(active, mode="symbolic", label=f"glint {gs.role} list"):
            prim = dr.gather(mi.UInt32, listed, slot + k, active)
            acc, alpha, g_o, g_d = self._hit(gs, prim, o0, d, active, T, acc, total, adjoint, ray_grad)
            d_o += g_o
            d_d += g_d
            T *= 1.0 - alpha
            k += 1
            active &= k < count
        return d_o, d_d

    @staticmethod
    def _frame(gs: GaussianSetRef, prim_index, active):
        """(interaction, packed ellipsoid record, centre, rotation) of the primitives ``prim_index`` of a set."""
        si = dr.zeros(mi.SurfaceInteraction3f)
        si.prim_index = prim_index
        e = gs.shape.eval_attribute_x("ellipsoid", si, active)
        q = mi.Quaternion4f(e[6], e[7], e[8], e[9])
        qn = dr.norm(q)
        q = dr.select(qn > 1e-12, q / dr.maximum(qn, 1e-12), mi.Quaternion4f(0, 0, 0, 1))
        return si, e, mi.Point3f(e[0], e[1], e[2]), dr.quat_to_matrix(mi.Matrix3f, q)

    @staticmethod
    def _contains(gs: GaussianSetRef, prim_index, point, active):
        """Whether the bounding shell of each hit primitive contains ``point`` (detached)."""
        si, e, center, rot = GaussianPasses._frame(gs, prim_index, active)
        radius = gs.shape.eval_attribute_1("extent", si, active)
        local = rot.T @ (point - center)
        shell = dr.maximum(mi.Vector3f(e[3], e[4], e[5]) * radius, 1e-30)
        return active & (dr.squared_norm(local / shell) < 1.0)

    def _hit(self, gs, prim_index, o0, d, fresh, T, acc, total, adjoint, ray_grad):
        """One hit: forward, add its weighted features to ``acc``; replay (``adjoint`` given), also back-propagate:
        d(total)/d(params of this hit) = T d(alpha f) - S d(alpha) / (1 - alpha), with the suffix
        S = total - prefix (everything behind this hit, all of it scaled by 1 - alpha).
        Returns (new acc, alpha (detached in replay), origin adjoint, direction adjoint)."""
        zero = mi.Vector3f(0.0)
        median = lambda a: fresh & (T > 0.5) & (T * (1.0 - dr.detach(a)) <= 0.5)  # where T falls to 0.5
        if adjoint is None:
            alpha, t, n, c, beta, tau = self._eval_kernel(gs, prim_index, o0, d, fresh)
            return acc + Composite.of_hit(T * alpha, t, n, c, beta, tau, median(alpha)), alpha, zero, zero
        with dr.resume_grad():
            o_l, d_l = mi.Point3f(dr.detach(o0)), mi.Vector3f(dr.detach(d))
            if ray_grad:
                dr.enable_grad(o_l, d_l)
            alpha, t, n, c, beta, tau = self._eval_kernel(gs, prim_index, o_l, d_l, fresh)
            alpha_d = dr.detach(alpha)
            mine = Composite.of_hit(T * alpha, t, n, c, beta, tau, median(alpha_d))
            prefix = acc + mine.detached()
            suffix = (total - prefix).detached()
            Lo = mine + suffix.scaled((1.0 - alpha) / (1.0 - alpha_d))
            dr.backward_from(dr.select(fresh, adjoint.dot(Lo), 0.0), flags=dr.ADFlag.Default | dr.ADFlag.AllowNoGrad)
            g_o = mi.Vector3f(dr.grad(o_l)) if ray_grad else zero
            g_d = dr.grad(d_l) if ray_grad else zero
        return prefix, alpha_d, g_o, g_d
