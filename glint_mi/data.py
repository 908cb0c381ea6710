"""Datasets: views (image, intrinsics, Mitsuba camera-to-world), SfM points, split, optional ground truth.

Reads (protocol.md): a COLMAP folder (``sparse/0/{cameras,images,points3D}.{txt,bin}``, PINHOLE or SIMPLE_PINHOLE),
a NeRF ``transforms.json`` (OpenGL camera axes), and the generated layout (both of those plus ``gt/*.exr``).
Every inconsistency raises :class:`DatasetError` naming the file, the field and the fix.
"""
from __future__ import annotations

import dataclasses
import json
import struct
from pathlib import Path

import numpy as np

from .dataset.cameras import MI_TO_COLMAP, MI_TO_GL, qvec_to_rotmat

CAMERA_MODELS = {0: ("SIMPLE_PINHOLE", 3), 1: ("PINHOLE", 4), 2: ("SIMPLE_RADIAL", 4), 3: ("RADIAL", 5),
                 4: ("OPENCV", 8), 5: ("OPENCV_FISHEYE", 8), 6: ("FULL_OPENCV", 12), 7: ("FOV", 5),
                 8: ("SIMPLE_RADIAL_FISHEYE", 4), 9: ("RADIAL_FISHEYE", 5), 10: ("THIN_PRISM_FISHEYE", 12)}
IMAGE_EXTS = (".png", ".jpg", ".jpeg", ".PNG", ".JPG", ".JPEG")


class DatasetError(ValueError):
    """Bad dataset input; the message names the file, the field and the fix."""


@dataclasses.dataclass
class View:
    name: str                 # image stem, e.g. "view_003"
    image_path: Path
    width: int
    height: int
    K: np.ndarray             # [3, 3] pixels
    c2w: np.ndarray           # [4, 4] Mitsuba camera-to-world (x left, y up, z forward)
    gt_path: Path | None = None

    def load_image(self) -> np.ndarray:
        """[H, W, 3] float32 sRGB in [0, 1]."""
        from PIL import Image

        img = np.asarray(Image.open(self.image_path).convert("RGB"), dtype=np.float32) / 255.0
        if img.shape[:2] != (self.height, self.width):
            raise DatasetError(f"{self.image_path}: {img.shape[0]}x{img.shape[1]} (HxW) but the camera says "
                               f"{self.height}x{self.width}; resize the image or fix the camera.")
        return img

    def load_gt(self) -> dict[str, np.ndarray] | None:
        """{'rgb' [H,W,3] linear, 'depth' [H,W] planar z, 'normal' [H,W,3] world, 'glass' [H,W]} or None."""
        if self.gt_path is None:
            return None
        from .exr import read_gt_exr

        ch = read_gt_exr(self.gt_path)
        need = ["R", "G", "B", "Z", "N.X", "N.Y", "N.Z", "T"]
        missing = [c for c in need if c not in ch]
        if missing:
            raise DatasetError(f"{self.gt_path}: missing EXR channel(s) {missing}; expected {need}.")
        out = {"rgb": np.stack([ch["R"], ch["G"], ch["B"]], -1), "depth": ch["Z"],
               "normal": np.stack([ch["N.X"], ch["N.Y"], ch["N.Z"]], -1), "glass": ch["T"]}
        for k, v in out.items():
            if v.shape[:2] != (self.height, self.width):
                raise DatasetError(f"{self.gt_path}: {v.shape[0]}x{v.shape[1]} but the camera says "
                                   f"{self.height}x{self.width}.")
            if not np.isfinite(v).all():
                raise DatasetError(f"{self.gt_path}: NaN/Inf in '{k}'; regenerate or mask that view.")
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


# ------------------------------------------------------------------ COLMAP
def _read_colmap_text(folder: Path):
    """(cameras, images, points [P,3], colours [P,3], point ids [P], tracks: image name -> (xy [n,2], point ids [n]))."""
    cams, images, pts, cols, pids, tracks = {}, [], [], [], [], {}
    with open(folder / "cameras.txt") as f:
        for ln, line in enumerate(f, 1):
            if not line.strip() or line.startswith("#"):
                continue
            tok = line.split()
            try:
                cams[int(tok[0])] = (tok[1], int(tok[2]), int(tok[3]), [float(t) for t in tok[4:]])
            except (IndexError, ValueError):
                raise DatasetError(f"{folder / 'cameras.txt'}:{ln}: expected 'ID MODEL W H params...'.") from None
    with open(folder / "images.txt") as f:
        lines = [line for line in f if not line.startswith("#")]
    for ln in range(0, len(lines), 2):
        tok = lines[ln].split()
        if not tok:
            continue
        try:
            images.append((int(tok[0]), np.array([float(t) for t in tok[1:5]]), np.array([float(t) for t in tok[5:8]]),
                           int(tok[8]), " ".join(tok[9:])))
        except (IndexError, ValueError):
            raise DatasetError(f"{folder / 'images.txt'}: bad image line '{lines[ln].strip()[:60]}'; expected "
                               f"'ID QW QX QY QZ TX TY TZ CAMERA_ID NAME' followed by a points line.") from None
        try:
            a = np.array(lines[ln + 1].split() if ln + 1 < len(lines) else [], np.float64).reshape(-1, 3)
        except ValueError:
            raise DatasetError(f"{folder / 'images.txt'}: the points line of image '{images[-1][4]}' is not "
                               f"'X Y POINT3D_ID' triples.") from None
        tracks[images[-1][4]] = (a[:, :2], a[:, 2].astype(np.int64))
    p3 = folder / "points3D.txt"
    if p3.exists():
        with open(p3) as f:
            for line in f:
                if line.strip() and not line.startswith("#"):
                    tok = line.split()
                    pids.append(int(tok[0]))
                    pts.append([float(t) for t in tok[1:4]])
                    cols.append([int(t) for t in tok[4:7]])
    return (cams, images, np.array(pts).reshape(-1, 3), np.array(cols, np.uint8).reshape(-1, 3),
            np.array(pids, np.int64), tracks)


