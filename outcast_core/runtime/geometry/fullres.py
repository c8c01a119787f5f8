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

Along the skyline (:class:`SkyGuide`, by colour) and at the photo's edges where the gain changes
with the luminance (:class:`EdgeGuide`), a pixel takes the gain of the working pixels like it
instead of the bilinear mix, so neither side's gain bleeds onto the other. Before all that, the
working-size gain is smoothed where the photo is smooth (:func:`smooth_gain`), so a new
shadow's edge cast at working size is not upsampled into a staircase of working pixels.

Peak memory is the input and the output plus ``threads`` bands of temporaries, whatever the
photo's size.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np

from outcast_core.runtime.geometry.colour import linear_to_srgb, luminance, srgb_to_linear

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


#: :func:`smooth_gain`: the spatial sigma (working pixels) of the gain's joint bilateral filter
#: when the photo is at least twice the working size (it fades in from 1x to 2x) ...
GAIN_SMOOTH_SIGMA = 1.2
#: ... and its range sigma, in the working photo's log luminance (:data:`EDGE_RANGE_SIGMA`'s).
GAIN_SMOOTH_RANGE = 0.2
#: :func:`smooth_gain` keeps a line of gain one or two working pixels wide that stands out by
#: more than the first (log) from its surroundings, wholly from the second: a thin new
#: shadow. Smoothed alone, one working pixel wide, its gain of 0.3 came out 0.67 (a review).
GAIN_THIN = (0.5, 1.0)


def _as_float(photo_srgb: np.ndarray) -> np.ndarray:
    """A working-size sRGB photo as float32 in [0, 1] (uint8 0-255 or float)."""
    photo = np.asarray(photo_srgb)
    return (photo.astype(np.float32) / np.float32(255.0) if photo.dtype == np.uint8
            else photo.astype(np.float32))


def log_luminance(photo_srgb: np.ndarray) -> np.ndarray:
    """The log linear luminance (floored by :data:`_LOG_FLOOR`) of a working-size photo: the
    guide of :func:`smooth_gain` and :class:`EdgeGuide`."""
    lum = luminance(srgb_to_linear(_as_float(photo_srgb)))
    return np.log(lum + np.float32(_LOG_FLOOR)).astype(np.float32)


