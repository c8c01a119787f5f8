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


def log_chromaticity(radiance_lin: np.ndarray, eps: float = 1e-4) -> np.ndarray:
    """``(log R/G, log B/G)`` of linear RGB (``... x 3 -> ... x 2``, float32), each channel
    offset by ``eps``: a change of the light's colour moves every material's by the same
    amount (the shade's shift, :data:`~outcast_core.runtime.pipeline.photo_shadows.
    SKY_SHADE_SHIFT`).

    Example:
        >>> [round(float(c), 3) for c in log_chromaticity(np.array([0.2, 0.4, 0.8]), eps=0.0)]
        [-0.693, 0.693]
    """
    lg = np.log(np.asarray(radiance_lin, np.float32) + np.float32(eps))
    return np.stack([lg[..., 0] - lg[..., 1], lg[..., 2] - lg[..., 1]], axis=-1)


#: :func:`is_greyscale`: the largest channel spread (sRGB) of a grey pixel (JPEG's chroma
#: noise) and the share of pixels that must be grey; and the spread of a coloured pixel, of
#: which a black-and-white photo has at most :data:`COLOUR_SHARE` (a red coat in a misty photo
#: is colour, and must not be turned grey).
GREY_SPREAD = 3.0 / 255.0
GREY_SHARE = 0.99
COLOUR_SPREAD = 12.0 / 255.0
COLOUR_SHARE = 0.001


def is_greyscale(image_srgb: np.ndarray) -> bool:
    """Whether an ``H x W x 3`` image is a black-and-white photo stored as RGB: its channels
    equal within :data:`GREY_SPREAD` on :data:`GREY_SHARE` of the pixels, and no more than
    :data:`COLOUR_SHARE` of them coloured (:data:`COLOUR_SPREAD`). A uint8 image is read as
    ``0..255``.

    Example:
        >>> grey = np.repeat(np.linspace(0, 1, 12, dtype=np.float32).reshape(3, 4, 1), 3, 2)
        >>> is_greyscale(grey), is_greyscale(grey * np.float32([1.0, 0.9, 0.8]))
        (True, False)
    """
    x = np.asarray(image_srgb)
    if x.ndim != 3 or x.shape[2] != 3:
        raise ValueError(f"expected an H x W x 3 image, got shape {x.shape}")
    if x.size == 0:
        return False
    step = max(1, int(np.sqrt(x.shape[0] * x.shape[1] / 250_000)))  # about 250k pixels
    x = x[::step, ::step].astype(np.float32)
    if np.asarray(image_srgb).dtype == np.uint8:
        x = x / np.float32(255.0)
    spread = x.max(axis=2) - x.min(axis=2)
    return bool(np.mean(spread <= GREY_SPREAD) >= GREY_SHARE
                and np.mean(spread > COLOUR_SPREAD) <= COLOUR_SHARE)


def grey_like(image_srgb: np.ndarray) -> np.ndarray:
    """An sRGB image made black-and-white: its luminance (linear, Rec. 709) in all three
    channels, so a relit black-and-white photo stays one (``H x W x 3`` float32)."""
    y = luminance(srgb_to_linear(image_srgb))
    return np.repeat(linear_to_srgb(y)[..., None], 3, axis=-1)


def tonemap_aces(radiance_lin: np.ndarray, exposure: float = 1.0) -> np.ndarray:
    """Filmic tone map (Narkowicz's ACES fit) of linear HDR radiance to sRGB-encoded [0, 1]."""
    x = np.maximum(np.asarray(radiance_lin, dtype=np.float32) * exposure, 0.0)
    a, b, c, d, e = 2.51, 0.03, 2.43, 0.59, 0.14
    mapped = np.clip((x * (a * x + b)) / (x * (c * x + d) + e), 0.0, 1.0)
    return linear_to_srgb(mapped)


#: Linear sRGB (D65) to CIE XYZ, and the D65 white point (IEC 61966-2-1).
_RGB_TO_XYZ = np.array([[0.4124564, 0.3575761, 0.1804375],
                        [0.2126729, 0.7151522, 0.0721750],
                        [0.0193339, 0.1191920, 0.9503041]], dtype=np.float32)
#: CIE XYZ (D65) to linear sRGB, float64 (colour profiles compose it with their own matrices).
XYZ_TO_SRGB = np.linalg.inv(_RGB_TO_XYZ.astype(np.float64))
_XYZ_TO_RGB = XYZ_TO_SRGB.astype(np.float32)
_WHITE_D65 = np.array([0.95047, 1.0, 1.08883], dtype=np.float32)
_LAB_EPS = (6.0 / 29.0) ** 3


def _lab_f(t: np.ndarray) -> np.ndarray:
    return np.where(t > _LAB_EPS, np.cbrt(t), t / (3 * (6.0 / 29.0) ** 2) + 4.0 / 29.0)


def lightness(y: np.ndarray) -> np.ndarray:
    """CIE ``L*`` (0-100) of relative luminance ``y`` (linear, white = 1): the ``L*`` of
    :func:`linear_to_lab` from the luminance alone.

    Example:
        >>> [round(float(v), 2) for v in lightness(np.array([0.0, 0.18, 1.0]))]
        [0.0, 49.5, 100.0]
    """
    return (116.0 * _lab_f(np.maximum(np.asarray(y, np.float32), 0.0)) - 16.0).astype(np.float32)


def linear_to_lab(radiance_lin: np.ndarray) -> np.ndarray:
    """Linear RGB (D65) to CIE L*a*b* (``L*`` in [0, 100]), ``... x 3``; negatives count as 0.

    Example:
        >>> [round(float(v), 3) + 0.0 for v in linear_to_lab(np.array([1.0, 1.0, 1.0]))]
        [100.0, 0.0, 0.0]
    """
    x = np.maximum(np.asarray(radiance_lin, np.float32), 0.0)
    f = _lab_f((x @ _RGB_TO_XYZ.T) / _WHITE_D65)
    lab = np.stack([116.0 * f[..., 1] - 16.0, 500.0 * (f[..., 0] - f[..., 1]),
                    200.0 * (f[..., 1] - f[..., 2])], axis=-1)
    return lab.astype(np.float32)


def lab_to_linear(lab: np.ndarray) -> np.ndarray:
    """CIE L*a*b* to linear RGB (D65), the inverse of :func:`linear_to_lab`; colours outside
    the sRGB gamut come out below 0 or above 1 (not clipped).

    Example:
        >>> x = np.array([[0.2, 0.5, 0.1], [0.9, 0.01, 0.3]], np.float32)
        >>> bool(np.allclose(lab_to_linear(linear_to_lab(x)), x, atol=1e-4))
        True
    """
    lab = np.asarray(lab, np.float32)
    fy = (lab[..., 0] + 16.0) / 116.0
    f = np.stack([fy + lab[..., 1] / 500.0, fy, fy - lab[..., 2] / 200.0], axis=-1)
    t = np.where(f > 6.0 / 29.0, f**3, 3 * (6.0 / 29.0) ** 2 * (f - 4.0 / 29.0))
    return ((t * _WHITE_D65) @ _XYZ_TO_RGB.T).astype(np.float32)
