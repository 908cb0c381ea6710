"""The ``glint_gaussians`` shape: one Gaussian set (interface, transmission or reflection) for the ``glint`` integrator.

.. pluginparameters::

 * - role
   - |string|
   - ``interface``, ``transmission`` or ``reflection``. (Default: the name under which the shape is nested in the
     integrator, else required)
 * - kernel
   - |string|
   - ``surfel`` (flat 2D Gaussian evaluated where the ray crosses its plane; normal = thin axis; default, as in the
     paper) or ``ellipsoid`` (3D Gaussian evaluated at its peak along the ray, as in 3DGRT).
 * - normal_source
   - |string|
   - ``axis`` (the kernel's thin axis is its normal; default, as in the paper) or ``attribute`` (each Gaussian carries a
     normal of its own, read from the file's ``nx, ny, nz``, so that its shape is free for appearance; surfels only).
 * - filename
   - |string|
   - A 3DGS ``.ply`` (raw values: log scales, logit opacity, rot_0..3 = w,x,y,z; optional ``specular`` and
     ``transparency`` logits).
 * - centers, scales, quaternions, opacities, sh_coeffs, specular, transparency
   - |tensor|
   - Activated values instead of a file: [N,3] metres, [N,3] standard deviations, [N,4] (x,y,z,w), [N,1], [N,3K]
     coefficient-major linear-RGB SH, [N,1], [N,1]. Missing opacities/specular/transparency take the paper's inits
     (0.5 / 1e-3 / 0.01); missing SH gives grey.
 * - extent
   - |float|
   - Shell radius in standard deviations. (Default: 3.33 = sqrt(2 ln 255), where alpha of an opaque Gaussian drops
     below the 1/255 cut-off, so the shell adds no discontinuity)
 * - min_shell_ratio
   - |float|
   - No shell axis thinner than this fraction of the longest one (BVH proxy only; see README "Limits"). (Default: 0.3)
 * - opacity_shells
   - |bool|
   - Shrink each shell to where opacity x G reaches the cut-off of an opaque Gaussian's shell (exp(-extent^2/2) =
     1/255): a faint Gaussian is skipped there anyway, and its smaller shell spares the BVH the hits (fewer hits per
     ray, the hit budget spent on Gaussians that contribute). Shell entry order, which orders the compositing,
     follows the smaller shells. The shell is set from the opacities given here (or in the trainer's push): after
     changing ``opacities`` through ``mi.traverse``, rebuild the shape or set ``data`` too. With an integrator
     ``alpha_min`` below exp(-extent^2/2) (volprim's cut-offs: 0) the faint tails it would composite lie outside
     these shells: set ``false`` there. (Default: true)

Mitsuba 3.9.1 cannot subclass ``mi.Shape`` from Python, so the factory returns a configured built-in ``ellipsoids``
shape and records the set's role and kernel in :data:`SET_INFO`. The ellipsoid ``data`` is the *bounding shell*; the
kernel's own standard deviations live in the ``kernel_scales`` attribute, which is what the integrator evaluates.
"""
from __future__ import annotations

import mitsuba as mi
import numpy as np

import glint_mi.conventions as cv
from glint_mi.model.gaussians import SHELL_EXTENT, GaussianDataError, GaussianSet
from glint_mi.model.shapes import (PARAM_KEYS, SET_INFO, SetInfo, info, make_shape, pack, save_ply,
                                   to_gaussian_set)

# the shape functions live in glint_mi.model.shapes (below the plugins); here too, where scripts import them
__all__ = ["PARAM_KEYS", "SET_INFO", "SetInfo", "info", "make_shape", "pack", "save_ply", "to_gaussian_set",
           "gaussian_set_from_props", "register"]


def _tensor(props, name, source, width=None):
    value = np.asarray(props.get(name), dtype=np.float64)
    if value.ndim == 1 and width:
        value = value.reshape(-1, width) if value.size % width == 0 else value
    if width and (value.ndim != 2 or value.shape[1] != width):
        raise GaussianDataError(f"{source}: property '{name}' has shape {value.shape}, expected (N, {width}).")
    return value


