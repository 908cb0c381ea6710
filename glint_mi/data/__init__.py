"""Datasets: views (image, intrinsics, Mitsuba camera-to-world), SfM points, split, optional ground truth.

One parser per format returns the frames a camera file lists (:mod:`.colmap`: ``sparse/0`` text or binary, any
camera model; :mod:`.transforms`: NeRF / instant-ngp / nerfstudio ``transforms.json``); :func:`load_dataset` then
does what every format needs, in one place: frames whose image is missing are listed all at once (and dropped on
request), every image is decoded up front (errors name the file), distorted cameras are undistorted once into a
cache with COLMAP's undistorter (:mod:`.undistort`), ``downscale`` reduces every view by an area filter (or reads
``images_<k>/`` when the capture ships one), and the split is decided (``split.json``, the file's own split, or
every 8th view from 0). Errors are :class:`DatasetError` naming the file, the field and the fix.

What every capture shares lives here too: cameras (:mod:`.cameras`: intrinsics, poses, COLMAP / transforms.json
writers, Mitsuba sensors), rays through pixels (:mod:`.rays`) and SfM triangulation from known poses (:mod:`.sfm`).
The room generator (glint_mi.dataset) builds on them; nothing here imports it.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from glint_mi.data.errors import DatasetError
from glint_mi.data.frames import Frame
from glint_mi.data.images import (block_mean, check_decodable, decode, fit_to,  # noqa: F401 (block_mean re-exported)
                                  image_size)

MISSING = ("error", "skip")


@dataclasses.dataclass
class View:
    name: str                 # image stem, e.g. "view_003"
    image_path: Path          # the image file: at this view's size, or ``downscale`` x larger (block-averaged)
    width: int
    height: int
    K: np.ndarray             # [3, 3] pixels
    c2w: np.ndarray           # [4, 4] Mitsuba camera-to-world (x left, y up, z forward)
    gt_path: Path | None = None
    downscale: int = 1        # this view's pixels are downscale x those of the dataset's full resolution

    def load_image(self) -> np.ndarray:
        """[H, W, 3] float32 sRGB in [0, 1] at this view's resolution."""
        return fit_to(decode(self.image_path), self.height, self.width, self.downscale, str(self.image_path))

    def load_gt(self) -> dict[str, np.ndarray] | None:
        """{'rgb' [H,W,3] linear, 'depth' [H,W] planar z, 'normal' [H,W,3] world, 'glass' [H,W]} or None, at this
        view's resolution. Downscaled: block means (normals renormalised; depth only where the whole block has
        one, else 0 = invalid; glass the covered fraction, which the metrics threshold at 0.5)."""
        if self.gt_path is None:
            return None
        from glint_mi.data.exr import read_gt_exr

        ch = read_gt_exr(self.gt_path)
        need = ["R", "G", "B", "Z", "N.X", "N.Y", "N.Z", "T"]
        missing = [c for c in need if c not in ch]
        if missing:
            raise DatasetError(f"{self.gt_path}: missing EXR channel(s) {missing}; expected {need}.")
        out = {"rgb": np.stack([ch["R"], ch["G"], ch["B"]], -1), "depth": ch["Z"],
               "normal": np.stack([ch["N.X"], ch["N.Y"], ch["N.Z"]], -1), "glass": ch["T"]}
        for k, v in out.items():
            if not np.isfinite(v).all():
                raise DatasetError(f"{self.gt_path}: NaN/Inf in '{k}'; regenerate or mask that view.")
        valid = fit_to((out["depth"] > 0).astype(np.float32), self.height, self.width, self.downscale,
                       str(self.gt_path))
        out = {k: fit_to(v, self.height, self.width, self.downscale, str(self.gt_path)) for k, v in out.items()}
        if self.downscale > 1:
            out["depth"] = np.where(valid >= 1.0, out["depth"], 0.0)
            n = out["normal"]
            out["normal"] = n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)
        return out

    def sensor_dict(self, spp: int = 1) -> dict:
        """A Mitsuba perspective sensor for this view (square pixels only)."""
        import mitsuba as mi

        fx, fy, cx, cy = self.K[0, 0], self.K[1, 1], self.K[0, 2], self.K[1, 2]
        if abs(fx - fy) > 1e-3 * fx:
            raise DatasetError(f"view {self.name}: fx = {fx:g} != fy = {fy:g}; Mitsuba's perspective camera needs "
                               f"square pixels: resample the images.")
        return {"type": "perspective", "fov": float(np.degrees(2 * np.arctan(0.5 * self.width / fx))),
                # Mitsuba's offsets are in film fractions with the opposite sign of (c - size / 2) (tested)
                "fov_axis": "x", "principal_point_offset_x": float((self.width / 2 - cx) / self.width),
                "principal_point_offset_y": float((self.height / 2 - cy) / self.height),
                "to_world": mi.ScalarTransform4f(self.c2w.tolist()),
                "film": {"type": "hdrfilm", "width": self.width, "height": self.height, "rfilter": {"type": "box"}},
                "sampler": {"type": "independent", "sample_count": spp}}


