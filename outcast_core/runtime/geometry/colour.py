"""Colour spaces: the one module that converts between sRGB-encoded and linear RGB.

Images at the boundaries (files, Qt) and network inputs are sRGB-encoded float32 in [0, 1];
physics code (shading ratios, renders) works in linear RGB. Arrays are ``H x W x 3`` float32.
"""

from __future__ import annotations

import numpy as np

#: Rec. 709 / sRGB luminance weights (linear RGB).
LUMA_709 = np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)


def srgb_to_linear(image_srgb: np.ndarray) -> np.ndarray:
    """sRGB-encoded values in [0, 1] to linear RGB (IEC 61966-2-1 piecewise curve).

    Example:
        >>> float(srgb_to_linear(np.array([1.0]))[0])
        1.0
    """
    x = np.clip(np.asarray(image_srgb, dtype=np.float32), 0.0, 1.0)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4).astype(np.float32)


def linear_to_srgb(radiance_lin: np.ndarray) -> np.ndarray:
    """Linear RGB to sRGB encoding; values are clipped to [0, 1] first."""
    x = np.clip(np.nan_to_num(np.asarray(radiance_lin, dtype=np.float32), nan=0.0), 0.0, 1.0)
    return np.where(x <= 0.0031308, x * 12.92, 1.055 * np.power(x, 1 / 2.4) - 0.055).astype(
        np.float32
    )


def luminance(radiance_lin: np.ndarray) -> np.ndarray:
    """Rec. 709 luminance of linear RGB, ``H x W x 3 -> H x W``."""
    x = np.asarray(radiance_lin, dtype=np.float32)
    if x.shape[-1] != 3:
        raise ValueError(f"expected ... x 3 RGB, got shape {x.shape}")
    return x @ LUMA_709


def tonemap_aces(radiance_lin: np.ndarray, exposure: float = 1.0) -> np.ndarray:
    """Filmic tone map (Narkowicz's ACES fit) of linear HDR radiance to sRGB-encoded [0, 1]."""
    x = np.maximum(np.asarray(radiance_lin, dtype=np.float32) * exposure, 0.0)
    a, b, c, d, e = 2.51, 0.03, 2.43, 0.59, 0.14
    mapped = np.clip((x * (a * x + b)) / (x * (c * x + d) + e), 0.0, 1.0)
    return linear_to_srgb(mapped)
