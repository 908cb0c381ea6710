"""Structure from motion with pycolmap: SfM points for known poses (any capture without points, generated rooms),
or full SfM with its pose error against known poses (the generator's check); CPU SIFT, exhaustive matching."""
from __future__ import annotations

import contextlib
import tempfile
import time
from pathlib import Path

import numpy as np

from glint_mi.conventions import qvec_to_rotmat
from glint_mi.data.cameras import Camera, colmap_pose


@contextlib.contextmanager
def quiet_colmap(level: int = 2):
    """COLMAP's log (hundreds of lines per run) down to errors only while the block runs."""
    import pycolmap

    old = pycolmap.logging.minloglevel
    pycolmap.logging.minloglevel = level
    try:
        yield
    finally:
        pycolmap.logging.minloglevel = old


def _extract_and_match(db: Path, images: Path, names: list[str], cams: list[Camera], max_image_size: int = 1600,
                       log=lambda m: None):
    """SIFT (CPU) on ``names`` in ``images`` and exhaustive matching into the database ``db``. One camera when all
    views share intrinsics (SINGLE), else one per image; the reconstruction sets the true intrinsics anyway."""
    import pycolmap

    reader = pycolmap.ImageReaderOptions()
    reader.camera_model = "PINHOLE"
    shared = all(np.allclose(c.K, cams[0].K) and (c.width, c.height) == (cams[0].width, cams[0].height)
                 for c in cams)
    if shared:
        c = cams[0]
        reader.camera_params = f"{c.fx},{c.fy},{c.cx},{c.cy}"
    extraction = pycolmap.FeatureExtractionOptions()
    extraction.max_image_size = max_image_size
    extraction.num_threads = 2
    t0 = time.perf_counter()
    pycolmap.extract_features(db, images, image_names=names,
                              camera_mode=pycolmap.CameraMode.SINGLE if shared else pycolmap.CameraMode.PER_IMAGE,
                              reader_options=reader, extraction_options=extraction, device=pycolmap.Device.cpu)
    pairs = len(names) * (len(names) - 1) // 2
    log(f"SfM 1/3: SIFT features of {len(names)} images in {time.perf_counter() - t0:.0f} s; matching all {pairs} "
        f"pairs (exhaustive; the longest stage)")
    t0 = time.perf_counter()
    pycolmap.match_exhaustive(db, device=pycolmap.Device.cpu)
    log(f"SfM 2/3: {pairs} pairs matched in {time.perf_counter() - t0:.0f} s; triangulating with the known poses")


@contextlib.contextmanager
def _linked(images: list[Path], cams: list[Camera]):
    """A temporary folder holding ``<camera name><suffix>`` links to ``images`` (COLMAP reads one folder, by
    name): any image names, formats and folders."""
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "images"
        folder.mkdir()
        names = []
        for p, c in zip(images, cams):
            name = f"{c.name}{Path(p).suffix.lower()}"
            (folder / name).symlink_to(Path(p).resolve())
            names.append(name)
        yield Path(tmp), folder, names


