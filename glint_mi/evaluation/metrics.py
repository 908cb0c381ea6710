"""The evaluation metrics of protocol.md, one implementation for every CLI, notebook and benchmark.

All functions take numpy arrays of one view: ``rgb`` sRGB in [0, 1] [H,W,3], ``depth`` planar z [H,W] (0 = nothing),
``normal`` world unit vectors [H,W,3], ``t`` / ``glass`` [H,W] in [0, 1]. Empty pixel sets give NaN (never 0, which
would look like a perfect score), and means over views skip NaN.
"""
from __future__ import annotations

import math

import numpy as np

METRICS = ("psnr", "ssim", "normal_mae", "normal_mae_glass", "absrel", "absrel_glass", "t_iou", "t_f1",
           "t_off_glass", "t_on_glass", "psnr_glass", "psnr_off_glass")
HIGHER_IS_BETTER = {"psnr": True, "ssim": True, "normal_mae": False, "normal_mae_glass": False, "absrel": False,
                    "absrel_glass": False, "t_iou": True, "t_f1": True, "t_off_glass": False, "t_on_glass": True,
                    "psnr_glass": True, "psnr_off_glass": True,
                    "fps": True, "train_s": False}


def psnr(pred: np.ndarray, gt: np.ndarray, mask: np.ndarray | None = None) -> float:
    """PSNR of sRGB images in [0, 1]; with ``mask`` [H,W] over those pixels only (NaN when it has none)."""
    d = (np.clip(pred, 0, 1) - np.clip(gt, 0, 1)) ** 2
    if mask is not None:
        if not mask.any():
            return float("nan")
        d = d[mask]
    mse = float(np.mean(d))
    return float("inf") if mse == 0 else 10.0 * math.log10(1.0 / mse)


def ssim(pred: np.ndarray, gt: np.ndarray) -> float:
    """SSIM with a Gaussian window (sigma 1.5, 11 taps), channels averaged."""
    from skimage.metrics import structural_similarity

    h, w = gt.shape[:2]
    win = min(11, h - (1 - h % 2), w - (1 - w % 2))  # odd and no larger than the image (tiny test images)
    return float(structural_similarity(np.clip(pred, 0, 1), np.clip(gt, 0, 1), channel_axis=-1, data_range=1.0,
                                       gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
                                       win_size=max(win, 3) if win < 11 else None))


def normal_mae(pred: np.ndarray, gt: np.ndarray, mask: np.ndarray) -> float:
    """Mean angle in degrees between unit normals over ``mask`` (pixels where either normal is 0 count as 90 deg
    when the prediction is missing, and are excluded when the ground truth is)."""
    m = mask & (np.linalg.norm(gt, axis=-1) > 0.5)
    if not m.any():
        return float("nan")
    return float(angles_deg(pred[m], gt[m]).mean())


def angles_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per-pixel angle in degrees between [..., 3] normals (each normalised; a zero vector against a unit one: 90)."""
    a = a / np.maximum(np.linalg.norm(a, axis=-1, keepdims=True), 1e-12)
    b = b / np.maximum(np.linalg.norm(b, axis=-1, keepdims=True), 1e-12)
    return np.degrees(np.arccos(np.clip(np.sum(a * b, axis=-1), -1.0, 1.0)))


def absrel(pred: np.ndarray, gt: np.ndarray, mask: np.ndarray) -> float:
    m = mask & (gt > 0)
    if not m.any():
        return float("nan")
    return float(np.mean(np.abs(pred[m] - gt[m]) / gt[m]))


def iou_f1(t: np.ndarray, glass: np.ndarray, threshold: float = 0.5) -> tuple[float, float]:
    """Transparency IoU and F1 of ``t > threshold`` against the glass mask; NaN when neither has any pixel."""
    p, g = t > threshold, glass > 0.5
    inter, union = np.sum(p & g), np.sum(p | g)
    if union == 0:
        return float("nan"), float("nan")
    return float(inter / union), float(2 * inter / (p.sum() + g.sum()))


def view_metrics(pred: dict, gt: dict, image: np.ndarray) -> dict[str, float]:
    """Every metric of one view. ``pred``: rgb (sRGB), depth, normal, transparency; ``gt``: from
    :meth:`glint_mi.data.View.load_gt` (or None: image metrics only); ``image``: the sRGB photo."""
    out = {"psnr": psnr(pred["rgb"], image), "ssim": ssim(pred["rgb"], image)}
    if gt is None:
        return out
    valid = gt["depth"] > 0
    glass = valid & (gt["glass"] > 0.5)
    out.update(normal_mae=normal_mae(pred["normal"], gt["normal"], valid),
               normal_mae_glass=normal_mae(pred["normal"], gt["normal"], glass),
               absrel=absrel(pred["depth"], gt["depth"], valid),
               absrel_glass=absrel(pred["depth"], gt["depth"], glass))
    out["t_iou"], out["t_f1"] = iou_f1(pred["transparency"], gt["glass"])
    # mean transparency where the first surface is opaque (a 'veil' raises it) and where it is glass
    t = pred["transparency"]
    off = valid & ~glass
    out["t_off_glass"] = float(t[off].mean()) if off.any() else float("nan")
    out["t_on_glass"] = float(t[glass].mean()) if glass.any() else float("nan")
    # where the photometric error lies: the glass pixels and the rest (the background and surfaces seen directly)
    out["psnr_glass"] = psnr(pred["rgb"], image, glass)
    out["psnr_off_glass"] = psnr(pred["rgb"], image, ~glass)
    return out


def mean_metrics(per_view: list[dict]) -> dict[str, float]:
    keys = sorted({k for m in per_view for k in m})
    out = {}
    for k in keys:
        vals = np.array([m.get(k, np.nan) for m in per_view], np.float64)
        vals = vals[np.isfinite(vals)]
        out[k] = float(vals.mean()) if len(vals) else float("nan")
    return out


def table(rows: dict[str, dict], keys=("psnr", "ssim", "normal_mae", "absrel", "t_iou", "fps", "train_s")) -> str:
    """A markdown table, one row per name."""
    head = "| run | " + " | ".join(keys) + " |\n|---|" + "---|" * len(keys) + "\n"
    fmt = lambda v: "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f"{v:.4g}"
    return head + "".join(f"| {n} | " + " | ".join(fmt(r.get(k)) for k in keys) + " |\n" for n, r in rows.items())
