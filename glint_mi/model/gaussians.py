"""One Gaussian set as raw parameters: validation, activations, 3DGS ``.ply`` I/O and packing into Mitsuba's layout.

Raw parameters are what an optimiser updates and what a 3DGS ``.ply`` stores (log scales, logit opacities,
(w,x,y,z) rotations); :meth:`GaussianSet.activated` gives the values the renderer uses.  :meth:`GaussianSet.to_mitsuba`
is the only place that packs them into the ``ellipsoids`` layout used by the ``glint_gaussians`` shape.
"""
from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np

import glint_mi.conventions as cv

PLY_BASE = ("x", "y", "z", "nx", "ny", "nz")
# initial values of the paper (glint-method.md section 1), used wherever a value is not given
INIT_OPACITY, INIT_SPECULAR, INIT_TRANSPARENCY = 0.5, 1e-3, 0.01
SHELL_EXTENT = float(np.sqrt(2.0 * np.log(255.0)))  # shell radius in standard deviations: alpha of an opaque
#                                                  Gaussian falls below the 1/255 compositing cut-off there
MIN_SHELL_FACTOR = 1e-3  # the shell of a Gaussian that never reaches the cut-off (Mitsuba needs a positive scale)


def shell_factors(opacity, extent: float = SHELL_EXTENT) -> np.ndarray:
    """Per Gaussian, the fraction of the ``extent``-sigma shell inside which alpha = opacity x G can reach
    exp(-extent^2 / 2): sqrt(extent^2 + 2 ln opacity) / extent, clipped to [MIN_SHELL_FACTOR, 1]. Outside it the
    Gaussian's alpha is below the cut-off that the full shell of an opaque one has (1/255 at the default extent), so
    the integrator would skip it anyway; a smaller shell only spares the BVH those hits."""
    o = np.clip(np.asarray(opacity, np.float64).reshape(-1), 1e-300, 1.0)
    r2 = extent * extent + 2.0 * np.log(o)
    return np.clip(np.sqrt(np.maximum(r2, 0.0)) / extent, MIN_SHELL_FACTOR, 1.0)


NORMAL_MIN_LENGTH = 1e-6  # a normal attribute shorter than this has no direction (refused)


def axis_normals(quats_wxyz) -> np.ndarray:
    """The local z axis of each rotation in world space (a surfel's normal): the third column of R(q), q normalised."""
    q = cv.normalize_quaternions_xyzw(cv.wxyz_to_xyzw(np.asarray(quats_wxyz, np.float64).reshape(-1, 4)))
    return cv.rotation_matrices_xyzw(q)[:, :, 2]


def unit_normals(normals) -> np.ndarray:
    """Rows of ``normals`` at unit length (float64)."""
    n = np.asarray(normals, np.float64).reshape(-1, 3)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), NORMAL_MIN_LENGTH)


EXTRA_FIELDS = ("specular", "transparency")  # logit-valued per-Gaussian extras, written after the 3DGS fields


class GaussianDataError(ValueError):
    """Bad Gaussian input; the message names the source, the field and the fix."""