def smooth_gain(work_photo_srgb: np.ndarray, gain: np.ndarray, scale: float,
                sky: np.ndarray | None = None, log_lum: np.ndarray | None = None) -> np.ndarray:
    """The working-size gain smoothed where the photo is smooth, before it is upsampled by
    ``scale`` (the full size over the working size).

    A new shadow is cast at working size: its edge is a staircase of working pixels, and the
    relighting's gain inside it has working-pixel blotches of its own. Upsampled as it is, both
    show in the full-size photo as blocks: a user trial saw a new shadow's edge stepped in
    5-pixel blocks across a white umbrella (pool sample, balanced), and the pool's water in the
    new shade is mottled with working-pixel squares. Smoothed by a joint bilateral filter
    (:data:`GAIN_SMOOTH_SIGMA` working pixels in space, :data:`GAIN_SMOOTH_RANGE` in the
    photo's log luminance), a gain edge the photo does not have (a cast shadow's on a flat
    surface) becomes a soft straight edge, about three working pixels from 10 % to 90 %, like
    a penumbra, while a gain edge the photo has (an object's outline, the old shadow's own
    edge) stays where it is: the filter does not average across it. A new shadow only one or
    two working pixels wide (a pole's, a wire's) is kept as it is (:data:`GAIN_THIN`): blurred,
    it lost half its darkness. The sky does not mix with the surface (``sky``, the
    working-size sky mask). At 1:1 (``scale`` 1) nothing changes; the filter fades in to 2x.
    A NaN or infinite gain counts as 1. ``log_lum``: the photo's :func:`log_luminance`, when
    the caller has it (:class:`EdgeGuide` takes the same).

    Example:
        >>> photo = np.full((16, 16, 3), 0.5, np.float32); photo[:, 8:] = 0.1  # an edge
        >>> g = np.ones((16, 16, 3), np.float32); g[:, 8:] = 3.0  # the gain follows it
        >>> out = smooth_gain(photo, g, 4.0)
        >>> bool(np.allclose(out, g, atol=1e-3))  # kept
        True
        >>> flat = np.full((16, 16, 3), 0.5, np.float32)  # the same gain on a flat surface
        >>> out = smooth_gain(flat, g, 4.0)
        >>> 1.2 < float(out[0, 7, 0]) < 2.0 and 1.5 < float(out[0, 8, 0]) < 2.8  # softened
        True
    """
    g = np.asarray(gain, np.float32)
    photo = np.asarray(work_photo_srgb)
    if g.ndim != 3 or g.shape[2] != 3 or photo.shape[:2] != g.shape[:2]:
        raise ValueError(f"expected an h x w x 3 gain of the photo's size {photo.shape[:2]}, "
                         f"got {g.shape}")
    if sky is not None and np.shape(sky) != g.shape[:2]:
        raise ValueError(f"expected a sky mask of the gain's size {g.shape[:2]}, got "
                         f"{np.shape(sky)}")
    g = np.nan_to_num(g, nan=1.0, posinf=1.0, neginf=1.0)
    sigma = GAIN_SMOOTH_SIGMA * min(1.0, float(scale) - 1.0)
    if sigma <= 0.05 or min(g.shape[:2]) < 2:
        return g
    guide = log_luminance(photo) if log_lum is None else log_lum
    if sky is not None:  # the sky far from the surface in the guide: never mixed
        guide = np.where(np.asarray(sky, bool), guide + np.float32(100.0), guide)
    log_gain = np.log(np.maximum(g, 1e-6)).astype(np.float32)
    size = 2 * int(np.ceil(2.0 * sigma)) + 1
    out = cv2.ximgproc.jointBilateralFilter(guide, log_gain, size, GAIN_SMOOTH_RANGE, sigma,
                                            borderType=cv2.BORDER_REPLICATE)
    # A new shadow one or two working pixels wide (a pole's, a wire's) is kept: a grey-level
    # closing (opening) by 3 x 3 fills such a dark (bright) line and leaves an edge, a
    # staircase included, as it is.
    # Read on the gain's luminance, one weight for the three channels (per channel, a
    # coloured line changed hue: a review). Its neighbours keep their blur, a soft edge of
    # about a working pixel either side; spread to them, the weight brought back the
    # staircase along the umbrella's new shadow (looked at).
    k = np.ones((3, 3), np.uint8)
    lum = np.log(np.maximum(luminance(g), 1e-6)).astype(np.float32)
    thin = np.maximum(cv2.morphologyEx(lum, cv2.MORPH_CLOSE, k) - lum,
                      lum - cv2.morphologyEx(lum, cv2.MORPH_OPEN, k))
    keep = np.clip((thin - GAIN_THIN[0]) / (GAIN_THIN[1] - GAIN_THIN[0]), 0.0, 1.0)[..., None]
    out = out + keep * (log_gain - out)
    return np.exp(out).astype(np.float32)


def _linear_coefficients(out_rows: int, in_rows: int) -> tuple[np.ndarray, np.ndarray]:
    """Source row ``y0`` and weight ``f`` of row ``y0 + 1`` for each output row (or column),
    as ``cv2.resize`` with ``INTER_LINEAR`` computes them (pixel centres aligned, clamped)."""
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
        self._y0, self._f = _linear_coefficients(height, gh)

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


#: The log floor (linear) of the colours and luminances the guides compare (:class:`SkyGuide`,
#: :class:`EdgeGuide`, :func:`smooth_gain`).
_LOG_FLOOR = 1e-3
#: :class:`SkyGuide`: how far (working pixels) each side's colour, and its gain where the other
#: side's pixels stand, reach across the skyline.
SKYLINE_REACH = 1
#: :class:`SkyGuide`: below this squared distance (log colour) between the two sides' colours
#: the choice by colour fades into the plain bilinear weights (noise would speckle it).
SKYLINE_SEPARATION = 0.5
#: :class:`SkyGuide`: how far (working pixels, each way) a skyline pixel looks for the working
#: pixels of pure sky and of pure surface whose colour it may share (see :class:`SkyGuide`).
SKYLINE_EXEMPLAR_REACH = 3
#: :class:`SkyGuide`: within this squared distance (log colour) of a nearby working pixel of
#: sky away from the skyline, a pixel's colour is the sky's, and the surface's pixels are not
#: consulted (the gaps between a pine's branches); from twice it on, they are.
SKYLINE_SKY_MATCH = 0.05


