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
