"""Training pixels of a dataset as patches of rays, drawn across views (the ray tracer's cost is per ray).

:class:`RayBank` holds, for every training view, the photo, its priors and the world-space ray through every pixel
centre; :meth:`RayBank.sample` draws ``patches`` random ``p x p`` patches (views and positions from a numpy
Generator, so a run is reproducible and resumable). Rays of a patch are contiguous, row-major: patch losses
(D-SSIM, depth-normal consistency, TV) use fixed neighbour indices.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from .data import View
from .dataset.cameras import MI_TO_COLMAP
from .dataset.priors import load_prior


def pixel_rays(view: View, pixels: np.ndarray | None = None):
    """World ray directions [M,3] (unit) through pixel centres ``pixels`` [M,2] (x, y), default all (row-major)."""
    if pixels is None:
        ys, xs = np.mgrid[0:view.height, 0:view.width]
        pixels = np.stack([xs.ravel(), ys.ravel()], -1)
    K = view.K
    x = (pixels[:, 0] + 0.5 - K[0, 2]) / K[0, 0]
    y = (pixels[:, 1] + 0.5 - K[1, 2]) / K[1, 1]
    d_cv = np.stack([x, y, np.ones_like(x)], -1)
    R_cv = view.c2w[:3, :3] @ MI_TO_COLMAP  # OpenCV camera axes in world coordinates
    d = d_cv @ R_cv.T
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def camera_axes_cv(view: View) -> np.ndarray:
    """[3,3] columns = OpenCV camera x (right), y (down), z (forward) axes in world coordinates."""
    return view.c2w[:3, :3] @ MI_TO_COLMAP


@dataclasses.dataclass
class Batch:
    view: np.ndarray        # [M] view index of each ray
    flat: np.ndarray        # [M] index into the bank's flat pixel arrays
    origin: np.ndarray      # [M,3]
    direction: np.ndarray   # [M,3]
    axes: np.ndarray        # [M,3,3] OpenCV camera axes (columns) of each ray's view
    rgb: np.ndarray         # [M,3] sRGB target
    depth_prior: np.ndarray | None
    normal_prior: np.ndarray | None   # camera space, OpenCV axes
    albedo_prior: np.ndarray | None
    glass: np.ndarray | None            # ground-truth glass mask (TSGS baseline only)
    patches: int
    patch: int


def downsampled_view(view: View, k: int) -> View:
    """The camera of ``view`` with pixels ``k`` times larger (trailing rows / columns that do not fill a block are
    dropped): the ray through a coarse pixel centre passes through the centre of its k x k block of fine pixels."""
    if k == 1:
        return view
    K = view.K.copy()
    K[:2] /= k
    return dataclasses.replace(view, width=view.width // k, height=view.height // k, K=K)


def block_mean(a: np.ndarray, k: int) -> np.ndarray:
    """[H, W, ...] -> [H // k, W // k, ...] by averaging k x k blocks (an area filter, like a lower-resolution
    sensor)."""
    if k == 1:
        return a
    h, w = a.shape[0] // k, a.shape[1] // k
    a = a[:h * k, :w * k]
    return a.reshape(h, k, w, k, *a.shape[2:]).mean(axis=(1, 3))


class RayBank:
    def __init__(self, views: list[View], root, use_priors: bool = True, glass_masks: bool = False,
                 downsample: int = 1):
        k = int(downsample)
        fine = views
        views = [downsampled_view(v, k) for v in fine]
        if k > 1 and any(v.width < 3 or v.height < 3 for v in views):
            raise ValueError(f"train_downsample = {k} leaves images smaller than 3 x 3 pixels; use a smaller factor.")
        self.views = views
        self.sizes = [(v.height, v.width) for v in views]
        self.offsets = np.cumsum([0] + [h * w for h, w in self.sizes])
        self.rgb = np.concatenate([block_mean(v.load_image(), k).reshape(-1, 3) for v in fine]).astype(np.float32)
        self.dirs = np.concatenate([pixel_rays(v) for v in views]).astype(np.float32)
        self.origins = np.array([v.c2w[:3, 3] for v in views], np.float32)
        self.axes = np.array([camera_axes_cv(v) for v in views], np.float32)
        self.priors = {}
        for kind in ("depth", "normal", "albedo"):
            maps = [load_prior(root, v, kind) if use_priors else None for v in fine]
            if all(m is not None for m in maps):
                maps = [block_mean(m, k) for m in maps]
                if kind == "normal" and k > 1:
                    maps = [m / np.maximum(np.linalg.norm(m, axis=-1, keepdims=True), 1e-12) for m in maps]
                self.priors[kind] = np.concatenate([m.reshape(h * w, -1) for m, (h, w) in zip(maps, self.sizes)])
        self.priors.setdefault("depth", None)
        self.glass = None
        if glass_masks:
            gts = [v.load_gt() for v in fine]
            if any(g is None for g in gts):
                from .data import DatasetError

                raise DatasetError(f"{root}: trans_masks = gt needs gt/<view>.exr for every training view.")
            self.glass = np.concatenate([block_mean(g["glass"], k).reshape(-1) for g in gts]).astype(np.float32)

    @property
    def has(self) -> set[str]:
        return {k for k, v in self.priors.items() if v is not None}

    def sample(self, rng: np.random.Generator, patches: int, p: int) -> Batch:
        vidx = rng.integers(0, len(self.views), patches)
        hs = np.array([self.sizes[i][0] for i in vidx])
        ws = np.array([self.sizes[i][1] for i in vidx])
        if (hs < p).any() or (ws < p).any():
            raise ValueError(f"patch size {p} is larger than an image ({hs.min()}x{ws.min()}); lower 'patch'.")
        y0 = (rng.random(patches) * (hs - p + 1)).astype(np.int64)
        x0 = (rng.random(patches) * (ws - p + 1)).astype(np.int64)
        dy, dx = np.mgrid[0:p, 0:p]
        ys = (y0[:, None] + dy.ravel()[None]).ravel()
        xs = (x0[:, None] + dx.ravel()[None]).ravel()
        view = np.repeat(vidx, p * p)
        flat = self.offsets[view] + ys * np.repeat(ws, p * p) + xs
        get = lambda k: None if self.priors.get(k) is None else self.priors[k][flat]
        return Batch(view, flat, self.origins[view], self.dirs[flat], self.axes[view], self.rgb[flat],
                     None if get("depth") is None else get("depth")[:, 0], get("normal"), get("albedo"),
                     None if self.glass is None else self.glass[flat], patches, p)


def patch_neighbours(patches: int, p: int):
    """Indices (i, right, down) of every pixel that has a right and a lower neighbour in its patch."""
    dy, dx = np.mgrid[0:p - 1, 0:p - 1]
    local = (dy * p + dx).ravel()
    base = (np.arange(patches)[:, None] * p * p + local[None]).ravel()
    return base, base + 1, base + p
