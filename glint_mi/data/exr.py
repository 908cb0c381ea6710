"""Ground-truth EXR files of the protocol (``gt/<view>.exr``: R G B linear, Z planar depth, N.X N.Y N.Z world
normal, T glass mask): the one reader and writer, shared by the dataset loader and the generators."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np


def write_gt_exr(path: Path, rgb: np.ndarray, buffers: dict) -> None:
    """R G B Z N.X N.Y N.Z T as float32 channels (contiguous copies: OpenEXR scrambles strided arrays)."""
    import OpenEXR

    chans = {"R": rgb[..., 0], "G": rgb[..., 1], "B": rgb[..., 2], "Z": buffers["Z"][..., 0],
             "N.X": buffers["N"][..., 0], "N.Y": buffers["N"][..., 1], "N.Z": buffers["N"][..., 2],
             "T": buffers["T"][..., 0]}
    chans = {k: np.ascontiguousarray(v, dtype=np.float32) for k, v in chans.items()}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    tmp = path.with_name(path.name + ".tmp.exr")
    with OpenEXR.File(header, chans) as f:
        f.write(str(tmp))
    os.replace(tmp, path)


def read_gt_exr(path: Path) -> dict[str, np.ndarray]:
    import OpenEXR

    with OpenEXR.File(str(path), separate_channels=True) as f:
        ch = f.channels()
        return {k: np.array(v.pixels) for k, v in ch.items()}
