"""Full-resolution stages in row bands: a working-size relighting moved onto the full photo.

The networks work at a few hundred pixels; the photo may have 100 megapixels. What reaches full
resolution is only a per-pixel linear *gain* (``relit / photo`` at working size), upsampled
bilinearly and multiplied into the photo, so the photo's own detail survives. This module does
that in bands of rows, in a few threads, without any full-size float buffer:

* an 8-bit photo is decoded to linear light by a 256-entry table (:data:`DECODE_U8`), and an 8-bit
  result is encoded by a 65536-entry table on the 16-bit-quantised linear value
  (:data:`ENCODE_U8`), so no ``pow`` runs at full resolution;
* the gain is upsampled separably: once horizontally to the full width (``h x W x 3``, small),
  then per band vertically, with the same pixel-centre-aligned coefficients as
  ``cv2.resize(..., INTER_LINEAR)``; every band uses the rows' absolute positions, so the result
  does not depend on the band size (no seams: tested equal to one band covering the image).

Peak memory is the input and the output plus ``threads`` bands of temporaries, whatever the
photo's size.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np

from outcast_core.runtime.geometry.colour import linear_to_srgb, srgb_to_linear

#: Offset that guards dark pixels in the gain ``(after + e) / (before + e)``: where the photo is
#: black, the relit value itself comes through.
GAIN_EPS = 1e-3

#: ``k / 255`` (sRGB) -> linear + :data:`GAIN_EPS` (float32, 256 entries).
DECODE_U8 = (srgb_to_linear(np.arange(256, dtype=np.float32) / 255.0) + GAIN_EPS).astype(
    np.float32
)
#: Linear ``i / 65535`` -> 8-bit sRGB, rounded (65536 entries). The 16-bit linear step is below
#: a twentieth of an 8-bit level everywhere (the sRGB curve is steepest at black: 12.92).
ENCODE_U8 = np.rint(
    linear_to_srgb(np.arange(65536, dtype=np.float32) / 65535.0) * 255.0
).astype(np.uint8)

#: Pixels per band (rows = this / width): a band's temporaries stay in the CPU's cache.
BAND_PIXELS = 1 << 17


def default_threads() -> int:
    """Worker threads for the banded stages: the machine's cores, at most 4."""
    return max(1, min(4, os.cpu_count() or 1))


def gain_map(work_before_srgb: np.ndarray, work_after_srgb: np.ndarray) -> np.ndarray:
    """The per-pixel linear gain ``(after + e) / (before + e)`` at working size (``h x w x 3``)."""
    if work_before_srgb.shape != work_after_srgb.shape:
        raise ValueError(
            f"expected before/after of one shape, got {work_before_srgb.shape} and "
            f"{work_after_srgb.shape}"
        )
    before = srgb_to_linear(work_before_srgb)
    after = srgb_to_linear(work_after_srgb)
    return ((after + GAIN_EPS) / (before + GAIN_EPS)).astype(np.float32)


def _vertical_coefficients(out_rows: int, in_rows: int) -> tuple[np.ndarray, np.ndarray]:
    """Source row ``y0`` and weight ``f`` of row ``y0 + 1`` for each output row, as
    ``cv2.resize`` with ``INTER_LINEAR`` computes them (pixel centres aligned, clamped)."""
    ys = (np.arange(out_rows, dtype=np.float64) + 0.5) * (in_rows / out_rows) - 0.5
    y0 = np.floor(ys)
    f = ys - y0
    y0 = y0.astype(np.int64)
    low = y0 < 0
    y0[low], f[low] = 0, 0.0
    high = y0 >= in_rows - 1
    y0[high], f[high] = in_rows - 1, 0.0
    return y0, f.astype(np.float32)


class GainUpsampler:
    """Bilinear upsampling of an ``h x w x C`` map to ``H x W``, one band of rows at a time.

    Equal (within float rounding) to ``cv2.resize(gain, (W, H), interpolation=INTER_LINEAR)``
    for any band split.

    Args:
        gain: ``h x w x C`` float32.
        shape: the output ``(H, W)``.
    """

    def __init__(self, gain: np.ndarray, shape: tuple[int, int]) -> None:
        gain = np.ascontiguousarray(gain, dtype=np.float32)
        if gain.ndim == 2:
            gain = gain[:, :, None]
        height, width = int(shape[0]), int(shape[1])
        if height < 1 or width < 1:
            raise ValueError(f"expected a non-empty output shape, got {shape}")
        self.shape = (height, width)
        self.channels = gain.shape[2]
        gh = gain.shape[0]
        # Horizontal pass once, at the gain's height: h x W x C (small).
        wide = cv2.resize(gain, (width, gh), interpolation=cv2.INTER_LINEAR)
        self._wide = wide.reshape(gh, width, self.channels)
        # Row differences, so each output row is wide[y0] + f * diff[y0].
        diff = np.empty_like(self._wide)
        diff[-1] = 0.0
        if gh > 1:
            np.subtract(self._wide[1:], self._wide[:-1], out=diff[:-1])
        self._diff = diff
        self._y0, self._f = _vertical_coefficients(height, gh)

    def rows(self, r0: int, r1: int, out: np.ndarray | None = None) -> np.ndarray:
        """Output rows ``r0:r1`` (``(r1 - r0) x W x C`` float32), written into ``out`` if given."""
        width = self.shape[1]
        if out is None:
            out = np.empty((r1 - r0, width, self.channels), np.float32)
        y0, f = self._y0[r0:r1], self._f[r0:r1]
        # Output rows sharing a source row pair form runs: one broadcast per run.
        starts = np.flatnonzero(np.diff(y0, prepend=-1))
        ends = np.append(starts[1:], len(y0))
        for a, b in zip(starts.tolist(), ends.tolist(), strict=True):
            j = int(y0[a])
            seg = out[a:b]
            np.multiply(f[a:b, None, None], self._diff[j][None], out=seg)
            seg += self._wide[j][None]
        return out