class SkyGuide:
    """Keeps the sky's gain on the sky and the surface's on the surface at full resolution.

    Bilinear upsampling gives a full-resolution pixel next to the skyline a mix of its working
    neighbours' gains; where the relighting darkens a roof or a treetop and keeps the sky (the
    learned relighting keeps the photo's sky), the sky along the
    edge took part of the darkening: dark smudges along the pool sample's roof and tree line
    (a user trial). So for a full-resolution pixel whose bilinear neighbours are within
    :data:`SKYLINE_REACH` working pixels of both sides (the working mask is coarse: a working
    pixel called surface may hold sky), each side's gain is interpolated over that side's
    neighbours (its own gain on its own pixels, the mean of the side's pixels within reach on
    the other side's), and the pixel takes the sky's or the surface's by how close its own
    colour is to each side's mean colour (``alpha = d_surface / (d_sky + d_surface)``, ``d``
    the fourth power of the distance in log colour; the sides' means hold the skyline's mixed
    pixels, and a softer choice left a twentieth of the other side's gain). Where the two
    sides' colours are close (:data:`SKYLINE_SEPARATION`) the choice fades into the plain
    bilinear weights, so noise does not speckle a hazy skyline. Every other pixel keeps the
    plain bilinear gain; at 1:1 nothing changes.

    The surface's mean is a poor likeness of a thin surface of the sky's lightness: the pool
    sample's grey-blue roof fascia was always nearer the sky's mean than the roof's (a mix
    with the dark soffit), and took the sky's gain in triangles one working pixel long, a
    staircase along the roof when the roof was darkened (a user trial). So a pixel whose
    3 x 3 mean colour (one pixel's noise would read as unlike) is unlike every working pixel
    of pure sky (no surface next to it) within :data:`SKYLINE_EXEMPLAR_REACH`
    (:data:`SKYLINE_SKY_MATCH`) is also measured against the nearest in colour of the pure
    surface pixels there. Where no pure sky is within reach (the gaps between a pine's
    branches, whose surface pixels mix in the sky) the means alone decide, as before; the ski
    slope's pines, measured against pure surface pixels there too, took white specks of the
    pines' lift. Looked at on the three samples (2026-12-05, relit 290,67.8 -> 55,40;
    354,15 -> 200,30; 120,39 -> 270,30; /tmp): the fascia's staircase and the light blotches
    on the roof's corner are gone, fewer pale specks atop the pool's trees, the ski slope's
    pines and the field path much as before (2,107 of the ski slope's 4 million pixels
    brighter by more than 20 of 255, mixed pixels between the pines' and the sky's). Noisy
    skylines (a review's synthetic dusk sky over a roof, log noise 0.15 / 0.25 per pixel)
    flip fewer pixels to the other side's gain than before: 64 / 556 of 8,958 against 71 /
    632. Weighing luminance less than chromaticity in these distances (0.3) took more lit
    leaves atop the pool's trees off the sky's gain but flipped noisy skylines (145 / 861).
    The transfer of the ski slope enlarged to 16 MP takes 1.21 s instead of 0.88 (2 cores,
    best of 3; only the pixels the means call partly sky are searched).

    Args:
        sky: ``h x w`` bool, the working-size sky mask.
        photo_srgb: ``h x w x 3`` the working-size photo (sRGB; uint8 0-255 or float 0-1).
    """

    def __init__(self, sky: np.ndarray, photo_srgb: np.ndarray) -> None:
        self.sky = np.asarray(sky, bool)
        photo = np.asarray(photo_srgb)
        if self.sky.shape != photo.shape[:2]:
            raise ValueError(f"expected a sky mask of the photo's size {photo.shape[:2]}, "
                             f"got {self.sky.shape}")
        self.log_photo = np.log(srgb_to_linear(_as_float(photo)) + np.float32(_LOG_FLOOR)
                                ).astype(np.float32)

    def useful(self) -> bool:
        """Whether there is a skyline to guard (some sky and some surface)."""
        return bool(self.sky.any() and not self.sky.all())

    def sides(self, gain: np.ndarray) -> dict[str, np.ndarray]:
        """At working size: ``packed``, ``h x w x 14`` per pixel the sky side's presence within
        reach, its gain and its mean log colour there, then the same for the surface (one
        gather per neighbour at full resolution); ``band``, 1 where both sides are within
        reach; ``rows``, per working row whether ``band`` has any pixel there; ``exemplars``,
        the pure sky's and the pure surface's log colours (two ``3 x (h w)`` arrays: a pixel
        of the other side, or next to it, holds a far colour) for :func:`_nearest_pure`."""
        size = (2 * SKYLINE_REACH + 1,) * 2
        parts = []
        for mask in (self.sky, ~self.sky):
            m = mask.astype(np.float32)
            w = cv2.blur(m, size, borderType=cv2.BORDER_REPLICATE)
            safe = np.maximum(w, 1e-6)[..., None]
            mean_gain = cv2.blur(gain * m[..., None], size,
                                 borderType=cv2.BORDER_REPLICATE) / safe
            colour = cv2.blur(self.log_photo * m[..., None], size,
                              borderType=cv2.BORDER_REPLICATE) / safe
            # A pixel of this side keeps its own gain (the strip's edge then meets the plain
            # transfer, and shadows on a roof stay sharp); the other side's take the mean.
            side_gain = np.where(mask[..., None], gain, mean_gain)
            parts += [(w > 0).astype(np.float32)[..., None], side_gain, colour]
        packed = np.concatenate(parts, axis=-1).astype(np.float32)
        band = (packed[..., 0] > 0) & (packed[..., 7] > 0)
        # The working pixels away from the skyline (no pixel of the other side next to them),
        # per side 3 x (h w): their log colours (the other side's pixels far away).
        kernel = np.ones((3, 3), np.uint8)
        frame = self.log_photo.reshape(-1, 3)
        exemplars = []
        for mask in (self.sky, ~self.sky):
            pure = cv2.erode(mask.astype(np.uint8), kernel, borderType=cv2.BORDER_REPLICATE)
            exemplars.append(np.ascontiguousarray(
                np.where(pure.reshape(-1, 1) > 0, frame, np.float32(_FAR)).T, np.float32))
        return {"packed": packed, "band": band.astype(np.float32), "rows": band.any(axis=1),
                "exemplars": exemplars}


