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
 * - blend
   - |string|
   - How the components are weighted. ``fresnel`` (default): GLINT's Schlick weights. ``envgs``: EnvGS's blend
     k_s = beta, k_d = 1 - beta, k_t = 0. ``alpha``: plain front-to-back alpha compositing of the interface,
     C = sum T_i alpha_i c_i (k_d = 1, no specular, no transparency), as 3DGS / 2DGS / PGSR composite. ``refgs``:
     Ref-GS's deferred shading of the interface alone, C = srgb(c_I + s), s read from a directional grid at the
     reflection of the composited normal, blurred by the composited beta as roughness (``glint_env``).
     A set that is absent (switched off, or dropped by a run's ``components: auto``) gives its weight to the
     diffuse term, so the image is never darkened by a missing component. The boolean ``fresnel`` of older
     scenes is read as ``fresnel`` (true) or ``envgs`` (false).
 * - env_levels, env_file
   - |int|, |string|
   - ``refgs`` only: mip levels of the directional grid (2^L x 2^(L+1) texels; default 7) and the ``.npy`` of its
     [h, w, 3] log-radiance that a trained model writes (``env.npy``; default: the initial grid).
 * - reflect_min, transmit_min
   - |float|
   - Per-ray thresholds of ``auto``. (Default: 0.05, just above F0 = 0.04, and 1e-3)
 * - gradient
   - |string|
   - Reverse-mode method: ``replay`` (default; path replay, memory independent of the number of hits) or ``ad``
     (plain Dr.Jit AD through evaluated loops; memory grows with rays x hits; the reference the replay is tested
     against). Forward-mode AD always uses ``ad``.
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
 * - stored_hits_mb
   - |float|
   - mi.render's backward: the forward stores each pass's hit list (rays x max_hits x 4 bytes per pass) and the
     replay walks it instead of re-running the BVH queries - exact, and about half the time of a gradient - when
     the lists of all passes fit in this many MiB; otherwise the replay re-traces. (Default: 1024)
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
 * - inside_origins
   - |bool|
   - ``true`` (default): a Gaussian whose bounding shell contains the ray origin is composited like any other (its
     kernel counted where it lies ahead of the origin): each pass starts its BVH walk one shell diameter behind the
     origin. ``false``: Mitsuba's shell test alone, which never reports a shell around the origin (such Gaussians
     are invisible; kept to measure what the walk back costs).
 * - traversal
   - |string|
   - How each pass finds the shells along a ray. ``kbuffer``: the native traversal of :mod:`glint_mi.native`
     (Embree, as shipped in the mitsuba wheel, built with the system C++ compiler): one traversal lists a ray's
     next ``kbuffer_k`` shell entries in order, shells that hold the origin first. ``bvh``: one Mitsuba
     ``ray_intersect_preliminary`` from the BVH root per hit, walking back one shell diameter behind the origin
     (the plain-AD path ``gradient=ad`` always uses it). ``shellbvh``: the same k-buffer lists from our own BVH
     (``glint_mi/native/shellbvh.h``), code that runs on the host and, under a CUDA variant, on the device
     (compiled by NVRTC through CuPy; at most 32 entries a round there). ``auto`` (default): kbuffer when the
     library is built and the variant is LLVM, else bvh. They composite in order of shell entry; kbuffer and
     shellbvh list the same entries, and differ from bvh only where float32 shell tests disagree (tested against
     each other and a float64 brute force).
 * - kbuffer_k
   - |int|
   - Shell entries listed per traversal (a round); rays still going take another round. Any size gives the same
     image; the default lists the whole hit budget in one round (each further round re-traverses the BVH and traces
     another compositing kernel: 64 at a 256-hit budget made training steps 1.18-1.29x slower), capped so that a round's
     buffers stay under 256 MiB (12 bytes per ray and entry). (Default: ``max_hits``)
 * - max_depth
   - |int|
   - Mesh mode: path depth of the ``path`` tracer that gives radiance beyond the glass. (Default: 64)