@dataclasses.dataclass
class GaussianSet:
    """Raw parameters of N Gaussians (float32 numpy arrays).

    Attributes:
        means:        [N, 3] world metres.
        log_scales:   [N, 3] log of the standard deviations along the local axes; a surfel ignores axis 2.
        quats_wxyz:   [N, 4] rotation local->world, (w, x, y, z) as in 3DGS files, not necessarily normalised.
        logit_opacity:[N] sigmoid -> opacity in (0, 1).
        sh:           [N, K, 3] SH coefficients, K = (deg+1)^2; sh[:, 0] is the DC term.
        logit_specular:    [N] sigmoid -> specular weight beta.
        logit_transparency:[N] sigmoid -> transparency tau.
        normals:      [N, 3] the normal a set carries as its own attribute (``normal_source: attribute``), not
                      necessarily unit length; the renderer reads it normalised. Derived from the rotation (the local
                      z axis, a surfel's normal) where not given; ignored with ``normal_source: axis``.
    """

    means: np.ndarray
    log_scales: np.ndarray
    quats_wxyz: np.ndarray
    logit_opacity: np.ndarray
    sh: np.ndarray
    logit_specular: np.ndarray
    logit_transparency: np.ndarray
    normals: np.ndarray | None = None

    def __post_init__(self):
        if self.normals is None:
            self.normals = axis_normals(self.quats_wxyz)
        for f in dataclasses.fields(self):
            setattr(self, f.name, np.ascontiguousarray(np.asarray(getattr(self, f.name), dtype=np.float32)))
        self.validate()

    # ----------------------------------------------------------------- checks
    def validate(self, source: str = "GaussianSet") -> "GaussianSet":
        n = self.means.shape[0] if self.means.ndim == 2 else -1
        expected = {"means": (n, 3), "log_scales": (n, 3), "quats_wxyz": (n, 4), "logit_opacity": (n,),
                    "logit_specular": (n,), "logit_transparency": (n,), "normals": (n, 3)}
        for name, shape in expected.items():
            arr = getattr(self, name)
            if arr.shape != shape:
                raise GaussianDataError(f"{source}: field '{name}' has shape {arr.shape}, expected {shape} "
                                        f"(N = {n} from 'means'); pass one row per Gaussian.")
        if self.sh.ndim != 3 or self.sh.shape[0] != n or self.sh.shape[2] != 3:
            raise GaussianDataError(f"{source}: field 'sh' has shape {self.sh.shape}, expected ({n}, K, 3).")
        cv.sh_degree_from_coeffs(3 * self.sh.shape[1])
        for f in dataclasses.fields(self):
            arr = getattr(self, f.name)
            if not np.all(np.isfinite(arr)):
                bad = int(np.argwhere((~np.isfinite(arr.reshape(arr.shape[0], -1))).any(1))[0, 0])
                raise GaussianDataError(f"{source}: field '{f.name}' has NaN/Inf (first at Gaussian {bad}); "
                                        f"remove or re-initialise those Gaussians.")
        short = np.linalg.norm(self.normals.astype(np.float64), axis=1) < NORMAL_MIN_LENGTH
        if short.any():
            raise GaussianDataError(f"{source}: field 'normals' has a zero-length row (first at Gaussian "
                                    f"{int(np.argmax(short))}); give a direction, or leave the field out to derive it "
                                    f"from the rotation.")
        return self

    def __len__(self) -> int:
        return int(self.means.shape[0])

    @property
    def sh_degree(self) -> int:
        return cv.sh_degree_from_coeffs(3 * self.sh.shape[1])

    # ------------------------------------------------------------ creation
    @classmethod
    def from_activated(cls, means, scales, quats_xyzw=None, opacities=None, colors=None, sh=None,
                       specular=None, transparency=None, sh_degree: int = 0) -> "GaussianSet":
        """Build from renderer-space values: scales > 0, opacities etc. in [0, 1], linear RGB colours or SH."""
        means = np.asarray(means, np.float64).reshape(-1, 3)
        n = len(means)
        scales = np.broadcast_to(np.asarray(scales, np.float64), (n, 3)) if np.ndim(scales) else np.full((n, 3), scales)
        if np.any(~(scales > 0)):
            raise GaussianDataError("from_activated: 'scales' must be > 0 (they are standard deviations in metres).")
        q = np.tile(cv.IDENTITY_XYZW, (n, 1)) if quats_xyzw is None else np.asarray(quats_xyzw, np.float64).reshape(n, 4)
        k = (sh_degree + 1) ** 2
        if sh is None:
            rgb = np.full((n, 3), 0.5) if colors is None else np.broadcast_to(np.asarray(colors, np.float64), (n, 3))
            sh = np.zeros((n, k, 3))
            sh[:, 0] = (rgb - 0.5) / cv.SH_C0
        fill = lambda v, d: np.full(n, d) if v is None else np.broadcast_to(np.asarray(v, np.float64).reshape(-1), (n,))
        return cls(means=means, log_scales=np.log(scales), quats_wxyz=cv.xyzw_to_wxyz(q),
                   logit_opacity=cv.logit(fill(opacities, INIT_OPACITY)), sh=np.asarray(sh).reshape(n, -1, 3),
                   logit_specular=cv.logit(fill(specular, INIT_SPECULAR)),
                   logit_transparency=cv.logit(fill(transparency, INIT_TRANSPARENCY)))

    @classmethod
    def empty(cls, sh_degree: int = 0) -> "GaussianSet":
        return cls(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 4)), np.zeros(0),
                   np.zeros((0, (sh_degree + 1) ** 2, 3)), np.zeros(0), np.zeros(0))

    # ---------------------------------------------------------- activations
    def activated(self) -> dict[str, np.ndarray]:
        """Renderer-space values: scales [N,3] m, quats_xyzw [N,4] unit, opacity/specular/transparency [N]."""
        return {
            "means": self.means.astype(np.float64),
            "scales": np.exp(self.log_scales.astype(np.float64)),
            "quats_xyzw": cv.normalize_quaternions_xyzw(cv.wxyz_to_xyzw(self.quats_wxyz)),
            "opacity": cv.sigmoid(self.logit_opacity),
            "sh": self.sh.astype(np.float64),
            "specular": cv.sigmoid(self.logit_specular),
            "transparency": cv.sigmoid(self.logit_transparency),
        }

    # --------------------------------------------------------- mitsuba pack
    def to_mitsuba(self, kernel: str = "surfel", min_shell_ratio: float = 0.3, opacity_shells: bool = True,
                   extent: float = SHELL_EXTENT, normals: bool = False) -> dict[str, np.ndarray]:
        """Arrays for the ``ellipsoids`` shape behind ``glint_gaussians`` (float32, C-contiguous).

        ``data`` [N,10] holds centre, *shell* scales and (x,y,z,w) quaternion: the bounding shell Mitsuba's BVH
        intersects (the shape multiplies its scales by ``extent``, in standard deviations). Its scales are the kernel
        scales widened so that no axis is thinner than ``min_shell_ratio`` times the largest (Mitsuba's float32
        ray/ellipsoid test loses hits on flat shells, see README "Limits"). With ``opacity_shells`` each shell is
        also shrunk to where the Gaussian's alpha = opacity x G falls to exp(-extent^2 / 2) (1/255 at the default
        extent, the compositing cut-off an opaque Gaussian's shell already has): :func:`shell_factors`.
        ``kernel_scales`` [N,3] are the standard deviations the integrator evaluates (a surfel ignores the third, which
        is kept so that files round-trip). With ``normals`` (``normal_source: attribute``) also ``normals`` [N,3], the
        unit normal attribute the integrator then reads instead of the rotation's axis.
        """
        a = self.activated()
        ks = a["scales"]
        axes = ks[:, :2] if kernel == "surfel" else ks
        smax = np.max(axes, axis=1, keepdims=True) if len(self) else np.zeros((0, 1))
        shell = np.maximum(ks, min_shell_ratio * smax)
        if opacity_shells:
            shell = shell * shell_factors(a["opacity"], extent)[:, None]
        data = np.concatenate([a["means"], shell, a["quats_xyzw"]], axis=1)
        out = {
            "data": data,
            "kernel_scales": ks,
            "opacities": a["opacity"][:, None],
            "sh_coeffs": a["sh"].reshape(len(self), -1),
            "specular": a["specular"][:, None],
            "transparency": a["transparency"][:, None],
        }
        if normals:
            out["normals"] = unit_normals(self.normals)
        return {k: np.ascontiguousarray(v, dtype=np.float32) for k, v in out.items()}

    @classmethod
    def from_mitsuba(cls, arrays: dict[str, np.ndarray], kernel: str = "surfel") -> "GaussianSet":
        """Inverse of :meth:`to_mitsuba`, up to float32 rounding of the activations (log(exp(x)) is not always x)."""
        data = np.asarray(arrays["data"], np.float64).reshape(-1, 10)
        n = len(data)
        ks = np.asarray(arrays.get("kernel_scales", data[:, 3:6]), np.float64).reshape(n, 3).copy()
        if kernel == "surfel":  # keep the file loadable by 3DGS viewers: a thin but finite third axis
            ks[:, 2] = np.maximum(ks[:, 2], 1e-6 * ks[:, :2].max(axis=1, initial=0.0) + 1e-12)
        get = lambda k, d: np.asarray(arrays[k], np.float64).reshape(n) if k in arrays else np.full(n, d)
        normals = np.asarray(arrays["normals"], np.float64).reshape(n, 3) if "normals" in arrays else None
        return cls(means=data[:, :3], log_scales=np.log(ks), quats_wxyz=cv.xyzw_to_wxyz(data[:, 6:10]),
                   logit_opacity=cv.logit(get("opacities", INIT_OPACITY)),
                   sh=np.asarray(arrays.get("sh_coeffs", np.zeros((n, 3))), np.float64).reshape(n, -1, 3),
                   logit_specular=cv.logit(get("specular", INIT_SPECULAR)),
                   logit_transparency=cv.logit(get("transparency", INIT_TRANSPARENCY)), normals=normals)

    # ---------------------------------------------------------------- PLY
    def save_ply(self, path: str | os.PathLike) -> Path:
        """Write a standard 3DGS binary ``.ply`` plus ``specular``/``transparency`` (logits); atomic. ``nx, ny, nz``
        (zeros in 3DGS's files) hold the normal attribute."""
        from plyfile import PlyData, PlyElement

        n, k = len(self), self.sh.shape[1]
        names = list(PLY_BASE) + [f"f_dc_{i}" for i in range(3)] + [f"f_rest_{i}" for i in range(3 * (k - 1))]
        # the standard 3DGS fields first, in their usual order (viewers read fixed offsets), GLINT's extras last
        names += ["opacity"] + [f"scale_{i}" for i in range(3)] + [f"rot_{i}" for i in range(4)] + list(EXTRA_FIELDS)
        # 3DGS stores f_rest channel-major: all R coefficients 1..K-1, then G, then B.
        rest = np.transpose(self.sh[:, 1:, :], (0, 2, 1)).reshape(n, -1)
        cols = [self.means, self.normals, self.sh[:, 0, :], rest, self.logit_opacity[:, None],
                self.log_scales, self.quats_wxyz, self.logit_specular[:, None], self.logit_transparency[:, None]]
        table = np.concatenate(cols, axis=1).astype(np.float32)
        rec = np.empty(n, dtype=[(nm, "f4") for nm in names])
        for i, nm in enumerate(names):
            rec[nm] = table[:, i]
        path = Path(path)
        tmp = path.with_name(path.name + ".tmp")
        PlyData([PlyElement.describe(rec, "vertex")]).write(str(tmp))
        os.replace(tmp, path)
        return path

    @classmethod
    def load_ply(cls, path: str | os.PathLike) -> "GaussianSet":
        """Read a 3DGS ``.ply`` (extras optional: missing ``specular``/``transparency`` get their init values; a
        normal ``nx, ny, nz`` of zero length, as 3DGS writes them, or none, is derived from the rotation)."""
        from plyfile import PlyData

        path = Path(path)
        if not path.exists():
            raise GaussianDataError(f"{path}: file not found.")
        try:
            v = PlyData.read(str(path))["vertex"]
        except Exception as exc:
            raise GaussianDataError(f"{path}: not a readable PLY with a 'vertex' element ({exc}).") from None
        have = set(v.data.dtype.names)
        required = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2",
                    "rot_0", "rot_1", "rot_2", "rot_3"]
        missing = [f for f in required if f not in have]
        if missing:
            raise GaussianDataError(f"{path}: missing PLY field(s) {missing}; a 3DGS .ply needs {required} "
                                    f"(+ optional f_rest_*, specular, transparency).")
        col = lambda names: np.stack([np.asarray(v[nm], np.float32) for nm in names], axis=1)
        n = len(v.data)
        n_rest = len([f for f in have if f.startswith("f_rest_")])
        if n_rest % 3:
            raise GaussianDataError(f"{path}: {n_rest} f_rest_* fields is not a multiple of 3.")
        k = 1 + n_rest // 3
        sh = np.zeros((n, k, 3), np.float32)
        sh[:, 0] = col(["f_dc_0", "f_dc_1", "f_dc_2"])
        if k > 1:
            sh[:, 1:] = np.transpose(col([f"f_rest_{i}" for i in range(n_rest)]).reshape(n, 3, k - 1), (0, 2, 1))
        extra = lambda nm, init: np.asarray(v[nm], np.float32) if nm in have else np.full(n, cv.logit(init), np.float32)
        quats = col(["rot_0", "rot_1", "rot_2", "rot_3"])
        normals = axis_normals(quats)
        if {"nx", "ny", "nz"} <= have:
            given = col(["nx", "ny", "nz"])
            given_ = ~(np.linalg.norm(given, axis=1) < NORMAL_MIN_LENGTH)  # NaN stays, and validate refuses it
            normals[given_] = given[given_]
        try:
            return cls(means=col(["x", "y", "z"]), log_scales=col(["scale_0", "scale_1", "scale_2"]),
                       quats_wxyz=quats, logit_opacity=np.asarray(v["opacity"]),
                       sh=sh, logit_specular=extra("specular", INIT_SPECULAR),
                       logit_transparency=extra("transparency", INIT_TRANSPARENCY), normals=normals)
        except GaussianDataError as exc:
            raise GaussianDataError(str(exc).replace("GaussianSet", str(path))) from None

    def subset(self, mask_or_index) -> "GaussianSet":
        return GaussianSet(**{f.name: getattr(self, f.name)[mask_or_index] for f in dataclasses.fields(self)})

    @staticmethod
    def concatenate(sets: list["GaussianSet"]) -> "GaussianSet":
        return GaussianSet(**{f.name: np.concatenate([getattr(s, f.name) for s in sets]) for f in dataclasses.fields(GaussianSet)})