#: :func:`_nearest_pure`: the colour given to a working pixel that is not of the side sought
#: (its squared distance, above ``_FAR``, reads as none).
_FAR = 1e4


def _colour_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Squared distance between ``N x 3`` log colours."""
    v = a - b
    return (v * v).sum(axis=1)


def _nearest_pure(frame: np.ndarray, exemplars: np.ndarray, yn: np.ndarray, xn: np.ndarray,
                  width: int, reach: int | None = None) -> np.ndarray:
    """Per pixel (``frame``, ``3 x N``: its log colour; ``yn, xn``: the working pixel it lies
    in), the least :func:`_colour_distance` to the pure working pixels of one side
    (``exemplars``, one of :meth:`SkyGuide.sides`' two, ``3 x (h width)``) within ``reach``
    (default :data:`SKYLINE_EXEMPLAR_REACH`) working pixels (infinity where there is none)."""
    height = exemplars.shape[1] // width
    best = np.full(frame.shape[1], np.inf, np.float32)
    acc = np.empty_like(best)
    diff = np.empty_like(best)
    r = SKYLINE_EXEMPLAR_REACH if reach is None else reach
    for dy in range(-r, r + 1):
        row = np.clip(yn + dy, 0, height - 1) * width
        for dx in range(-r, r + 1):
            idx = row + np.clip(xn + dx, 0, width - 1)
            acc.fill(0.0)
            for c in range(3):
                np.subtract(np.take(exemplars[c], idx), frame[c], out=diff)
                diff *= diff
                acc += diff
            np.minimum(best, acc, out=best)
    best[best > _FAR] = np.inf
    return best


def _mean_log_colour(photo: np.ndarray, ys: np.ndarray, xs: np.ndarray) -> np.ndarray:
    """The log colour (as :func:`_guard_skyline` takes it) of the 3 x 3 mean, in linear
    light, round each of the photo's pixels ``(ys, xs)`` (``N x 3``; clamped at the photo's
    edges, read from the whole photo so that no band's edge changes it)."""
    height, width = photo.shape[:2]
    acc = np.zeros((ys.size, 3), np.float32)
    for dy in (-1, 0, 1):
        yi = np.clip(ys + dy, 0, height - 1)
        for dx in (-1, 0, 1):
            px = photo[yi, np.clip(xs + dx, 0, width - 1)]
            acc += (DECODE_U8[px] - np.float32(GAIN_EPS) if photo.dtype == np.uint8
                    else srgb_to_linear(np.clip(px.astype(np.float32), 0.0, 1.0)))
    return np.log(np.maximum(acc / np.float32(9.0), 0.0) + np.float32(_LOG_FLOOR))


def _guard_skyline(g: np.ndarray, lin: np.ndarray, near: np.ndarray, r0: int,
                   sides: dict[str, np.ndarray], ycoef: tuple[np.ndarray, np.ndarray],
                   xcoef: tuple[np.ndarray, np.ndarray], photo: np.ndarray) -> None:
    """:class:`SkyGuide`'s gain, in place, on the band's pixels near the skyline (``near``
    > 0: the upsampled ``band`` of :meth:`SkyGuide.sides`). ``lin`` is the band's linear
    photo plus :data:`GAIN_EPS`; ``r0`` the band's first row; ``photo`` the whole photo (the
    band's pixels are compared with the pure sky near them by their 3 x 3 mean: a single
    pixel's noise read as unlike the sky)."""
    ys, xs = np.nonzero(near > 1e-6)
    if ys.size == 0:
        return
    packed = sides["packed"]
    h, w = packed.shape[:2]
    y0, fy = ycoef[0][ys + r0], ycoef[1][ys + r0]
    x0, fx = xcoef[0][xs], xcoef[1][xs]
    y1, x1 = np.minimum(y0 + 1, h - 1), np.minimum(x0 + 1, w - 1)
    acc = np.zeros((ys.size, 14), np.float32)  # weight-summed: [wk, gk*3, ck*3, ws, gs, cs]
    plain_sky = np.zeros(ys.size, np.float32)  # the bilinear sky weight (the fallback)
    sky = sides["sky"]
    for yi, xi, wt in ((y0, x0, (1 - fy) * (1 - fx)), (y0, x1, (1 - fy) * fx),
                       (y1, x0, fy * (1 - fx)), (y1, x1, fy * fx)):
        p = packed[yi, xi]  # N x 14
        wk, ws = wt * p[:, 0], wt * p[:, 7]
        acc[:, 0] += wk
        acc[:, 1:7] += wk[:, None] * p[:, 1:7]
        acc[:, 7] += ws
        acc[:, 8:14] += ws[:, None] * p[:, 8:14]
        plain_sky += wt * sky[yi, xi]
    wk = np.maximum(acc[:, 0:1], 1e-6)
    ws = np.maximum(acc[:, 7:8], 1e-6)
    g_k, c_k = acc[:, 1:4] / wk, acc[:, 4:7] / wk
    g_s, c_s = acc[:, 8:11] / ws, acc[:, 11:14] / ws
    lf = np.log(np.maximum(lin[ys, xs] - GAIN_EPS, 0.0) + _LOG_FLOOR)
    d_k = _colour_distance(lf, c_k) ** 2
    d_s = _colour_distance(lf, c_s) ** 2
    by_colour = d_s / np.maximum(d_s + d_k, 1e-24)
    trust = np.clip(((c_k - c_s) ** 2).sum(axis=1) / SKYLINE_SEPARATION, 0.0, 1.0)
    # A pixel the means call partly sky but unlike the pure sky near it, when a pure surface
    # pixel near it is nearer its colour than the surface's mean is, is measured against that
    # pixel (a thin grey fascia under a roof's edge: against the sky's and the mixed surface's
    # means it read as sky). Only the pixels it could move are searched.
    pick = np.flatnonzero((trust > 0) & (by_colour > 1e-3))
    if pick.size:
        yn = np.where(fy >= 0.5, y1, y0)[pick]
        xn = np.where(fx >= 0.5, x1, x0)[pick]
        sky_pure, surface_pure = sides["exemplars"]
        # Most of them match a pure sky pixel next to theirs: only the rest search further
        # (the same least distance wherever it matters: within the match it is all alike).
        smooth = np.ascontiguousarray(_mean_log_colour(photo, ys[pick] + r0, xs[pick]).T)
        reach = min(1, SKYLINE_EXEMPLAR_REACH)
        e_k = _nearest_pure(smooth, sky_pure, yn, xn, w, reach=reach)
        rest = np.flatnonzero(e_k > SKYLINE_SKY_MATCH)
        if rest.size and reach < SKYLINE_EXEMPLAR_REACH:
            e_k[rest] = _nearest_pure(np.ascontiguousarray(smooth[:, rest]), sky_pure,
                                      yn[rest], xn[rest], w)
        unlike = np.clip((e_k - SKYLINE_SKY_MATCH) / SKYLINE_SKY_MATCH, 0.0, 1.0)
        unlike[~np.isfinite(e_k)] = 0.0  # (no pure sky near: the means decide, as before)
        far = np.flatnonzero(unlike > 0)
        if far.size:
            at = pick[far]
            frame = np.ascontiguousarray(lf[at].T)
            e_s = _nearest_pure(frame, surface_pure, yn[far], xn[far], w) ** 2
            ds = d_s[at]
            ds = ds * (np.minimum(ds, e_s) / np.maximum(ds, 1e-24)) ** unlike[far]
            by_colour[at] = ds / np.maximum(ds + d_k[at], 1e-24)
    alpha = (trust * by_colour + (1.0 - trust) * plain_sky)[:, None]
    g[ys, xs] = alpha * g_k + (1.0 - alpha) * g_s


#: :class:`EdgeGuide`: a full-resolution pixel is guided where, among the working pixels
#: within :data:`EDGE_STATS_REACH` of the one it lies in, the log luminance gain spans more
#: than this (elsewhere the gain is smooth and the bilinear one is right) ...
EDGE_GAIN_SPREAD = 0.3
#: ... the working photo's log luminance spans more than this (a new shadow's edge across one
#: surface keeps the plain transfer: the photo says nothing about where it runs) ...
EDGE_LUMINANCE_SPREAD = 0.6
#: ... and the gain follows the luminance there (absolute correlation of the two logs over the
#: neighbourhood): an object's edge, not a blotchy new shadow over a textured surface (which,
#: guided, printed the pool's ripples into its new shadow as jagged steps).
EDGE_CORRELATION = 0.7
#: :class:`EdgeGuide`: the neighbourhood (working pixels each way) those three are taken over.
EDGE_STATS_REACH = 1
#: :class:`EdgeGuide`: how far (working pixels, each way) a pixel looks for the working pixels
#: of its own colour, and the half-width (working pixels) of the tent its spatial weight is.
EDGE_REACH = 1
EDGE_TENT = 1.5
#: :class:`EdgeGuide`: Gaussian sigma of the range weight (log luminance distance).
EDGE_RANGE_SIGMA = 0.2
#: :class:`EdgeGuide`: floor of the range weight (a colour that no neighbour has falls back
#: to the spatial weights).
EDGE_RANGE_FLOOR = 1e-3


class EdgeGuide:
    """Joint bilateral upsampling of the gain where it jumps at an edge of the photo.

    Bilinear upsampling gives a full-resolution pixel beside an object's edge part of the
    object's gain. The working pixel on the edge mixes both sides, and the learned relighting
    gives it a gain of its own, often the object's, which the bilinear weights then spread
    onto the other side: on the README's relit pool sample, a light strip down the pool beside
    each dark pole. Here a full-resolution pixel whose working neighbourhood has a gain and a
    colour that both change, and change together (:data:`EDGE_GAIN_SPREAD`,
    :data:`EDGE_LUMINANCE_SPREAD`, :data:`EDGE_CORRELATION`), takes its gain from the working
    pixels within :data:`EDGE_REACH` of its own luminance: a tent of :data:`EDGE_TENT` working
    pixels times a Gaussian (:data:`EDGE_RANGE_SIGMA`) of the log luminance distance between
    the pixel and each working pixel (Kopf et al. 2007's joint bilateral upsampling, on the
    edges only). Every other pixel keeps the bilinear gain; at 1:1 nothing changes.

    Args:
        photo_srgb: ``h x w x 3`` the working-size photo (sRGB; uint8 0-255 or float 0-1).
        gain: ``h x w x 3`` its gain (:func:`gain_map`).
        log_lum: the photo's :func:`log_luminance`, when the caller has made it already.

    Attributes:
        flag: ``h x w`` bool, the working pixels on such an edge.
        neighbours: ``h x w x K x 4`` float32 (None when nothing is flagged): per working pixel,
            the gain and log luminance of its ``K = (2 EDGE_REACH + 1) ** 2`` neighbours
            (rows, then columns; clamped at the border).
    """

    def __init__(self, photo_srgb: np.ndarray, gain: np.ndarray,
                 log_lum: np.ndarray | None = None) -> None:
        photo = np.asarray(photo_srgb)
        gain = np.asarray(gain, np.float32)
        if gain.shape != photo.shape or gain.ndim != 3 or gain.shape[2] != 3:
            raise ValueError(f"expected an h x w x 3 gain of the photo's shape {photo.shape}, "
                             f"got {gain.shape}")
        log_lum = log_luminance(photo) if log_lum is None else log_lum
        log_gain = np.log(np.maximum(luminance(gain), 1e-6)).astype(np.float32)
        size = (2 * EDGE_STATS_REACH + 1,) * 2
        kernel = np.ones(size, np.uint8)

        def spread(a: np.ndarray) -> np.ndarray:
            return (cv2.dilate(a, kernel, borderType=cv2.BORDER_REPLICATE)
                    - cv2.erode(a, kernel, borderType=cv2.BORDER_REPLICATE))

        def box(a: np.ndarray) -> np.ndarray:
            return cv2.blur(a, size, borderType=cv2.BORDER_REPLICATE)

        mg, ml = box(log_gain), box(log_lum)
        cov = box(log_gain * log_lum) - mg * ml
        vg = np.maximum(box(log_gain * log_gain) - mg * mg, 1e-12)
        vl = np.maximum(box(log_lum * log_lum) - ml * ml, 1e-12)
        self.flag = ((spread(log_gain) > EDGE_GAIN_SPREAD)
                     & (spread(log_lum) > EDGE_LUMINANCE_SPREAD)
                     & (np.abs(cov) > EDGE_CORRELATION * np.sqrt(vg * vl)))
        self.neighbours: np.ndarray | None = None
        if self.useful():  # (built only when there is an edge to guard)
            packed = np.concatenate([gain, log_lum[..., None]], axis=-1)
            h, w, r = gain.shape[0], gain.shape[1], EDGE_REACH
            pad = np.pad(packed, ((r, r), (r, r), (0, 0)), mode="edge")
            self.neighbours = np.ascontiguousarray(np.stack(
                [pad[dy:dy + h, dx:dx + w] for dy in range(2 * r + 1)
                 for dx in range(2 * r + 1)], axis=2), dtype=np.float32)

    def useful(self) -> bool:
        """Whether any working pixel is on such an edge."""
        return bool(self.flag.any())


def _tent_table(out_size: int, in_size: int) -> tuple[np.ndarray, np.ndarray]:
    """Per output row (or column): the working row it lies in (``nearest``) and the tent
    weights (:data:`EDGE_TENT`) of the working rows ``nearest + d``, ``d`` in
    ``-EDGE_REACH..EDGE_REACH`` (``out_size x (2 EDGE_REACH + 1)`` float32; 0 for rows past
    the edge, which the gather clamps onto it)."""
    pos = (np.arange(out_size) + 0.5) * (in_size / out_size)
    nearest = np.minimum(pos.astype(np.int64), in_size - 1)
    offsets = np.arange(-EDGE_REACH, EDGE_REACH + 1)
    q = nearest[:, None] + offsets[None, :]
    wt = np.maximum(0.0, 1.0 - np.abs(pos[:, None] - 0.5 - q) / EDGE_TENT)
    wt[(q < 0) | (q >= in_size)] = 0.0  # (the gather clamps them onto the edge row)
    return nearest, wt.astype(np.float32)


def _guard_edges(g: np.ndarray, lin: np.ndarray, r0: int, guide: EdgeGuide,
                 tables: tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]],
                 share: np.ndarray) -> None:
    """:class:`EdgeGuide`'s gain, in place, on the band's pixels near an edge. ``lin`` is the
    band's linear photo plus :data:`GAIN_EPS`; ``r0`` the band's first row; ``tables`` the
    rows' and the columns' :func:`_tent_table`; ``share`` (the band's rows of the flag
    upsampled bilinearly) how much of the guided gain a pixel takes: switched on and off by
    the nearest working pixel's flag, the gain stepped along the working grid where a
    shadow's edge meets its object (a review: a ratio of 0.30 next to 0.68)."""
    (yn, wy), (xn, wx) = tables
    ys, xs = np.nonzero(share > 1e-6)
    if ys.size == 0:
        return
    nb = guide.neighbours[yn[ys + r0], xn[xs]]  # N x K x 4: each neighbour's gain, log lum
    lf = np.log(np.maximum(luminance(lin[ys, xs]) - GAIN_EPS, 0.0) + _LOG_FLOOR)
    d = lf.astype(np.float32)[:, None] - nb[:, :, 3]
    rng = np.exp(d * d * np.float32(-0.5 / EDGE_RANGE_SIGMA ** 2))
    rng += np.float32(EDGE_RANGE_FLOOR)
    k = wy.shape[1]
    rng *= (wy[ys + r0][:, :, None] * wx[xs][:, None, :]).reshape(-1, k * k)
    total = rng.sum(axis=1, keepdims=True)
    guided = np.einsum("nk,nkc->nc", rng, nb[:, :, :3]) / np.maximum(total, 1e-12)
    a = share[ys, xs][:, None]
    g[ys, xs] = g[ys, xs] + a * (guided - g[ys, xs])


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
    sky: SkyGuide | None = None,
    edges: EdgeGuide | None = None,
) -> np.ndarray:
    """Multiply an upsampled working-size gain into a full-resolution photo, band by band.

    ``C_out = (C_photo + e) * gain - e`` in linear light (``e`` = :data:`GAIN_EPS`); with
    ``edges``, pixels at the photo's edges take the gain of the working pixels like them
    (:class:`EdgeGuide`); with ``sky``, pixels along the skyline then take the sky's or the
    surface's gain (:class:`SkyGuide`).

    Args:
        photo_srgb: ``H x W x 3`` sRGB, uint8 or float in [0, 1].
        gain: ``h x w x 3`` float32 linear gain (:func:`gain_map`).
        out_dtype: ``np.uint8`` (rounded sRGB) or ``np.float32``; default: the photo's (uint8
            stays uint8, anything else gives float32).
        band_rows: rows per band (default: about :data:`BAND_PIXELS` pixels per band).
        threads: worker threads (default :func:`default_threads`).
        out: an ``H x W x 3`` array of ``out_dtype`` to write into (e.g. a memory map).
        sky: the working-size sky and photo (:class:`SkyGuide`), or None.
        edges: the working-size photo's edges and gain (:class:`EdgeGuide`), or None.

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
    guard = sky is not None and sky.useful()
    edge_guard = (edges is not None and edges.useful()
                  and (height > gain.shape[0] or width > gain.shape[1]))
    if edge_guard:
        if edges.flag.shape != gain.shape[:2]:
            raise ValueError(f"expected an edge guide of the gain's size {gain.shape[:2]}, "
                             f"got {edges.flag.shape}")
        edge_tables = (_tent_table(height, gain.shape[0]), _tent_table(width, gain.shape[1]))
        edge_up = GainUpsampler(edges.flag.astype(np.float32), (height, width))
    if guard:
        if sky.sky.shape != gain.shape[:2]:
            raise ValueError(f"expected a sky guide of the gain's size {gain.shape[:2]}, got "
                             f"{sky.sky.shape}")
        sides = {**sky.sides(gain), "sky": sky.sky.astype(np.float32)}
        band_up = GainUpsampler(sides["band"], (height, width))
        ycoef = _linear_coefficients(height, gain.shape[0])
        xcoef = _linear_coefficients(width, gain.shape[1])

    def band(r: tuple[int, int]) -> None:
        r0, r1 = r
        src = photo[r0:r1]
        if in_u8:
            lin = cv2.LUT(np.ascontiguousarray(src), DECODE_U8)  # linear + e, float32
        else:
            lin = srgb_to_linear(src)
            lin += GAIN_EPS
        g = up.rows(r0, r1)
        if edge_guard:
            _guard_edges(g, lin, r0, edges, edge_tables, edge_up.rows(r0, r1)[..., 0])
        if guard:
            y_first, y_last = int(ycoef[0][r0]), int(ycoef[0][r1 - 1]) + 1
            if sides["rows"][y_first:y_last + 1].any():  # (bands far from it: nothing to do)
                _guard_skyline(g, lin, band_up.rows(r0, r1)[..., 0], r0, sides, ycoef, xcoef,
                               photo)
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
    "EdgeGuide",
    "ENCODE_U8",
    "GAIN_EPS",
    "GainUpsampler",
    "SkyGuide",
    "apply_gain",
    "default_threads",
    "gain_map",
    "resize_to_working",
]
