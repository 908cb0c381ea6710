"""Pinhole cameras and their export: COLMAP text model, NeRF ``transforms.json``, Mitsuba sensors (the
generator's trajectories around the glass case are :mod:`glint_mi.dataset.trajectory`).

Camera frames: Mitsuba camera-to-world matrices (x left, y up, z forward). COLMAP: x right, y down, z forward, so
``R_c2w_colmap = R_c2w_mitsuba @ diag(-1, -1, 1)``; NeRF/OpenGL: x right, y up, z backward, so
``R_c2w_gl = R_c2w_mitsuba @ diag(-1, 1, -1)``.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from glint_mi.conventions import MI_TO_COLMAP, MI_TO_GL, rotmat_to_qvec


@dataclasses.dataclass
class Camera:
    """A pinhole view: Mitsuba camera-to-world [4,4] and intrinsics in pixels."""

    name: str
    c2w: np.ndarray
    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @classmethod
    def from_view(cls, v) -> "Camera":
        """The camera of a dataset View (glint_mi.data)."""
        return cls(v.name, v.c2w, v.width, v.height, v.K[0, 0], v.K[1, 1], v.K[0, 2], v.K[1, 2])

    def scaled(self, s: float) -> "Camera":
        """The same view with pixels ``1 / s`` as large (an image ``s`` times wider)."""
        return dataclasses.replace(self, width=round(self.width * s), height=round(self.height * s), fx=self.fx * s,
                                   fy=self.fy * s, cx=self.cx * s, cy=self.cy * s)

    @property
    def fov_x_deg(self) -> float:
        return float(np.degrees(2 * np.arctan(0.5 * self.width / self.fx)))

    @property
    def K(self) -> np.ndarray:
        return np.array([[self.fx, 0, self.cx], [0, self.fy, self.cy], [0, 0, 1.0]])


# ------------------------------------------------------------------ export
def colmap_pose(cam: Camera):
    """World-to-camera (qvec w,x,y,z; tvec) in COLMAP axes for a Mitsuba camera."""
    R_c2w = cam.c2w[:3, :3] @ MI_TO_COLMAP
    R_w2c = R_c2w.T
    t = -R_w2c @ cam.c2w[:3, 3]
    return rotmat_to_qvec(R_w2c), t


def write_colmap_text(folder: Path, cams: list[Camera], points=None, tracks=None) -> None:
    """``cameras.txt`` (one PINHOLE camera per view), ``images.txt``, ``points3D.txt`` (xyz, rgb) in ``folder``;
    with ``tracks`` (per camera name: pixel positions [n,2] and point rows [n]) also each image's POINTS2D and each
    point's TRACK, so that readers get the SfM observations (glint_mi's L_trans see-through cue uses them)."""
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / "cameras.txt", "w") as f:
        f.write("# CAMERA_ID, MODEL, WIDTH, HEIGHT, fx, fy, cx, cy\n")
        for i, c in enumerate(cams, 1):
            f.write(f"{i} PINHOLE {c.width} {c.height} {c.fx:.10g} {c.fy:.10g} {c.cx:.10g} {c.cy:.10g}\n")
    tracks = tracks or {}
    point_track = {}  # point row -> [(image id, point2D index)]
    with open(folder / "images.txt", "w") as f:
        f.write("# IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n#   POINTS2D[] as (X, Y, POINT3D_ID)\n")
        for i, c in enumerate(cams, 1):
            q, t = colmap_pose(c)
            xy, rows = tracks.get(c.name, (np.zeros((0, 2)), np.zeros(0, np.int64)))
            for k, r in enumerate(rows):
                point_track.setdefault(int(r), []).append((i, k))
            pts2d = " ".join(f"{x:.6f} {y:.6f} {int(r) + 1}" for (x, y), r in zip(xy, rows))
            f.write(f"{i} {' '.join(f'{v:.12g}' for v in q)} {' '.join(f'{v:.12g}' for v in t)} {i} {c.name}.png\n"
                    f"{pts2d}\n")
    with open(folder / "points3D.txt", "w") as f:
        f.write("# POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[]\n")
        if points is not None:
            xyz, rgb = points
            for i, (p, c) in enumerate(zip(xyz, rgb), 1):
                track = " ".join(f"{im} {k}" for im, k in point_track.get(i - 1, []))
                f.write(f"{i} {p[0]:.8g} {p[1]:.8g} {p[2]:.8g} {int(c[0])} {int(c[1])} {int(c[2])} 0"
                        f"{' ' + track if track else ''}\n")


def write_transforms_json(path: Path, cams: list[Camera]) -> None:
    c0 = cams[0]
    frames = []
    for c in cams:
        m = c.c2w.copy()
        m[:3, :3] = m[:3, :3] @ MI_TO_GL
        frames.append({"file_path": f"images/{c.name}.png", "transform_matrix": m.tolist()})
    data = {"fl_x": c0.fx, "fl_y": c0.fy, "cx": c0.cx, "cy": c0.cy, "w": c0.width, "h": c0.height,
            "camera_model": "OPENCV", "frames": frames}
    path.write_text(json.dumps(data, indent=1))


def sensor_xml(cam: Camera, spp: int) -> str:
    """A Mitsuba perspective sensor for ``cam`` (XML text, indented for a <scene>)."""
    mat = " ".join(f"{v:.10g}" for v in cam.c2w.ravel())
    return (f'    <sensor type="perspective" id="{cam.name}">\n'
            f'        <float name="fov" value="{cam.fov_x_deg:.10g}"/><string name="fov_axis" value="x"/>\n'
            f'        <transform name="to_world"><matrix value="{mat}"/></transform>\n'
            f'        <film type="hdrfilm"><integer name="width" value="{cam.width}"/>'
            f'<integer name="height" value="{cam.height}"/><rfilter type="box"/></film>\n'
            f'        <sampler type="independent"><integer name="sample_count" value="{spp}"/></sampler>\n'
            f'    </sensor>\n')
