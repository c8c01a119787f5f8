"""Image metrics of the evaluation (numpy in, floats out): MSE and DSSIM."""

from __future__ import annotations

import numpy as np
import torch

from outcast_core.train.losses import dssim as _dssim_torch


def mse(a: np.ndarray, b: np.ndarray) -> float:
    """Mean squared error of two arrays of one shape."""
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    if a.shape != b.shape:
        raise ValueError(f"expected arrays of one shape, got {a.shape} and {b.shape}")
    return float(np.mean((a - b) ** 2))


def dssim(a: np.ndarray, b: np.ndarray) -> float:
    """``(1 - SSIM) / 2`` of two ``H x W x 3`` (or ``H x W``) images in [0, 1]."""
    a = np.asarray(a, np.float32)
    b = np.asarray(b, np.float32)
    if a.shape != b.shape:
        raise ValueError(f"expected images of one shape, got {a.shape} and {b.shape}")
    if a.ndim == 2:
        a, b = a[..., None], b[..., None]
    ta = torch.from_numpy(np.ascontiguousarray(np.moveaxis(a, -1, 0)))[None]
    tb = torch.from_numpy(np.ascontiguousarray(np.moveaxis(b, -1, 0)))[None]
    with torch.no_grad():
        return float(_dssim_torch(ta, tb)[0])


def depth_errors(pred: np.ndarray, gt: np.ndarray, valid: np.ndarray) -> dict[str, float]:
    """Scale-free depth errors of ``pred`` against ``gt`` on the ``valid`` pixels.

    ``pred`` has no scale (``Z`` is scale-invariant), so it is first scaled by the median of
    ``gt / pred`` (the usual protocol for monocular depth without a metric scale).

    Returns:
        ``silog``: ``sqrt(mean(e^2) - mean(e)^2)`` of ``e = log pred - log gt`` (scale-free);
        ``abs_rel``: ``mean(|s pred - gt| / gt)``; ``delta1``: fraction with
        ``max(s pred / gt, gt / (s pred)) < 1.25``. NaN when no pixel is valid.
    """
    pred = np.asarray(pred, np.float64)
    gt = np.asarray(gt, np.float64)
    if pred.shape != gt.shape or valid.shape != gt.shape:
        raise ValueError(f"expected arrays of one shape, got {pred.shape}, {gt.shape}, "
                         f"{valid.shape}")
    ok = valid & np.isfinite(gt) & (gt > 0) & np.isfinite(pred) & (pred > 0)
    if not ok.any():
        return {"silog": float("nan"), "abs_rel": float("nan"), "delta1": float("nan")}
    p, g = pred[ok], gt[ok]
    e = np.log(p) - np.log(g)
    s = np.median(g / p)
    ratio = np.maximum(s * p / g, g / (s * p))
    return {"silog": float(np.sqrt(max(np.mean(e**2) - np.mean(e) ** 2, 0.0))),
            "abs_rel": float(np.mean(np.abs(s * p - g) / g)),
            "delta1": float(np.mean(ratio < 1.25))}


def iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two boolean masks (1 when both are empty)."""
    a, b = np.asarray(a, bool), np.asarray(b, bool)
    union = np.logical_or(a, b).sum()
    return 1.0 if union == 0 else float(np.logical_and(a, b).sum() / union)