Gaussian mode (any set present): alpha_i = min(0.99, o_i G_i), skipped below 1/255, stop at transmittance 1e-4
(secondary passes stop once k T < 1e-4, k their weight in the pixel: the same bound on missed radiance);
interface pass -> colour c_I, alpha A_I, expected distance D_I, normal N_I, beta_I, t; Schlick F with
cos = max(0, <-d, N_I>); k_s = clamp(beta + (1 - beta) F, F0, 1), k_d = (1 - k_s)(1 - t), k_t = (1 - k_s) t;
reflection from x_I = o + detach(D_I) d along reflect(d, N_I) (normal attached); transmission from x_I along d;
C = k_d c_I + k_s c_R + k_t c_T.

Mesh mode (no set present): at the first surface along the camera ray, a ``dielectric``/``thindielectric`` BSDF is
split by its own exact Fresnel into one mirror ray and one transmitted ray (straight for thin glass, refracted for
solid glass); each continues *through* further glass to the first opaque surface, whose radiance comes from
Mitsuba's ``path`` integrator. Non-glass pixels are plain ``path`` samples. Primal only.

Gradients: reverse mode replays every pass hit by hit in symbolic loops (constant memory, see :meth:`backward`);
forward mode and ``gradient = ad`` run plain Dr.Jit AD through evaluated loops. Ray/shell intersections are
detached; kernels, compositing, Fresnel weights, the reflected direction (hence interface normals) and every AOV are
differentiated.
"""
from __future__ import annotations

import contextlib

import drjit as dr
import mitsuba as mi

import glint_mi.conventions as cv
import glint_mi.native as native
from glint_mi.model.render import AOV_GROUPS, from_pinhole

from . import glint_gaussians
from .glint_composite import Composite, GaussianSetRef, _widen  # noqa: F401  (re-exported)
from .glint_env import DirectionalGrid, reflect, refgs_shade
from .glint_march import KBUFFER_BYTES, GaussianPasses  # noqa: F401
from .glint_mesh import first_surface, is_glass, trace_meshes  # noqa: F401

DEFAULT_AOVS = "depth,normal,transparency,interface,reflection,transmission,alpha"
ALPHA_MIN, ALPHA_MAX, T_MIN = 1.0 / 255.0, 0.99, 1e-4
BLENDS = ("fresnel", "envgs", "alpha", "refgs")
TRAVERSALS = ("auto", "kbuffer", "shellbvh", "bvh")


def shellbvh_why_not() -> str:
    """Why ``traversal: shellbvh`` cannot run in this process ('' if it can): the native library is needed to build
    the tree, and under a CUDA variant CuPy (NVRTC) and a device to run it."""
    why = native.why_not()
    if why or (mi.variant() or "").startswith("llvm"):
        return why
    from glint_mi.native import cuda
    return cuda.why_not()


def schlick(cos_theta, f0):
    return f0 + (1.0 - f0) * dr.power(1.0 - cos_theta, 5)


def _read_env(filename: str):
    """An env_file's [h, w, 3] log-radiance grid (.npy, as a trained refgs model writes it), or None (initial)."""
    if not filename:
        return None
    import numpy as np

    path = mi.file_resolver().resolve(filename)
    try:
        return np.load(str(path))
    except (OSError, ValueError) as e:
        raise ValueError(f"glint: cannot read env_file '{path}' ({e}); it is the model's env.npy, written by "
                         f"training with blend refgs.") from e


def stored_lists_mb(n_rays: int, max_hits: int) -> float:
    """MiB the stored hit lists of ``n_rays`` rays take: n_rays x max_hits x 4 bytes for each of up to five passes
    (the one definition: the integrator's ``lists_fit``, the trainer's note and the presets' tests read it)."""
    return n_rays * max_hits * 4 * 5 / 2 ** 20


