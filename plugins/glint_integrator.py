"""The ``glint`` integrator: GLINT's first-order, Fresnel-weighted radiance transport over three Gaussian sets,
and the same transport as a first-order reference on mesh scenes with real glass.

.. pluginparameters::

 * - interface, transmission, reflection
   - |shape|
   - Nested ``glint_gaussians`` shapes, one per set. A missing set is a component switched off.
 * - ior
   - |float|
   - Index of refraction of the interface for Schlick's Fresnel, F0 = ((1 - n) / (1 + n))^2. (Default: 1.5)
 * - components
   - |string|
   - ``auto`` (default): trace a set only for rays whose weight is worth it (reflection where k_s > reflect_min,
     transmission where k_t > transmit_min; the skipped weight goes to the diffuse term, so weights still sum to
     1); ``all``: trace every present set for every ray (exact first-order model); or a comma list of the sets to
     use, e.g. ``interface,transmission``.
 * - reflect_min, transmit_min
   - |float|
   - Per-ray thresholds of ``auto``. (Default: 0.05, just above F0 = 0.04, and 1e-3)
 * - detach_depth
   - |bool|
   - Detach D_I where it places the secondary rays' origin x_I, as the paper does (gradients then reach the
     interface through its normal and weights only). (Default: true)
 * - max_order
   - |int|
   - 1: first order (the paper). 2: adds the release's second-surface reflection: the transmitted ray's own
     specular weight beta_T splits c_T into (1 - beta_T) c_T + beta_T c_R2, c_R2 traced from the transmission
     set's expected depth along reflect(d, N_T). (Default: 1)
 * - max_hits
   - |int|
   - Hit budget per ray and set. (Default: 256)
 * - alpha_min, alpha_max, transmittance_min
   - |float|
   - Compositing cut-offs: skip alpha below alpha_min, clamp alpha to alpha_max, stop once the transmittance falls
     below transmittance_min. (Default: 1/255, 0.99, 1e-4, as in the paper)
 * - aovs
   - |string|
   - Comma list of AOV groups: depth (planar camera z), normal (3, world), transparency, interface (3, c_I), reflection
     (3, c_R), transmission (3, c_T), alpha (A_I), weights (k_d, k_s, k_t), trans_direct (the transmission set seen
     straight from the camera: colour 3, depth, normal 3, alpha; an extra pass). (Default:
     depth,normal,transparency,interface,reflection,transmission,alpha)
 * - max_depth
   - |int|
   - Mesh mode: path depth of the ``path`` tracer that gives radiance beyond the glass. (Default: 64)

Gaussian mode (any set present): alpha_i = min(0.99, o_i G_i), skipped below 1/255, stop at transmittance 1e-4;
interface pass -> colour c_I, alpha A_I, expected distance D_I, normal N_I, beta_I, t; Schlick F with
cos = max(0, <-d, N_I>); k_s = clamp(beta + (1 - beta) F, F0, 1), k_d = (1 - k_s)(1 - t), k_t = (1 - k_s) t;
reflection from x_I = o + detach(D_I) d along reflect(d, N_I) (normal attached); transmission from x_I along d;
C = k_d c_I + k_s c_R + k_t c_T.

Mesh mode (no set present): at the first surface along the camera ray, a ``dielectric``/``thindielectric`` BSDF is
split by its own exact Fresnel into one mirror ray and one transmitted ray (straight for thin glass, refracted for
solid glass); each continues *through* further glass to the first opaque surface, whose radiance comes from
Mitsuba's ``path`` integrator. Non-glass pixels are plain ``path`` samples. Primal only.

Gradients: every AD mode evaluates the same code with Dr.Jit AD through evaluated loops (memory grows with
rays x hits; measured in ``benchmarks/bench_integrator.py``). Ray/shell intersections are detached; kernels,
compositing, Fresnel weights and the reflected direction are differentiated.
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi

from glint_mi import conventions as cv

from . import glint_gaussians

AOV_GROUPS = {
    "depth": ["depth"],
    "normal": ["nx", "ny", "nz"],
    "transparency": ["t"],
    "interface": ["cI.R", "cI.G", "cI.B"],
    "reflection": ["cR.R", "cR.G", "cR.B"],
    "transmission": ["cT.R", "cT.G", "cT.B"],
    "alpha": ["A"],
    "weights": ["kd", "ks", "kt"],
    "trans_direct": ["cTd.R", "cTd.G", "cTd.B", "depthT", "nTx", "nTy", "nTz", "AT"],
}
DEFAULT_AOVS = "depth,normal,transparency,interface,reflection,transmission,alpha"
ALPHA_MIN, ALPHA_MAX, T_MIN = 1.0 / 255.0, 0.99, 1e-4


class GaussianSetRef:
    """One set as the integrator sees it: its shape, kernel and the sub-scene holding its BVH."""

    def __init__(self, role: str, shape):
        meta = glint_gaussians.info(shape)
        if meta.role is not None and meta.role != role:
            raise ValueError(f"glint: the shape nested as '{role}' declares role '{meta.role}'.")
        self.role, self.shape, self.kernel, self.empty = role, shape, meta.kernel, meta.empty
        self.scene = mi.load_dict({"type": "scene", "gaussians": shape})


class Composite:
    """Accumulators of one alpha-compositing pass (front to back)."""

    def __init__(self, C, A, Dt, N, B, Tau):
        self.C, self.A, self.Dt, self.N, self.B, self.Tau = C, A, Dt, N, B, Tau

    @staticmethod
    def zeros(n=1):
        z = lambda t: dr.zeros(t, n)
        return Composite(z(mi.Color3f), z(mi.Float), z(mi.Float), z(mi.Vector3f), z(mi.Float), z(mi.Float))

    @property
    def depth(self):  # expected distance along the ray
        return dr.select(self.A > 0, self.Dt / dr.maximum(self.A, 1e-12), 0.0)

    @property
    def normal(self):  # normalised, 0 where nothing was hit
        n = dr.norm(self.N)
        return dr.select(n > 1e-12, self.N / dr.maximum(n, 1e-12), mi.Vector3f(0.0))


def schlick(cos_theta, f0):
    return f0 + (1.0 - f0) * dr.power(1.0 - cos_theta, 5)


def reflect(d, n):
    return d - 2.0 * dr.dot(d, n) * n


def _ray_epsilon(p):
    """Origin offset after a hit: ~8 float32 ulps of the coordinates, at least 1e-6 m (stable from 1e-3 to 1e4 m)."""
    return dr.maximum(1e-6, dr.max(dr.abs(p)) * 1e-6)


class GlintIntegrator(mi.ad.integrators.common.ADIntegrator):
    def __init__(self, props):
        super().__init__(props)
        self.max_depth = int(props.get("max_depth", 64))
        self.ior = float(props.get("ior", 1.5))
        if not self.ior > 1.0:
            raise ValueError(f"glint: 'ior' must be > 1 (got {self.ior}).")
        self.f0 = ((1.0 - self.ior) / (1.0 + self.ior)) ** 2
        self.detach_depth = bool(props.get("detach_depth", True))
        self.max_order = int(props.get("max_order", 1))
        if self.max_order not in (1, 2):
            raise ValueError(f"glint: 'max_order' must be 1 or 2 (got {self.max_order}).")
        self.max_hits = int(props.get("max_hits", 256))
        self.alpha_min = float(props.get("alpha_min", ALPHA_MIN))
        self.alpha_max = float(props.get("alpha_max", ALPHA_MAX))
        self.transmittance_min = float(props.get("transmittance_min", T_MIN))
        if not (0.0 <= self.alpha_min < self.alpha_max < 1.0 and 0.0 <= self.transmittance_min < 1.0):
            raise ValueError("glint: need 0 <= alpha_min < alpha_max < 1 and 0 <= transmittance_min < 1.")
        self.reflect_min = float(props.get("reflect_min", 0.05))
        self.transmit_min = float(props.get("transmit_min", 1e-3))
        comps = str(props.get("components", "auto")).replace(" ", "")
        self.auto = comps == "auto"
        if comps in ("auto", "all"):
            self.enabled = set(cv.ROLES)
        else:
            self.enabled = set(comps.split(","))
            bad = self.enabled - set(cv.ROLES)
            if bad:
                raise ValueError(f"glint: unknown component(s) {sorted(bad)} in 'components'; use auto, all or a "
                                 f"comma list of {cv.ROLES}.")
        groups = [g for g in str(props.get("aovs", DEFAULT_AOVS)).replace(" ", "").split(",") if g]
        bad = [g for g in groups if g not in AOV_GROUPS]
        if bad:
            raise ValueError(f"glint: unknown AOV group(s) {bad} in 'aovs'; choose from {list(AOV_GROUPS)}.")
        self.aov_groups = groups

        self.sets: dict[str, GaussianSetRef] = {}
        for name in props.keys():
            value = props.get(name)
            if isinstance(value, mi.Shape):
                meta = glint_gaussians.info(value)
                role = name if name in cv.ROLES else meta.role
                if role not in cv.ROLES:
                    raise ValueError(f"glint: nested shape '{name}' has no role; name it interface, transmission or "
                                     f"reflection, or give it a 'role' property.")
                if role in self.sets:
                    raise ValueError(f"glint: two shapes for the '{role}' set.")
                self.sets[role] = GaussianSetRef(role, value)
        if self.sets and "interface" not in self.sets:
            raise ValueError("glint: Gaussian mode needs an 'interface' set (the transmission and reflection sets are "
                             "traced from the interface's expected depth).")
        self._forward = mi.Vector3f(0, 0, 1)
        self._path = None

    # ------------------------------------------------------------------ API
    @property
    def mesh_mode(self) -> bool:
        return not self.sets

    def active_set(self, role):
        s = self.sets.get(role)
        return s if (s is not None and not s.empty and role in self.enabled) else None

    def aov_names(self):
        return [name for g in self.aov_groups for name in AOV_GROUPS[g]]

    def traverse(self, cb):
        # Keys read `<integrator>.<role>.<param>` (data, kernel_scales, opacities, sh_coeffs, specular, transparency)
        for role, s in self.sets.items():
            cb.put(role, s.shape, mi.ParamFlags.Differentiable)

    def parameters_changed(self, keys=[]):
        # A set's `data` changed: rebuild that sub-scene's BVH (the shape itself only marks itself dirty).
        for role, s in self.sets.items():
            if not keys or any(k == role or k.startswith(role + ".") for k in keys):
                s.scene.parameters_changed()

    def to_string(self):
        sets = ", ".join(f"{r}={s.kernel}{' (empty)' if s.empty else ''}" for r, s in self.sets.items())
        return f"GlintIntegrator[{sets or 'mesh mode'}, ior={self.ior}, max_order={self.max_order}]"

    def sample_rays(self, scene, sensor, sampler, *args):
        # The camera's forward axis converts expected distance to planar depth (see glint_mi.conventions).
        self._forward = mi.Vector3f(sensor.world_transform() @ mi.Vector3f(0, 0, 1))
        return super().sample_rays(scene, sensor, sampler, *args)

    def sample(self, mode, scene, sampler, ray, δL=None, state_in=None, active=True, **kwargs):
        primal = mode == dr.ADMode.Primal
        if self.mesh_mode:
            if not primal:
                raise RuntimeError("glint: mesh mode (no Gaussian sets) renders references only; it has no gradients.")
            out = self.trace_meshes(scene, sampler, mi.Ray3f(ray), mi.Bool(active))
        else:
            with dr.resume_grad(when=not primal):
                out = self.trace(mi.Ray3f(dr.detach(ray)), mi.Bool(active), ad=not primal,
                                 need=set(self.aov_groups))
        aovs = []
        for g in self.aov_groups:
            aovs += self._aov_values(g, out)
        return out["rgb"], mi.Bool(True), aovs, None

    def _aov_values(self, group, out):
        v = out[group]
        if group == "depth":
            return [v]
        if group in ("transparency", "alpha"):
            return [v]
        if group == "trans_direct":
            return [*v[0], v[1], *v[2], v[3]]
        return list(v)

    # ------------------------------------------------------------- kernels
    def _eval_kernel(self, gs: GaussianSetRef, prim_index, o0, d, active):
        """Alpha, distance along the ray, facing normal and attributes of hit primitives (differentiable)."""
        si = dr.zeros(mi.SurfaceInteraction3f)
        si.prim_index = prim_index
        shape = gs.shape
        e = shape.eval_attribute_x("ellipsoid", si, active)
        center = mi.Point3f(e[0], e[1], e[2])
        q = mi.Quaternion4f(e[6], e[7], e[8], e[9])
        qn = dr.norm(q)
        q = dr.select(qn > 1e-12, q / dr.maximum(qn, 1e-12), mi.Quaternion4f(0, 0, 0, 1))
        rot = dr.quat_to_matrix(mi.Matrix3f, q)
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

    @dr.syntax
    def composite(self, gs: GaussianSetRef, o0, d, active, ad: bool) -> Composite:
        """Front-to-back alpha compositing of one set along rays (o0, d); d may carry gradients."""
        o = mi.Point3f(dr.detach(o0))
        dd = mi.Vector3f(dr.detach(d))
        T = mi.Float(1.0)
        C, A, Dt = mi.Color3f(0.0), mi.Float(0.0), mi.Float(0.0)
        N, B, Tau = mi.Vector3f(0.0), mi.Float(0.0), mi.Float(0.0)
        hits = mi.UInt32(0)
        last0, last1 = mi.UInt32(0xFFFFFFFF), mi.UInt32(0xFFFFFFFF)
        step = mi.Float(1.0)
        active = mi.Bool(active)
        while dr.hint(active, mode="evaluated" if ad else "symbolic", label=f"glint {gs.role}"):
            pi = gs.scene.ray_intersect_preliminary(mi.Ray3f(o, dd), coherent=False, active=active)
            hit = active & pi.is_valid()
            # Just past a shell entry the float32 shell test can report the same primitive again: each Gaussian
            # counts once per pass (the last two are remembered) and the step grows until the ray leaves the band.
            fresh = hit & (pi.prim_index != last0) & (pi.prim_index != last1)
            alpha, t, n, c, beta, tau = self._eval_kernel(gs, pi.prim_index, o0, d, fresh)
            w = T * alpha
            C += w * c
            A += w
            Dt += w * t
            N += w * n
            B += w * beta
            Tau += w * tau
            T *= 1.0 - alpha
            p = o + dd * pi.t
            o = dr.select(hit, p + dd * (_ray_epsilon(p) * step), o)
            step = dr.select(hit & ~fresh, step * 4.0, 1.0)
            last1 = dr.select(fresh, last0, last1)
            last0 = dr.select(fresh, pi.prim_index, last0)
            hits += 1
            active = hit & (T > self.transmittance_min) & (hits < self.max_hits)
        return Composite(C, A, Dt, N, B, Tau)

    # ------------------------------------------------------ Gaussian mode
    def trace(self, ray: mi.Ray3f, active, ad: bool = False, need=frozenset(), forward=None) -> dict:
        """All buffers of the GLINT image model for a batch of rays (Dr.Jit arrays, differentiable when ``ad``).

        Returns a dict with ``rgb`` (Color3f) and the AOV groups in ``need`` (see AOV_GROUPS), plus the raw pieces
        ``kd ks kt`` and ``distance`` (expected distance along the ray).
        """
        forward = self._forward if forward is None else forward
        o, d = ray.o, ray.d
        zero = Composite.zeros()
        I = self.composite(self.sets["interface"], o, d, active, ad) if self.active_set("interface") else zero
        has = I.A > 0
        n_hat = I.normal
        cos = dr.select(dr.squared_norm(n_hat) > 0, dr.maximum(0.0, dr.dot(-d, n_hat)), 1.0)
        F = schlick(cos, self.f0)
        ks = dr.clip(I.B + (1.0 - I.B) * F, self.f0, 1.0)
        kd = (1.0 - ks) * (1.0 - I.Tau)
        kt = (1.0 - ks) * I.Tau
        ks, kt, kd = dr.select(has, ks, 0.0), dr.select(has, kt, 0.0), dr.select(has, kd, 1.0)

        refl, trans = self.active_set("reflection"), self.active_set("transmission")
        do_r = active & has & (ks > (self.reflect_min if self.auto else 0.0)) & (refl is not None)
        do_t = active & has & (kt > (self.transmit_min if self.auto else 0.0)) & (trans is not None)
        if self.auto:  # skipped weight goes to the diffuse term, keeping k_d + k_s + k_t = 1
            kd = kd + dr.select(~do_r & (refl is not None), ks, 0.0) + dr.select(~do_t & (trans is not None), kt, 0.0)
            ks = dr.select(do_r | (refl is None), ks, 0.0)
            kt = dr.select(do_t | (trans is None), kt, 0.0)

        x_i = o + (dr.detach(I.depth) if self.detach_depth else I.depth) * d
        cR = cT = mi.Color3f(0.0)
        if refl is not None:
            cR = self.composite(refl, x_i, reflect(d, n_hat), do_r, ad).C
        if trans is not None:
            Tr = self.composite(trans, x_i, d, do_t, ad)
            cT = Tr.C
            if self.max_order == 2 and refl is not None:
                # The release's second-surface reflection, split by the transmitted ray's own specular weight.
                x_t = x_i + (dr.detach(Tr.depth) if self.detach_depth else Tr.depth) * d
                do_r2 = do_t & (Tr.A > 0) & (Tr.B > (1e-3 if self.auto else 0.0))
                cR2 = self.composite(refl, x_t, reflect(d, Tr.normal), do_r2, ad).C
                cT = (1.0 - Tr.B) * cT + Tr.B * cR2
        rgb = kd * I.C + ks * cR + kt * cT

        out = {"rgb": mi.Spectrum(rgb), "kd": kd, "ks": ks, "kt": kt, "distance": I.depth,
               "depth": I.depth * dr.dot(d, forward), "normal": n_hat, "transparency": I.Tau,
               "interface": I.C, "reflection": cR, "transmission": cT, "alpha": I.A, "weights": (kd, ks, kt)}
        if "trans_direct" in need:
            D = self.composite(trans, o, d, active, ad) if trans is not None else zero
            out["trans_direct"] = (D.C, D.depth * dr.dot(d, forward), D.normal, D.A)
        return out

    # ----------------------------------------------------------- mesh mode
    def _path_tracer(self):
        if self._path is None:
            self._path = mi.load_dict({"type": "path", "max_depth": self.max_depth, "hide_emitters": False})
        return self._path

    @staticmethod
    def _is_glass(si):
        # dielectric: delta transmission; thindielectric: delta reflection + a Null (straight-through) lobe
        flags = si.bsdf().flags()
        thin = mi.has_flag(flags, mi.BSDFFlags.Null) & mi.has_flag(flags, mi.BSDFFlags.DeltaReflection)
        return si.is_valid() & (mi.has_flag(flags, mi.BSDFFlags.DeltaTransmission) | thin)

    @dr.syntax
    def _through_glass(self, scene, ray, active):
        """Advance rays past every glass surface they meet; returns rays whose first hit is opaque (or none)."""
        ray = mi.Ray3f(ray)
        active = mi.Bool(active)
        steps = mi.UInt32(0)
        while dr.hint(active, label="glint skip glass"):
            si = scene.ray_intersect(ray, active)
            glass = active & self._is_glass(si)
            ray[glass] = si.spawn_ray(ray.d)
            steps += 1
            active = glass & (steps < self.max_hits)
        return ray

    def trace_meshes(self, scene, sampler, ray, active) -> dict:
        """First-order reference on a mesh scene: one Fresnel split at the first glass surface (primal only)."""
        path = self._path_tracer()
        si = scene.ray_intersect(ray, active)
        glass = active & self._is_glass(si)
        # Non-glass pixels first, so they consume the sampler exactly like a plain `path` render.
        L_direct, _, _ = path.sample(scene, sampler, ray, None, active & ~glass)

        ctx = mi.BSDFContext()
        bsdf = si.bsdf()
        # sample1 = 0 always picks the reflection lobe and 1 the transmission lobe; pdf is then F resp. 1 - F.
        bs_r, w_r = bsdf.sample(ctx, si, 0.0, mi.Point2f(0.5), glass)
        bs_t, w_t = bsdf.sample(ctx, si, 1.0 - 1e-6, mi.Point2f(0.5), glass)
        ok_r = glass & (bs_r.pdf > 0) & mi.has_flag(bs_r.sampled_type, mi.BSDFFlags.Reflection)
        ok_t = glass & (bs_t.pdf > 0) & (mi.has_flag(bs_t.sampled_type, mi.BSDFFlags.Transmission)
                                         | mi.has_flag(bs_t.sampled_type, mi.BSDFFlags.Null))
        F = dr.select(ok_r, bs_r.pdf, 0.0)
        ray_r = self._through_glass(scene, si.spawn_ray(si.to_world(bs_r.wo)), ok_r)
        ray_t = self._through_glass(scene, si.spawn_ray(si.to_world(bs_t.wo)), ok_t)
        L_r, _, _ = path.sample(scene, sampler, ray_r, None, ok_r)
        L_t, _, _ = path.sample(scene, sampler, ray_t, None, ok_t)
        L_r = dr.select(ok_r, mi.Spectrum(w_r) * L_r, 0.0)
        L_t = dr.select(ok_t, mi.Spectrum(w_t) * L_t, 0.0)
        kt = dr.select(ok_t, bs_t.pdf, 0.0)
        rgb = dr.select(glass, F * L_r + kt * L_t, L_direct)

        valid = active & si.is_valid()
        dist = dr.select(valid, si.t, 0.0)
        n = dr.select(valid, dr.select(dr.dot(si.n, ray.d) > 0, -si.n, si.n), mi.Vector3f(0.0))
        zero3 = mi.Color3f(0.0)
        tmask = dr.select(glass, 1.0, 0.0)
        kd = dr.select(glass, 0.0, 1.0)
        return {"rgb": rgb, "kd": kd, "ks": F, "kt": kt, "distance": dist, "depth": dist * dr.dot(ray.d, self._forward),
                "normal": n, "transparency": tmask, "interface": dr.select(glass, zero3, mi.Color3f(L_direct)),
                "reflection": mi.Color3f(L_r), "transmission": mi.Color3f(L_t),
                "alpha": dr.select(valid, 1.0, 0.0), "weights": (kd, F, kt),
                "trans_direct": (zero3, mi.Float(0.0), mi.Vector3f(0.0), mi.Float(0.0))}


def register() -> None:
    mi.register_integrator("glint", lambda props: GlintIntegrator(props))