def gaussian_set_from_props(props, source: str) -> GaussianSet:
    """The GaussianSet described by a shape's properties (file or tensors)."""
    if "init" in props:
        raise GaussianDataError(f"{source}: init='{props.get('init')}' marks an optimisation input (Gaussians made "
                                f"from the dataset when training starts); run `python -m glint_mi.optimize` on this "
                                f"file, or render a trained run's scene.xml instead.")
    if "filename" in props:
        return GaussianSet.load_ply(str(mi.file_resolver().resolve(props.get("filename"))))
    if "data" in props:
        data = _tensor(props, "data", source, 10)
        centers, scales, quats = data[:, :3], data[:, 3:6], data[:, 6:10]
    elif "centers" in props:
        centers = _tensor(props, "centers", source, 3)
        scales = _tensor(props, "scales", source, 3) if "scales" in props else np.full_like(centers, 0.01)
        quats = _tensor(props, "quaternions", source, 4) if "quaternions" in props else None
    else:
        raise GaussianDataError(f"{source}: give 'filename' (a 3DGS .ply) or 'centers' (+ scales, quaternions, ...) "
                                f"or 'data' (N x 10).")
    n = len(centers)
    for name, arr in (("centers", centers), ("scales", scales)):
        if len(arr) != n:
            raise GaussianDataError(f"{source}: property '{name}' has {len(arr)} rows but 'centers' has {n}.")
        if not np.all(np.isfinite(arr)):
            raise GaussianDataError(f"{source}: property '{name}' contains NaN/Inf.")
    if n and np.any(~(scales > 0)):
        raise GaussianDataError(f"{source}: property 'scales' must be > 0 (standard deviations in metres).")

    def column(name):  # None -> from_activated uses the paper's init value
        if name not in props:
            return None
        arr = _tensor(props, name, source, 1)
        if len(arr) != n:
            raise GaussianDataError(f"{source}: property '{name}' has {len(arr)} rows, expected {n}.")
        if not np.all((arr >= 0) & (arr <= 1)):
            raise GaussianDataError(f"{source}: property '{name}' must lie in [0, 1] (activated values).")
        return arr[:, 0]

    sh = None
    if "sh_coeffs" in props:
        raw = np.asarray(props.get("sh_coeffs"), np.float64)
        raw = raw.reshape(n, -1) if n else raw.reshape(0, 3)
        try:
            cv.sh_degree_from_coeffs(raw.shape[1])
        except ValueError as exc:
            raise GaussianDataError(f"{source}: property 'sh_coeffs': {exc}.") from None
        sh = raw.reshape(n, -1, 3)
    if n == 0:
        return GaussianSet.empty(0 if sh is None else int(round(sh.shape[1] ** 0.5)) - 1)
    return GaussianSet.from_activated(centers, scales, quats, opacities=column("opacities"), sh=sh,
                                      specular=column("specular"), transparency=column("transparency"))


PROPERTIES = ("filename, data, centers, scales, quaternions, opacities, sh_coeffs, specular, transparency, role, "
              "kernel, normal_source, extent, min_shell_ratio, opacity_shells")


def _factory(props):
    sid = props.id()
    role = props.get("role", None)
    source = f"glint_gaussians '{sid or role or '?'}'"
    gset = gaussian_set_from_props(props, source)
    kw = dict(kernel=props.get("kernel", "surfel"), extent=props.get("extent", SHELL_EXTENT),
              min_shell_ratio=props.get("min_shell_ratio", 0.3), opacity_shells=bool(props.get("opacity_shells", True)),
              normal_source=props.get("normal_source", "axis"))
    unread = props.unqueried()
    if unread:  # a misspelling, or a property that 'filename' overrides: either way it would be ignored
        raise GaussianDataError(f"{source}: propert{'ies' if len(unread) > 1 else 'y'} "
                                f"{', '.join(repr(n) for n in unread)} not read; glint_gaussians takes {PROPERTIES} "
                                f"('filename' alone, or 'data' / 'centers' with their columns).")
    return make_shape(gset, role=role, shape_id=sid or (role or ""), source=source, **kw)


def register() -> None:
    mi.register_shape("glint_gaussians", _factory)
