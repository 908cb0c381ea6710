"""Structure from motion with pycolmap: SfM points for the known poses of generated scenes, or full SfM with its
pose error against the truth (CPU SIFT, exhaustive matching)."""
from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import numpy as np

from .cameras import Camera, colmap_pose, qvec_to_rotmat


def _extract_and_match(db: Path, images: Path, names: list[str], cam: Camera):
    import pycolmap

    reader = pycolmap.ImageReaderOptions()
    reader.camera_model = "PINHOLE"
    reader.camera_params = f"{cam.fx},{cam.fy},{cam.cx},{cam.cy}"
    pycolmap.extract_features(db, images, image_names=names, camera_mode=pycolmap.CameraMode.SINGLE,
                              reader_options=reader, device=pycolmap.Device.cpu)
    pycolmap.match_exhaustive(db, device=pycolmap.Device.cpu)


def triangulate_known_poses(folder: Path, cams: list[Camera]) -> tuple[np.ndarray, np.ndarray, dict, dict]:
    """SIFT + exhaustive matching + triangulation with the true poses: ([P,3] xyz, [P,3] uint8 rgb, stats, tracks);
    tracks: per camera name, the pixel positions [n,2] (in these cameras' pixels) of its features that triangulated
    and the rows [n] of their points in xyz."""
    import pycolmap

    images = folder / "images"
    names = [f"{c.name}.png" for c in cams]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        db_path = tmp / "database.db"
        _extract_and_match(db_path, images, names, cams[0])
        db = pycolmap.Database.open(db_path)
        rec = pycolmap.Reconstruction()
        for camera in db.read_all_cameras():
            rec.add_camera_with_trivial_rig(camera)
        by_name = {f"{c.name}.png": c for c in cams}
        for image in db.read_all_images():
            q, t = colmap_pose(by_name[image.name])
            R = qvec_to_rotmat(q)
            im = pycolmap.Image(name=image.name, camera_id=image.camera_id, image_id=image.image_id)
            rec.add_image_with_trivial_frame(im, pycolmap.Rigid3d(np.column_stack([R, t])))
        n_matches = db.num_matches()
        db.close()
        out = tmp / "tri"
        out.mkdir()
        tri = pycolmap.triangulate_points(rec, db_path, images, out)
        pts = tri.points3D
        row = {pid: i for i, pid in enumerate(pts)}
        tracks = {}
        for image in tri.images.values():
            obs = [(p.xy, row[p.point3D_id]) for p in image.points2D if p.has_point3D() and p.point3D_id in row]
            tracks[Path(image.name).stem] = (np.array([o[0] for o in obs], np.float64).reshape(-1, 2),
                                             np.array([o[1] for o in obs], np.int64))
    xyz = np.array([p.xyz for p in pts.values()]).reshape(-1, 3)
    rgb = np.array([p.color for p in pts.values()], np.uint8).reshape(-1, 3)
    stats = {"points3D": int(len(xyz)), "mean_track_length": float(tri.compute_mean_track_length()) if len(xyz) else 0.0,
             "mean_reprojection_error_px": float(tri.compute_mean_reprojection_error()) if len(xyz) else 0.0,
             "matches": int(n_matches)}
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

    images = folder / "images"
    names = [f"{c.name}.png" for c in cams]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        _extract_and_match(tmp / "database.db", images, names, cams[0])
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
