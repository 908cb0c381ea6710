"""Undistortion of real captures, once, into a cache: COLMAP's undistorter (through pycolmap) turns every frame of a
distorted camera (OPENCV, fisheye, radial, ...) into a pinhole image, which the ray tracer can use.

The cache lives under ``$GLINT_CACHE`` (default ``~/.cache/glint_mi``), keyed by the images' contents and the
cameras, so a dataset folder can be read-only; a second run finds the undistorted images there, and so does a copy
of the capture elsewhere or one re-synced with new file times. The folder is written under a temporary name and
renamed when complete (an interrupted run leaves nothing half-written).
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
from pathlib import Path

import numpy as np

from glint_mi.data.errors import DatasetError
from glint_mi.data.images import decode

VERSION = 1  # bump when the undistorted output would change for the same input
PINHOLE_MODELS = ("PINHOLE", "SIMPLE_PINHOLE")


def cache_root() -> Path:
    return Path(os.environ.get("GLINT_CACHE") or Path.home() / ".cache" / "glint_mi")


_content_keys: dict[tuple, str] = {}  # (resolved path, size, mtime) -> content hash, within one process


def file_key(path: Path) -> str:
    """A file's cache key: the SHA-1 of its bytes. Paths and modification times are not part of it: a capture copied
    elsewhere, or re-synced with new times, keeps its undistortion and SfM caches (it did not, when they were)."""
    path = Path(path).resolve()
    st = path.stat()
    memo = (str(path), st.st_size, st.st_mtime_ns)
    if memo not in _content_keys:
        h = hashlib.sha1()
        with open(path, "rb") as f:
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
        _content_keys[memo] = f"{st.st_size}:{h.hexdigest()}"
    return _content_keys[memo]


def digest(*parts) -> str:
    return hashlib.sha1(json.dumps(parts, sort_keys=True, default=str).encode()).hexdigest()[:16]


def colmap_camera(model: str, width: int, height: int, params):
    import pycolmap

    try:
        cam = pycolmap.Camera(model=model, width=int(width), height=int(height), params=[float(p) for p in params])
        ok = cam.verify_params()
    except Exception as e:  # pycolmap raises plain exceptions for unknown models
        raise DatasetError(f"camera model {model}: {e}") from None
    if not ok:
        raise DatasetError(f"camera model {model} takes the parameters {cam.params_info}; got {len(params)} "
                           f"values ({', '.join(f'{p:g}' for p in params)}).")
    return cam


def distortion_shift(model: str, width: int, height: int, params, grid: int = 64) -> tuple[float, float]:
    """(max, mean) distance in pixels between where the distorted camera images a point and where the pinhole with
    the same focal lengths and centre would, over a grid of pixels: how much undistortion moves the image."""
    cam = colmap_camera(model, width, height, params)
    xs, ys = np.meshgrid(np.linspace(0.5, width - 0.5, grid), np.linspace(0.5, height - 0.5, grid))
    px = np.stack([xs.ravel(), ys.ravel()], -1)
    norm = np.asarray(cam.cam_from_img(px), np.float64)
    ok = np.isfinite(norm).all(1)
    K = cam.calibration_matrix()
    pin = norm[ok] @ K[:2, :2].T + K[:2, 2]
    d = np.linalg.norm(pin - px[ok], axis=1)
    return (float(d.max()), float(d.mean())) if len(d) else (float("nan"), float("nan"))


def undistort_points(model: str, width: int, height: int, params, K_new: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Pixel positions [n,2] of a distorted camera -> the same rays' pixels in the undistorted pinhole ``K_new``."""
    if len(xy) == 0:
        return xy
    cam = colmap_camera(model, width, height, params)
    norm = np.asarray(cam.cam_from_img(np.asarray(xy, np.float64)), np.float64)
    return norm @ K_new[:2, :2].T + K_new[:2, 2]


def undistort_frames(frames: list, log=print, progress: bool = True) -> dict[str, dict]:
    """Undistorted pinhole images of ``frames`` (objects with name, image_path, width, height, model, params) that
    have a distorted camera model. Returns, per frame name, {'image_path', 'width', 'height', 'K'} in the cache."""
    todo = [f for f in frames if f.model not in PINHOLE_MODELS]
    if not todo:
        return {}
    key = digest(VERSION, [(f.name, file_key(f.image_path), f.model, list(map(float, f.params)), f.width, f.height)
                           for f in todo])
    folder = cache_root() / "undistorted" / key
    manifest = folder / "manifest.json"
    if manifest.exists():
        return {n: {**v, "image_path": folder / v["image_path"], "K": np.array(v["K"])}
                for n, v in json.loads(manifest.read_text())["frames"].items()}
    import pycolmap
    from PIL import Image
    from tqdm.auto import tqdm

    log(f"undistorting {len(todo)} images with COLMAP's undistorter (pycolmap) into {folder} (once; cached)")
    tmp = folder.with_name(folder.name + f".partial-{os.getpid()}")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    opts = pycolmap.UndistortCameraOptions()  # blank_pixels 0: crop to the region every output pixel sees
    out = {}
    try:
        for f in tqdm(todo, desc="undistort", unit="img", disable=not progress):
            img = np.clip(np.round(decode(f.image_path) * 255), 0, 255).astype(np.uint8)
            if img.shape[:2] != (f.height, f.width):
                raise DatasetError(f"{f.image_path}: {img.shape[0]}x{img.shape[1]} (HxW) but its camera says "
                                   f"{f.height}x{f.width}; the images and the camera file do not match.")
            bitmap, cam = pycolmap.undistort_image(opts, pycolmap.Bitmap.from_array(img),
                                                   colmap_camera(f.model, f.width, f.height, f.params))
            name = f"{f.name}.png"
            Image.fromarray(np.asarray(bitmap.to_array(), np.uint8)).save(tmp / name, compress_level=1)
            out[f.name] = {"image_path": name, "width": int(cam.width), "height": int(cam.height),
                           "K": np.asarray(cam.calibration_matrix(), np.float64).tolist()}
        (tmp / "manifest.json").write_text(json.dumps({"version": VERSION, "frames": out}, indent=1))
        try:
            tmp.rename(folder)
        except OSError:  # another process finished first: use its copy
            shutil.rmtree(tmp, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return {n: {**v, "image_path": folder / v["image_path"], "K": np.array(v["K"])} for n, v in out.items()}