def _read_colmap_binary(folder: Path):
    def rd(f, fmt):
        return struct.unpack("<" + fmt, f.read(struct.calcsize("<" + fmt)))

    cams, images, tracks = {}, [], {}
    with open(folder / "cameras.bin", "rb") as f:
        for _ in range(rd(f, "Q")[0]):
            cid, model, w, h = rd(f, "iiQQ")
            name, n = CAMERA_MODELS.get(model, (f"model {model}", 0))
            cams[cid] = (name, w, h, list(rd(f, "d" * n)))
    with open(folder / "images.bin", "rb") as f:
        for _ in range(rd(f, "Q")[0]):
            iid, *qt, cid = rd(f, "idddddddi")
            name = b""
            while (c := f.read(1)) != b"\x00":
                name += c
            n2 = rd(f, "Q")[0]
            rec = np.frombuffer(f.read(24 * n2), dtype=[("x", "<f8"), ("y", "<f8"), ("id", "<i8")])
            images.append((iid, np.array(qt[:4]), np.array(qt[4:]), cid, name.decode()))
            tracks[name.decode()] = (np.column_stack([rec["x"], rec["y"]]), rec["id"].astype(np.int64))
    pts, cols, pids = [], [], []
    if (folder / "points3D.bin").exists():
        with open(folder / "points3D.bin", "rb") as f:
            for _ in range(rd(f, "Q")[0]):
                pid, x, y, z, r, g, b, _err, tl = rd(f, "QdddBBBdQ")
                f.read(8 * tl)
                pids.append(pid)
                pts.append([x, y, z])
                cols.append([r, g, b])
    return (cams, images, np.array(pts).reshape(-1, 3), np.array(cols, np.uint8).reshape(-1, 3),
            np.array(pids, np.int64), tracks)


def colmap_folder(root: Path) -> Path:
    return root / "sparse" / "0" if (root / "sparse" / "0").exists() else root / "sparse"


def read_observations(root: Path) -> dict[str, tuple[np.ndarray, np.ndarray]] | None:
    """The SfM tracks of a COLMAP model: per image (keyed by the name's stem, as View.name), the pixel positions
    [n,2] of its features that triangulated to a 3D point and those points [n,3]. None without a COLMAP model or
    without points3D (a transforms.json dataset)."""
    sparse = colmap_folder(Path(root))
    if (sparse / "cameras.bin").exists() and (sparse / "points3D.bin").exists():
        _, _, pts, _, pids, tracks = _read_colmap_binary(sparse)
    elif (sparse / "cameras.txt").exists() and (sparse / "points3D.txt").exists():
        _, _, pts, _, pids, tracks = _read_colmap_text(sparse)
    else:
        return None
    row = {int(pid): i for i, pid in enumerate(pids)}
    obs = {}
    for name, (xy, ids) in tracks.items():
        rows = np.array([row.get(int(k), -1) for k in ids], np.int64)
        obs[Path(name).stem] = (xy[rows >= 0], pts[rows[rows >= 0]].reshape(-1, 3))
    return obs


def _intrinsics(model, params, where) -> np.ndarray:
    if model == "SIMPLE_PINHOLE":
        f, cx, cy = params
        fx = fy = f
    elif model == "PINHOLE":
        fx, fy, cx, cy = params
    else:
        raise DatasetError(f"{where}: camera model {model} is not supported; undistort the images to PINHOLE first "
                           f"(`colmap image_undistorter`).")
    return np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])


def _find_image(folder: Path, name: str) -> Path | None:
    p = folder / name
    if p.exists():
        return p
    for ext in IMAGE_EXTS:
        if (folder / (name + ext)).exists():
            return folder / (name + ext)
    return None


