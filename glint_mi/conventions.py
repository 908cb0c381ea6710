"""The project's conventions, stated once: units, depth, normals, quaternion orders, activations, colour spaces.

Everything else imports these helpers instead of re-deriving them.

- Units: metres; world frame right-handed, +Z up for generated rooms.
- Depth: *planar camera z* of the first surface (Cycles' Z pass), measured from the camera centre. The integrator
  composites the distance ``t`` along the (unit) ray from the pinhole and converts with z = t <d, forward>.
- Normals: world-space unit vectors, flipped to face the incoming ray. Camera-space comparisons use OpenCV axes
  (x right, y down, z forward), see :func:`world_to_opencv_normals`.
- Quaternions: Mitsuba ``ellipsoids`` store (x, y, z, w), identity (0, 0, 0, 1); 3DGS ``.ply`` ``rot_0..3`` store
  (w, x, y, z). Convert only with :func:`wxyz_to_xyzw` / :func:`xyzw_to_wxyz`.
- Activations (graphdeco 3DGS): scale = exp(raw), opacity / specular / transparency = sigmoid(raw),
  colour = max(SH(d) + 0.5, 0) with SH coefficients stored coefficient-major ``[c0 r g b, c1 r g b, ...]``.
- Colour: Gaussian colours and integrator outputs are *linear* RGB; PNGs are 8-bit sRGB.
"""
from __future__ import annotations

import numpy as np

SH_C0 = 0.28209479177387814  # Y_0^0, so colour = SH_C0 * dc + 0.5 for degree 0
IDENTITY_XYZW = (0.0, 0.0, 0.0, 1.0)
ROLES = ("interface", "transmission", "reflection")
KERNELS = ("surfel", "ellipsoid")
NORMAL_SOURCES = ("axis", "attribute")  # a Gaussian's normal: its kernel's thin axis, or an attribute of its own


def wxyz_to_xyzw(q: np.ndarray) -> np.ndarray:
    """[N, 4] (w, x, y, z) -> [N, 4] (x, y, z, w)."""
    q = np.asarray(q)
    return np.concatenate([q[..., 1:4], q[..., 0:1]], axis=-1)


def xyzw_to_wxyz(q: np.ndarray) -> np.ndarray:
    """[N, 4] (x, y, z, w) -> [N, 4] (w, x, y, z)."""
    q = np.asarray(q)
    return np.concatenate([q[..., 3:4], q[..., 0:3]], axis=-1)


def normalize_quaternions_xyzw(q: np.ndarray) -> np.ndarray:
    """Unit quaternions; a (near-)zero quaternion becomes the identity instead of NaN."""
    q = np.asarray(q, dtype=np.float64)
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    ident = np.broadcast_to(np.array(IDENTITY_XYZW), q.shape)
    return np.where(n > 1e-12, q / np.maximum(n, 1e-30), ident)


def sigmoid(x):
    x = np.asarray(x, dtype=np.float64)
    return 1.0 / (1.0 + np.exp(-x))


def logit(p, eps: float = 1e-7):
    p = np.clip(np.asarray(p, dtype=np.float64), eps, 1.0 - eps)
    return np.log(p / (1.0 - p))


def sh_degree_from_coeffs(n_values: int) -> int:
    """Degree of an SH colour block with ``n_values`` = 3 (deg + 1)^2 floats; raises for other widths."""
    k = n_values // 3
    deg = int(round(np.sqrt(k))) - 1
    if n_values % 3 or (deg + 1) ** 2 != k or not 0 <= deg <= 3:
        raise ValueError(f"{n_values} SH values per Gaussian is not 3*(deg+1)^2 for a degree 0..3")
    return deg


def world_to_opencv_normals(n_world: np.ndarray, cam_to_world: np.ndarray) -> np.ndarray:
    """World normals [.., 3] -> camera normals in OpenCV axes, given a Mitsuba camera-to-world 4x4 matrix.

    Mitsuba cameras look along +z with +y up and +x *left* in the image; OpenCV is x right, y down, z forward.
    """
    R = np.asarray(cam_to_world)[:3, :3]
    n_cam_mi = np.asarray(n_world) @ R  # R^T n for row vectors
    return n_cam_mi * np.array([-1.0, -1.0, 1.0])


def linear_to_srgb(x):
    x = np.clip(np.asarray(x, dtype=np.float64), 0.0, None)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def srgb_to_linear(x):
    x = np.asarray(x, dtype=np.float64)
    return np.where(x <= 0.04045, x / 12.92, np.power((x + 0.055) / 1.055, 2.4))


# Camera frames: Mitsuba camera-to-world matrices (x left, y up, z forward). COLMAP / OpenCV: x right, y down,
# z forward, so R_c2w_colmap = R_c2w_mitsuba @ MI_TO_COLMAP; NeRF / OpenGL: x right, y up, z backward,
# R_c2w_gl = R_c2w_mitsuba @ MI_TO_GL. The dataset readers (glint_mi.data) and the generator both use them.
MI_TO_COLMAP = np.diag([-1.0, -1.0, 1.0])
MI_TO_GL = np.diag([-1.0, 1.0, -1.0])


def rotmat_to_qvec(R: np.ndarray) -> np.ndarray:
    """Rotation matrix -> unit quaternion (w, x, y, z) with w >= 0 (COLMAP's convention)."""
    # symmetric 4x4 whose dominant eigenvector is the quaternion (x, y, z, w); names follow R's row-major flattening
    Rxx, Ryx, Rzx, Rxy, Ryy, Rzy, Rxz, Ryz, Rzz = np.asarray(R, float).flat
    K = np.array([
        [Rxx - Ryy - Rzz, 0, 0, 0],
        [Ryx + Rxy, Ryy - Rxx - Rzz, 0, 0],
        [Rzx + Rxz, Rzy + Ryz, Rzz - Rxx - Ryy, 0],
        [Ryz - Rzy, Rzx - Rxz, Rxy - Ryx, Rxx + Ryy + Rzz]]) / 3.0
    vals, vecs = np.linalg.eigh(K)
    q = vecs[[3, 0, 1, 2], np.argmax(vals)]
    return -q if q[0] < 0 else q


def rotation_matrices_xyzw(q_xyzw: np.ndarray) -> np.ndarray:
    """[N, 3, 3] rotation matrices of unit quaternions [N, 4] in (x, y, z, w) order (local -> world)."""
    x, y, z, w = np.asarray(q_xyzw).T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
    ], 1)


def qvec_to_rotmat(q) -> np.ndarray:
    w, x, y, z = q
    return np.array([[1 - 2 * y * y - 2 * z * z, 2 * x * y - 2 * w * z, 2 * x * z + 2 * w * y],
                     [2 * x * y + 2 * w * z, 1 - 2 * x * x - 2 * z * z, 2 * y * z - 2 * w * x],
                     [2 * x * z - 2 * w * y, 2 * y * z + 2 * w * x, 1 - 2 * x * x - 2 * y * y]])
