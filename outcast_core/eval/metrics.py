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