def _adjoint_dot(out: dict, adjoints: dict):
    """sum_k <adjoints[k], out[k]> per ray, over rgb and AOV groups (tuples are dotted entry-wise)."""
    total = mi.Float(0.0)
    for key, adj in adjoints.items():
        value = out[key]
        pairs = zip(adj, value) if isinstance(value, tuple) else [(adj, value)]
        for a, v in pairs:
            total += dr.dot(a, v) if dr.size_v(v) == 3 else a * v
    return total


def _group_value(group: str, vals: list):
    """Per-channel AOV floats -> the structured value of that group in trace()'s output."""
    if group in ("depth", "transparency", "alpha"):
        return vals[0]
    if group == "normal":
        return mi.Vector3f(*vals)
    if group == "weights":
        return tuple(vals)
    if group == "trans_direct":
        return (mi.Color3f(*vals[0:3]), vals[3], mi.Vector3f(*vals[4:7]), vals[7])
    return mi.Color3f(*vals)


# every property the integrator reads (besides the nested Gaussian shapes)
PROPERTIES = ("components", "max_order", "max_hits", "blend", "traversal", "aovs", "ior", "max_depth", "dataset",
              "detach_depth", "gradient", "stored_hits_mb", "alpha_min", "alpha_max", "transmittance_min",
              "inside_origins", "kbuffer_k", "fresnel", "env_levels", "env_file", "reflect_min", "transmit_min")


