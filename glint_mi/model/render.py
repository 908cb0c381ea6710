"""Rendering helpers: split a ``glint`` render into named buffers and trace arbitrary ray batches."""
from __future__ import annotations

import numpy as np


def aligned(a: np.ndarray, dtype=np.float32) -> np.ndarray:
    """A 64-byte aligned contiguous copy of ``a``. Dr.Jit's LLVM kernels encode the alignment of their inputs:
    arrays made from unaligned numpy memory compile a new kernel every time the alignment changes (measured:
    4-8 recompilations per training iteration before this)."""
    a = np.ascontiguousarray(a, dtype)
    buf = np.empty(a.nbytes + 64, np.uint8)
    off = (-buf.ctypes.data) % 64
    out = buf[off:off + a.nbytes].view(dtype).reshape(a.shape)
    out[...] = a
    return out


# the glint integrator's AOV groups and their channels, in the order it writes them
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


def floats(a: np.ndarray):
    """numpy [M] -> mi.Float, or [M, 3] -> a list of three mi.Float columns (aligned, see :func:`aligned`)."""
    import mitsuba as mi

    a = np.asarray(a)
    if a.ndim == 1:
        return mi.Float(aligned(a))
    return [mi.Float(aligned(a[:, k])) for k in range(a.shape[1])]


def aov_layout(integrator) -> dict[str, slice]:
    """Channel slices of a ``mi.render`` tensor made with ``integrator``: rgb first, then the AOV groups."""
    layout, start = {"rgb": slice(0, 3)}, 3
    for g in integrator.aov_groups:
        n = len(AOV_GROUPS[g])
        layout[g] = slice(start, start + n)
        start += n
    return layout


def render_buffers(scene, spp: int | None = None, seed: int = 0, sensor: int = 0) -> dict[str, np.ndarray]:
    """Render ``scene`` and return {name: [H, W, C] float32} for rgb and every AOV group of its glint integrator."""
    import mitsuba as mi

    img = np.array(mi.render(scene, spp=spp or 0, seed=seed, sensor=sensor))
    integrator = scene.integrator()
    if not hasattr(integrator, "aov_groups"):
        return {"rgb": img[..., :3]}
    return {name: img[..., sl] for name, sl in aov_layout(integrator).items()}


def camera_rays(sensor, pixels: np.ndarray | None = None):
    """Rays through pixel centres ``pixels`` [M, 2] (x, y) of ``sensor`` (default: every pixel of its film, row-major);
    returns (mi.Ray3f, forward Vector3f).

    Perspective rays start at the camera centre (not on the near plane), so hit distances are from the camera.
    """
    import mitsuba as mi

    size = np.array(sensor.film().crop_size(), dtype=np.float64)
    if pixels is None:
        w, h = (int(x) for x in size)
        pixels = np.stack(np.meshgrid(np.arange(w), np.arange(h)), -1).reshape(-1, 2)
    uv = (np.asarray(pixels, np.float64) + 0.5) / size
    ray, _ = sensor.sample_ray(0.0, 0.0, mi.Point2f(mi.Float(uv[:, 0]), mi.Float(uv[:, 1])), mi.Point2f(0.5))
    forward = mi.Vector3f(sensor.world_transform() @ mi.Vector3f(0, 0, 1))
    return from_pinhole(sensor, mi.Ray3f(ray)), forward


def from_pinhole(sensor, ray):
    """Perspective sensors start rays on the near plane (near_clip away); move the origins back to the pinhole so
    that hit distances, hence depths, are measured from the camera centre (protocol: planar depth from the camera)."""
    import mitsuba as mi

    if sensor.class_name() == "PerspectiveCamera":
        ray = mi.Ray3f(ray)
        ray.o = mi.Point3f(sensor.world_transform().translation())
    return ray