def load_colmap(root: Path, images_dir: Path | None = None):
    sparse = colmap_folder(root)
    if (sparse / "cameras.bin").exists():
        cams, images, pts, cols, _, _ = _read_colmap_binary(sparse)
    elif (sparse / "cameras.txt").exists():
        cams, images, pts, cols, _, _ = _read_colmap_text(sparse)
    else:
        raise DatasetError(f"{sparse}: no cameras.txt or cameras.bin (expected a COLMAP model in sparse/0).")
    images_dir = images_dir or root / "images"
    views = []
    for iid, q, t, cid, name in sorted(images, key=lambda im: im[4]):
        if cid not in cams:
            raise DatasetError(f"{sparse}/images: image '{name}' uses camera {cid}, which cameras.* does not define.")
        model, w, h, params = cams[cid]
        K = _intrinsics(model, params, f"{sparse}/cameras camera {cid}")
        R_w2c = qvec_to_rotmat(q / np.linalg.norm(q))
        c2w = np.eye(4)
        c2w[:3, :3] = R_w2c.T @ MI_TO_COLMAP
        c2w[:3, 3] = -R_w2c.T @ t
        path = _find_image(images_dir, name)
        if path is None:
            raise DatasetError(f"{images_dir / name}: image listed in {sparse}/images.* is missing.")
        views.append(View(Path(name).stem, path, int(w), int(h), K, c2w))
    return views, pts, cols


# ---------------------------------------------------------- transforms.json
def load_transforms(path: Path):
    root = path.parent
    try:
        meta = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise DatasetError(f"{path}: not valid JSON ({exc}).") from None
    frames = meta.get("frames")
    if not frames:
        raise DatasetError(f"{path}: field 'frames' is missing or empty.")
    views = []
    for i, fr in enumerate(frames):
        get = lambda k: fr.get(k, meta.get(k))
        fp = fr.get("file_path")
        if fp is None or "transform_matrix" not in fr:
            raise DatasetError(f"{path}: frames[{i}] needs 'file_path' and 'transform_matrix'.")
        img = _find_image(root, fp)
        if img is None:
            raise DatasetError(f"{root / fp}: image of frames[{i}] in {path.name} is missing.")
        w, h = get("w"), get("h")
        if w is None or h is None:
            from PIL import Image

            w, h = Image.open(img).size
        fx, fy = get("fl_x"), get("fl_y") or get("fl_x")
        if fx is None:
            if "camera_angle_x" not in meta:
                raise DatasetError(f"{path}: give 'fl_x' (pixels) or 'camera_angle_x' (radians).")
            fx = fy = 0.5 * w / np.tan(0.5 * meta["camera_angle_x"])
        cx, cy = get("cx") if get("cx") is not None else w / 2, get("cy") if get("cy") is not None else h / 2
        m = np.asarray(fr["transform_matrix"], float)
        if m.shape != (4, 4) or not np.isfinite(m).all():
            raise DatasetError(f"{path}: frames[{i}].transform_matrix must be a finite 4x4 matrix.")
        c2w = m.copy()
        c2w[:3, :3] = m[:3, :3] @ MI_TO_GL
        views.append(View(Path(fp).stem, img, int(w), int(h), np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]]), c2w))
    return views


# ------------------------------------------------------------------ entry
def load_dataset(root: str | Path, check_images: bool = True) -> Dataset:
    """Load a COLMAP folder, a transforms.json (file or folder holding one) or a generated scene folder."""
    root = Path(root)
    if not root.exists():
        raise DatasetError(f"{root}: no such dataset folder.")
    if root.is_file() and root.suffix == ".json":
        views, pts, cols, source, root = load_transforms(root), None, None, "transforms", root.parent
    elif (root / "sparse").exists():
        (views, pts, cols), source = load_colmap(root), "colmap"
    elif (root / "transforms.json").exists():
        views, pts, cols, source = load_transforms(root / "transforms.json"), None, None, "transforms"
    else:
        raise DatasetError(f"{root}: neither sparse/0 (COLMAP) nor transforms.json found.")
    if not views:
        raise DatasetError(f"{root}: the camera file lists no images.")
    for v in views:
        gt = root / "gt" / f"{v.name}.exr"
        v.gt_path = gt if gt.exists() else None
        if check_images:
            from PIL import Image

            with Image.open(v.image_path) as im:
                if im.size != (v.width, v.height):
                    raise DatasetError(f"{v.image_path}: {im.size[1]}x{im.size[0]} (HxW) but its camera says "
                                       f"{v.height}x{v.width}; the images and the camera file do not match.")
    names = [v.name for v in views]
    split_path = root / "split.json"
    if split_path.exists():
        split = json.loads(split_path.read_text())
        unknown = [n for n in split.get("train", []) + split.get("test", []) if n not in names]
        if unknown or "train" not in split or "test" not in split:
            raise DatasetError(f"{split_path}: needs 'train' and 'test' lists of view names; unknown: {unknown[:5]}.")
    else:  # protocol: every 8th view from 0 is a test view
        test = names[::8]
        split = {"train": [n for n in names if n not in test], "test": test}
    return Dataset(root, views, pts if pts is not None and len(pts) else None,
                   cols if cols is not None and len(cols) else None, split, source)