class GlintIntegrator(GaussianPasses):
    """The image model. One set's passes are :class:`~.glint_march.GaussianPasses`, mesh mode
    :func:`~.glint_mesh.trace_meshes`."""

    def __init__(self, props):
        super().__init__(props)
        self.max_depth = int(props.get("max_depth", 64))
        self.dataset = str(props.get("dataset", ""))  # the training data of an optimisation scene (glint_mi.scene)
        self.ior = float(props.get("ior", 1.5))
        if not self.ior > 1.0:
            raise ValueError(f"glint: 'ior' must be > 1 (got {self.ior}).")
        self.f0 = ((1.0 - self.ior) / (1.0 + self.ior)) ** 2
        self.detach_depth = bool(props.get("detach_depth", True))
        self.gradient = str(props.get("gradient", "replay"))
        if self.gradient not in ("replay", "ad"):
            raise ValueError(f"glint: 'gradient' must be 'replay' or 'ad' (got '{self.gradient}').")
        self.max_order = int(props.get("max_order", 1))
        if self.max_order not in (1, 2):
            raise ValueError(f"glint: 'max_order' must be 1 or 2 (got {self.max_order}).")
        self.max_hits = int(props.get("max_hits", 256))
        self.stored_hits_mb = float(props.get("stored_hits_mb", 1024.0))
        self.alpha_min = float(props.get("alpha_min", ALPHA_MIN))
        self.alpha_max = float(props.get("alpha_max", ALPHA_MAX))
        self.transmittance_min = float(props.get("transmittance_min", T_MIN))
        self.inside_origins = bool(props.get("inside_origins", True))
        traversal = str(props.get("traversal", "auto"))
        if traversal not in TRAVERSALS:
            raise ValueError(f"glint: 'traversal' must be one of {', '.join(TRAVERSALS)} (got '{traversal}').")
        self.kbuffer_k = int(props.get("kbuffer_k", self.max_hits))
        if self.kbuffer_k < 1:
            raise ValueError(f"glint: 'kbuffer_k' must be >= 1 (got {self.kbuffer_k}).")
        self.kbuffer, self.kbuffer_engine = False, "embree"
        if traversal == "shellbvh":
            why = shellbvh_why_not()
            if why:
                raise ValueError(f"glint: traversal=shellbvh is unavailable: {why}. Use traversal=bvh.")
            self.kbuffer, self.kbuffer_engine = True, "shellbvh"
        elif traversal != "bvh":
            why = native.why_not_here()
            if why and traversal == "kbuffer":
                raise ValueError(f"glint: traversal=kbuffer is unavailable: {why}. Use traversal=bvh, or build it "
                                 f"with `python -m glint_mi.native`.")
            self.kbuffer = not why and self.inside_origins  # without inside origins: Mitsuba's shell test, as it was
        if self.kbuffer and not self.inside_origins:
            raise ValueError("glint: a k-buffer traversal lists the shells that hold the ray origin: it needs "
                             "inside_origins=true (or use traversal=bvh).")
        if not (0.0 <= self.alpha_min < self.alpha_max < 1.0 and 0.0 <= self.transmittance_min < 1.0):
            raise ValueError("glint: need 0 <= alpha_min < alpha_max < 1 and 0 <= transmittance_min < 1.")
        legacy = "fresnel" if bool(props.get("fresnel", True)) else "envgs"
        self.blend = str(props.get("blend", legacy))
        if self.blend not in BLENDS:
            raise ValueError(f"glint: 'blend' must be one of {', '.join(BLENDS)} (got '{self.blend}').")
        self.env = None  # refgs: Ref-GS's directional grid (glint_env), read at the composited normal's reflection
        if self.blend == "refgs":
            self.env = DirectionalGrid(int(props.get("env_levels", 7)), _read_env(str(props.get("env_file", ""))))
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

        unqueried = props.unqueried()  # before the loop below reads every property
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
        unknown = [n for n in unqueried if not isinstance(props.get(n), mi.Object)]
        if unknown:  # a misspelled property would otherwise be ignored without a word
            import difflib

            near = {n: difflib.get_close_matches(n, PROPERTIES, n=1) for n in unknown}
            raise ValueError("glint: unknown propert" + ("ies " if len(unknown) > 1 else "y ")
                             + ", ".join(f"'{n}'" + (f" (did you mean '{near[n][0]}'?)" if near[n] else "")
                                         for n in unknown)
                             + f"; the integrator's properties are {', '.join(PROPERTIES)}.")
        self._forward = mi.Vector3f(0, 0, 1)
        self._path = None

    # ------------------------------------------------------------------ API
    @property
    def mesh_mode(self) -> bool:
        return not self.sets

    def active_set(self, role):
        s = self.sets.get(role)
        return s if (s is not None and not s.empty and role in self.enabled) else None

    def select(self, roles) -> None:
        """Trace the sets ``roles`` from now on (of those the integrator holds; e.g. the sets a trained model kept)."""
        roles = set(roles)
        bad = roles - set(cv.ROLES)
        if bad:
            raise ValueError(f"glint: unknown set(s) {sorted(bad)}; the sets are {', '.join(cv.ROLES)}.")
        self.enabled = roles

    @contextlib.contextmanager
    def tracing(self, roles):
        """Trace only the sets ``roles`` inside the block (a training stage's sets, the interface alone for a depth
        render); the sets traced before come back after it, also when the block raises."""
        before = self.enabled
        self.select(roles)
        try:
            yield self
        finally:
            self.enabled = before

    def lists_mb(self, n_rays: int) -> float:
        """MiB the stored hit lists of ``n_rays`` rays take (:func:`stored_lists_mb` at this integrator's budget)."""
        return stored_lists_mb(n_rays, self.max_hits)

    def lists_fit(self, n_rays: int, budget_mb: float | None = None) -> bool:
        """Whether the stored hit lists of ``n_rays`` rays fit in ``budget_mb`` MiB (default: ``stored_hits_mb``); a
        batch that does not re-traces in the replay."""
        return self.lists_mb(n_rays) <= (self.stored_hits_mb if budget_mb is None else budget_mb)

    def aov_names(self):
        return [name for g in self.aov_groups for name in AOV_GROUPS[g]]

    def traverse(self, cb):
        # Keys read `<integrator>.<role>.<param>` (data, kernel_scales, opacities, sh_coeffs, specular, transparency)
        for role, s in self.sets.items():
            cb.put(role, s.shape, mi.ParamFlags.Differentiable)

    def parameters_changed(self, keys=[]):
        # A set changed: its Mitsuba BVH is rebuilt when a bvh traversal next needs it, its native shells on the
        # next k-buffer query (the shape itself only marks itself dirty).
        for role, s in self.sets.items():
            if not keys or any(k == role or k.startswith(role + ".") for k in keys):
                s.bvh_stale = True
                s.refresh()

    def to_string(self):
        sets = ", ".join(f"{r}={s.kernel}{' (empty)' if s.empty else ''}" for r, s in self.sets.items())
        return f"GlintIntegrator[{sets or 'mesh mode'}, ior={self.ior}, max_order={self.max_order}]"

    def sample_rays(self, scene, sensor, sampler, *args):
        # The camera's forward axis converts expected distance to planar depth (see glint_mi.conventions).
        self._forward = mi.Vector3f(sensor.world_transform() @ mi.Vector3f(0, 0, 1))
        ray, weight, pos = super().sample_rays(scene, sensor, sampler, *args)
        return from_pinhole(sensor, ray), weight, pos

    def sample(self, mode, scene, sampler, ray, δL=None, state_in=None, active=True, **kwargs):
        primal = mode == dr.ADMode.Primal
        if self.mesh_mode:
            if not primal:
                raise RuntimeError("glint: mesh mode (no Gaussian sets) renders references only; it has no gradients.")
            if self._path is None:
                self._path = mi.load_dict({"type": "path", "max_depth": self.max_depth, "hide_emitters": False})
            out = trace_meshes(self._path, scene, sampler, mi.Ray3f(ray), mi.Bool(active), self._forward,
                               self.max_hits)
        else:
            with dr.resume_grad(when=not primal):
                out = self.trace(mi.Ray3f(dr.detach(ray)), mi.Bool(active), ad=not primal,
                                 need=set(self.aov_groups))
        aovs = []
        for g in self.aov_groups:
            aovs += self._aov_values(g, out)
        return out["rgb"], mi.Bool(True), aovs, None

    def render_backward(self, scene, params, grad_in, sensor=0, seed=0, spp=0):
        if self.mesh_mode:
            raise RuntimeError("glint: mesh mode (no Gaussian sets) renders references only; it has no gradients.")
        if self.gradient == "ad":
            return super().render_backward(scene, params, grad_in, sensor, seed, spp)
        if isinstance(sensor, int):
            sensor = scene.sensors()[sensor]
        film = sensor.film()
        with dr.suspend_grad():
            sampler, spp = self.prepare(sensor, seed, spp, self.aov_names())
            ray, weight, pos = self.sample_rays(scene, sensor, sampler)
            # The splat + develop steps are linear: differentiating them at unit values gives each sample's adjoint.
            with dr.resume_grad():
                L = dr.full(mi.Spectrum, 1.0, dr.width(ray))
                aovs = [dr.full(mi.Float, 1.0, dr.width(ray)) for _ in self.aov_names()]
                dr.enable_grad(L, aovs)
                block = film.create_block()
                block.set_coalesce(block.coalesce() and spp >= 4)
                # (Mitsuba's RB integrators multiply float AOVs by the Spectrum weight; take its scalar channel)
                splat = mi.ad.integrators.common.ADIntegrator._splat_to_block
                splat(block, film, pos, value=L * weight, weight=1.0, alpha=1.0,
                      aovs=[a * weight[0] for a in aovs], wavelengths=ray.wavelengths)
                film.put_block(block)
                image = film.develop()
                dr.set_grad(image, grad_in)
                dr.enqueue(dr.ADMode.Backward, image)
                dr.traverse(dr.ADMode.Backward)
                dL, daovs = dr.grad(L), dr.grad(aovs)
            film.clear()
            ray = mi.Ray3f(dr.detach(ray))
            record = self.lists_fit(dr.width(ray))
            out = self.trace(ray, mi.Bool(True), need=set(self.aov_groups), record=record)
            adjoints, k = {"rgb": dL}, 0
            for g in self.aov_groups:
                n = len(AOV_GROUPS[g])
                vals = daovs[k:k + n]
                k += n
                adjoints[g] = _group_value(g, vals)
            self.backward(ray, mi.Bool(True), out, adjoints)
            dr.eval()

    def _aov_values(self, group, out):
        v = out[group]
        if group == "depth":
            return [v]
        if group in ("transparency", "alpha"):
            return [v]
        if group == "trans_direct":
            return [*v[0], v[1], *v[2], v[3]]
        return list(v)

    # ------------------------------------------------------ Gaussian mode
    def _weights(self, I: Composite, d, active):
        """Fresnel weights and which secondary rays to trace; returns (kd, ks, kt, do_r, do_t)."""
        has = I.A > 0
        n_hat = I.normal
        cos = dr.select(dr.squared_norm(n_hat) > 0, dr.maximum(0.0, dr.dot(-d, n_hat)), 1.0)
        if self.blend == "fresnel":
            ks = dr.clip(I.B + (1.0 - I.B) * schlick(cos, self.f0), self.f0, 1.0)
            kd, kt = (1.0 - ks) * (1.0 - I.Tau), (1.0 - ks) * I.Tau
        elif self.blend == "envgs":
            ks = dr.clip(I.B, 0.0, 1.0)
            kd, kt = 1.0 - ks, mi.Float(0.0)
        else:  # alpha, refgs: the interface alone, composited front to back (refgs adds its specular in _combine)
            ks, kt, kd = mi.Float(0.0), mi.Float(0.0), mi.Float(1.0)
        ks, kt, kd = dr.select(has, ks, 0.0), dr.select(has, kt, 0.0), dr.select(has, kd, 1.0)
        refl, trans = self.active_set("reflection"), self.active_set("transmission")
        # an absent set's weight goes to the diffuse term: C = (k_d + k_s) c_I + k_t c_T without reflections, etc.
        if refl is None:
            kd, ks = kd + ks, mi.Float(0.0)
        if trans is None:
            kd, kt = kd + kt, mi.Float(0.0)
        do_r = mi.Bool(dr.detach(active & has & (ks > (self.reflect_min if self.auto else 0.0)))) & (refl is not None)
        do_t = mi.Bool(dr.detach(active & has & (kt > (self.transmit_min if self.auto else 0.0)))) & (trans is not None)
        if self.auto:  # skipped weight goes to the diffuse term, keeping k_d + k_s + k_t = 1
            kd = kd + dr.select(~do_r, ks, 0.0) + dr.select(~do_t, kt, 0.0)
            ks, kt = dr.select(do_r, ks, 0.0), dr.select(do_t, kt, 0.0)
        return kd, ks, kt, do_r, do_t

    def _secondary(self, I: Composite, o, d):
        """Origin x_I and mirror direction of the secondary rays (the transmitted ray keeps d)."""
        depth = dr.detach(I.depth) if self.detach_depth else I.depth
        return o + depth * d, reflect(d, I.normal)

    def _second_order(self, x_i, Tr: Composite, d, do_t):
        """The release's second-surface reflection ray, from the transmission set's expected depth."""
        depth = dr.detach(Tr.depth) if self.detach_depth else Tr.depth
        do_r2 = mi.Bool(dr.detach(do_t & (Tr.A > 0) & (Tr.B > (1e-3 if self.auto else 0.0))))
        return x_i + depth * d, reflect(d, Tr.normal), do_r2

    def _combine(self, I, R, Tr, R2, D, weights, d, forward, order2: bool) -> dict:
        kd, ks, kt = weights[:3]
        cT = (1.0 - Tr.B) * Tr.C + Tr.B * R2.C if order2 else Tr.C
        if self.blend == "refgs":  # deferred: srgb(albedo + grid(reflect(d, N), beta as roughness))
            rgb = refgs_shade(I.C, I.A, I.B, I.normal, d, self.env)
        else:
            rgb = kd * I.C + ks * R.C + kt * cT
        z = dr.dot(d, forward)
        return {"rgb": mi.Spectrum(rgb), "kd": kd, "ks": ks, "kt": kt, "distance": I.depth,
                "depth": I.depth * z, "normal": I.normal, "transparency": I.Tau, "interface": I.C,
                "reflection": R.C, "transmission": cT, "alpha": I.A, "weights": (kd, ks, kt),
                "distortion": I.distortion, "median": I.Med,
                "trans_direct": (D.C, D.depth * z, D.normal, D.A)}

    def trace(self, ray: mi.Ray3f, active, ad: bool = False, need=frozenset(), forward=None,
              record: bool = False) -> dict:
        """All buffers of the GLINT image model for a batch of rays (Dr.Jit arrays; plain AD when ``ad``).

        Returns ``rgb`` (Spectrum), the AOV groups of AOV_GROUPS (``trans_direct`` only if in ``need``, else zeros),
        ``kd ks kt``, ``distance`` (expected distance along the ray) and ``passes``, the per-set composites that
        :meth:`backward` replays; with ``record``, also ``hit_lists``, each pass's stored hit list (see :meth:`march`),
        which the replay then walks instead of re-running the BVH queries (exact; memory rays x max_hits x 4 bytes
        per pass, so meant for training batches, not full-image renders).
        """
        forward = self._forward if forward is None else forward
        with dr.suspend_grad(when=not ad):  # a primal trace never records AD edges through its loops
            o, d = ray.o, ray.d
            active = mi.Bool(active)
            refl, trans, intf = self.active_set("reflection"), self.active_set("transmission"), self.active_set("interface")
            lists = []

            def march(gs, *args, **kw):
                if not gs:
                    lists.append(None)
                    return Composite()
                info = {}
                acc = self.march(gs, *args, ad=ad, record=record, info=info, **kw)
                lists.append(info["list"])  # (march evaluated the pass: its scatters ran with its totals)
                return acc

            I = march(intf, o, d, active)
            weights = self._weights(I, d, active)
            x_i, d_r = self._secondary(I, o, d)
            kd, ks, kt, do_r, do_t = weights
            R = march(refl, x_i, d_r, do_r, weight=ks)
            Tr = march(trans, x_i, d, do_t, weight=kt)
            order2 = self.max_order == 2 and refl is not None and trans is not None
            R2 = Composite()
            if order2:
                x_t, d_r2, do_r2 = self._second_order(x_i, Tr, d, do_t)
                R2 = march(refl, x_t, d_r2, do_r2, weight=kt * Tr.B)
            else:
                lists.append(None)
            D = march(trans if "trans_direct" in need else None, o, d, active)
            out = self._combine(I, R, Tr, R2, D, weights, d, forward, order2)
            out["passes"] = (I, R, Tr, R2, D)
            if record:
                out["hit_lists"] = tuple(lists)
            return out

    def backward(self, ray: mi.Ray3f, active, out: dict, adjoints: dict, forward=None, t_raise=None) -> None:
        """Path-replay backward: accumulate into the sets' parameter gradients the derivative of
        sum_k <adjoints[k], out[k]>, for ``out`` = :meth:`trace` (primal) of the same rays.

        ``adjoints`` maps output names (rgb and AOV group names) to per-ray adjoints shaped like the outputs.
        Memory is independent of the number of hits: every pass is re-traced in a symbolic loop.
        ``t_raise`` (per ray, optional): where the transparency t may be pushed up; elsewhere a negative adjoint of
        the interface's t (all terms together: the shading head's and the transparency AOV's) is dropped, so those
        rays can only lower t (TrainConfig.t_raise).
        """
        forward = self._forward if forward is None else forward
        o, d = mi.Point3f(dr.detach(ray.o)), mi.Vector3f(dr.detach(ray.d))
        active = mi.Bool(active)
        I, R, Tr, R2, D = out["passes"]
        lI, lR, lTr, lR2, lD = out.get("hit_lists", (None,) * 5)
        dr.eval(I, R, Tr, R2, D)  # one kernel for all totals (else each field would re-run its pass when detached)
        refl, trans, intf = self.active_set("reflection"), self.active_set("transmission"), self.active_set("interface")
        order2 = self.max_order == 2 and refl is not None and trans is not None
        flags = dr.ADFlag.Default | dr.ADFlag.AllowNoGrad

        # 1. the shading head: adjoints of every pass's totals
        with dr.resume_grad():
            leaves = [p.leaf() for p in (I, R, Tr, R2, D)]
            Il, Rl, Trl, R2l, Dl = leaves
            res = self._combine(Il, Rl, Trl, R2l, Dl, self._weights(Il, d, active), d, forward, order2)
            dr.backward_from(_adjoint_dot(res, adjoints), flags=flags)
            gI, gR, gTr, gR2, gD = [leaf.grad() for leaf in leaves]
        if t_raise is not None:
            gI.Tau = dr.select(mi.Bool(t_raise) | (gI.Tau >= 0), gI.Tau, 0.0)

        _, ks, kt, do_r, do_t = self._weights(I, d, active)
        x_i, d_r = self._secondary(I, o, d)
        g_xi = mi.Vector3f(0.0)
        # 2. second-order reflection, then its ray's dependence on the transmission pass (and x_I)
        if order2:
            x_t, d_r2, do_r2 = self._second_order(x_i, Tr, d, do_t)
            g_xt, g_dr2 = self.march(refl, x_t, d_r2, do_r2, total=R2, adjoint=gR2, ray_grad=True,
                                     weight=kt * Tr.B, hit_list=lR2)
            with dr.resume_grad():
                x_il, Trl = mi.Point3f(x_i), Tr.leaf()
                dr.enable_grad(x_il)
                x_tl, d_r2l, _ = self._second_order(x_il, Trl, d, do_t)
                dr.backward_from(dr.dot(g_xt, x_tl) + dr.dot(g_dr2, d_r2l), flags=flags)
                gTr = gTr + Trl.grad()
                g_xi += dr.grad(x_il)
        # 3. transmission and reflection replays; their rays' origin/direction adjoints
        if trans:
            g_o, _ = self.march(trans, x_i, d, do_t, total=Tr, adjoint=gTr, ray_grad=not self.detach_depth,
                                weight=kt, hit_list=lTr)
            g_xi += g_o
        g_dr = mi.Vector3f(0.0)
        if refl:
            g_o, g_dr = self.march(refl, x_i, d_r, do_r, total=R, adjoint=gR, ray_grad=True, weight=ks,
                                   hit_list=lR)
            g_xi += g_o
        # 4. secondary rays -> interface totals (normal through the mirror direction, depth through x_I)
        with dr.resume_grad():
            Il = I.leaf()
            x_il, d_rl = self._secondary(Il, o, d)
            dr.backward_from(dr.dot(g_xi, x_il) + dr.dot(g_dr, d_rl), flags=flags)
            gI = gI + Il.grad()
        # 5. the camera-ray passes
        if intf:
            self.march(intf, o, d, active, total=I, adjoint=gI, hit_list=lI)
        if trans and "trans_direct" in adjoints:
            self.march(trans, o, d, active, total=D, adjoint=gD, hit_list=lD)


def register() -> None:
    mi.register_integrator("glint", lambda props: GlintIntegrator(props))