@dataclasses.dataclass
class Dataset:
    root: Path
    views: list[View]
    points: np.ndarray | None          # [P, 3] world metres
    colors: np.ndarray | None          # [P, 3] uint8
    split: dict[str, list[str]]
    source: str                        # colmap | transforms
    sparse: Path | None = None         # the COLMAP model holding the SfM tracks (the dataset's, or SfM's cache)
    notes: list[str] = dataclasses.field(default_factory=list)  # what reading it did (undistortion, drops, split)
    downscale: int = 1
    distorted: dict = dataclasses.field(default_factory=dict)  # view name -> (model, w, h, params) undistorted
    options: dict = dataclasses.field(default_factory=dict)    # how it was read (load_dataset's arguments)
    tracks_distorted: bool = False     # the tracks of ``sparse`` are in the distorted images' pixels

    def view(self, name: str) -> View:
        for v in self.views:
            if v.name == name:
                return v
        raise KeyError(name)

    @property
    def train_views(self) -> list[View]:
        return [self.view(n) for n in self.split["train"]]

    @property
    def test_views(self) -> list[View]:
        return [self.view(n) for n in self.split["test"]]

    def observations(self) -> dict[str, tuple[np.ndarray, np.ndarray]] | None:
        """The SfM tracks (:func:`.colmap.read_observations`) in this dataset's views' pixels: undistorted where
        the camera was, divided by ``downscale``. None without a model holding tracks."""
        from glint_mi.data.colmap import read_observations
        from glint_mi.data.undistort import undistort_points

        if self.sparse is None:
            return None
        obs = read_observations(self.sparse)
        if obs is None:
            return None
        out = {}
        for v in self.views:
            if v.name not in obs:
                continue
            xy, xyz = obs[v.name]
            if self.tracks_distorted and v.name in self.distorted:
                model, w, h, params = self.distorted[v.name]
                xy = undistort_points(model, w, h, params, v.K * np.array([[v.downscale], [v.downscale], [1]]), xy)
            out[v.name] = (xy / v.downscale, xyz)
        return out

    def summary(self) -> str:
        n_tr, n_te = len(self.split["train"]), len(self.split["test"])
        w, h = self.views[0].width, self.views[0].height
        pts = (f"{len(self.points)} SfM points" if self.points is not None else
               "no SfM points (training triangulates them with pycolmap from the known poses, once, cached)")
        return (f"{self.root}: {len(self.views)} views ({n_tr} train, {n_te} test) at {w}x{h}"
                + (f" (1/{self.downscale} size)" if self.downscale > 1 else "") + f", {self.source}, {pts}"
                + "".join(f"\n  - {n}" for n in self.notes))