def triangulate_known_poses(images: list[Path], cams: list[Camera], max_image_size: int = 1600, log=lambda m: None
                            ) -> tuple[np.ndarray, np.ndarray, dict, dict]:
    """SIFT + exhaustive matching + triangulation with the known poses ``cams`` (pinhole, at the resolution of
    ``images``, one file per camera, any format Pillow and COLMAP read): ([P,3] xyz, [P,3] uint8 rgb, stats,
    tracks); tracks: per camera name, the pixel positions [n,2] (in these cameras' pixels) of its features that
    triangulated and the rows [n] of their points in xyz. Raises RuntimeError with one line on failure."""
    import pycolmap

    with _linked(images, cams) as (tmp, img_dir, names), quiet_colmap():
        db_path = tmp / "database.db"
        _extract_and_match(db_path, img_dir, names, cams, max_image_size, log)
        db = pycolmap.Database.open(db_path)
        by_name = dict(zip(names, cams))
        db_images = db.read_all_images()
        if len(db_images) < 2:
            db.close()
            raise RuntimeError(f"SIFT read {len(db_images)} of {len(names)} images")
        rec = pycolmap.Reconstruction()
        seen_cams = set()
        for image in db_images:
            c = by_name[image.name]
            if image.camera_id not in seen_cams:
                cam = pycolmap.Camera(model="PINHOLE", width=c.width, height=c.height,
                                      params=[c.fx, c.fy, c.cx, c.cy], camera_id=image.camera_id)
                rec.add_camera_with_trivial_rig(cam)
                seen_cams.add(image.camera_id)
            q, t = colmap_pose(c)
            im = pycolmap.Image(name=image.name, camera_id=image.camera_id, image_id=image.image_id)
            rec.add_image_with_trivial_frame(im, pycolmap.Rigid3d(np.column_stack([qvec_to_rotmat(q), t])))
        n_matches = db.num_matches()
        n_keypoints = sum(db.num_keypoints_for_image(im.image_id) for im in db_images)
        db.close()
        if n_matches == 0:
            raise RuntimeError(f"no feature matches between the {len(names)} images ({n_keypoints} SIFT keypoints "
                               f"in all; images too small, too blurry or without texture)")
        out = tmp / "tri"
        out.mkdir()
        tri = pycolmap.triangulate_points(rec, db_path, img_dir, out)
        pts = tri.points3D
        row = {pid: i for i, pid in enumerate(pts)}
        tracks = {}
        for image in tri.images.values():
            obs = [(p.xy, row[p.point3D_id]) for p in image.points2D if p.has_point3D() and p.point3D_id in row]
            tracks[Path(image.name).stem] = (np.array([o[0] for o in obs], np.float64).reshape(-1, 2),
                                             np.array([o[1] for o in obs], np.int64))
    xyz = np.array([p.xyz for p in pts.values()]).reshape(-1, 3)
    rgb = np.array([p.color for p in pts.values()], np.uint8).reshape(-1, 3)
    if not len(xyz):
        raise RuntimeError(f"{n_matches} image pairs matched but no point triangulated (poses inconsistent with the "
                           f"images, or too little parallax)")
    stats = {"points3D": int(len(xyz)), "mean_track_length": float(tri.compute_mean_track_length()),
             "mean_reprojection_error_px": float(tri.compute_mean_reprojection_error()),
             "matches": int(n_matches), "keypoints": int(n_keypoints)}
    return xyz, rgb, stats, tracks


def _umeyama(src: np.ndarray, dst: np.ndarray):
    """Similarity (s, R, t) minimising |s R src + t - dst|^2 (points as rows)."""
    ms, md = src.mean(0), dst.mean(0)
    a, b = src - ms, dst - md
    U, S, Vt = np.linalg.svd(b.T @ a / len(src))
    D = np.diag([1, 1, np.sign(np.linalg.det(U @ Vt))])
    R = U @ D @ Vt
    s = np.trace(np.diag(S) @ D) / (a ** 2).sum(1).mean()
    return s, R, md - s * R @ ms


def full_sfm_pose_error(folder: Path, cams: list[Camera]) -> dict:
    """Incremental SfM (poses unknown), aligned to the truth by a similarity on camera centres; reports errors."""
    import pycolmap

    files = [folder / "images" / f"{c.name}.png" for c in cams]
    with _linked(files, cams) as (tmp, images, names), quiet_colmap():
        _extract_and_match(tmp / "database.db", images, names, cams)
        (tmp / "sfm").mkdir()
        recs = pycolmap.incremental_mapping(tmp / "database.db", images, tmp / "sfm")
    if not recs:
        return {"registered": 0, "views": len(cams)}
    rec = max(recs.values(), key=lambda r: r.num_reg_images())
    truth = {f"{c.name}.png": c for c in cams}
    est_c, true_c, rot_err = [], [], []
    poses = []
    for im in rec.images.values():
        if not im.has_pose:
            continue
        T = im.cam_from_world()
        R_w2c, t = T.rotation.matrix(), T.translation
        est_c.append(-R_w2c.T @ t)
        true_c.append(truth[im.name].c2w[:3, 3])
        poses.append((im.name, R_w2c))
    est_c, true_c = np.array(est_c), np.array(true_c)
    s, R, t = _umeyama(est_c, true_c)
    pos_err = np.linalg.norm((s * (R @ est_c.T)).T + t - true_c, axis=1)
    for name, R_w2c in poses:
        R_true = (truth[name].c2w[:3, :3] @ np.diag([-1.0, -1.0, 1.0])).T
        R_est = R_w2c @ R.T  # world (aligned) -> camera
        cos = (np.trace(R_est @ R_true.T) - 1) / 2
        rot_err.append(np.degrees(np.arccos(np.clip(cos, -1, 1))))
    extent = np.linalg.norm(true_c.max(0) - true_c.min(0))
    return {"registered": int(len(est_c)), "views": len(cams), "position_error_m_mean": float(pos_err.mean()),
            "position_error_rel_extent": float(pos_err.mean() / max(extent, 1e-9)),
            "rotation_error_deg_mean": float(np.mean(rot_err)), "scale": float(s)}
