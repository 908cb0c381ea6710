"""Training pixels of a dataset as patches of rays, drawn across views (the ray tracer's cost is per ray).

:class:`RayBank` holds, for every training view, the photo, its priors and the world-space ray through every pixel
centre; :meth:`RayBank.sample` draws ``patches`` random ``p x p`` patches (views and positions from a numpy
Generator, so a run is reproducible and resumable). Rays of a patch are contiguous, row-major: patch losses
(D-SSIM, depth-normal consistency, TV) use fixed neighbour indices.
"""
from __future__ import annotations

import dataclasses
import functools

import numpy as np

from glint_mi.data import View

from glint_mi.data.priors import load_prior, prior_conventions
from glint_mi.data.rays import camera_axes_cv, pixel_rays  # noqa: F401 (pixel_rays: the trainer's)


@dataclasses.dataclass
class Batch:
    view: np.ndarray        # [M] view index of each ray
    flat: np.ndarray        # [M] index into the bank's flat pixel arrays
    origin: np.ndarray      # [M,3]
    direction: np.ndarray   # [M,3]
    axes: np.ndarray        # [M,3,3] OpenCV camera axes (columns) of each ray's view
    rgb: np.ndarray         # [M,3] sRGB target
    depth_prior: np.ndarray | None
    normal_prior: np.ndarray | None   # camera space, OpenCV axes
    albedo_prior: np.ndarray | None
    glass: np.ndarray | None            # ground-truth glass mask (TSGS baseline only)
    depth_affine: np.ndarray | None     # [M,2] (w, q) of each ray's view: prior ~ w * metric depth + q (depth_align sfm)
    patches: int
    patch: int
    cue: np.ndarray | None = None       # [M] SfM see-through cue: +1 seen through, -1 opaque, 0 no evidence
    depth_inverse: bool = False         # the depth prior is a disparity: affine in 1 / depth
    sfm_depth: np.ndarray | None = None  # [M] planar depth of a tracked SfM feature at the ray's pixel (0 = none)
    depth_weight: np.ndarray | None = None  # [M] the depth prior's weight in the ray's view (depth_prior_ref)


def inverse_variance_share(ref, err):
    """The share of its weight a prior term keeps when its measured error is ``err`` against a reference error
    ``ref``: min(1, (ref / err)^2) (scalar or array) - the normal prior's floor (prior_decay_ref) and each view's
    depth-prior weight (depth_prior_ref)."""
    return np.minimum(1.0, (ref / np.maximum(err, 1e-9)) ** 2)


def sfm_planes(points: np.ndarray, k: int = 12, planarity: float = 0.05):
    """The plane through each SfM point's ``k`` nearest points (itself among them): (a KD-tree of the points, [N] bool
    where they lie on a plane - smallest over middle eigenvalue of their covariance < ``planarity`` - and [N, 3] the
    planes' unit normals, unoriented). A point is tracked in many views, so each plane is fitted once."""
    from scipy.spatial import cKDTree

    pts = np.asarray(points, np.float64)
    tree = cKDTree(pts)
    _, idx = tree.query(pts, k)
    nb = pts[idx] - pts[idx].mean(1, keepdims=True)
    lam, vec = np.linalg.eigh(np.einsum("nki,nkj->nij", nb, nb))
    return tree, lam[:, 0] < planarity * np.maximum(lam[:, 1], 1e-300), vec[:, :, 0]


