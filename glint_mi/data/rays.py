"""Rays of a view: world directions through pixel centres and the camera's axes (what training, evaluation and the
initialisation all trace)."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from glint_mi.conventions import MI_TO_COLMAP

if TYPE_CHECKING:
    from glint_mi.data import View


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