def _bands(height: int, width: int, band_rows: int | None) -> list[tuple[int, int]]:
    rows = band_rows if band_rows is not None else max(8, BAND_PIXELS // max(1, width))
    rows = max(1, int(rows))
    return [(r0, min(height, r0 + rows)) for r0 in range(0, height, rows)]


def apply_gain(
    photo_srgb: np.ndarray,
    gain: np.ndarray,
    *,
    out_dtype: type | np.dtype | None = None,
    band_rows: int | None = None,
    threads: int | None = None,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """Multiply an upsampled working-size gain into a full-resolution photo, band by band.

    ``C_out = (C_photo + e) * gain - e`` in linear light (``e`` = :data:`GAIN_EPS`).

    Args:
        photo_srgb: ``H x W x 3`` sRGB, uint8 or float in [0, 1].
        gain: ``h x w x 3`` float32 linear gain (:func:`gain_map`).
        out_dtype: ``np.uint8`` (rounded sRGB) or ``np.float32``; default: the photo's (uint8
            stays uint8, anything else gives float32).
        band_rows: rows per band (default: about :data:`BAND_PIXELS` pixels per band).
        threads: worker threads (default :func:`default_threads`).
        out: an ``H x W x 3`` array of ``out_dtype`` to write into (e.g. a memory map).

    Returns:
        ``H x W x 3`` sRGB of ``out_dtype``.
    """
    photo = np.asarray(photo_srgb)
    if photo.ndim != 3 or photo.shape[2] != 3:
        raise ValueError(f"expected an H x W x 3 photo, got shape {photo.shape}")
    if gain.ndim != 3 or gain.shape[2] != 3:
        raise ValueError(f"expected an h x w x 3 gain, got shape {gain.shape}")
    in_u8 = photo.dtype == np.uint8
    if out_dtype is None:
        out_dtype = np.uint8 if in_u8 else np.float32
    out_u8 = np.dtype(out_dtype) == np.uint8
    if not out_u8 and np.dtype(out_dtype) != np.float32:
        raise ValueError(f"expected out_dtype uint8 or float32, got {np.dtype(out_dtype)}")
    height, width = photo.shape[:2]
    want = (height, width, 3)
    if out is None:
        out = np.empty(want, np.uint8 if out_u8 else np.float32)
    elif out.shape != want or out.dtype != (np.uint8 if out_u8 else np.float32):
        raise ValueError(f"expected out of shape {want} and dtype {np.dtype(out_dtype)}, "
                         f"got {out.shape} {out.dtype}")
    up = GainUpsampler(gain, (height, width))

    def band(r: tuple[int, int]) -> None:
        r0, r1 = r
        src = photo[r0:r1]
        if in_u8:
            lin = cv2.LUT(np.ascontiguousarray(src), DECODE_U8)  # linear + e, float32
        else:
            lin = srgb_to_linear(src)
            lin += GAIN_EPS
        g = up.rows(r0, r1)
        cv2.multiply(lin, g, dst=lin)
        if out_u8:
            # (lin - e) * 65535, rounded and saturated to uint16 by OpenCV, then the table.
            idx = cv2.addWeighted(lin, 65535.0, lin, 0.0, -GAIN_EPS * 65535.0, dtype=cv2.CV_16U)
            np.take(ENCODE_U8, idx, out=out[r0:r1])
        else:
            lin -= GAIN_EPS
            out[r0:r1] = linear_to_srgb(lin)

    bands = _bands(height, width, band_rows)
    n = threads if threads is not None else default_threads()
    if n <= 1 or len(bands) <= 1:
        for r in bands:
            band(r)
    else:
        with ThreadPoolExecutor(max_workers=n) as pool:
            list(pool.map(band, bands))
    return out


def resize_to_working(photo_srgb: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """A full-resolution photo (uint8 or float) at ``shape`` as float32 sRGB in [0, 1]
    (area averaging; an 8-bit photo is averaged in 8 bits, then scaled)."""
    photo = np.asarray(photo_srgb)
    h, w = shape
    if photo.shape[:2] == (h, w):
        small = photo
    else:
        small = cv2.resize(photo, (w, h), interpolation=cv2.INTER_AREA)
    if small.dtype == np.uint8:
        return small.astype(np.float32) * np.float32(1.0 / 255.0)
    return np.asarray(small, np.float32)


__all__ = [
    "DECODE_U8",
    "ENCODE_U8",
    "GAIN_EPS",
    "GainUpsampler",
    "apply_gain",
    "default_threads",
    "gain_map",
    "resize_to_working",
]