class RayBank:
    def __init__(self, views: list[View], root, use_priors: bool = True, glass_masks: str = "depth_gap"):
        """Photos, priors and rays of ``views`` at their own resolution (a dataset loaded with ``downscale`` k
        gives views whose images, priors and ground truth are block-averaged by k). ``glass_masks``: the config's
        ``trans_masks``; ``gt`` or ``prior`` load TSGS's per-pixel glass masks into ``self.glass``."""
        self.views = views
        self.sizes = [(v.height, v.width) for v in views]
        self.offsets = np.cumsum([0] + [h * w for h, w in self.sizes])
        self.rgb = np.concatenate([v.load_image().reshape(-1, 3) for v in views]).astype(np.float32)
        self.dirs = np.concatenate([pixel_rays(v) for v in views]).astype(np.float32)
        self.origins = np.array([v.c2w[:3, 3] for v in views], np.float32)
        self.axes = np.array([camera_axes_cv(v) for v in views], np.float32)
        self.priors = {}
        self.prior_info = prior_conventions(root) if use_priors else {}
        for kind in ("depth", "normal", "albedo"):
            maps = [load_prior(root, v, kind) if use_priors else None for v in views]
            lack = [v.name for v, m in zip(views, maps) if m is None]
            if lack and len(lack) < len(views):  # a kind for some views only would be dropped without a word
                from glint_mi.data.priors import PriorError, partial_kind

                raise PriorError(partial_kind(root, kind, lack, len(views)))
            if not lack:
                self.priors[kind] = np.concatenate([m.reshape(h * w, -1) for m, (h, w) in zip(maps, self.sizes)])
        self.priors.setdefault("depth", None)
        self.depth_inverse = self.prior_info.get("depth") == "disparity"
        self.depth_affine = None  # see align_depth_priors
        self.cue = None  # see see_through_cue
        self.sfm_depth = None  # see set_sfm_depth
        self.depth_weight = None  # see depth_prior_weights
        self.glass = None
        if glass_masks in ("gt", "prior"):  # TSGS's masks: ground truth (labelled) or a segmentation model's
            from glint_mi.data import DatasetError

            read = (lambda v: (v.load_gt() or {}).get("glass")) if glass_masks == "gt" else \
                (lambda v: load_prior(root, v, "glass"))
            maps = [read(v) for v in views]
            if any(m is None for m in maps):
                need = "gt/<view>.exr" if glass_masks == "gt" else \
                    "priors/glass/<view>.(npy|png|exr) (a segmentation model's glass masks)"
                raise DatasetError(f"{root}: trans_masks = {glass_masks} needs {need} for every training view.")
            self.glass = np.concatenate([m.reshape(-1) for m in maps]).astype(np.float32)

    def project(self, i: int, X: np.ndarray):
        """World points ``X`` [n,3] seen from view ``i``: continuous pixel coordinates (u, v), pixel (col, row) =
        (floor u, floor v), NaN behind the camera (z <= 1e-9), and their planar depth z (float64)."""
        pc = (X - self.origins[i]) @ self.axes[i].astype(np.float64)  # OpenCV camera coordinates
        z = pc[:, 2]
        front = z > 1e-9
        zs = np.where(front, z, 1.0)
        K = self.views[i].K
        u = np.where(front, K[0, 0] * pc[:, 0] / zs + K[0, 2], np.nan)
        v = np.where(front, K[1, 1] * pc[:, 1] / zs + K[1, 2], np.nan)
        return u, v, z

    def align_depth_priors(self, points: np.ndarray | None, min_points: int = 12, trials: int = 256,
                           seed: int = 0, rel: float = 0.05) -> dict:
        """Fit, once per view, the affine map prior ~ w * z + q from the metric SfM points the view sees (z their
        planar depth, the prior read at their pixel): RANSAC on pairs (inliers: the aligned prior within ``rel`` of
        the point's depth, or of its inverse for a disparity prior), then least squares on the inliers. Points
        hidden behind a surface, or seen through glass where the prior sees the glass, are outliers. Views with
        fewer than ``min_points`` points or no fit with w > 0 keep the per-batch fit (NaN here). Sets
        ``self.depth_affine`` [V,2]; returns a summary for the run report."""
        V = len(self.views)
        self.depth_affine = np.full((V, 2), np.nan)
        prior = self.priors.get("depth")
        if prior is None or points is None or len(points) == 0:
            return {"aligned_views": 0, "views": V, "why": "no depth prior" if prior is None else "no SfM points"}
        rng = np.random.default_rng(seed)
        counts, inlier_share = [], []
        for i, v in enumerate(self.views):
            u, w_, z = self.project(i, points)
            ok = z > 1e-6
            u, w_ = u[ok], w_[ok]
            col, row = np.floor(u).astype(np.int64), np.floor(w_).astype(np.int64)
            inside = (col >= 0) & (col < v.width) & (row >= 0) & (row < v.height)
            zz = z[ok][inside]
            pp = prior[self.offsets[i] + row[inside] * v.width + col[inside], 0].astype(np.float64)
            keep = pp > 0
            zz, pp = zz[keep], pp[keep]
            if self.depth_inverse:  # disparity prior ~ w / z + q
                zz = 1.0 / zz
            counts.append(len(zz))
            if len(zz) < min_points:
                continue
            best = None
            for _ in range(trials):
                a, b = rng.choice(len(zz), 2, replace=False)
                if abs(zz[a] - zz[b]) < 1e-9:
                    continue
                w = (pp[a] - pp[b]) / (zz[a] - zz[b])
                if not w > 0:
                    continue
                # inliers judged in metric depth (relative): a prior-space band lets a near-flat fit (w ~ 0) win on
                # a view of little depth range, whose depths (p - q) / w then blow up
                inl = np.abs((pp - (pp[a] - w * zz[a])) / w - zz) < rel * zz
                if best is None or inl.sum() > best.sum():
                    best = inl
            if best is None or best.sum() < max(min_points // 2, 3):
                continue
            A = np.column_stack([zz[best], np.ones(best.sum())])
            (w, q), *_ = np.linalg.lstsq(A, pp[best], rcond=None)
            if w > 0:
                self.depth_affine[i] = (w, q)
                inlier_share.append(float(best.mean()))
        done = int(np.isfinite(self.depth_affine[:, 0]).sum())
        return {"aligned_views": done, "views": V, "points_per_view_median": float(np.median(counts)),
                "inlier_share_median": float(np.median(inlier_share)) if inlier_share else float("nan")}

    def observation_pixels(self, observations: dict | None, points: bool = False) -> dict[int, tuple]:
        """Per view index with tracked SfM features: (rows [n], cols [n], planar depth of their 3D points [n]), and
        with ``points`` their 3D points [n, 3] (one 3D point has the same coordinates in every view that tracks it)."""
        out = {}
        for i, v in enumerate(self.views):
            ob = (observations or {}).get(v.name)
            if ob is None or len(ob[0]) == 0:
                continue
            xy, xyz = ob
            h, w = self.sizes[i]
            z = ((xyz - self.origins[i]) @ self.axes[i].astype(np.float64))[:, 2]
            col, row = np.floor(xy[:, 0]).astype(np.int64), np.floor(xy[:, 1]).astype(np.int64)
            ok = (col >= 0) & (col < w) & (row >= 0) & (row < h) & (z > 0)
            if ok.any():
                out[i] = (row[ok], col[ok], z[ok]) + ((xyz[ok],) if points else ())
        return out

    def prior_surface_depth(self, i: int, row: np.ndarray, col: np.ndarray) -> np.ndarray:
        """Metric planar depth of the surface the depth prior sees at pixels of view ``i`` (its SfM-aligned
        affine map inverted; NaN where the prior is invalid or view ``i`` has no fit)."""
        if self.priors.get("depth") is None or self.depth_affine is None or not np.isfinite(self.depth_affine[i, 0]):
            return np.full(len(row), np.nan)
        pr = self.priors["depth"][self.offsets[i] + row * self.sizes[i][1] + col, 0].astype(np.float64)
        a, q = self.depth_affine[i]
        z = (pr - q) / a  # the prior's metric depth (its inverse for a disparity prior)
        if self.depth_inverse:
            z = np.where(z > 0, 1.0 / np.maximum(z, 1e-12), np.inf)
        return np.where(pr > 0, z, np.nan)

    def depth_prior_weights(self, observations: dict | None, ref: float, min_points: int = 12,
                            quantile: float = 25.0) -> dict:
        """Each view's depth-prior weight from the prior's agreement with the SfM points it was aligned to
        (:meth:`align_depth_priors` first), measured without ground truth: r = the ``quantile``-th percentile of
        |z_prior - z| / z over the tracked features of the view (z the feature's 3D point's planar depth, z_prior
        the aligned prior's at its pixel), weight min(1, (ref / r)^2) - inverse variance, full for a view whose
        prior agrees to ``ref``. A low quantile: features seen through glass (where the prior sees the pane) or
        hidden behind a surface lie in the upper tail; the prior's own error moves the whole distribution. Views
        with fewer than ``min_points`` measured features (or no fit) take the median measured view's weight; with
        no measured view every weight is 1 (said in the summary). Sets ``self.depth_weight`` [V] float32; returns a
        summary for the run report."""
        V = len(self.views)
        r = np.full(V, np.nan)
        for i, (row, col, z) in self.observation_pixels(observations).items():
            zp = self.prior_surface_depth(i, row, col)
            ok = np.isfinite(zp) & (z > 0)
            if ok.sum() >= min_points:
                r[i] = np.percentile(np.abs(zp[ok] - z[ok]) / z[ok], quantile)
        measured = np.isfinite(r)
        w = inverse_variance_share(ref, r)
        out = {"ref": ref, "quantile": quantile, "views": V, "measured_views": int(measured.sum())}
        if not measured.any():
            self.depth_weight = np.ones(V, np.float32)
            return {**out, "why": f"no view with {min_points} tracked features on the aligned depth prior: "
                                  "every view at w_depth"}
        w = np.where(measured, w, np.median(w[measured]))
        self.depth_weight = w.astype(np.float32)
        return {**out, "residual_median": float(np.median(r[measured])), "weight_median": float(np.median(w)),
                "weight_min": float(w.min()), "weight_mean": float(w.mean()),
                "full_weight_views": int((w >= 1.0).sum())}

    def prior_normals_world(self, i: int) -> np.ndarray:
        """View ``i``'s normal prior as an [H, W, 3] image of world-space normals (float64; 0 where it is invalid or
        there is no normal prior): the prior is stored in OpenCV camera axes, the metrics compare in world space."""
        h, w = self.sizes[i]
        if self.priors.get("normal") is None:
            return np.zeros((h, w, 3))
        n_cv = self.priors["normal"][self.offsets[i]:self.offsets[i + 1]].reshape(h, w, 3).astype(np.float64)
        return n_cv @ self.axes[i].astype(np.float64).T

    def normal_prior_sfm_angles(self, observations: dict | None, points: np.ndarray | None, k: int = 12,
                                planarity: float = 0.05) -> dict[int, tuple]:
        """Per view index: (rows [n], cols [n], angles [n] deg) of its tracked features whose ``k`` nearest SfM points
        lie on a plane (smallest over middle eigenvalue of their covariance < ``planarity``) and whose pixel has a
        normal prior: the angle between that plane's normal and the prior's (unoriented, world space). Empty without
        a normal prior, SfM points (>= ``k``) or tracks."""
        out = {}
        for i, row, col, j, n_prior, plane in self.planar_prior_normals(observations, points, k, planarity):
            cos = np.abs(np.einsum("ni,ni->n", plane, n_prior)) / np.linalg.norm(n_prior, axis=1)
            out[i] = (row, col, np.degrees(np.arccos(np.clip(cos, 0.0, 1.0))))
        return out

    def planar_prior_normals(self, observations: dict | None, points: np.ndarray | None, k: int = 12,
                             planarity: float = 0.05):
        """The features :meth:`normal_prior_sfm_angles` measures, per view: yields (view index, rows [n], cols [n],
        their SfM points' indices [n], the normal prior there [n, 3] (world space, not normalised), the planes' unit
        normals [n, 3] (:func:`sfm_planes`, unoriented)). Nothing without a normal prior, SfM points (>= ``k``) or
        tracks."""
        if self.priors.get("normal") is None or points is None or len(points) < k or not observations:
            return
        tree, flat, plane = sfm_planes(points, k, planarity)
        for i, (row, col, _, xyz) in self.observation_pixels(observations, points=True).items():
            _, j = tree.query(xyz)  # the tracked feature's own 3D point
            n_prior = self.prior_normals_world(i)[row, col]
            ok = flat[j] & (np.linalg.norm(n_prior, axis=1) > 0.5)
            yield i, row[ok], col[ok], j[ok], n_prior[ok], plane[j[ok]]

    def normal_prior_sfm_agreement(self, observations: dict | None, points: np.ndarray | None, k: int = 12,
                                   planarity: float = 0.05, min_observations: int = 50) -> dict:
        """How far the normal prior is from the surfaces the SfM points describe, measured without ground truth: the
        angles of :meth:`normal_prior_sfm_angles` over every view. Returns their median and mean (deg; None with
        fewer than ``min_observations`` such features, and why) and the counts. On the tuning rooms the median
        follows the prior model's error scale (7301: 8.0, 11.1, 14.5, 28.2 deg at 0.5, 0.75, 1, 2;
        docs/results/prior_sweep)."""
        out = {"observations": 0, "median_deg": None}
        if self.priors.get("normal") is None:
            return {**out, "why": "no normal prior"}
        if points is None or len(points) < k or not observations:
            return {**out, "why": "no SfM points and tracks"}
        angles = [a for _, _, a in self.normal_prior_sfm_angles(observations, points, k, planarity).values()]
        a = np.concatenate(angles) if angles else np.zeros(0)
        out["observations"] = int(len(a))
        if len(a) < min_observations:
            return {**out, "why": f"{len(a)} tracked features on planar SfM neighbourhoods (< {min_observations})"}
        return {**out, "median_deg": float(np.median(a)), "mean_deg": float(a.mean())}

    def fit_depth_to_renders(self, render_depth, max_rays: int = 2048) -> None:
        """depth_align: image — the paper's per-image scale and shift of the depth prior (MonoSDF's closed form),
        fitted over each whole training view: ``render_depth(flat, vid)`` gives the interface's depth and alpha on a
        grid of <= ``max_rays`` pixels per view; least squares prior ~ w D + q (or w / D + q for a disparity prior)
        where both are valid sets each view's (w, q), which the depth loss uses until the next refit."""
        flats, vids = [], []
        for i, (h, w) in enumerate(self.sizes):
            step = max(1, int(np.ceil(np.sqrt(h * w / max_rays))))
            ys, xs = np.mgrid[step // 2:h:step, step // 2:w:step]
            flats.append(self.offsets[i] + ys.ravel() * w + xs.ravel())
            vids.append(np.full(ys.size, i))
        flat, vid = np.concatenate(flats), np.concatenate(vids)
        D, A = render_depth(flat, vid)
        P = self.priors["depth"][flat, 0].astype(np.float64)
        x = np.where(D > 1e-6, 1.0 / np.maximum(D, 1e-6), 0.0) if self.depth_inverse else D
        aff = np.full((len(self.views), 2), np.nan)
        for i in range(len(self.views)):
            m = (vid == i) & (P > 0) & (A > 0.5) & (D > 1e-6)
            if m.sum() >= 8:
                (w, q), *_ = np.linalg.lstsq(np.column_stack([x[m], np.ones(m.sum())]), P[m], rcond=None)
                if w > 0:
                    aff[i] = (w, q)
        self.depth_affine = aff

    def see_through_cue(self, observations: dict | None, margin: float = 0.05, radius: float = 0.04,
                        votes: str = "view", point_share: float = 0.2, photo: float = 0.0) -> dict:
        """A 3D cue for L_trans that the transmission set cannot bend (glint_mi's; the paper has only the albedo
        prior): an SfM feature tracked in a view lies on the surface that view sees, or behind it if that surface
        is glass. With the depth prior aligned to the metric SfM points (:meth:`align_depth_priors`,
        :meth:`prior_surface_depth`; a prior that sees the glass surface), an observation more than ``margin`` x
        its depth behind the prior is seen through (+1), any other lies on an opaque surface (-1). Every pixel
        takes the label of its nearest observation within ``radius`` x the image width (0 farther away, or where
        observations on one pixel disagree). Sets ``self.cue`` [pixels] int8; without any labelled view
        ``self.cue`` is None (the paper's depth-gap rule applies). Returns counts for the run report.

        ``votes``: ``view`` labels each observation by its own view's prior; ``point`` labels a 3D point seen through
        (+1 in every view that tracks it) when at least ``point_share`` of its labelled observations are: a prior that
        sees through the glass in some views (then the feature agrees with it) and the pane in others still marks
        what lies behind the glass in all of them.

        ``photo`` in (0, 1): the opaque label is dropped (0) on the pixels whose :meth:`photo_inconsistency` is above
        that quantile of the training pixels': a feature behind a pane agrees with a prior that sees through it, so
        agreement alone is no evidence of an opaque surface where the photos show light that moves with the view."""
        from scipy.ndimage import distance_transform_edt

        self.cue = None  # until a view has evidence: L_trans keeps the paper's depth-gap rule
        if not observations:
            return {"views": 0, "why": "no SfM tracks (a COLMAP model with images and points3D)"}
        if self.priors.get("depth") is None or self.depth_affine is None:
            return {"views": 0, "why": "no depth prior" if self.priors.get("depth") is None else
                    "the depth prior is not aligned to SfM (depth_align: sfm)"}
        if votes not in ("view", "point"):
            raise ValueError(f"votes must be view or point (got {votes!r})")
        cue = np.zeros(self.offsets[-1], np.int8)
        n_t = n_o = used = 0
        pix = self.observation_pixels(observations, points=True)
        labels = {}
        for i, (row, col, z, _) in pix.items():
            zs = self.prior_surface_depth(i, row, col)
            labels[i] = np.where(np.isfinite(zs), np.where(z > zs * (1.0 + margin), 1, -1), 0)
        if votes == "point" and labels:
            _, inv = np.unique(np.concatenate([pix[i][3] for i in labels]), axis=0, return_inverse=True)
            lab = np.concatenate([labels[i] for i in labels])
            inv = inv.ravel()
            plus = np.bincount(inv, weights=lab > 0)
            share = plus / np.maximum(np.bincount(inv, weights=lab != 0), 1)
            through = (share >= point_share) & (plus > 0)
            start = 0
            for i in labels:
                n = len(labels[i])
                labels[i] = np.where(labels[i] != 0, np.where(through[inv[start:start + n]], 1, -1), 0)
                start += n
        for i, (row, col, z, _) in pix.items():
            h, w = self.sizes[i]
            seen = labels[i] != 0
            lab = labels[i][seen]
            acc = np.zeros((h, w))
            np.add.at(acc, (row[seen], col[seen]), lab)
            if not acc.any():
                continue
            dist, (iy, ix) = distance_transform_edt(acc == 0, return_indices=True)
            lab_map = np.sign(acc[iy, ix]) * (dist <= radius * w)
            cue[self.offsets[i]:self.offsets[i + 1]] = lab_map.ravel().astype(np.int8)
            n_t, n_o, used = n_t + int((lab > 0).sum()), n_o + int((lab < 0).sum()), used + 1
        dropped = 0.0
        if photo > 0 and used:
            moving = self.photo_moving(photo)
            if moving is not None:
                moving &= cue == -1
                dropped = float(moving.sum() / max(int((cue == -1).sum()), 1))
                cue[moving] = 0
        rep = {"views": used, "seen_through_observations": n_t, "opaque_observations": n_o,
               "pixels_seen_through": float(np.mean(cue == 1)), "pixels_opaque": float(np.mean(cue == -1)),
               "margin": margin, "radius": radius, "votes": votes,
               **({"photo": photo, "opaque_dropped_by_photo": dropped} if photo > 0 else {})}
        if not used:  # an all-zero cue would silence L_trans (no pixel has evidence)
            return {**rep, "why": "no view has tracked SfM features and an aligned depth prior"}
        self.cue = cue
        return rep

    def photo_inconsistency(self, neighbours: int = 6, sigma: float = 1.0, depth_tol: float = 0.05) -> np.ndarray:
        """Per training pixel [pixels] float32: how far its colour is from what its ``neighbours`` nearest views (by
        camera centre) see at the same 3D point, the point placed by the depth prior aligned to SfM
        (:meth:`prior_surface_depth`): the median, over the views that see the point (their own aligned prior
        within ``depth_tol`` of its depth there), of the mean |c_i - c_j| of the photos blurred by ``sigma`` pixels,
        divided by the local gradient of view i's blurred photo + 0.01 (a point placed a pixel off on a texture
        differs for that reason alone). A diffuse surface agrees up to that misregistration; light reflected by a
        pane moves with the view. NaN where fewer than 2 views see the point, or the view has no alignment."""
        from scipy.ndimage import gaussian_filter, map_coordinates

        out = np.full(self.offsets[-1], np.nan, np.float32)
        if self.priors.get("depth") is None or self.depth_affine is None:
            return out
        V = len(self.views)
        blur = []
        for i in range(V):
            h, w = self.sizes[i]
            im = self.rgb[self.offsets[i]:self.offsets[i + 1]].reshape(h, w, 3).astype(np.float64)
            blur.append(np.stack([gaussian_filter(im[..., c], sigma) for c in range(3)], -1))
        centres = np.asarray(self.origins, np.float64)
        for i in range(V):
            h, w = self.sizes[i]
            rr, cc = np.mgrid[0:h, 0:w]
            z = self.prior_surface_depth(i, rr.ravel(), cc.ravel())
            ok = np.isfinite(z) & (z > 0)
            if not ok.any():
                continue
            dirs = self.dirs[self.offsets[i]:self.offsets[i + 1]].astype(np.float64)  # through the pixel centres
            X = centres[i] + dirs * (z / (dirs @ self.axes[i, :, 2].astype(np.float64)))[:, None]
            d = np.linalg.norm(centres - centres[i], axis=1)
            d[i] = np.inf
            diffs = []
            for j in np.argsort(d)[:min(neighbours, V - 1)]:
                hj, wj = self.sizes[j]
                u, q, zj = self.project(j, X)
                u, q = u - 0.5, q - 0.5  # pixel centres at integers (map_coordinates)
                inside = ok & (u >= 0) & (u <= wj - 1) & (q >= 0) & (q <= hj - 1)
                u, q = np.where(inside, u, 0.0), np.where(inside, q, 0.0)  # (NaN where the prior is not valid)
                col = np.clip(np.round(u), 0, wj - 1).astype(np.int64)
                row = np.clip(np.round(q), 0, hj - 1).astype(np.int64)
                dj = self.prior_surface_depth(j, row, col)
                seen = inside & np.isfinite(dj) & (np.abs(zj - dj) < depth_tol * np.where(np.isfinite(dj), dj, 1))
                cj = np.stack([map_coordinates(blur[j][..., c], [q, u], order=1, mode="nearest") for c in range(3)],
                              -1)
                diffs.append(np.where(seen, np.abs(cj - blur[i].reshape(-1, 3)).mean(-1), np.nan))
            D = np.array(diffs)
            n = np.isfinite(D).sum(0)
            med = np.full(len(z), np.nan)
            some = n >= 2
            med[some] = np.nanmedian(D[:, some], axis=0)
            gy, gx = np.gradient(blur[i].mean(-1))
            out[self.offsets[i]:self.offsets[i + 1]] = med / (np.hypot(gx, gy).ravel() + 0.01)
        return out

    def photo_moving(self, q: float) -> np.ndarray | None:
        """[pixels] bool: the training pixels whose :meth:`photo_inconsistency` (its defaults) is above its
        ``q``-quantile, where ``cue_photo`` drops opaque votes and ``prior_photo`` the priors; None when no pixel is
        scored. The score is computed once for both (seconds a room), again if the alignment or the depth prior is
        replaced (the photos of a bank do not change)."""
        cached = getattr(self, "_photo", None)
        if cached is None or cached[0] is not self.depth_affine or cached[1] is not self.priors.get("depth"):
            cached = self._photo = (self.depth_affine, self.priors.get("depth"), self.photo_inconsistency())
        score = cached[2]
        if not np.isfinite(score).any():
            return None
        return np.isfinite(score) & (score > np.nanquantile(score, q))

    def drop_priors_by_photo(self, q: float) -> dict:
        """``prior_photo``: the depth and normal priors are left out (0, which their terms read as no prior) at the
        training pixels whose :meth:`photo_inconsistency` is above its ``q``-quantile: there the colour at the
        prior's depth disagrees with the nearest views (light that moves with the view: a prior seeing through a
        pane, a reflection, a prior off its surface), and the photos alone decide. Pixels the measure cannot score
        (NaN: fewer than two views see the point) keep their priors. Call after the cue, which reads the whole prior."""
        if not 0 < q < 1:
            raise ValueError(f"q must be a quantile in (0, 1) (got {q!r})")
        if self.priors.get("depth") is None or self.depth_affine is None:
            return {"dropped": 0.0, "why": "no depth prior aligned to SfM: nothing places the point to compare"}
        drop = self.photo_moving(q)
        if drop is None:
            return {"dropped": 0.0, "why": "no pixel seen by two views at the prior's depth"}
        scored = float(np.isfinite(self._photo[2]).mean())
        for k in ("depth", "normal"):
            if self.priors.get(k) is not None:
                self.priors[k] = np.where(drop[:, None], 0, self.priors[k]).astype(self.priors[k].dtype)
        self._device = None  # the device copies hold the priors as they were
        return {"q": q, "dropped": float(drop.mean()), "scored": scored}

    def set_sfm_depth(self, observations: dict | None) -> dict:
        """``self.sfm_depth`` [pixels] float32: the planar depth of the tracked SfM feature at each training pixel
        (the median where several fall on one pixel; 0 = none), except where the see-through cue (computed first)
        says the feature lies behind glass. The interface's depth is pulled to it (``w_sfm_depth``)."""
        self.sfm_depth = None
        pix = self.observation_pixels(observations)
        if not pix:
            return {"pixels": 0, "why": "no SfM tracks"}
        depth = np.zeros(self.offsets[-1], np.float32)
        n = 0
        for i, (row, col, z) in pix.items():
            flat = self.offsets[i] + row * self.sizes[i][1] + col
            if self.cue is not None:
                keep = self.cue[flat] <= 0
                flat, z = flat[keep], z[keep]
            order = np.argsort(flat, kind="stable")
            flat, z = flat[order], z[order]
            uniq, start = np.unique(flat, return_index=True)
            depth[uniq] = [np.median(part) for part in np.split(z, start[1:])]
            n += len(uniq)
        self.sfm_depth = depth
        return {"pixels": n, "share_of_pixels": n / max(int(self.offsets[-1]), 1)}

    @property
    def has(self) -> set[str]:
        return {k for k, v in self.priors.items() if v is not None}

    def _draw(self, rng: np.random.Generator, patches: int, p: int):
        """The random part of a batch: each patch's view and top-left pixel (numpy, one Generator stream: a run is
        reproducible and resumes exactly)."""
        vidx = rng.integers(0, len(self.views), patches)
        hs = np.array([self.sizes[i][0] for i in vidx])
        ws = np.array([self.sizes[i][1] for i in vidx])
        if (hs < p).any() or (ws < p).any():
            raise ValueError(f"patch size {p} is larger than an image ({hs.min()}x{ws.min()}); lower 'patch'.")
        y0 = (rng.random(patches) * (hs - p + 1)).astype(np.int64)
        x0 = (rng.random(patches) * (ws - p + 1)).astype(np.int64)
        return vidx, ws, y0, x0

    def sample_device(self, rng: np.random.Generator, patches: int, p: int) -> "DeviceBatch":
        """:meth:`sample` on the device: the same draws from ``rng`` (3 numbers a patch go to the device), the
        pixel indices computed and the bank's arrays gathered there (:meth:`device_arrays`); equal to
        ``to_device(sample(...))`` (tested)."""
        import drjit as dr
        import mitsuba as mi

        from glint_mi.model.render import aligned

        vidx, _, y0, x0 = self._draw(rng, patches, p)
        a = self.device_arrays()
        i = dr.arange(mi.UInt32, patches * p * p)
        j, local = i // (p * p), i % (p * p)
        up = lambda x: mi.UInt32(aligned(x, np.uint32))
        view = dr.gather(mi.UInt32, up(vidx), j)
        y = dr.gather(mi.UInt32, up(y0), j) + local // p
        x = dr.gather(mi.UInt32, up(x0), j) + local % p
        flat = dr.gather(mi.UInt32, a["offsets"], view) + y * dr.gather(mi.UInt32, a["widths"], view) + x
        return _gather_batch(a, view, flat, patches, p, self.depth_inverse)

    def device_arrays(self) -> dict:
        """The bank's photos, rays and priors as flat Dr.Jit arrays (made once, again when the depth alignment, the
        see-through cue, the SfM depth or the depth prior's view weights are replaced)."""
        key = (self.depth_affine, self.cue, self.sfm_depth, self.depth_weight)
        cached = getattr(self, "_device", None)
        if cached is not None and all(x is y for x, y in zip(cached[0], key)):
            return cached[1]
        import mitsuba as mi

        from glint_mi.model.render import aligned

        f = lambda x: None if x is None else mi.Float(aligned(np.asarray(x, np.float32).ravel()))
        arrays = {"offsets": mi.UInt32(aligned(self.offsets[:-1], np.uint32)),
                  "widths": mi.UInt32(aligned([w for _, w in self.sizes], np.uint32)),
                  "rgb": f(self.rgb), "dirs": f(self.dirs), "origins": f(self.origins),
                  "axes": f(np.transpose(self.axes, (0, 2, 1))),  # per view: the x, y, z axes one after the other
                  "depth": None if self.priors.get("depth") is None else f(self.priors["depth"][:, 0]),
                  "normal": f(self.priors.get("normal")), "albedo": f(self.priors.get("albedo")),
                  "glass": f(self.glass), "affine": f(self.depth_affine), "cue": f(self.cue),
                  "sfm_depth": f(self.sfm_depth), "depth_weight": f(self.depth_weight)}
        self._device = (key, arrays)
        return arrays

    def sample(self, rng: np.random.Generator, patches: int, p: int) -> Batch:
        vidx, ws, y0, x0 = self._draw(rng, patches, p)
        dy, dx = np.mgrid[0:p, 0:p]
        ys = (y0[:, None] + dy.ravel()[None]).ravel()
        xs = (x0[:, None] + dx.ravel()[None]).ravel()
        view = np.repeat(vidx, p * p)
        flat = self.offsets[view] + ys * np.repeat(ws, p * p) + xs
        get = lambda k: None if self.priors.get(k) is None else self.priors[k][flat]
        return Batch(view, flat, self.origins[view], self.dirs[flat], self.axes[view], self.rgb[flat],
                     None if get("depth") is None else get("depth")[:, 0], get("normal"), get("albedo"),
                     None if self.glass is None else self.glass[flat],
                     None if self.depth_affine is None else self.depth_affine[view], patches, p,
                     None if self.cue is None else self.cue[flat], self.depth_inverse,
                     None if self.sfm_depth is None else self.sfm_depth[flat],
                     None if self.depth_weight is None else self.depth_weight[view])


def device_neighbours(patches: int, p: int):
    """:func:`patch_neighbours` as UInt32 arrays of the variant in force, made once per batch shape and variant (the
    objective gathers with them every step)."""
    import mitsuba as mi

    return _device_neighbours(patches, p, mi.variant())


@functools.lru_cache(maxsize=8)
def _device_neighbours(patches: int, p: int, variant: str):
    import mitsuba as mi

    from glint_mi.model.render import aligned

    return tuple(mi.UInt32(aligned(x, np.uint32)) for x in patch_neighbours(patches, p))


def patch_neighbours(patches: int, p: int):
    """Indices (i, right, down) of every pixel that has a right and a lower neighbour in its patch."""
    dy, dx = np.mgrid[0:p - 1, 0:p - 1]
    local = (dy * p + dx).ravel()
    base = (np.arange(patches)[:, None] * p * p + local[None]).ravel()
    return base, base + 1, base + p


@dataclasses.dataclass
class DeviceBatch:
    """A :class:`Batch` as Dr.Jit values of the variant in force (what the objective reads): per ray its view index,
    the ray, its view's OpenCV camera axes (``axes[2]`` the forward axis), the photo and the priors; ``depth_affine``
    = (w, q) per ray (NaN where the view has no fit)."""
    view: object
    origin: object
    direction: object
    axes: tuple
    rgb: object
    depth_prior: object | None
    normal_prior: object | None
    albedo_prior: object | None
    glass: object | None
    depth_affine: tuple | None
    cue: object | None
    sfm_depth: object | None
    patches: int
    patch: int
    depth_inverse: bool = False
    depth_weight: object | None = None  # per ray, its view's depth-prior weight (depth_prior_ref)


def _gather_batch(a: dict, view, flat, patches: int, p: int, depth_inverse: bool) -> DeviceBatch:
    """The rays ``flat`` (with their views ``view``) of a bank's device arrays ``a``."""
    import drjit as dr
    import mitsuba as mi

    g1 = lambda key, idx: None if a[key] is None else dr.gather(mi.Float, a[key], idx)
    g3 = lambda cls, key, idx: None if a[key] is None else dr.gather(cls, a[key], idx)
    affine = None if a["affine"] is None else (g1("affine", view * 2), g1("affine", view * 2 + 1))
    return DeviceBatch(view, g3(mi.Point3f, "origins", view), g3(mi.Vector3f, "dirs", flat),
                       tuple(g3(mi.Vector3f, "axes", view * 3 + k) for k in range(3)), g3(mi.Color3f, "rgb", flat),
                       g1("depth", flat), g3(mi.Vector3f, "normal", flat), g3(mi.Color3f, "albedo", flat),
                       g1("glass", flat), affine, g1("cue", flat), g1("sfm_depth", flat), patches, p, depth_inverse,
                       g1("depth_weight", view))


def to_device(b: Batch) -> DeviceBatch:
    """A host :class:`Batch` sent to the device as it is (tests and benchmarks that draw with :meth:`RayBank.sample`)."""
    import mitsuba as mi

    from glint_mi.model.render import aligned, floats

    vec = lambda cls, x: None if x is None else cls(*floats(x))
    one = lambda x: None if x is None else floats(x)
    affine = None if b.depth_affine is None else (floats(b.depth_affine[:, 0]), floats(b.depth_affine[:, 1]))
    return DeviceBatch(mi.UInt32(aligned(b.view, np.uint32)), vec(mi.Point3f, b.origin),
                       vec(mi.Vector3f, b.direction), tuple(vec(mi.Vector3f, b.axes[:, :, k]) for k in range(3)),
                       vec(mi.Color3f, b.rgb), one(b.depth_prior), vec(mi.Vector3f, b.normal_prior),
                       vec(mi.Color3f, b.albedo_prior), one(b.glass), affine, one(b.cue), one(b.sfm_depth),
                       b.patches, b.patch, b.depth_inverse, one(b.depth_weight))
