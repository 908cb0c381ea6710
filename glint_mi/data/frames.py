"""A frame as a camera file lists it, before the loader checks, undistorts and downscales it into a View."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from glint_mi.data.errors import DatasetError


@dataclasses.dataclass
class Frame:
    name: str                   # image stem, the view's name
    image_path: Path | None     # None: the camera file lists an image that is not there
    listed_as: str              # the image as the camera file names it (for messages)
    width: int
    height: int
    model: str                  # COLMAP camera model name (PINHOLE, OPENCV, OPENCV_FISHEYE, ...)
    params: list                # COLMAP parameter order for that model
    c2w: np.ndarray             # [4, 4] Mitsuba camera-to-world (x left, y up, z forward)

    @property
    def pinhole_K(self) -> np.ndarray:
        """[3, 3] intrinsics of a PINHOLE / SIMPLE_PINHOLE frame."""
        if self.model == "SIMPLE_PINHOLE":
            f, cx, cy = self.params
            fx = fy = f
        elif self.model == "PINHOLE":
            fx, fy, cx, cy = self.params
        else:
            raise DatasetError(f"frame {self.name}: camera model {self.model} is not a pinhole; undistort it first.")
        return np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])


POSE_TOLERANCE = 1e-3  # max |R^T R - I|: rounding in a written file is ~1e-6 (the fox: 1.2e-6)


def check_pose(m: np.ndarray, where: str) -> None:
    """Refuse a camera-to-world matrix whose rotation is not one: scaled, sheared, mirrored (det -1) or degenerate
    (all zero), or whose last row is not 0 0 0 1. Such a pose would give rays of the wrong length or a mirrored
    image, and a zero one fails deep in training."""
    R = m[:3, :3]
    err = float(np.abs(R.T @ R - np.eye(3)).max())
    det = float(np.linalg.det(R))
    if not np.allclose(m[3], [0.0, 0.0, 0.0, 1.0], atol=1e-6):
        raise DatasetError(f"{where}: the last row is {m[3].tolist()}, not [0, 0, 0, 1]; a camera-to-world matrix is "
                           f"a rotation and a translation.")
    if err > POSE_TOLERANCE or det <= 0:
        what = ("all zero" if not R.any() else "mirrored (det {:.3g})".format(det) if det < 0 and err <= POSE_TOLERANCE
                else f"not orthonormal (|R^T R - I| = {err:.3g}, det {det:.3g}: scaled or sheared)")
        raise DatasetError(f"{where}: its rotation is {what}; a camera pose must be a rotation (orthonormal, det +1) "
                           f"and a translation: remove any scale from the matrix (a scene scale goes on the "
                           f"translations) and export the poses again.")
