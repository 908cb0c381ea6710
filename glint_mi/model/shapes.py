"""Mitsuba shapes for Gaussian sets: :func:`make_shape` instantiates the ``ellipsoids`` shape of a
:class:`~glint_mi.model.gaussians.GaussianSet` and records its role and kernel in :data:`SET_INFO`, which the
``glint_gaussians`` plugin (plugins/glint_gaussians.py, its XML / dict factory) and the ``glint`` integrator read.
Below the plugins: they import it, it imports none of them."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

import glint_mi.conventions as cv
from glint_mi.model.gaussians import SHELL_EXTENT, GaussianSet


@dataclasses.dataclass
class SetInfo:
    role: str | None
    kernel: str
    empty: bool
    source: str
    min_shell_ratio: float
    opacity_shells: bool
    extent: float
    normals: bool = False  # normal_source: attribute (the set's normals attribute, not its rotation's axis)
    shape: object = dataclasses.field(repr=False, default=None)  # keeps id(shape) from being reused


SET_INFO: dict[int, SetInfo] = {}


def info(shape) -> SetInfo:
    """Metadata of a shape made by this factory; raises for any other shape."""
    try:
        return SET_INFO[id(shape)]
    except KeyError:
        raise ValueError(f"shape '{shape.id()}' is not a glint_gaussians shape (declare it with "
                         f"type=\"glint_gaussians\")") from None


def make_shape(gset: GaussianSet, kernel: str = "surfel", role: str | None = None, shape_id: str = "",
               extent: float = SHELL_EXTENT, min_shell_ratio: float = 0.3, opacity_shells: bool = True,
               source: str = "glint_gaussians", normal_source: str = "axis"):
    """Instantiate the ``ellipsoids`` shape for a GaussianSet and register its metadata. ``normal_source``: axis (the
    kernel's thin axis, as the paper) or attribute (the set's ``normals``, surfels only)."""
    if kernel not in cv.KERNELS:
        raise ValueError(f"{source}: unknown kernel '{kernel}'; use one of {cv.KERNELS}.")
    if normal_source not in cv.NORMAL_SOURCES:
        raise ValueError(f"{source}: unknown normal_source '{normal_source}'; use one of {cv.NORMAL_SOURCES}.")
    if normal_source == "attribute" and kernel != "surfel":
        raise ValueError(f"{source}: normal_source 'attribute' needs kernel 'surfel' (an ellipsoid's normal is the "
                         f"axis its ray meets); use normal_source 'axis' with kernel '{kernel}'.")
    if role is not None and role not in cv.ROLES:
        raise ValueError(f"{source}: unknown role '{role}'; use one of {cv.ROLES}.")
    import mitsuba as mi

    empty = len(gset) == 0
    if empty:  # Mitsuba's ellipsoids cannot hold 0 primitives: one invisible placeholder, skipped by the integrator
        gset = GaussianSet.from_activated(np.zeros((1, 3)), 1e-3, opacities=1e-6, sh_degree=gset.sh_degree)
    normals = normal_source == "attribute"
    arrays = gset.to_mitsuba(kernel, min_shell_ratio, opacity_shells, float(extent), normals)
    desc = {"type": "ellipsoids", "extent": float(extent)}
    if shape_id:
        desc["id"] = shape_id
    desc.update({k: mi.TensorXf(v) for k, v in arrays.items()})
    shape = mi.load_dict(desc)
    SET_INFO[id(shape)] = SetInfo(role, kernel, empty, source, min_shell_ratio, opacity_shells, float(extent), normals,
                                  shape)
    return shape


def pack(shape, gset: GaussianSet) -> dict[str, np.ndarray]:
    """``gset`` as the arrays of ``shape``'s parameters, packed as the shape was made (kernel, shell ratio,
    opacity shells, extent): what to send through ``mi.traverse`` when a set changes."""
    meta = info(shape)
    return gset.to_mitsuba(meta.kernel, meta.min_shell_ratio, meta.opacity_shells, meta.extent, meta.normals)


PARAM_KEYS = ("data", "kernel_scales", "opacities", "sh_coeffs", "specular", "transparency")


def param_keys(shape) -> tuple[str, ...]:
    """The parameters of a glint_gaussians shape: :data:`PARAM_KEYS`, and ``normals`` where the set carries them."""
    return PARAM_KEYS + ("normals",) if info(shape).normals else PARAM_KEYS


def to_gaussian_set(shape) -> GaussianSet:
    """The current parameters of a glint_gaussians shape (e.g. after optimisation) as a raw GaussianSet."""
    import mitsuba as mi

    meta = info(shape)
    if meta.empty:
        return GaussianSet.empty()
    params = mi.traverse(shape)
    arrays = {k: np.array(params[k], dtype=np.float64).ravel() for k in param_keys(shape) if k in params}
    return GaussianSet.from_mitsuba(arrays, kernel=meta.kernel)


def save_ply(shape, path) -> Path:
    """Write a shape's current Gaussians as a standard 3DGS .ply with ``specular``/``transparency`` (atomic)."""
    return to_gaussian_set(shape).save_ply(path)
