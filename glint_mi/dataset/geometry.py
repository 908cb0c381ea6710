"""Mesh primitives with per-face UVs (each face maps its texture once, no repetition) and a PLY writer for Mitsuba.

Meshes are (vertices [V,3], normals [V,3], uvs [V,2], faces [F,3] int) tuples; boxes are axis-aligned.
"""
from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np


@dataclasses.dataclass
class Mesh:
    vertices: np.ndarray  # [V, 3] metres
    normals: np.ndarray   # [V, 3] unit
    uvs: np.ndarray       # [V, 2] in [0, 1]
    faces: np.ndarray     # [F, 3] int32

    @staticmethod
    def concatenate(meshes: list["Mesh"]) -> "Mesh":
        offs = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
        return Mesh(np.concatenate([m.vertices for m in meshes]), np.concatenate([m.normals for m in meshes]),
                    np.concatenate([m.uvs for m in meshes]),
                    np.concatenate([m.faces + o for m, o in zip(meshes, offs)]).astype(np.int32))

    def save_ply(self, path: str | os.PathLike) -> Path:
        from plyfile import PlyData, PlyElement

        v = np.empty(len(self.vertices), dtype=[(n, "f4") for n in ("x", "y", "z", "nx", "ny", "nz", "u", "v")])
        for i, n in enumerate(("x", "y", "z")):
            v[n] = self.vertices[:, i]
            v["n" + n] = self.normals[:, i]
        v["u"], v["v"] = self.uvs[:, 0], self.uvs[:, 1]
        f = np.empty(len(self.faces), dtype=[("vertex_indices", "i4", (3,))])
        f["vertex_indices"] = self.faces
        path = Path(path)
        PlyData([PlyElement.describe(v, "vertex"), PlyElement.describe(f, "face")]).write(str(path))
        return path


def quad(origin, u, v) -> Mesh:
    """Rectangle origin + a u + b v, a, b in [0, 1]; normal u x v; UV (a, b)."""
    origin, u, v = (np.asarray(x, np.float64) for x in (origin, u, v))
    verts = np.array([origin, origin + u, origin + u + v, origin + v])
    n = np.cross(u, v)
    n /= np.linalg.norm(n)
    return Mesh(verts, np.tile(n, (4, 1)), np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float),
                np.array([[0, 1, 2], [0, 2, 3]], np.int32))


def box(lo, hi) -> Mesh:
    """Axis-aligned box [lo, hi] with outward normals; each face carries the full UV square."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    dx, dy, dz = hi - lo
    X, Y, Z = np.array([dx, 0, 0]), np.array([0, dy, 0]), np.array([0, 0, dz])
    return Mesh.concatenate([
        quad(lo, Y, X), quad(lo + Z, X, Y),                    # bottom (-z), top (+z)
        quad(lo, X, Z), quad(lo + Y, Z, X),                    # front (-y), back (+y)
        quad(lo, Z, Y), quad(lo + X, Y, Z),                    # left (-x), right (+x)
    ])


def sphere(center, radius, rings: int = 16, segments: int = 32) -> Mesh:
    th, ph = np.meshgrid(np.linspace(0, np.pi, rings + 1), np.linspace(0, 2 * np.pi, segments + 1), indexing="ij")
    n = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], -1).reshape(-1, 3)
    uv = np.stack([ph / (2 * np.pi), th / np.pi], -1).reshape(-1, 2)
    idx = np.arange((rings + 1) * (segments + 1)).reshape(rings + 1, segments + 1)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    faces = faces[np.linalg.norm(np.cross(n[faces[:, 1]] - n[faces[:, 0]], n[faces[:, 2]] - n[faces[:, 0]]), axis=1) > 1e-12]
    return Mesh(np.asarray(center) + radius * n, n, uv, faces.astype(np.int32))


def cylinder(center_bottom, radius, height, segments: int = 32) -> Mesh:
    ph = np.linspace(0, 2 * np.pi, segments + 1)
    ring = np.stack([np.cos(ph), np.sin(ph), np.zeros_like(ph)], -1)
    c = np.asarray(center_bottom, float)
    side_v = np.concatenate([c + radius * ring, c + radius * ring + [0, 0, height]])
    side_n = np.concatenate([ring, ring])
    side_uv = np.concatenate([np.stack([ph / (2 * np.pi), np.zeros_like(ph)], -1),
                              np.stack([ph / (2 * np.pi), np.ones_like(ph)], -1)])
    k = segments + 1
    i = np.arange(segments)
    side_f = np.concatenate([np.stack([i, i + 1, i + 1 + k], -1), np.stack([i, i + 1 + k, i + k], -1)])
    meshes = [Mesh(side_v, side_n, side_uv, side_f.astype(np.int32))]
    for z, sgn in ((0.0, -1.0), (height, 1.0)):
        v = np.concatenate([[c + [0, 0, z]], c + radius * ring[:-1] + [0, 0, z]])
        uv = np.concatenate([[[0.5, 0.5]], 0.5 + 0.5 * ring[:-1, :2]])
        j = np.arange(segments)
        f = np.stack([np.zeros(segments, int), 1 + j, 1 + (j + 1) % segments], -1)
        f = f if sgn > 0 else f[:, ::-1]
        meshes.append(Mesh(v, np.tile([0, 0, sgn], (len(v), 1)), uv, f.astype(np.int32)))
    return Mesh.concatenate(meshes)


def wall_with_openings(origin, u, v, holes) -> Mesh:
    """A wall rectangle (origin, u, v) minus axis-aligned holes given in wall coordinates (a0, a1, b0, b1) in [0,1].

    The wall is cut into a grid along the hole edges; cells inside a hole are dropped. UVs stay global to the wall.
    """
    a_cuts = sorted({0.0, 1.0, *[h[0] for h in holes], *[h[1] for h in holes]})
    b_cuts = sorted({0.0, 1.0, *[h[2] for h in holes], *[h[3] for h in holes]})
    origin, u, v = (np.asarray(x, float) for x in (origin, u, v))
    cells = []
    for a0, a1 in zip(a_cuts[:-1], a_cuts[1:]):
        for b0, b1 in zip(b_cuts[:-1], b_cuts[1:]):
            am, bm = 0.5 * (a0 + a1), 0.5 * (b0 + b1)
            if any(h[0] <= am <= h[1] and h[2] <= bm <= h[3] for h in holes):
                continue
            m = quad(origin + a0 * u + b0 * v, (a1 - a0) * u, (b1 - b0) * v)
            m.uvs = np.array([[a0, b0], [a1, b0], [a1, b1], [a0, b1]])
            cells.append(m)
    return Mesh.concatenate(cells)