def _missing_error(missing: list[Frame], total: int, camera_file: Path) -> DatasetError:
    names = ", ".join(f.listed_as for f in missing)
    return DatasetError(
        f"{camera_file}: {len(missing)} of {total} frames name images that are not there: {names}. Drop those "
        f"frames with `python -m glint_mi.scene DATASET --skip-missing` (it writes <string name=\"missing_images\" "
        f"value=\"skip\"/> into the scene), or restore the images.")


def _images_k(frame: Frame, root: Path, k: int) -> Path | None:
    """The frame's image in a ``images_<k>`` folder beside its own (nerfstudio's downscaled copies), if present."""
    p = frame.image_path
    if k == 1 or p is None or not p.parent.name.startswith("images"):
        return None
    q = p.parent.with_name(f"{p.parent.name}_{k}") / p.name
    return q if q.is_file() else None


def load_dataset(root: str | Path, downscale: int = 1, missing: str = "error", check_images: bool = True,
                 log=None) -> Dataset:
    """Load a COLMAP folder, a transforms.json (file or folder holding one) or a generated scene folder.

    ``downscale`` k: every view at 1/k of its full resolution (area filter; intrinsics scaled, rays through the
    centres of k x k blocks); ``missing``: ``error`` (default) lists every frame whose image is missing, ``skip``
    drops them (noted); ``check_images``: decode every image now (errors name the file)."""
    from glint_mi.data import colmap, transforms
    from glint_mi.data.undistort import colmap_camera, distortion_shift, undistort_frames

    log = log or (lambda *a: None)
    root = Path(root)
    if missing not in MISSING:
        raise DatasetError(f"missing_images = {missing!r}: use one of {MISSING}.")
    if not isinstance(downscale, int) or downscale < 1:
        raise DatasetError(f"downscale = {downscale!r}: must be an integer >= 1 (4 = a quarter of the width).")
    if not root.exists():
        raise DatasetError(f"{root}: no such dataset folder.")
    split = sparse = None
    if root.is_file() and root.suffix == ".json":
        camera_file, root = root, root.parent
    elif (root / "sparse").exists():
        camera_file = colmap.model_folder(root)
    elif (root / "transforms.json").exists():
        camera_file = root / "transforms.json"
    else:
        raise DatasetError(f"{root}: neither sparse/0 (COLMAP) nor transforms.json found.")
    if camera_file.suffix == ".json":
        frames, split, pts, cols = transforms.read_frames(camera_file)
        source = "transforms"
    else:
        frames, pts, cols, sparse = colmap.read_frames(root)
        source = "colmap"
    if not frames:
        raise DatasetError(f"{camera_file}: the camera file lists no images.")
    notes = []
    gone = [f for f in frames if f.image_path is None]
    if gone and missing == "error":
        raise _missing_error(gone, len(frames), camera_file)
    if gone:
        notes.append(f"{len(gone)} of {len(frames)} frames skipped, their images are missing: "
                     + ", ".join(f.listed_as for f in gone))
        frames = [f for f in frames if f.image_path is not None]
        if not frames:
            raise DatasetError(f"{camera_file}: none of its {len(gone)} frames has an image.")
    names = [f.name for f in frames]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise DatasetError(f"{camera_file}: several frames share the image name(s) {dup[:5]}; view names must be "
                           f"unique.")
    for f in frames:
        w, h = image_size(f.image_path)
        if (w, h) != (f.width, f.height):
            raise DatasetError(f"{f.image_path}: {h}x{w} (HxW) but its camera says {f.height}x{f.width}; the "
                               f"images and the camera file do not match.")
    if check_images:
        check_decodable([f.image_path for f in frames])
    distorted = {f.name: (f.model, f.width, f.height, list(f.params)) for f in frames
                 if f.model not in ("PINHOLE", "SIMPLE_PINHOLE")}
    for cam in {(m, w, h, tuple(p)) for m, w, h, p in distorted.values()}:  # every camera valid before any work
        colmap_camera(*cam)
    undist = undistort_frames(frames, log=log) if distorted else {}
    if distorted:
        models = sorted({m for m, *_ in distorted.values()})
        shifts = [distortion_shift(*distorted[n]) for n in list(distorted)[:8]]
        notes.append(f"{len(distorted)} views with a {'/'.join(models)} camera undistorted with COLMAP's undistorter "
                     f"(pycolmap; cropped to valid pixels, {undist[frames[0].name]['width']}x"
                     f"{undist[frames[0].name]['height']}): distortion moved pixels by up to "
                     f"{max(s[0] for s in shifts):.1f} px (mean {np.mean([s[1] for s in shifts]):.1f} px) at full size")
    views = []
    k = downscale
    for f in frames:
        if f.name in undist:
            u = undist[f.name]
            path, w, h, K = u["image_path"], u["width"], u["height"], u["K"]
        else:
            path, w, h, K = f.image_path, f.width, f.height, f.pinhole_K
        small = None if f.name in undist else _images_k(f, root, k)
        if small is not None:  # a downscaled copy that ships with the capture
            ws, hs = image_size(small)
            if abs(ws - w / k) > 1 or abs(hs - h / k) > 1:  # a stale or cropped copy: its pixels are not the rays
                raise DatasetError(f"{small}: {ws} x {hs}, but downscale {k} of the {w} x {h} image {path.name} is "
                                   f"{w / k:g} x {h / k:g}; write {small.parent.name}/ again from the images, or "
                                   f"remove it (the images are then downscaled on loading).")
            K = K * np.array([[ws / w], [hs / h], [1.0]])
            views.append(View(f.name, small, ws, hs, K, f.c2w, downscale=k))
            continue
        if w // k < 3 or h // k < 3:
            raise DatasetError(f"{path}: downscale {k} leaves {w // k}x{h // k} pixels; use a smaller factor.")
        views.append(View(f.name, path, w // k, h // k, K / np.array([[k], [k], [1.0]]), f.c2w, downscale=k))
    for v in views:
        gt = root / "gt" / f"{v.name}.exr"
        v.gt_path = gt if gt.exists() else None
    names = [v.name for v in views]
    split_path = root / "split.json"
    if split_path.exists():
        split = json.loads(split_path.read_text())
        if "train" not in split or "test" not in split:
            raise DatasetError(f"{split_path}: needs 'train' and 'test' lists of view names.")
    if split is not None:
        where = split.pop("from", split_path.name)
        unknown = [n for n in split["train"] + split["test"] if n not in names]
        if unknown and missing == "skip":  # frames dropped for missing images leave the split too
            split = {s: [n for n in split[s] if n in names] for s in ("train", "test")}
        elif unknown:
            raise DatasetError(f"{where}: names view(s) the camera file does not list: {unknown[:5]}.")
        both = sorted(set(split["train"]) & set(split["test"]))
        if both:
            raise DatasetError(f"{where}: view(s) {both[:5]} are in both 'train' and 'test'; a test view trained on "
                               f"measures nothing: keep each view in one list.")
    else:  # protocol: every 8th view from 0 is a test view
        test = names[::8]
        split = {"train": [n for n in names if n not in test], "test": test}
        notes.append(f"no split.json: the test views are every 8th view from the first ({len(test)} of {len(names)})")
    return Dataset(root, views, pts if pts is not None and len(pts) else None,
                   cols if cols is not None and len(cols) else None, split, source, sparse, notes, k,
                   distorted, {"downscale": k, "missing": missing}, source == "colmap" and bool(distorted))


def read_observations(root: str | Path):
    """The SfM tracks of the COLMAP model of a dataset folder (``sparse/0`` or ``sparse``), keyed by image stem, in
    that model's own pixels; None without one (see :meth:`Dataset.observations` for a loaded dataset's views)."""
    from glint_mi.data.colmap import model_folder, read_observations as read

    return read(model_folder(Path(root)))
