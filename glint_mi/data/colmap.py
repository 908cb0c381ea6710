"""COLMAP models (``sparse/0`` or ``sparse``, text or binary): cameras, posed images, points and their tracks.

Any COLMAP camera model is read; the loader undistorts every non-pinhole one (glint_mi.data.undistort).
"""
from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from glint_mi.conventions import MI_TO_COLMAP, qvec_to_rotmat
from glint_mi.data.errors import DatasetError
from glint_mi.data.frames import Frame
from glint_mi.data.images import find_image

CAMERA_MODELS = {0: ("SIMPLE_PINHOLE", 3), 1: ("PINHOLE", 4), 2: ("SIMPLE_RADIAL", 4), 3: ("RADIAL", 5),
                 4: ("OPENCV", 8), 5: ("OPENCV_FISHEYE", 8), 6: ("FULL_OPENCV", 12), 7: ("FOV", 5),
                 8: ("SIMPLE_RADIAL_FISHEYE", 4), 9: ("RADIAL_FISHEYE", 5), 10: ("THIN_PRISM_FISHEYE", 12)}


def read_text(folder: Path):
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


def read_binary(folder: Path):
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


def model_folder(root: Path) -> Path:
    return root / "sparse" / "0" if (root / "sparse" / "0").exists() else root / "sparse"


def read_model(sparse: Path):
    for ext, reader in ((".bin", read_binary), (".txt", read_text)):
        if (sparse / f"cameras{ext}").exists():
            if not (sparse / f"images{ext}").exists():
                raise DatasetError(f"{sparse}: cameras{ext} but no images{ext}; a COLMAP model needs both (export "
                                   f"the model again, e.g. `colmap model_converter --output_type TXT`).")
            return reader(sparse)
    raise DatasetError(f"{sparse}: no cameras.txt or cameras.bin (expected a COLMAP model in sparse/0).")


def read_observations(sparse: Path) -> dict[str, tuple[np.ndarray, np.ndarray]] | None:
    """The SfM tracks of a COLMAP model: per image (keyed by the name's stem, as View.name), the pixel positions
    [n,2] of its features that triangulated to a 3D point and those points [n,3]. None without a model or without
    points3D."""
    sparse = Path(sparse)
    has_bin = (sparse / "cameras.bin").exists() and (sparse / "points3D.bin").exists()
    has_txt = (sparse / "cameras.txt").exists() and (sparse / "points3D.txt").exists()
    if not (has_bin or has_txt):
        return None
    _, _, pts, _, pids, tracks = read_binary(sparse) if has_bin else read_text(sparse)
    row = {int(pid): i for i, pid in enumerate(pids)}
    obs = {}
    for name, (xy, ids) in tracks.items():
        rows = np.array([row.get(int(k), -1) for k in ids], np.int64)
        obs[Path(name).stem] = (xy[rows >= 0], pts[rows[rows >= 0]].reshape(-1, 3))
    return obs


QUAT_TOLERANCE = 1e-3  # |q| - 1 beyond this is not a rounded unit quaternion but a broken pose


def read_frames(root: Path, images_dir: Path | None = None) -> tuple[list[Frame], np.ndarray, np.ndarray, Path]:
    """(frames sorted by image name, points [P,3], colours [P,3] uint8, the model folder)."""
    sparse = model_folder(root)
    cams, images, pts, cols, _, _ = read_model(sparse)
    images_dir = images_dir or root / "images"
    frames = []
    for iid, q, t, cid, name in sorted(images, key=lambda im: im[4]):
        if cid not in cams:
            raise DatasetError(f"{sparse}/images: image '{name}' uses camera {cid}, which cameras.* does not define.")
        model, w, h, params = cams[cid]
        q, t = np.asarray(q, float), np.asarray(t, float)
        norm = float(np.linalg.norm(q)) if np.isfinite(q).all() else float("nan")
        if not (abs(norm - 1.0) <= QUAT_TOLERANCE) or not np.isfinite(t).all():
            pose = f"QW QX QY QZ = {' '.join(f'{x:g}' for x in q)}, T = {' '.join(f'{x:g}' for x in t)}"
            raise DatasetError(f"{sparse}/images: image '{name}' has the pose {pose}: the quaternion must be a finite "
                               f"unit quaternion (|q| = {norm:g}) and T finite; export the model from COLMAP again.")
        R_w2c = qvec_to_rotmat(q / norm)
        c2w = np.eye(4)
        c2w[:3, :3] = R_w2c.T @ MI_TO_COLMAP
        c2w[:3, 3] = -R_w2c.T @ t
        frames.append(Frame(Path(name).stem, find_image(images_dir, name), str(images_dir / name), int(w), int(h),
                            model, list(params), c2w))
    return frames, pts, cols, sparse
