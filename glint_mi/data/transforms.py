"""NeRF / instant-ngp / nerfstudio ``transforms.json``: camera-to-world matrices in OpenGL axes, shared or per-frame
intrinsics (``fl_x fl_y cx cy w h`` or ``camera_angle_x``), distortion (``k1 k2 k3 k4 p1 p2``; nerfstudio's
``camera_model`` OPENCV / OPENCV_FISHEYE), an optional split (``train_filenames`` / ``test_filenames``) and an
optional point cloud (``ply_file_path``)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from glint_mi.conventions import MI_TO_GL
from glint_mi.data.errors import DatasetError
from glint_mi.data.frames import Frame, check_pose
from glint_mi.data.images import find_image, image_size

DISTORTION_KEYS = ("k1", "k2", "k3", "k4", "p1", "p2")


def _camera_model(get, where: str) -> tuple[str, list]:
    """(COLMAP model name, its extra parameters after fx fy cx cy) from the distortion keys."""
    k = {key: float(get(key) or 0.0) for key in DISTORTION_KEYS}
    model = str(get("camera_model") or "").upper()
    fisheye = model in ("OPENCV_FISHEYE", "FISHEYE") or bool(get("is_fisheye"))
    if fisheye:
        return "OPENCV_FISHEYE", [k["k1"], k["k2"], k["k3"], k["k4"]]
    if model not in ("", "OPENCV", "PINHOLE", "SIMPLE_PINHOLE"):
        raise DatasetError(f"{where}: camera_model '{model}' is not supported; use OPENCV or OPENCV_FISHEYE (or "
                           f"undistort the images and write a pinhole camera).")
    if k["k4"] != 0.0:
        raise DatasetError(f"{where}: k4 = {k['k4']} on a perspective (OPENCV) camera: that polynomial has no COLMAP "
                           f"model; undistort the images yourself or set camera_model to OPENCV_FISHEYE if it is one.")
    if k["k3"] != 0.0:  # radial 1 + k1 r^2 + k2 r^4 + k3 r^6: COLMAP's FULL_OPENCV with k4..k6 = 0
        return "FULL_OPENCV", [k["k1"], k["k2"], k["p1"], k["p2"], k["k3"], 0.0, 0.0, 0.0]
    if any(k[key] != 0.0 for key in ("k1", "k2", "p1", "p2")):
        return "OPENCV", [k["k1"], k["k2"], k["p1"], k["p2"]]
    return "PINHOLE", []


def _number(x) -> bool:
    """A finite real number (not a bool, not a string)."""
    return isinstance(x, (int, float)) and not isinstance(x, bool) and bool(np.isfinite(x))


def read_frames(path: Path) -> tuple[list[Frame], dict | None, np.ndarray | None, np.ndarray | None]:
    """(frames in file order, split or None, points [P,3] or None, colours [P,3] or None)."""
    root = path.parent
    try:
        meta = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise DatasetError(f"{path}: not valid JSON ({exc}).") from None
    frames_in = meta.get("frames")
    if not frames_in:
        raise DatasetError(f"{path}: field 'frames' is missing or empty.")
    frames = []
    sizes: dict = {}  # image size -> the first frame of that size whose intrinsics are the file's shared ones
    for i, fr in enumerate(frames_in):
        get = lambda k: fr.get(k, meta.get(k))
        where = f"{path}: frames[{i}]"
        fp = fr.get("file_path")
        if fp is None or "transform_matrix" not in fr:
            raise DatasetError(f"{where} needs 'file_path' and 'transform_matrix'.")
        img = find_image(root, fp)
        w, h = get("w"), get("h")
        if (w is None or h is None) and img is not None:
            w, h = image_size(img)
            shared = [k for k in ("fl_x", "fl_y", "cx", "cy") if k not in fr and k in meta]
            if shared:  # pixel intrinsics shared by images whose size each image gives: one size for all
                sizes.setdefault((int(w), int(h)), (i, fp, shared))
        for key in ("w", "h"):
            value = get(key)
            if value is not None and not (_number(value) and float(value) == int(value) and int(value) > 0):
                raise DatasetError(f"{where}: '{key}' = {value!r}: the image size in pixels must be a positive integer "
                                   f"(or leave it out: it is read from the image).")
        fx, fy = get("fl_x"), get("fl_y") if get("fl_y") is not None else get("fl_x")
        if fx is None:
            angle = get("camera_angle_x")
            if angle is None:
                raise DatasetError(f"{where}: give 'fl_x' (pixels) or 'camera_angle_x' (radians), per frame or at "
                                   f"the top level.")
            if not (_number(angle) and 0 < float(angle) < np.pi):
                raise DatasetError(f"{where}: 'camera_angle_x' = {angle!r}: the horizontal field of view must be in "
                                   f"radians, between 0 and pi (or give 'fl_x' in pixels).")
            if w is None:
                w = 0
            fx = fy = 0.5 * float(w) / np.tan(0.5 * float(angle))
        for key, value in (("fl_x", fx), ("fl_y", fy)):
            if img is None and not w:  # a missing image of unknown size: listed with the missing frames instead
                break
            if not (_number(value) and float(value) > 0):
                raise DatasetError(f"{where}: '{key}' = {value!r}: the focal length must be a positive number of "
                                   f"pixels (or give 'camera_angle_x' in radians instead).")
        cx = get("cx") if get("cx") is not None else (w or 0) / 2
        cy = get("cy") if get("cy") is not None else (h or 0) / 2
        for key, value in (("cx", cx), ("cy", cy)):
            if not _number(value):
                raise DatasetError(f"{where}: '{key}' = {value!r}: the principal point must be a finite number of "
                                   f"pixels (or leave it out: the image centre).")
        try:
            m = np.asarray(fr["transform_matrix"], float)
        except (TypeError, ValueError):
            m = np.zeros(0)
        if m.shape != (4, 4) or not np.isfinite(m).all():
            raise DatasetError(f"{where}.transform_matrix must be a finite 4x4 matrix.")
        check_pose(m, f"{where}.transform_matrix")
        c2w = m.copy()
        c2w[:3, :3] = m[:3, :3] @ MI_TO_GL
        model, extra = _camera_model(get, where)
        frames.append(Frame(Path(fp).stem, img, fp, int(w or 0), int(h or 0), model,
                            [float(fx), float(fy), float(cx), float(cy), *extra], c2w))
    if len(sizes) > 1:
        (w0, h0), (i0, f0, _), (w1, h1), (i1, f1, keys) = *list(sizes.items())[0], *list(sizes.items())[1]
        raise DatasetError(f"{path}: frames[{i1}] ({f1}) is {w1} x {h1} but frames[{i0}] ({f0}) is {w0} x {h0}, and "
                           f"both use the shared {', '.join(keys)}: intrinsics in pixels fit one image size. Give the "
                           f"frames of another size their own w, h, fl_x, fl_y, cx, cy, or resize the images.")
    split = None
    if meta.get("train_filenames") is not None and meta.get("test_filenames") is not None:
        split = {"train": [Path(f).stem for f in meta["train_filenames"]],
                 "test": [Path(f).stem for f in meta["test_filenames"]], "from": f"{path.name} train/test_filenames"}
    pts = cols = None
    if meta.get("ply_file_path"):
        pts, cols = _read_points_ply(root / meta["ply_file_path"])
    return frames, split, pts, cols


def _read_points_ply(path: Path):
    from plyfile import PlyData

    if not path.exists():
        raise DatasetError(f"{path}: the ply_file_path of transforms.json does not exist.")
    v = PlyData.read(str(path))["vertex"]
    xyz = np.stack([v["x"], v["y"], v["z"]], -1).astype(np.float64)
    names = v.data.dtype.names
    rgb = (np.stack([v["red"], v["green"], v["blue"]], -1).astype(np.uint8) if "red" in names
           else np.full((len(xyz), 3), 128, np.uint8))
    return xyz, rgb
