"""The photo's own shadows: found from the photo, with the geometry as the prior, and lifted.

The refined original shadow ``S_o`` (what the app keeps after "Confirm sun") must describe the
shadows that are *in the photo*; the shadow network's ``S`` at the aligned sun only says where
the rough geometry puts them. On the real-photo dev set (``outcast eval real``, 47 photos,
balanced preset) the learned refinement ``R`` left ``S_o``'s balanced error rate at 0.257,
worse than Otsu's threshold on the photo's luminance (0.180) that ignores the sun. ``R`` was
trained on synthetic renders whose shadows are clean; real shade differs.

:func:`photo_shadow_probability` is a classical photometric stage instead. A sunlit photo's
log luminance is bimodal between sun and shade (a cast shadow is 1-3 stops darker than the lit
surface around it), so Otsu's threshold on the log luminance of the *surface* (the sky excluded:
it is a third mode that drags a linear threshold up) separates them; it is made soft (a
logistic of width :data:`SOFT_LOG`) and its edges follow the photo's (guided filter). When
Otsu calls more than half of the surface shade, its bright class is highlights and the split is
taken again inside the dark class (:func:`shade_threshold`). Measured on the dev set with the
same 47 photos at each photo's best sun (a choice among a few variants, nothing fitted;
``outcast eval real`` and the session's exact pipeline give 0.117 without the second split and
0.109 with it, 0.104 with the wider gate below, balanced preset):

==============================================  ===========
variant                                         BER of mask
==============================================  ===========
``R`` (learned refinement, before)               0.257
Otsu on sRGB luminance, whole frame              0.180
Otsu on log luminance of the surface             0.116
  ... soft, edges snapped, inside the prior      0.114
  ... the same without the prior                 0.111
  ... split again past half the surface (0.5)    0.102 (no prior, working size)
  ... the same past 0.6 / never                  0.103 / 0.115
  ... Kittler-Illingworth instead of Otsu        0.188
  ... hysteresis / small regions dropped         0.114-0.121
  ... on ``log Y - 0.3 log(B/R)`` (bluer)        0.123
  ... Otsu threshold moved by +-0.1 std          0.116-0.117
  ... only near the fitted ground plane          0.134-0.203
  ... darkness against a local bright level      0.16-0.47
  ... only where the chromaticity matches the
      lit surface around it (:func:`same_material`)  0.23-0.42
==============================================  ===========

The geometry gates it: a dark region more than :data:`PRIOR_RADIUS` of the image from anywhere
the shadow network puts a shadow at the aligned sun is dark albedo (a black car, a dark coat),
not a shadow the sun can lift. On the dev photos the overlay misses real shadows, so a tight
gate drops true ones: ``S_o``'s BER (fast preset, 47 photos, each at its best sun) is 0.1117
with a radius of 0.1 of the longer side (the earlier setting), 0.1072 at 0.15, 0.1059 at 0.2,
0.1056 at 0.3 and 0.1056 with no gate. 0.2 keeps nearly all of the gain and still drops dark
regions far from any possible shadow. It is kept because what ``S_o`` calls a shadow is what
relighting and de-shadowing brighten (on the sample photos dark furniture, railings and foliage
pass it even at 0.1: the overlay's attached shadows cover much of the frame).

Known failure: one threshold per photo splits its two largest modes. In the ski-slope sample
those are dark trees and bright snow, so the trees are called shadow and the long tree shadows
on the snow (shaded snow is brighter than trees) are missed.

:func:`deshadow` lifts the found shadows: per colour channel, the log-ratio between the lit and
the shadowed surface around each shadow (Gaussian-weighted log means, so the shade's blue cast
goes with its darkness), applied in proportion to the soft shadow probability. Two guards keep
dark materials dark: a pixel whose chromaticity differs from the lit surface around it
(:func:`same_material`), and one far darker than the photo's typical shade
(:data:`DARKER_MARGIN`), are lifted less. On the 7 dev pairs with a shadow-free twin the Lab
RMSE inside the shadows falls to 0.53 of the input's, and outside them rises by 0.11 (0.55
with the narrower gate; 0.62 and 0.68 before :func:`shade_threshold`'s second split), with
:data:`RATIO_SIGMA` 0.15 of the longer side (before the second split: 0.08: 0.70 / 0.76;
0.04: 0.72 / 0.64; 0.3: 0.57 / 0.74). With the human masks instead of the found shadows the
lift reaches 0.51 (0.15) or 0.50 (0.3), so the lift, not only the detection, limits it: with
the human masks and each pair's own (oracle) shadow/lit gain it would reach 0.27 (640 px); the
estimated gain is off by -0.5 to +0.3 log units per pair (models/EVAL.md, evening notes of
2026-11-30). 0.15 was kept then because these pairs are close-ups of one object on one ground,
where the most global ratio wins, and a street has many materials.

Re-measured on 2026-11-30 (late night), with the gate at 0.2 and the wide blurs on a coarse grid
(:func:`wide_blur`): :data:`RATIO_SIGMA` 0.15 / 0.3 / 0.5 gives 0.528 / 0.498 / 0.491 inside
and +0.11 / +0.12 / +0.13 outside on the 7 pairs. The street argument was measured on all 47
dev photos, none of which has a twin: after de-shadowing, the mean CIE Lab difference between
the inside of each human-marked shadow and a ring of lit surface just outside it is, in
``a*b*``, 13.0 / 13.0 / 13.2 (the photo: 15.4) and in ``L*`` 25.1 / 24.6 / 24.5. So 0.3: the
pairs gain and the other photos lose nothing measurable. 0.5 moves the colour. Lifting
luminance only (one gain for the three channels) reached 0.497 on the pairs but left the
shade's colour cast on the 47 photos (``a*b*`` gap 14.95): the blue-grey ghosts a user sees.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace
from typing import Any

import cv2
import numpy as np

from outcast_core.runtime.geometry.colour import (
    LUMA_709,
    linear_to_lab,
    linear_to_srgb,
    log_chromaticity,
    luminance,
    srgb_to_linear,
)

#: Width (natural log units of luminance) of the soft step around Otsu's threshold.
SOFT_LOG = 0.12
#: Radius (fraction of the longer side) of the geometric prior: how far from a predicted shadow
#: a dark region may be and still count as a shadow (the user's alignment is rough).
PRIOR_RADIUS = 0.2
#: The shadow network's ``S`` below this is a predicted shadow (the overlay's threshold).
PRIOR_THRESHOLD = 0.15
#: :func:`original_shadow_from_photo`: the visibility at ``p = 0.5``, just under the overlay's
#: threshold, so that ``S_o`` marks as shadow exactly the found shadows.
FOUND_VISIBILITY = 0.99 * PRIOR_THRESHOLD
#: Guided-filter radius (fraction of the longer side) and eps that snap the mask to the photo.
EDGE_RADIUS = 1.0 / 192.0
EDGE_EPS = 1e-3
#: ``S_o`` on a surface the photo shows lit: the cosine term, at least this (normals from a
#: rough depth call lit walls "facing away").
LIT_FLOOR = 0.3
#: Gaussian sigma (fraction of the longer side) of the neighbourhood whose lit and shadowed
#: surfaces give a shadow's colour ratio in :func:`deshadow`, and the largest lift (stops).
RATIO_SIGMA = 0.3
MAX_LIFT_LOG = float(np.log(16.0))
_LOG_EPS = 1e-3
#: The shade's level is measured at this fraction of :data:`RATIO_SIGMA`; a local lift is at
#: most this multiple of the photo's global lit/shade log ratio.
SHADE_SIGMA = 0.25
#: :func:`same_material`: the shade's expected chromaticity shift ``(log R/G, log B/G)`` from
#: the lit surface (the de-shadow's, chosen on the 7 dev pairs, whose shade is nearly neutral:
#: 6 of the 7 shift by less than 0.1) and the chromaticity distance :data:`CHROMA_TOL` (log
#: units) at which a dark pixel stops counting as shadow (0 turns it off).
SHADE_SHIFT: tuple[float, float] = (0.0, 0.2)
#: The shift of shade lit by a clear sky: the median, over the 47 dev photos, of the median
#: chromaticity inside each human-marked shadow minus that of the lit ring around it is
#: ``(-0.25, +0.42)`` (quartiles of ``log B/G`` 0.03 and 0.62); the held-out renders' true
#: shadows give ``(-0.28, +0.39)``. The relighting's lift uses it
#: (:data:`~outcast_core.runtime.pipeline.relight.LIFT_SHADE_SHIFT`).
SKY_SHADE_SHIFT: tuple[float, float] = (-0.25, 0.42)
#: Log luminance by which a pixel may be darker than the photo's typical shade (relative to
#: the lit surface around it) and still be lifted fully, and the fall-off beyond it.
DARKER_MARGIN = 0.5
DARKER_WIDTH = 0.3
CHROMA_TOL = 1.0
#: :func:`shade_threshold`: the largest share of a photo's surface that one threshold may call
#: shade before the split is taken again inside the dark class.
MAX_SHADE_FRACTION = 0.5
LOCAL_MAX = 1.5
#: :func:`without_texture`: radius (fraction of the longer side) of the opening that keeps
#: narrower dark structures (the surface's texture) out of the lift.
TEXTURE_RADIUS = 0.006


#: :func:`wide_blur` blurs on a grid this many times coarser than ``sigma``'s pixels.
WIDE_BLUR_TAPS = 8.0


def wide_blur(x: np.ndarray, sigma: float) -> np.ndarray:
    """A Gaussian blur (reflected borders) that stays cheap at large ``sigma``.

    Above ``2 * WIDE_BLUR_TAPS`` pixels the image is area-shrunk so that ``sigma`` spans
    :data:`WIDE_BLUR_TAPS` of the small grid's pixels, blurred there and brought back
    (bilinear): at the wide sigmas of the shade statistics a direct blur costs most of
    :func:`deshadow`'s time, and its output has no detail the small grid misses.
    """
    x = np.asarray(x, np.float32)
    h, w = x.shape[:2]
    factor = int(sigma // WIDE_BLUR_TAPS)
    if factor < 2 or min(h, w) < 2 * factor:
        return cv2.GaussianBlur(x, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
    small = cv2.resize(x, (max(1, round(w / factor)), max(1, round(h / factor))),
                       interpolation=cv2.INTER_AREA)
    small = cv2.GaussianBlur(small, (0, 0), sigma * small.shape[1] / w,
                             borderType=cv2.BORDER_REFLECT)
    out = cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)
    return out.reshape(x.shape)


def _otsu_threshold(values: np.ndarray, bins: int = 256) -> float:
    """Otsu's threshold of a 1-D sample (bins between its 0.5 and 99.5 percentiles).

    Where several thresholds separate the classes equally well (an empty gap between two
    modes), the middle of them is taken, not the first (OpenCV's choice hugs the dark mode).
    """
    lo, hi = np.percentile(values, [0.5, 99.5])
    if hi - lo < 1e-6:
        return float(lo)
    hist, edges = np.histogram(np.clip(values, lo, hi), bins=bins, range=(lo, hi))
    prob = hist.astype(np.float64) / max(hist.sum(), 1)
    centres = 0.5 * (edges[:-1] + edges[1:])
    w0 = np.cumsum(prob)[:-1]  # class 0: bins 0..k
    m0 = np.cumsum(prob * centres)[:-1]
    total = float((prob * centres).sum())
    w1 = 1.0 - w0
    with np.errstate(divide="ignore", invalid="ignore"):
        between = np.where((w0 > 0) & (w1 > 0),
                           (total * w0 - m0) ** 2 / (w0 * w1), 0.0)
    best = np.flatnonzero(between >= between.max() * (1.0 - 1e-9))
    return float(edges[1:][best].mean())


def shade_threshold(log_luminance: np.ndarray) -> float:
    """The log luminance that separates shade from sunlit surface in a photo.

    Otsu's threshold (:func:`_otsu_threshold`) splits the two largest modes. In a sunlit photo
    the lit surface is the larger one; when Otsu leaves less than
    ``1 - MAX_SHADE_FRACTION`` of the surface above its threshold, that bright class is
    highlights (a white object, glare, a lit wall in a shaded close-up), and the split that
    matters lies inside the dark class, so Otsu is taken again there.

    Example:
        >>> v = np.r_[np.full(300, -3.0), np.full(600, -1.0), np.full(100, 1.0)]
        >>> -3.0 < shade_threshold(v) < -1.0
        True
    """
    values = np.asarray(log_luminance, np.float64).ravel()
    t = _otsu_threshold(values)
    dark = values[values < t]
    if dark.size > 0.05 * values.size and dark.size > MAX_SHADE_FRACTION * values.size:
        t = _otsu_threshold(dark)
    return t


def photo_shadow_probability(
    image_srgb: np.ndarray,
    sky: np.ndarray,
    prior_shadow: np.ndarray | None = None,
) -> np.ndarray:
    """How likely each pixel is in a cast or attached shadow, from the photo and a prior.

    Args:
        image_srgb: ``H x W x 3`` sRGB in [0, 1].
        sky: ``H x W`` bool (never shadow).
        prior_shadow: optional ``H x W`` shadow image ``S`` at the photo's sun (the shadow
            network's or Direct's); dark regions farther than :data:`PRIOR_RADIUS` from its
            shadows (``S < PRIOR_THRESHOLD``) are not shadows. None: the photo alone.

    Returns:
        ``H x W`` float32 in [0, 1]; 0 on the sky.

    Example:
        >>> img = np.full((8, 8, 3), 0.8, np.float32); img[4:] = 0.2
        >>> p = photo_shadow_probability(img, np.zeros((8, 8), bool))
        >>> bool(p[6, 4] > 0.9 and p[1, 4] < 0.1)
        True
    """
    img = np.nan_to_num(np.clip(np.asarray(image_srgb, np.float32), 0.0, 1.0))
    sky = np.asarray(sky, bool)
    if img.ndim != 3 or img.shape[2] != 3 or sky.shape != img.shape[:2]:
        raise ValueError(f"expected an H x W x 3 image and an H x W sky mask, got {img.shape} "
                         f"and {sky.shape}")
    h, w = sky.shape
    surface = ~sky
    if surface.sum() < 16:
        return np.zeros((h, w), np.float32)
    log_y = _log_luminance(img)
    t = shade_threshold(log_y[surface])
    p = 1.0 / (1.0 + np.exp(np.clip((log_y - t) / SOFT_LOG, -30.0, 30.0)))
    side = max(h, w)
    radius = max(1, round(EDGE_RADIUS * side))
    if EDGE_RADIUS > 0:
        p = cv2.ximgproc.guidedFilter(img, p.astype(np.float32), radius, EDGE_EPS)
    if prior_shadow is not None:
        p = p * near_predicted_shadow(prior_shadow, sky, PRIOR_RADIUS)
    return np.where(surface, np.clip(p, 0.0, 1.0), 0.0).astype(np.float32)


def near_predicted_shadow(prior_shadow: np.ndarray, sky: np.ndarray, radius: float
                          ) -> np.ndarray:
    """1 within ``radius`` (fraction of the longer side) of a predicted shadow
    (``S < PRIOR_THRESHOLD`` off the sky), falling softly to 0 beyond it (``H x W`` float32)."""
    prior = np.asarray(prior_shadow, np.float32)
    sky = np.asarray(sky, bool)
    if prior.shape != sky.shape:
        raise ValueError(f"expected a prior of shape {sky.shape}, got {prior.shape}")
    geo = ((prior < PRIOR_THRESHOLD) & ~sky).astype(np.uint8)
    k = max(1, round(radius * max(sky.shape)))
    near = cv2.dilate(geo, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * k + 1,) * 2))
    gate = cv2.GaussianBlur(near.astype(np.float32), (0, 0), max(1.0, k / 4))
    return np.clip(gate * 2.0, 0.0, 1.0).astype(np.float32)


def shadow_edge_bands(shadow: np.ndarray, where: np.ndarray, ring: float,
                      edge_only: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """A shadow mask's inside (2 px in from its edge; with ``edge_only``, no further in than
    the ring's width) and the ring just outside it (from 3 px to ``ring`` of the longer side,
    at least 6 px, out), both within ``where`` (``H x W`` bool each): a shadow's surface and
    the lit surface next to it, mostly one material."""
    m = np.asarray(shadow, np.uint8)
    r = max(6, round(ring * max(m.shape)))
    ellipse = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1,) * 2)
    gap = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (7, 7))
    inner = (cv2.erode(m, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))) > 0) & where
    if edge_only:
        inner &= ~(cv2.erode(m, ellipse) > 0)
    outer = (cv2.dilate(m, ellipse) > 0) & ~(cv2.dilate(m, gap) > 0) & where
    return inner, outer


#: :func:`photo_shade_shift`: the ring (fraction of the longer side) round the found shadows,
#: the least pixels on each side, and how far along the clear sky's shift the estimate may go.
SHIFT_RING = 0.02
SHIFT_MIN_PIXELS = 50
SHIFT_RANGE = (0.0, 1.5)


def photo_shade_shift(image_srgb: np.ndarray, found: np.ndarray, surface: np.ndarray
                      ) -> tuple[float, float]:
    """The photo's own shade's chromaticity shift ``(log R/G, log B/G)`` against the lit
    surface next to it: the median inside its found shadows near their edge minus that of
    the lit ring round them (:func:`shadow_edge_bands`), taken along the clear sky's shift
    (:data:`SKY_SHADE_SHIFT`) and kept within :data:`SHIFT_RANGE` of it (a white balance moves
    lit and shade alike; shade is never warmer than its lit surface in daylight, and what
    points elsewhere is the found shadows' materials). :data:`SKY_SHADE_SHIFT` itself when
    either side has fewer than :data:`SHIFT_MIN_PIXELS` pixels."""
    inner, ring = shadow_edge_bands(found, surface, SHIFT_RING, edge_only=True)
    if min(int(inner.sum()), int(ring.sum())) < SHIFT_MIN_PIXELS:
        return SKY_SHADE_SHIFT
    chroma = log_chromaticity(srgb_to_linear(np.clip(image_srgb, 0.0, 1.0)), 1e-3)
    d = np.median(chroma[inner], axis=0) - np.median(chroma[ring], axis=0)
    sky = np.asarray(SKY_SHADE_SHIFT, np.float64)
    t = float(np.clip(d @ sky / (sky @ sky), *SHIFT_RANGE))
    return (float(t * sky[0]), float(t * sky[1]))


def same_material(image_srgb: np.ndarray, probability: np.ndarray, surface: np.ndarray,
                  shift: tuple[float, float] = SHADE_SHIFT) -> np.ndarray:
    """How well each pixel's chromaticity matches the lit surface around it (``H x W`` in
    [0, 1]).

    A shadow darkens a surface and turns it a little bluer (it is lit by the sky only); a dark
    material differs from its surroundings in chromaticity too. Chromaticity is
    ``(log R/G, log B/G)`` of the linear colour, lightly blurred (dark pixels are noisy); the
    lit surroundings' mean is Gaussian-weighted (sigma :data:`RATIO_SIGMA` of the longer side)
    by ``(1 - p)^2``. The shade's expected shift ``shift`` (:data:`SHADE_SHIFT`, or
    :data:`SKY_SHADE_SHIFT`) is allowed for, and the match falls off as
    ``exp(-(d / CHROMA_TOL)^2)``.
    """
    lin = srgb_to_linear(image_srgb)
    side = max(probability.shape)
    chroma = log_chromaticity(cv2.GaussianBlur(lin, (0, 0), max(0.5, side / 384.0)))
    w = ((1.0 - probability) ** 2 * surface).astype(np.float32)
    sigma = max(1.0, RATIO_SIGMA * side)
    n = wide_blur(w, sigma)
    mean = wide_blur(chroma * w[..., None], sigma) / np.maximum(n, 1e-6)[..., None]
    d = chroma - mean
    dist = np.hypot(d[..., 0] - shift[0], d[..., 1] - shift[1])
    return np.exp(-((dist / CHROMA_TOL) ** 2)).astype(np.float32)


def original_shadow_from_photo(
    probability: np.ndarray, cosine: np.ndarray, sky: np.ndarray
) -> np.ndarray:
    """``S_o = vis(p) * max(cos, LIT_FLOOR)`` on the surface, 0 on the sky.

    The photo decides visibility (``p``), the geometry the lit level (the cosine term).
    Visibility falls from 1 at ``p = 0.4`` through :data:`FOUND_VISIBILITY` at ``p = 0.5`` to 0
    at ``p = 0.6``, so ``S_o`` is below the overlay's threshold (0.15) wherever ``p > 0.5``, on
    any surface (and from ``p`` about 0.46 where the lit level is :data:`LIT_FLOOR`): what
    ``S_o`` calls shadow is what the app shows as the photo's found shadows and what
    de-shadowing lifts. (Until 2026-11-30 a straight ramp from 0.4 to 0.6 left
    surfaces facing the sun with ``p`` up to 0.57 above 0.15, although a comment said
    otherwise.)
    """
    p = np.asarray(probability, np.float32)
    cos = np.clip(np.asarray(cosine, np.float32), 0.0, 1.0)
    vis = np.interp(p, [0.4, 0.5, 0.6], [1.0, FOUND_VISIBILITY, 0.0]).astype(np.float32)
    out = vis * np.maximum(cos, LIT_FLOOR)
    return np.where(np.asarray(sky, bool), 0.0, out).astype(np.float32)


def _check_probability(image_srgb: np.ndarray, probability: np.ndarray, sky: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    img = np.nan_to_num(np.clip(np.asarray(image_srgb, np.float32), 0.0, 1.0))
    p = np.clip(np.asarray(probability, np.float32), 0.0, 1.0)
    sky = np.asarray(sky, bool)
    if p.shape != img.shape[:2] or sky.shape != p.shape:
        raise ValueError(f"expected probability and sky of shape {img.shape[:2]}, got "
                         f"{p.shape} and {sky.shape}")
    return img, p, sky


def _usable(lin: np.ndarray, sky: np.ndarray) -> np.ndarray:
    """Surface pixels whose colour can be measured (off the sky, no channel clipped)."""
    return ~sky & (lin.max(axis=-1) < 0.98)


def _shade_statistics(img: np.ndarray, p: np.ndarray, sky: np.ndarray) -> dict | None:
    """Log colour, the lit and shadowed surfaces' local log means and weights, and the whole
    photo's lit/shadow log ratio ``glob`` (per channel); None without both surfaces."""
    lin = srgb_to_linear(img)
    log_c = np.log(lin + _LOG_EPS).astype(np.float32)
    usable = _usable(lin, sky)
    w_lit = ((1.0 - p) ** 2 * usable).astype(np.float32)
    w_shd = (p**2 * usable).astype(np.float32)
    if w_lit.sum() < 1.0 or w_shd.sum() < 1.0:
        return None
    glob = (np.einsum("hw,hwc->c", w_lit, log_c) / w_lit.sum()
            - np.einsum("hw,hwc->c", w_shd, log_c) / w_shd.sum())
    sigma = max(1.0, RATIO_SIGMA * max(p.shape))

    def blur(x: np.ndarray) -> np.ndarray:
        return wide_blur(x, sigma)

    def blur_s(x: np.ndarray) -> np.ndarray:
        return wide_blur(x, sigma * SHADE_SIGMA)

    n_lit, n_shd = blur(w_lit), blur(w_shd)
    mu_lit = blur(log_c * w_lit[..., None]) / np.maximum(n_lit, 1e-6)[..., None]
    # The shade's own level more locally: a shadow darkens toward its occluder.
    mu_shd = blur_s(log_c * w_shd[..., None]) / np.maximum(blur_s(w_shd), 1e-6)[..., None]
    return {"log_c": log_c, "glob": glob, "n_lit": n_lit, "n_shd": n_shd, "mu_lit": mu_lit,
            "mu_shd": mu_shd}


#: :func:`deshadow_log_gain`: a lifted pixel's log luminance ends at most this much (natural
#: log) above the mean log colour of the lit surface around it: room for the surface's own
#: texture, while a bright fleck inside a shadow (a sun fleck a "Mark shadow" fill took in, a
#: reflection) or a lit surface wrongly found is not lifted into glare. Measured with
#: :func:`warm_lift` on (balanced preset, each dev photo at its best sun; the 7 twin pairs'
#: de-shadow error inside / outside the mask, as ``outcast eval real`` scores it, and on all 47
#: photos the Lab ``a*b*`` / ``L*`` gap between the de-shadowed inside of each human-marked
#: shadow and a lit ring round it): no bound 0.4841 / +0.143, 15.08 / 24.63; 1.0: 0.4840 /
#: +0.116, 15.09 / 24.63; 0.6 (default) 0.4842 / +0.094, 15.05 / 24.54; 0.3: 0.4837 / +0.060,
#: 14.99 / 24.33 (0.6 leaves bright texture more room than 0.3: the numbers cannot see that).
#: Not in the relighting's lift base (:func:`deshadow`'s ``above_lit``): there the bound
#: flattens bright texture that :func:`~outcast_core.runtime.pipeline.relight.restore_detail`
#: puts back where the new sun lights the surface (``relit_detail``, fast preset, 47 photos:
#: 0.921 -> 0.910); the bound read on the log luminance blurred at :data:`TEXTURE_RADIUS`
#: kept the detail (0.921) but lost most of the gain (pairs outside +0.140).
LIFT_ABOVE_LIT = 0.6


def warm_lift(log_gain: np.ndarray) -> np.ndarray:
    """A shadow's lift (``... x 3`` log gain per channel) made no cooler than neutral: red's
    gain at least green's, blue's at most green's.

    Lifting a shadow adds the sun's light to the sky's, and sunlight is warmer than skylight,
    so the lift warms a surface or leaves its colour (overcast), never cools or greens it. The
    local lit/shadow ratio breaks that when the lit surface nearby is another material: beside
    a cyan pool, lifted grey paving turned teal (a user trial). Measured on the 7 dev twin
    pairs (balanced, de-shadow error inside / outside the mask): 0.4993 / +0.117 without,
    0.4841 / +0.143 with; on all 47 dev photos the ``a*b*`` gap between each lifted human-marked
    shadow and its lit ring 15.23 -> 15.08 (see :data:`LIFT_ABOVE_LIT` for both together).

    Example:
        >>> warm_lift(np.array([0.2, 0.5, 0.9], np.float32)).tolist()  # a teal lift
        [0.5, 0.5, 0.5]
        >>> warm_lift(np.array([0.9, 0.5, 0.2], np.float32)).tolist()  # a warm one: kept
        [0.8999999761581421, 0.5, 0.20000000298023224]
    """
    g = np.asarray(log_gain, np.float32)
    green = g[..., 1]
    return np.stack([np.maximum(g[..., 0], green), green, np.minimum(g[..., 2], green)], -1)


#: :func:`marked_lift`: the lit surface round a marked shadow is read in a band this wide
#: (fraction of the longer side) beyond the band of :data:`MARKED_GAP` next to it, which holds
#: the shadow's soft edge; a lifted pixel of the mark ends no brighter than this percentile
#: of that lit surface's log luminance (a sun fleck a click's region closed over is not
#: lifted into glare).
MARKED_RING = 0.03
MARKED_GAP = 0.005
MARKED_TOP = 75.0


#: :func:`_region_bands`: a region of at most this many pixels stamps the elements.
_STAMP_AREA = 64


def _ellipse_spans(radius: int) -> np.ndarray:
    """Half the width of each row of OpenCV's ``2 radius + 1`` elliptical element."""
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1,) * 2)
    return k.sum(axis=1) // 2


def _dilated_ellipse(mask: np.ndarray, radius: int) -> np.ndarray:
    """``cv2.dilate`` of a ``uint8`` 0/1 mask by OpenCV's elliptical element of that radius,
    bit for bit, as one dilation by a row per distinct row width shifted onto each row (the
    element is symmetric and each row an unbroken run): a large element's direct dilation
    costs its area per pixel."""
    h = mask.shape[0]
    out = mask.copy()
    rows: dict[int, np.ndarray] = {}
    for i, half in enumerate(_ellipse_spans(radius).tolist()):
        dy = i - radius
        if abs(dy) >= h:
            continue
        wide = rows.get(half)
        if wide is None:
            wide = rows[half] = cv2.dilate(mask, np.ones((1, 2 * half + 1), np.uint8))
        if dy >= 0:
            np.maximum(out[:h - dy], wide[dy:], out=out[:h - dy])
        else:
            np.maximum(out[-dy:], wide[:h + dy], out=out[-dy:])
    return out


def _region_bands(labels: np.ndarray, stats: np.ndarray, gap: int, reach: int
                  ) -> Iterator[tuple[tuple[int, int, int, int], np.ndarray, np.ndarray]]:
    """For each 8-connected region of ``labels`` in turn: ``(window, inside, band)``, the
    window (``top, bottom, left, right``) of its bounding box widened by ``reach`` (cut to
    the image), the region inside it, and the pixels within ``reach`` of it (OpenCV's
    elliptical element) but not within ``gap``. A region of a few pixels stamps the two
    elements once per pixel; a larger one is dilated (:func:`_dilated_ellipse`)."""
    h, w = labels.shape
    far_k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * reach + 1,) * 2).astype(bool)
    near_k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * gap + 1,) * 2).astype(bool)
    lone = far_k.copy()  # a one-pixel region's band
    lone[reach - gap:reach + gap + 1, reach - gap:reach + gap + 1] &= ~near_k
    for k in range(1, len(stats)):
        x0, y0, bw, bh, area = (int(v) for v in stats[k, :5])
        t, le = max(0, y0 - reach), max(0, x0 - reach)
        b, r = min(h, y0 + bh + reach), min(w, x0 + bw + reach)
        inside = labels[t:b, le:r] == k
        if area <= _STAMP_AREA:
            # On a grid widened by ``reach`` on every side, then cut to the window.
            if area == 1:
                band = lone
            else:
                far = np.zeros((bh + 2 * reach, bw + 2 * reach), bool)
                near = np.zeros_like(far)
                ys, xs = np.nonzero(labels[y0:y0 + bh, x0:x0 + bw] == k)
                for yy, xx in zip(ys.tolist(), xs.tolist(), strict=True):
                    far[yy:yy + 2 * reach + 1, xx:xx + 2 * reach + 1] |= far_k
                    near[yy + reach - gap:yy + reach + gap + 1,
                         xx + reach - gap:xx + reach + gap + 1] |= near_k
                band = far & ~near
            band = band[t - y0 + reach:b - y0 + reach, le - x0 + reach:r - x0 + reach]
        else:
            region = inside.astype(np.uint8)
            near = cv2.dilate(region, cv2.getStructuringElement(cv2.MORPH_ELLIPSE,
                                                                (2 * gap + 1,) * 2))
            band = (_dilated_ellipse(region, reach) > 0) & (near == 0)
        yield (t, b, le, r), inside, band


#: :func:`marked_lift`: a class of the lit ring whose chromaticity differs from the marked
#: shadow's by more than this (log units)...
RING_OTHER_CHROMA = 0.1
#: ... in a direction more than this many degrees from the way shade's turns when it is lit
#: (``-SKY_SHADE_SHIFT``) is another material, not the shadow's surface lit.
RING_OTHER_ANGLE = 45.0


def _lit_class(log_c: np.ndarray, ring: np.ndarray, bright: np.ndarray, mark: np.ndarray
               ) -> np.ndarray:
    """Which class of a marked shadow's lit ring (``ring``, ``H x W`` bool, split by
    ``bright`` over its pixels) is the shadow's surface lit, as ``ring``'s pixels to keep.

    The bright class, as a rule: the dark one is another shadow, the mark's missed penumbra or
    dark dirt. But a shadow's occluder stands beside it, and a click's or a grown stroke's
    ring runs round the whole shadow and meets it: on a dev photo a box's shadow on carpet,
    marked, was lifted to the white box's cream, three times the carpet's brightness. So the
    dark class is kept when it is lit against the mark (:data:`ADD_DARKER` brighter), turns
    from the mark as lit shade does, and the bright class does not (:data:`RING_OTHER_CHROMA`,
    :data:`RING_OTHER_ANGLE`).
    """
    lc = log_c[ring]
    dark = ~bright
    mark_c = np.median(log_c[mark], axis=0)
    level = float(mark_c @ LUMA_709)
    away = -np.asarray(SKY_SHADE_SHIFT, np.float64)
    away /= np.linalg.norm(away)

    def other(cls: np.ndarray) -> bool:
        c = np.median(lc[cls], axis=0) - mark_c
        d = np.array([c[0] - c[1], c[2] - c[1]], np.float64)
        norm = float(np.linalg.norm(d))
        return norm > RING_OTHER_CHROMA and float(d @ away) < norm * math.cos(
            math.radians(RING_OTHER_ANGLE))

    keep = bright
    if (float(np.median(lc[dark] @ LUMA_709)) >= level + ADD_DARKER and other(bright)
            and not other(dark)):
        keep = dark
    out = np.zeros_like(ring)
    out[ring] = keep
    return out


def _marks_with_their_shadows(marks: np.ndarray, log_c: np.ndarray, usable: np.ndarray
                              ) -> np.ndarray:
    """The marked pixels (``H x W`` bool) with, for each 8-connected mark that has no lit
    surface round it, the even region it lies in: connected usable pixels within
    :data:`ADD_RANGE` of the mark's median log luminance (blurred as :func:`edit_luminance`
    blurs it; ``log_c``: ``H x W x 3`` log colour), where that region may be a shadow at that
    level (:func:`_darker_than_round`'s tests: at most :data:`ADD_MAX_SHARE` of the surface,
    darker than a ring :data:`ADD_RING` wide round it by :data:`ADD_DARKER`).
    :func:`marked_lift` reads the lit surface round this: a stroke inside a wide shadow is
    lifted to the lit ground beyond the shadow, as a click there is, and not to the shadow
    round the stroke (a user trial: tinted, not lifted). A mark with lit surface round it
    already (a click's region, a found shadow: its own ring that much brighter) keeps its own
    ring and costs that test only; a mark inside a region already taken, nothing."""
    out = marks.copy()
    n, labels, stats, _ = cv2.connectedComponentsWithStats(marks.astype(np.uint8),
                                                           connectivity=8)
    if n <= 1:
        return out
    h, w = marks.shape
    side = max(h, w)
    lum = np.maximum(np.exp(log_c) - _LOG_EPS, 0.0) @ LUMA_709
    smooth = cv2.GaussianBlur(np.log(lum + _LOG_EPS).astype(np.float32), (0, 0),
                              max(0.5, side / 384.0))
    ring_r = max(2, round(ADD_RING * side))
    most = ADD_MAX_SHARE * max(1, int(usable.sum()))
    taken = np.zeros((h, w), bool)  # regions added so far
    for k in range(1, n):
        x0, y0, bw, bh = (int(v) for v in stats[k, :4])
        t, le = max(0, y0 - ring_r), max(0, x0 - ring_r)
        b, r = min(h, y0 + bh + ring_r), min(w, x0 + bw + ring_r)
        mark = labels[t:b, le:r] == k
        if taken[t:b, le:r][mark].all():
            continue
        level = float(np.median(smooth[t:b, le:r][mark]))
        round_it = _grown(mark, ring_r) & ~mark & usable[t:b, le:r]
        if round_it.any() and level <= float(np.median(smooth[t:b, le:r][round_it])) - ADD_DARKER:
            continue  # lit surface round it already
        whole = labels == k
        even = ((np.abs(smooth - level) <= ADD_RANGE) & usable) | whole
        count, parts, part_stats, _ = cv2.connectedComponentsWithStats(
            even.astype(np.uint8), connectivity=8)
        touched = np.zeros(count, bool)
        touched[parts[whole]] = True
        if part_stats[touched, cv2.CC_STAT_AREA].sum() > most:
            continue
        ys, xs = np.nonzero(touched[parts])
        t, le = max(0, int(ys.min()) - ring_r), max(0, int(xs.min()) - ring_r)
        b, r = min(h, int(ys.max()) + 1 + ring_r), min(w, int(xs.max()) + 1 + ring_r)
        grown = touched[parts[t:b, le:r]]
        ring = _grown(grown, ring_r) & ~grown & usable[t:b, le:r]
        if not ring.any() or level <= float(np.median(smooth[t:b, le:r][ring])) - ADD_DARKER:
            out[t:b, le:r] |= grown
            taken[t:b, le:r] |= grown
    return out


def marked_lift(log_c: np.ndarray, p: np.ndarray, usable: np.ndarray, marked: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """The lift of the shadows the user marked, from the lit surface just round each of them
    (``log_c``: ``H x W x 3`` log colour; ``p``: the shadow probability; ``usable``: ``H x W``
    bool, the surface whose colour can be measured; ``marked``: ``H x W`` in [0, 1], how much
    the user's mark counts).

    Each marked region (8-connected, ``marked > 0``; one with no lit surface round it taken
    with the shadow it lies in, :func:`_marks_with_their_shadows`) is lifted to the lit
    surface round it: a band :data:`MARKED_RING` wide beyond :data:`MARKED_GAP` of its edge,
    its usable pixels not found shadow (``p <= 0.5``), split in two with Otsu's threshold
    and, where the two classes differ clearly (:data:`STROKE_SPLIT`), the class that is the
    shadow's surface lit (:func:`_lit_class`: the bright one unless that is another material,
    the shadow's occluder, and the dark one the surface). Only the marked pixels are lifted.
    The gain is that lit surface's mean log colour
    minus the marked shadow's own local mean (the shade's scale of :func:`deshadow_log_gain`,
    read on the marked pixels only), so the shadow ends at the level and colour of the lit
    surface round it, its texture kept; where the marked shadow itself (its local mean) lies
    further below that surface than the largest lift, its pixels take that surface's colour
    instead, in proportion (:func:`crushed_share`: the camera kept only noise there), while a
    dark object inside a shadow that is not crushed keeps the darker-than-shade guard. The
    photo-wide statistics the unmarked lift reads
    count every shadow the found probability missed as lit surface and every dark material
    found as shade: on the ski slope a marked snow shadow was lifted short of the snow (its
    outline left) and a thin one beside black pines past it, pale blue (user trials).

    Returns:
        ``(gain, top, keep, weight)``: the log gain (``H x W x 3``, at most
        :data:`MAX_LIFT_LOG`, no cooler than neutral: :func:`warm_lift`; in a crushed shadow,
        blended toward the gain that gives the pixel the lit surface's colour), the log luminance
        a lifted pixel may reach (``H x W``: :data:`MARKED_TOP` percentile of that lit
        surface), how much a pixel is lifted as shade, not as a darker
        material inside the mark (``H x W``: darker than the marked shadow round it by more
        than :data:`DARKER_MARGIN` falls off as :func:`deshadow_log_gain`'s guard), and
        ``marked`` where a lit surface was found round the region, 0 elsewhere (``H x W``);
        None when no region has one.
    """
    m = np.clip(np.asarray(marked, np.float32), 0.0, 1.0)
    h, w = m.shape
    side = max(h, w)
    gap = max(1, round(MARKED_GAP * side))
    reach = gap + max(2, round(MARKED_RING * side))
    y = log_c @ LUMA_709
    # Each mark is measured against the lit surface round the shadow it lies in: a stroke
    # painted inside a wide shadow has shadow all round it (a user trial: tinted, not lifted).
    region = _marks_with_their_shadows(m > 0, log_c, usable)
    _, labels, stats, _ = cv2.connectedComponentsWithStats(region.astype(np.uint8),
                                                           connectivity=8)
    candidates = usable & (p <= 0.5) & ~region
    lit = np.zeros(log_c.shape, np.float32)
    top = np.zeros((h, w), np.float32)
    weight = np.zeros((h, w), np.float32)
    for (t, b, le, r), whole, band in _region_bands(labels, stats, gap, reach):
        inside = whole & (m[t:b, le:r] > 0)
        ring = band & candidates[t:b, le:r]
        if ring.sum() < 16:
            continue
        values = y[t:b, le:r][ring]
        split = _otsu_threshold(values)
        bright = values >= split
        if (STROKE_MIN_SHARE * values.size <= bright.sum() < values.size
                and np.median(values[bright]) - np.median(values[~bright]) > STROKE_SPLIT):
            ring = _lit_class(log_c[t:b, le:r], ring, bright, inside)
        lit[t:b, le:r][inside] = log_c[t:b, le:r][ring].mean(axis=0)
        top[t:b, le:r][inside] = np.percentile(y[t:b, le:r][ring], MARKED_TOP)
        weight[t:b, le:r][inside] = m[t:b, le:r][inside]
    if not weight.any():
        return None
    on = (weight > 0) & usable
    sigma = max(1.0, RATIO_SIGMA * SHADE_SIGMA * side)
    n_m = wide_blur((weight * on).astype(np.float32), sigma)
    mu = (wide_blur(log_c * (weight * on)[..., None], sigma)
          / np.maximum(n_m, 1e-6)[..., None])
    mu = np.where((n_m > 1e-4)[..., None], mu, log_c)
    # A channel further below the lit surface than the largest lift (deep blue shade's red:
    # 3.1-3.2 in two dev photos) takes the others down by as much, so the shadow ends in the
    # lit surface's colour, a little darker, not tinted: clipped alone, red fell short and a
    # marked shadow on pavement or decking came out cyan.
    need = np.maximum(lit - mu, 0.0)
    over = np.maximum(need.max(axis=-1) - MAX_LIFT_LOG, 0.0)
    gain = warm_lift(np.clip(need - over[..., None], 0.0, MAX_LIFT_LOG))
    # A penumbra (a pixel of the mark lighter than its shadow, smoothly: not its fine texture)
    # takes the share of the gain that brings it to the lit surface: the whole gain lifted it
    # past, into a light rim round the shadow (a user trial: cream, 3 px wide).
    smooth = cv2.GaussianBlur(y, (0, 0), max(1.0, side * PENUMBRA_SMOOTH))
    share = np.clip((lit @ LUMA_709 - smooth) / np.maximum(gain @ LUMA_709, 1e-3), 0.0, 1.0)
    gain = gain * np.where(weight > 0, share, 1.0)[..., None]
    excess = (mu - log_c) @ LUMA_709 - DARKER_MARGIN
    keep = np.exp(-0.5 * (np.maximum(excess, 0.0) / DARKER_WIDTH) ** 2)
    # Crushed: a marked shadow no lift can bring back (the camera kept noise, not colour)
    # takes the lit surface's colour (a fill), in full from CRUSHED_FULL below it. Decided on
    # the shadow's local level, not the pixel's: a black object inside a shadow that is not
    # crushed stays dark (the guard above; a review found it painted over).
    fill = np.where(weight > 0, crushed_share((lit - mu) @ LUMA_709), 0.0)
    if fill.any():
        k = fill[..., None]
        gain = (1.0 - k) * gain + k * (lit - log_c)
        keep = keep + fill * (1.0 - keep)
    return (np.where((weight > 0)[..., None], gain, 0.0).astype(np.float32), top,
            keep.astype(np.float32), weight)


#: :func:`found_shade_marks`: a found shadow (:func:`without_texture` of the probability above
#: :data:`FOUND_MARK_LEVEL`, 8-connected, at least :data:`FOUND_MARK_MIN_SHARE` of the frame) is
#: compared with the lit ring round it (:data:`FOUND_MARK_RING` of the longer side wide, beyond
#: :data:`MARKED_GAP`, its usable pixels with a probability under :data:`FOUND_MARK_RING_P`, at
#: least :data:`FOUND_MARK_MIN_RING` of them, their log luminance's interquartile range under
#: :data:`FOUND_MARK_SPREAD`: one surface). It is shade of that surface when it is darker (median
#: log luminance, natural log) by :data:`FOUND_MARK_DARKER`, bluer (log B/G) by more than
#: :data:`FOUND_MARK_BLUER`, and its chromaticity moved within :data:`FOUND_MARK_ANGLE` degrees of
#: the clear sky's shift (:data:`SKY_SHADE_SHIFT`'s direction). The direction is what a white
#: balance cannot move (it scales lit and shade alike) and what blue materials do not share: on the
#: 47 dev photos the candidates that lie in the human-marked shadows are 2-30 degrees off it (two of
#: 35 at 42 and 56); of the 20 outside them, the large ones are 28-52 off (a sea 37, navy trousers
#: 30, a tree 52), nine (most of them small) within 25. Chosen on the dev photos (eighteenth
#: session's note in models/EVAL.md): at 20 / 25 / 30 / no limit the human-marked shadows keep 0.450
#: / 0.449 / 0.421 / 0.401 of their contrast after the de-shadow (0.525 without these marks) and the
#: photo outside them changes by 0.0999 / 0.1008 / 0.1024 / 0.1133 in log luminance (0.0974); at 25
#: with the penumbra (a thinner dark outline) 0.461 / 0.1009.
FOUND_MARK_LEVEL = 0.5
FOUND_MARK_MIN_SHARE = 0.001
FOUND_MARK_RING = 0.02
FOUND_MARK_RING_P = 0.3
FOUND_MARK_MIN_RING = 16
FOUND_MARK_SPREAD = 0.5
FOUND_MARK_DARKER = (0.4, 3.5)
FOUND_MARK_BLUER = 0.1
FOUND_MARK_ANGLE = 25.0


def found_shade_marks(image_srgb: np.ndarray, probability: np.ndarray, sky: np.ndarray
                      ) -> np.ndarray:
    """The found shadows whose own lit ring says they are its shade (``H x W`` bool): what
    :func:`deshadow` may lift as if the user had marked them (:func:`marked_lift`: to the lit
    surface round each one) rather than by the photo-wide statistics, with their penumbra.
    ``sky``: what is not surface (the sky, and what the user marked "not a shadow").

    The photo-wide lift reads its lit reference within a third of the frame and keeps a pixel
    whose colour is not the lit surface's in clear-sky shade (:func:`same_material`): deep
    blue shade (two to three times the clear sky's shift, common in the dev photos' SBU
    part) passed at 0.1-0.4 and stayed a blue-grey ghost, its lit reference the grass and
    trees round a pavement. Each shadow kept here is compared with its own ring
    (:data:`FOUND_MARK_LEVEL` and the constants after it) and grown into its penumbra against
    that ring (:func:`_with_penumbra`).

    Example:
        >>> img = np.full((64, 64, 3), [0.6, 0.55, 0.5], np.float32)
        >>> img[24:40, 24:40] = [0.08, 0.1, 0.14]  # deep blue shade on the surface
        >>> img[4:12, 4:12] = [0.05, 0.05, 0.35]   # a blue object: not along the sky's shift
        >>> p = photo_shadow_probability(img, np.zeros((64, 64), bool))
        >>> m = found_shade_marks(img, p, np.zeros((64, 64), bool))
        >>> bool(m[32, 32]), bool(m[8, 8])
        (True, False)
    """
    img, p, sky = _check_probability(image_srgb, probability, sky)
    h, w = p.shape
    side = max(h, w)
    found = ((without_texture(p) > FOUND_MARK_LEVEL) & ~sky).astype(np.uint8)
    out = np.zeros((h, w), bool)
    if not found.any():
        return out
    _, labels, stats, _ = cv2.connectedComponentsWithStats(found, connectivity=8)
    small = stats[:, cv2.CC_STAT_AREA] < FOUND_MARK_MIN_SHARE * h * w
    small[0] = True
    if small.all():
        return out
    _, labels, stats, _ = cv2.connectedComponentsWithStats(  # the large ones only
        (~small[labels]).astype(np.uint8), connectivity=8)
    lin = srgb_to_linear(img)
    y = np.log(luminance(lin) + _LOG_EPS)
    blurred = edit_luminance(img)  # the penumbra's test, as a "Mark shadow" fill reads it
    chroma = log_chromaticity(lin, _LOG_EPS)
    usable = _usable(lin, sky)
    ring_ok = usable & (p < FOUND_MARK_RING_P)
    gap = max(1, round(MARKED_GAP * side))
    reach = gap + max(2, round(FOUND_MARK_RING * side))
    sky_dir = math.atan2(SKY_SHADE_SHIFT[1], SKY_SHADE_SHIFT[0])
    for (t, b, le, r), inside, band in _region_bands(labels, stats, gap, reach):
        ring = band & ring_ok[t:b, le:r]
        shade = inside & usable[t:b, le:r]
        if min(int(ring.sum()), int(shade.sum())) < FOUND_MARK_MIN_RING:
            continue
        yy, cc = y[t:b, le:r], chroma[t:b, le:r]
        q1, q3 = np.percentile(yy[ring], [25, 75])
        darker = float(np.median(yy[ring]) - np.median(yy[shade]))
        shift = np.median(cc[shade], axis=0) - np.median(cc[ring], axis=0)
        turn = abs(math.degrees(math.atan2(float(shift[1]), float(shift[0])) - sky_dir))
        if (q3 - q1 < FOUND_MARK_SPREAD
                and FOUND_MARK_DARKER[0] < darker < FOUND_MARK_DARKER[1]
                and shift[1] > FOUND_MARK_BLUER and min(turn, 360.0 - turn) <= FOUND_MARK_ANGLE):
            # With its penumbra: grown into what is still darker than its own ring (the
            # rings of other shadows, on other surfaces, are not its: a review).
            bw = blurred[t:b, le:r]
            out[t:b, le:r] |= _with_penumbra(inside, bw, sky[t:b, le:r],
                                             float(np.median(bw[ring])), side)
    return out


#: :func:`marked_lift`: the blur (fraction of the longer side) under which a mark's pixels are
#: its texture, lifted with the shadow's whole gain; over it, lighter than the shadow is its
#: penumbra, lifted as far as the lit surface.
PENUMBRA_SMOOTH = 1.0 / 192

#: :func:`marked_lift`: a marked pixel darker than the lit surface round it by more than the
#: largest lift (:data:`MAX_LIFT_LOG`) is crushed shade, filled with that surface's colour in
#: proportion as it is darker, in full from :data:`CRUSHED_FULL` (natural log) below it.
CRUSHED_FULL = float(np.log(64.0))


def crushed_share(below_lit: np.ndarray) -> np.ndarray:
    """How much of a marked pixel is filled rather than lifted (``H x W`` float32 in [0, 1]),
    from how far (natural log luminance) its shadow is below the lit surface round it: 0 within
    :data:`MAX_LIFT_LOG` (the lift brings it back with its texture), rising to 1 at
    :data:`CRUSHED_FULL` (lifted further, its JPEG noise came out as blotches, blue where the
    blue channel was noisiest: a dev photo's shadow marked in the app).

    Example:
        >>> share = crushed_share(np.log(np.array([4.0, 16.0, 32.0, 64.0, 400.0])))
        >>> [round(float(v), 2) for v in share]
        [0.0, 0.0, 0.5, 1.0, 1.0]
    """
    x = (np.asarray(below_lit, np.float32) - MAX_LIFT_LOG) / (CRUSHED_FULL - MAX_LIFT_LOG)
    return np.clip(x, 0.0, 1.0).astype(np.float32)


def keep_fills(full_srgb: np.ndarray, before_srgb: np.ndarray, after_srgb: np.ndarray,
               where: np.ndarray | None, photo: np.ndarray) -> np.ndarray:
    """An image made from a photo (de-shadowed or relit) brought to full resolution by its
    gain (``full_srgb``, ``H x W x 3`` float32 or uint8), with what it filled rather than
    lifted (:func:`filled_share`, from ``before_srgb`` to ``after_srgb``, ``h x w x 3`` sRGB)
    taken from ``after_srgb`` upsampled: the full-size photo holds only noise there, which
    the gain would multiply (:func:`~outcast_core.runtime.pipeline.relight.
    transfer_to_full_resolution` calls it with its ``fills``). Only boxes round the filled
    pixels are upsampled, in bands of rows (a 100-megapixel photo has no full-size copy
    made). ``where`` (``h x w`` in [0, 1], or None: everywhere): where a fill may be (what
    the user marked as shadow). ``photo`` (the photo at ``full_srgb``'s size, uint8 or float
    sRGB): near a fill, each full-size pixel is filled as far as the photo there is darker
    than the fill (:data:`FILL_DARKER`), so the fill's edge is the photo's own, not the
    working grid's steps blurred (a user trial: a 10 px staircase with a dark outline at
    4000 px). Returns ``full_srgb``, changed in place where filled.

    Example:
        >>> before = np.full((8, 8, 3), 0.5, np.float32); before[2:6, 2:6] = 0.001
        >>> after = np.full((8, 8, 3), 0.5, np.float32)
        >>> full = np.full((16, 16, 3), 0.5, np.float32)
        >>> full[4:12, 4:12] = before[2, 2] * (1 + 30 * np.random.default_rng(0).random((8, 8, 3)))
        >>> out = keep_fills(full * (0.5 / 0.001), before, after, None, full)
        >>> bool(np.allclose(out[6:10, 6:10], 0.5, atol=1e-3))
        True
    """
    after = np.asarray(after_srgb, np.float32)
    share = filled_share(before_srgb, after)
    if where is not None:
        share = share * np.clip(np.asarray(where, np.float32), 0.0, 1.0)
    if not share.any():
        return full_srgb
    share = cv2.dilate(share, np.ones((3, 3), np.uint8))  # a working pixel's reach round the
    # fill; the photo says which of its pixels are filled
    h, w = share.shape
    big_h, big_w = full_srgb.shape[:2]
    fy, fx = big_h / h, big_w / w
    for r0, r1, c0, c1 in _fill_boxes(share > 0):
        # In full pixels; full pixel (Y, X) sits at small ((Y + 0.5) / fy - 0.5, ...).
        R0, R1 = int(math.floor(r0 * fy)), min(big_h, int(math.ceil(r1 * fy)))
        C0, C1 = int(math.floor(c0 * fx)), min(big_w, int(math.ceil(c1 * fx)))
        xs_all = ((np.arange(C0, C1) + 0.5) / fx - 0.5).astype(np.float32)
        for R in range(R0, R1, FILL_BAND):  # bands of rows, columns in remap's reach
            ys = ((np.arange(R, min(R1, R + FILL_BAND)) + 0.5) / fy - 0.5).astype(np.float32)
            for C in range(C0, C1, FILL_BAND_COLUMNS):
                xs = xs_all[C - C0:C - C0 + FILL_BAND_COLUMNS]
                map_x, map_y = np.meshgrid(xs, ys)
                k = cv2.remap(share, map_x, map_y, cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_REPLICATE)
                up = cv2.remap(after, map_x, map_y, cv2.INTER_LINEAR,
                               borderMode=cv2.BORDER_REPLICATE)
                crop = full_srgb[R:R + len(ys), C:C + len(xs)]
                own = np.asarray(photo[R:R + len(ys), C:C + len(xs)])
                own = (own.astype(np.float32) * np.float32(1.0 / 255.0)
                       if own.dtype == np.uint8 else own.astype(np.float32))
                darker = (np.log(luminance(srgb_to_linear(np.clip(up, 0.0, 1.0))) + _LOG_EPS)
                          - np.log(luminance(srgb_to_linear(np.clip(own, 0.0, 1.0)))
                                   + _LOG_EPS))
                lo, hi = (math.log(v) for v in FILL_DARKER)
                k = np.clip(4.0 * k, 0.0, 1.0) * np.clip((darker - lo) / (hi - lo), 0.0, 1.0)
                if crop.dtype == np.uint8:
                    c = crop.astype(np.float32) * np.float32(1.0 / 255.0)
                    c += k[..., None] * (up - c)
                    crop[...] = np.clip(np.rint(c * 255.0), 0, 255).astype(np.uint8)
                else:
                    crop += k[..., None] * (up - crop)
    return full_srgb


#: :func:`keep_fills` works in bands of this many full-size rows and columns (OpenCV's remap
#: takes fewer than 32767 a side), on at most :data:`FILL_MAX_BOXES` boxes (one round all of
#: them beyond).
FILL_BAND = 256
FILL_BAND_COLUMNS = 8192
FILL_MAX_BOXES = 32
#: :func:`keep_fills` with the photo: a full-size pixel near a fill is not filled where the
#: photo is at most the first times darker than the fill there, and filled in full from the
#: second (the ground round a crushed shadow stays the photo's, its penumbra joins the fill).
FILL_DARKER = (1.15, 2.0)


def _fill_boxes(filled: np.ndarray) -> list[tuple[int, int, int, int]]:
    """Boxes ``(r0, r1, c0, c1)`` (small pixels, end exclusive) that cover ``filled`` (``H x
    W`` bool) one small pixel wider each way (bilinear reaches that far), without overlap
    (overlapping ones merged): two marks in opposite corners make two boxes, not the frame."""
    h, w = filled.shape
    n, _, stats, _ = cv2.connectedComponentsWithStats(filled.astype(np.uint8), connectivity=8)
    boxes = [(max(0, int(y) - 1), min(h, int(y + bh) + 1), max(0, int(x) - 1),
              min(w, int(x + bw) + 1)) for x, y, bw, bh, _ in stats[1:]]
    if len(boxes) > FILL_MAX_BOXES:
        rows, cols = np.nonzero(filled)
        return [(max(0, int(rows.min()) - 1), min(h, int(rows.max()) + 2),
                 max(0, int(cols.min()) - 1), min(w, int(cols.max()) + 2))]
    merged = True
    while merged:
        merged = False
        for i in range(len(boxes)):
            for j in range(i + 1, len(boxes)):
                a, b = boxes[i], boxes[j]
                if a[0] <= b[1] and b[0] <= a[1] and a[2] <= b[3] and b[2] <= a[3]:  # (or touch)
                    boxes[i] = (min(a[0], b[0]), max(a[1], b[1]), min(a[2], b[2]),
                                max(a[3], b[3]))
                    del boxes[j]
                    merged = True
                    break
            if merged:
                break
    return boxes


def filled_share(before_srgb: np.ndarray, after_srgb: np.ndarray) -> np.ndarray:
    """How much of each pixel an image made from a photo holds filled rather than lifted
    (``H x W`` float32 in [0, 1]): :func:`crushed_share` of its log luminance gain from the
    photo (``before_srgb``) to it (``after_srgb``), both ``H x W x 3`` sRGB; 0 wherever the
    gain is within the largest lift."""
    y0 = luminance(srgb_to_linear(np.clip(np.asarray(before_srgb, np.float32), 0.0, 1.0)))
    y1 = luminance(srgb_to_linear(np.clip(np.asarray(after_srgb, np.float32), 0.0, 1.0)))
    return crushed_share(np.log(y1 + _LOG_EPS) - np.log(y0 + _LOG_EPS))


def deshadow_log_gain(
    image_srgb: np.ndarray, probability: np.ndarray, sky: np.ndarray,
    above_lit: float | None = LIFT_ABOVE_LIT, marked: np.ndarray | None = None,
) -> np.ndarray:
    """Per-pixel, per-channel log gain that lifts the photo's shadows (``H x W x 3``).

    Around each pixel (Gaussian weights, sigma :data:`RATIO_SIGMA` of the longer side) the mean
    log colour of the lit surface minus that of the shadowed surface, clamped to
    ``[0, MAX_LIFT_LOG]``, made no cooler than neutral (:func:`warm_lift`), times the pixel's
    shadow probability. Where no lit surface is near, the whole photo's lit/shadow ratio stands
    in. A lifted pixel ends no brighter than that lit surface's mean log colour plus
    ``above_lit`` (:data:`LIFT_ABOVE_LIT`; None: unbounded). ``marked`` (``H x W`` in [0, 1],
    or None): the marked shadows (the user's, and the found shadows :func:`found_shade_marks`
    keeps), as much as the mark counts, lifted to the lit surface just round each
    (:func:`marked_lift`) instead, and no brighter than that surface's bright end whatever
    ``above_lit`` says; elsewhere the gain is the same.
    """
    img, p, sky = _check_probability(image_srgb, probability, sky)
    st = _shade_statistics(img, p, sky)
    if st is None:
        return np.zeros(img.shape, np.float32)
    mark = None
    if marked is not None:
        m = np.clip(np.asarray(marked, np.float32), 0.0, 1.0)
        if m.shape != p.shape:
            raise ValueError(f"expected a marked mask of shape {p.shape}, got {m.shape}")
        if m.any():
            mark = marked_lift(st["log_c"], p, _usable(srgb_to_linear(img), sky), m)
    glob = st["glob"]
    gain = warm_lift(_local_ratio(st))
    keep = _not_darker_than_shade(st["log_c"], st["mu_lit"], glob)
    gain = gain * (p * keep)[..., None]
    if above_lit is not None:
        # No brighter than the lit surface around it, but for its texture: the excess comes
        # off every channel alike, so the lift's colour stays (until a channel's gain is 0).
        excess = (st["log_c"] + gain - st["mu_lit"]) @ LUMA_709 - above_lit
        gain = np.maximum(gain - np.maximum(excess, 0.0)[..., None], 0.0)
    if mark is None:
        return gain.astype(np.float32)
    # The marked shadows: lifted from the lit surface round each.
    m_gain, top, m_keep, m = mark
    m_gain = m_gain * (p * m_keep)[..., None]
    # No brighter than that lit surface's bright end, even with ``above_lit`` None (the
    # relighting's ceiling, where an edge lifted past it made a light rim): the gain scaled
    # down, so that a pixel lit already (a sun fleck) keeps its colour rather than turning warm.
    lum = m_gain @ LUMA_709
    room = top - st["log_c"] @ LUMA_709
    m_gain = m_gain * np.clip(room / np.maximum(lum, 1e-6), 0.0, 1.0)[..., None]
    return (gain + m[..., None] * (m_gain - gain)).astype(np.float32)


def _local_ratio(st: dict) -> np.ndarray:
    """The log ratio (per channel, ``H x W x 3``) between the lit surface and the shade round
    each pixel, from :func:`_shade_statistics`: the local one where both sides have weight,
    blended to the photo's global one elsewhere, clamped to ``[0, MAX_LIFT_LOG]`` and to
    :data:`LOCAL_MAX` times the global one (lit surfaces nearby may be another material)."""
    glob = st["glob"]
    trust = np.clip(np.minimum(st["n_lit"], st["n_shd"]) / 0.05, 0.0, 1.0)[..., None]
    ratio = trust * (st["mu_lit"] - st["mu_shd"]) + (1.0 - trust) * glob.reshape(1, 1, 3)
    return np.clip(ratio, 0.0, np.minimum(MAX_LIFT_LOG, LOCAL_MAX * np.maximum(glob, 0.0)))


def shade_log_ratio(image_srgb: np.ndarray, probability: np.ndarray, sky: np.ndarray
                    ) -> np.ndarray:
    """How much darker than the lit surface round it the photo's own shade is there (``H x W``
    float32, natural log of luminance, >= 0; 0 without both lit and shaded surface): the
    de-shadow's local lit/shade ratio (:func:`deshadow_log_gain` before each pixel's own
    probability). The learned relighting darkens a surface the new sun newly shadows at
    least this much (:func:`~outcast_core.runtime.pipeline.relight.shadow_contrast_floor`'s
    ``shade_ratio``).

    Example:
        >>> img = np.full((32, 32, 3), 0.8, np.float32); img[16:] *= 0.25
        >>> p = photo_shadow_probability(img, np.zeros((32, 32), bool))
        >>> r = shade_log_ratio(img, p, np.zeros((32, 32), bool))
        >>> bool(abs(float(r[8, 8]) - np.log(4.0)) < 0.25)
        True
    """
    img, p, sky = _check_probability(image_srgb, probability, sky)
    st = _shade_statistics(img, p, sky)
    if st is None:
        return np.zeros(p.shape, np.float32)
    return (_local_ratio(st) @ LUMA_709).astype(np.float32)


def material_guard(image_srgb: np.ndarray, probability: np.ndarray, sky: np.ndarray,
                   shift: tuple[float, float] = SHADE_SHIFT) -> np.ndarray:
    """How much each pixel's darkness may be taken for shade rather than material (``H x W``
    in [0, 1]): :func:`same_material` (with the shade's expected shift ``shift``) times the
    darker-than-shade guard of :func:`deshadow_log_gain`, the two guards :func:`deshadow` uses
    to keep dark materials dark.

    Example:
        >>> img = np.full((32, 32, 3), 0.8, np.float32); img[16:, 16:] *= 0.5
        >>> img[20:24, 20:24] = 0.01  # a black object inside the shadow
        >>> p = photo_shadow_probability(img, np.zeros((32, 32), bool))
        >>> g = material_guard(img, p, np.zeros((32, 32), bool))
        >>> bool(g[28, 28] > 0.8 and g[22, 22] < 0.2)
        True
    """
    img, p, sky = _check_probability(image_srgb, probability, sky)
    surface = ~sky
    guard = (same_material(img, p, surface, shift) if CHROMA_TOL > 0
             else np.ones(p.shape, np.float32))
    st = _shade_statistics(img, p * guard, sky)
    if st is None:
        return np.where(surface, guard, 0.0).astype(np.float32)
    keep = _not_darker_than_shade(st["log_c"], st["mu_lit"], st["glob"])
    return np.where(surface, guard * keep, 0.0).astype(np.float32)


def lit_surface_colour(image_srgb: np.ndarray, probability: np.ndarray, sky: np.ndarray,
                       sigma: float) -> np.ndarray:
    """The CIE Lab ``a*, b*`` of the lit surface around each pixel (``H x W x 2`` float32): a
    Gaussian-weighted mean (sigma ``sigma`` of the longer side) over the surface, weighted by
    ``(1 - p)^2`` and leaving out clipped pixels; where no lit surface is near, the photo's
    mean lit colour.

    Example:
        >>> img = np.full((16, 16, 3), [0.7, 0.5, 0.3], np.float32); img[8:] *= 0.2
        >>> p = photo_shadow_probability(img, np.zeros((16, 16), bool))
        >>> ab = lit_surface_colour(img, p, np.zeros((16, 16), bool), 0.5)
        >>> lab = linear_to_lab(srgb_to_linear(img))
        >>> bool(np.allclose(ab[12, 8], lab[2, 8, 1:], atol=1.0))
        True
    """
    img, p, sky = _check_probability(image_srgb, probability, sky)
    lin = srgb_to_linear(img)
    w = ((1.0 - p) ** 2 * _usable(lin, sky)).astype(np.float32)  # as the shade statistics' lit
    ab = linear_to_lab(lin)[..., 1:].astype(np.float32)
    if w.sum() < 1.0:
        return ab
    s = max(1.0, sigma * max(p.shape))
    n = wide_blur(w, s)
    glob = np.einsum("hw,hwc->c", w, ab) / w.sum()
    local = wide_blur(ab * w[..., None], s) / np.maximum(n, 1e-6)[..., None]
    trust = np.clip(n / 0.05, 0.0, 1.0)[..., None]
    return (trust * local + (1.0 - trust) * glob).astype(np.float32)


def _not_darker_than_shade(log_c: np.ndarray, mu_lit: np.ndarray, glob: np.ndarray
                           ) -> np.ndarray:
    """1 where a pixel is no darker than shade is here, falling to 0 beyond it.

    A pixel far darker than shade is here (black railings, navy cushions, foliage gaps) is a
    dark material or a deep cavity: lifting it by the shade's ratio would turn it grey. Its
    darkness against the lit surface around it (``mu_lit``, log colour) is compared with the
    photo's lit/shade log ratio ``glob`` plus :data:`DARKER_MARGIN`.
    """
    excess = ((mu_lit - log_c) @ LUMA_709 - float(np.maximum(glob, 0.0) @ LUMA_709)
              - DARKER_MARGIN)
    return np.exp(-0.5 * (np.maximum(excess, 0.0) / DARKER_WIDTH) ** 2).astype(np.float32)


def without_texture(probability: np.ndarray) -> np.ndarray:
    """The shadow probability with dark structures narrower than about
    ``2 * TEXTURE_RADIUS`` of the longer side removed (a grey-level opening).

    Furrows, gravel gaps and grass read as shade to the photometric stage; lifting them flattens
    the surface's texture, which de-shadowing must keep. Measured (2026-11-30, late night) with
    the radius 0 / 0.006 / 0.012 of the side: the 7 dev pairs 0.498 / 0.499 / 0.499 inside and
    +0.12 / +0.12 / +0.06 outside; on the 47 dev photos the mean Lab change outside the human
    shadow masks 1.05 / 1.00 / 0.83, the ``a*b*`` / ``L*`` gap between each lifted shadow and the
    lit ring around it 13.0 / 13.0 / 12.9 and 24.6 / 24.5 / 24.0. Those figures cannot see thin
    shadows (the pairs' are wide; the gaps are read inside eroded masks); on the field-path
    sample 0.012 left the hedge's streak shadows on the path, 0.006 lifted them and kept most of
    the ploughed field's furrows, which 0 flattened.
    """
    p = np.asarray(probability, np.float32)
    k = round(TEXTURE_RADIUS * max(p.shape))
    if k < 1:
        return p
    return cv2.morphologyEx(p, cv2.MORPH_OPEN,
                            cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * k + 1,) * 2))


def lift_probability(image_srgb: np.ndarray, probability: np.ndarray, sky: np.ndarray,
                     shift: tuple[float, float] = SHADE_SHIFT,
                     marked: np.ndarray | None = None) -> np.ndarray:
    """How much :func:`deshadow` lifts each pixel as shadow (``H x W`` float32 in [0, 1]):
    the found shadow probability without the surface's fine texture (:func:`without_texture`)
    and where its colour is the lit surface's in shade (:func:`same_material`), except where
    a shadow is marked (``marked``, as :func:`deshadow`'s), which keeps its probability.
    What the app shows as the photo's found shadows: the probability alone showed a thin
    trunk's shadow on snow at 0.4-0.5, which the lift then left dark (a user trial).
    """
    img = np.nan_to_num(np.clip(np.asarray(image_srgb, np.float32), 0.0, 1.0))
    p = without_texture(probability)
    if CHROMA_TOL > 0:
        p = p * same_material(img, p, ~np.asarray(sky, bool), shift)
    if marked is not None:
        m = np.clip(np.asarray(marked, np.float32), 0.0, 1.0)
        if m.shape != p.shape:
            raise ValueError(f"expected a marked mask of shape {p.shape}, got {m.shape}")
        p = p + m * (np.clip(np.asarray(probability, np.float32), 0.0, 1.0) - p)
    return np.clip(p, 0.0, 1.0).astype(np.float32)


def deshadow(image_srgb: np.ndarray, probability: np.ndarray, sky: np.ndarray,
             shift: tuple[float, float] = SHADE_SHIFT, marked: np.ndarray | None = None,
             above_lit: float | None = LIFT_ABOVE_LIT,
             lifted: np.ndarray | None = None) -> np.ndarray:
    """The photo with its shadows lifted (``H x W x 3`` sRGB float32, same size); the surface's
    fine texture is not lifted (:func:`without_texture`). ``shift``: the shade's expected
    chromaticity shift (:func:`same_material`). ``marked`` (``H x W`` in [0, 1], bool or
    float: :func:`shadow_edit_masks`' added cover, and the session's
    :func:`found_shade_marks`; or None): what the user marked as shadow ("Mark shadow"), or
    its own lit ring says is shade, taken at its word as far as it covers a pixel: neither
    opened as texture nor weakened as another material than the lit surface round it (grey paving
    marked beside a cyan pool was lifted to a quarter of its probability), and lifted to the
    lit surface just round it (:func:`marked_lift`). ``above_lit``: :func:`deshadow_log_gain`'s.
    ``lifted``: :func:`lift_probability` of these same inputs when the caller has it already
    (the session shows it as the found shadows), so it is not made twice.

    Example:
        >>> img = np.full((32, 32, 3), 0.8, np.float32); img[16:, 16:] *= 0.5
        >>> p = photo_shadow_probability(img, np.zeros((32, 32), bool))
        >>> out = deshadow(img, p, np.zeros((32, 32), bool))
        >>> bool(abs(out[24, 24, 0] - 0.8) < 0.1 and abs(out[4, 4, 0] - 0.8) < 0.01)
        True
    """
    img = np.nan_to_num(np.clip(np.asarray(image_srgb, np.float32), 0.0, 1.0))
    if lifted is None:
        p = lift_probability(img, probability, sky, shift, marked)
    else:
        p = np.asarray(lifted, np.float32)
        if p.shape != img.shape[:2]:
            raise ValueError(f"expected a lift probability of shape {img.shape[:2]}, got "
                             f"{p.shape}")
    gain = deshadow_log_gain(img, p, sky, above_lit, marked)
    lin = srgb_to_linear(np.clip(np.asarray(image_srgb, np.float32), 0.0, 1.0))
    return linear_to_srgb((lin + _LOG_EPS) * np.exp(gain) - _LOG_EPS)


#: :class:`ShadowEdit` "a shadow": the flood fill takes pixels whose (lightly blurred) log
#: luminance is within this of the clicked point's (a cast shadow on one surface is even to
#: within about a third of a stop; the lit surface around it is 1-3 stops brighter).
ADD_RANGE = 0.35
#: :class:`ShadowEdit` "a shadow": a fill that would cover more than this share of the photo's
#: surface has leaked into the lit surface (the lit level is within :data:`ADD_RANGE` of the
#: point's) and is refused. Measured with a simulated user on the 47 dev photos (``S_o`` BER,
#: fast preset, a "Mark shadow" click at the deepest point of each of the two largest missed
#: shadows): 0.0952 without clicks; clicks with no limit 0.1258 (8 photos worse, three of them
#: to 0.43-0.47: the whole ground marked); at most 0.6 of the surface 0.1030; at most 0.4
#: 0.0847 (2 worse, 10 better). A local Otsu threshold round the point instead of the fixed
#: range, with the same limit: 0.0871. (Those with each region found again at the detail
#: size; decided at the working size, with this limit and :data:`ADD_DARKER`'s test: 0.0717,
#: 13 photos better, none worse; with "Not a shadow" clicks too, 1.87 clicks a photo: 0.0570.)
ADD_MAX_SHARE = 0.4
#: :class:`ShadowEdit` "a shadow": the filled region must be darker than a ring round it
#: (:data:`ADD_RING` of the longer side wide) by this much (natural log; a cast shadow is 1-3
#: stops darker than the lit surface), else the click was on lit ground and is refused.
ADD_DARKER = 0.2
ADD_RING = 0.02
#: :class:`ShadowEdit` "a shadow" on a crushed point (within :data:`ADD_RANGE` of the floor):
#: the fill reads luminance plus this share of the photo's lit level (the 75th percentile of
#: its surface's luminance), which evens out what lies below it. Where the camera crushed a
#: shadow (a toddler's shadow on sunlit pavement at 1/400 of it) JPEG noise spreads its log
#: luminance over a stop, and a click took only a few pixels round the point; with the floor
#: at 1/100 the core of that shadow spreads 0.24 (5-95 %) and the fill takes it whole, while
#: the lit ground stays 4.3 above it (a dev photo). Applied to every click, it let one dev
#: photo's click through that was refused before (S_o BER 0.18 -> 0.30; sixteenth session).
ADD_FLOOR = 0.01
#: :class:`ShadowEdit` "not a shadow": how far (fraction of the longer side) from the click a
#: found shadow may be and still be the one meant (a click on a thin pole may miss it).
PICK_RADIUS = 0.02
#: :class:`ShadowEdit` "not a shadow": a click takes the part of the found region round it
#: whose (lightly blurred) log luminance lies within this of the median within
#: :data:`DROP_PICK` (fraction of the longer side) of the point. On the ski slope the
#: found region joins a black lift pylon (log luminance about -4.7) to the pines (-3.4 to
#: -4.0) across the frame: 0.35 leaves most of the pylon's crossarm, 0.5 takes the pylon
#: and none of the pines (a click on the pines: the pines of their brightness, not the
#: darker trunks and pylon), 0.7 runs into the pines.
DROP_RANGE = 0.5
DROP_PICK = 0.01
#: The soft edge of an edited region (Gaussian sigma, fraction of the longer side), and the
#: radius of the holes (texture) closed in an added region.
EDIT_SOFT = 1.0 / 768
EDIT_CLOSE = 1.0 / 192


#: :class:`ShadowEdit`: the largest brush radius (fraction of the photo's longer side); the
#: app's brush size box tops out at it too (15 %).
MAX_BRUSH_RADIUS = 0.15
#: A "Mark shadow" stroke (:func:`stroke_shadow`): the two Otsu classes of the log luminance
#: under it are a shadow and the lit surface beside it when their medians lie more than this
#: apart (natural log) and the dark class holds at least :data:`STROKE_MIN_SHARE` of the
#: stroke (less: dirt, a twig). A cast shadow is 1-3 stops (0.7-2.1) darker than the lit
#: surface; one surface's own texture split in two gives 0.1-0.4 (on the 47 dev photos the
#: median split under strokes inside a shadow is 0.18, its upper quartile 0.36; across a
#: shadow's edge the lower decile is 0.9). More than :data:`ADD_DARKER` (0.2, a region's
#: median against a ring round it), as a split of a surface's texture reaches that.
STROKE_SPLIT = 0.5
STROKE_MIN_SHARE = 0.05
#: A "Mark shadow" stroke's line (:func:`stroke_shadow`): its dabs' discs at this fraction of
#: the brush radius; a stroke is drawn along a class of its pixels when that holds this share
#: of its line.
STROKE_LINE = 0.25
STROKE_ALONG = 0.75
#: A "Mark shadow" stroke is a soft brush: what it adds fades out toward the edge of its
#: footprint (smoothstep of the distance inward from that edge, over this fraction of the
#: brush radius), so a stroke over part of a wider shadow that the app missed ends in a soft
#: transition, not the hard edge of its discs (a user trial on the ski slope: a stroke along
#: the big tree shadow on the snow lifted a band with sharp sides). The probability it sets
#: reaches 1 halfway through the fade (:func:`apply_edit_masks` doubles the soft mask), so
#: the lift fades over the outer half of the radius. Where the shadow itself ends under the
#: stroke (the dark class of :func:`stroke_shadow`), the edge stays the shadow's own.
STROKE_FEATHER = 1.0
#: A "Mark shadow" stroke changes a pixel of the shadow under it where it covers it by more
#: than this above what the user's earlier corrections cover there, and marks it by more than
#: this above what the found shadows lift there (what "Shadows found" shows): a stroke over a
#: shadow shown already marks what is there.
STROKE_NEW = 0.1
#: A "Mark shadow" stroke changes something (is used) when the pixels it changes make at least
#: this share of one of its dabs' discs: fewer (a trunk's edge already found, 160 pixels of a
#: stroke's 1656 on the ski slope: a user trial) is said to change nothing, and the app takes
#: it back, rather than counting a correction the user cannot see.
STROKE_MIN_NEW = 0.05
#: A "not a shadow" dab changes something (is used) when its disc holds a found shadow
#: probability above this (or something the user added): then its whole disc is dropped.
#: Below it the overlay's tint is under 6 % (alpha ``p`` times the default opacity 0.6) and
#: the de-shadow lifts little: on the three samples, where ``0.005 < p <= 0.1`` (9-14 % of the
#: surface) the export changes by 2 levels on average (99th percentile 10) when such ``p`` is
#: set to 0 (at 0.2: 3.4-4.3 and 19-21). A dab on ground the overlay shows as lit is said to
#: change nothing (the app takes the stroke back) rather than leaving it out of the lift's
#: measure of the lit surface unseen.
NOT_SHADOW_LEVEL = 0.1


@dataclass(frozen=True)
class ShadowEdit:
    """A user's correction of the found shadows: a click on the photo, or one dab of a brush
    stroke (``radius > 0``; a stroke is the sequence of its dabs).

    Attributes:
        x, y: where, as fractions of the upright photo's width and height (0-1), so one edit
            holds at every size the shadows are found at.
        shadow: True: "this is a shadow" (a click: the region of even brightness round the
            point is added; a stroke of dabs: the shadow under it, :func:`stroke_shadow`);
            False: "not a shadow" (a click: the found shadow there is dropped, a dark material,
            foliage, a black car; a dab: its whole disc, when that holds a found shadow).
        radius: 0, a click; else a brush dab's radius, as a fraction of the photo's longer
            side (at most :data:`MAX_BRUSH_RADIUS`).
        start: a dab that begins a stroke (the app marks the first dab of each;
            :func:`shadow_edit_strokes`); never a click.
    """

    x: float
    y: float
    shadow: bool
    radius: float = 0.0
    start: bool = False

    def __post_init__(self) -> None:
        if not (math.isfinite(self.x) and math.isfinite(self.y)
                and 0.0 <= self.x <= 1.0 and 0.0 <= self.y <= 1.0):
            raise ValueError(f"expected a point inside the photo (x, y in 0-1), got "
                             f"({self.x}, {self.y})")
        if not (math.isfinite(self.radius) and 0.0 <= self.radius <= MAX_BRUSH_RADIUS):
            raise ValueError(f"expected a brush radius 0-{MAX_BRUSH_RADIUS} of the photo's "
                             f"longer side (0: a click), got {self.radius}")
        if not isinstance(self.start, bool) or (self.start and not self.radius):
            raise ValueError(f"expected start true or false, and false for a click (radius "
                             f"0), got {self.start!r}")

    def __repr__(self) -> str:  # a click reads as before brushes existed
        brush = f", radius={self.radius!r}" if self.radius else ""
        brush += ", start=True" if self.start else ""
        return f"ShadowEdit(x={self.x!r}, y={self.y!r}, shadow={self.shadow!r}{brush})"

    def pixel(self, shape: tuple[int, int]) -> tuple[int, int]:
        """``(row, column)`` of the point in an ``H x W`` image."""
        h, w = shape
        return min(h - 1, int(self.y * h)), min(w - 1, int(self.x * w))


#: The most edits a project or a command line may hold (a sane bound on a file's content: a
#: brush stroke is one edit per dab, a dab every half radius, so a few hundred a stroke), and
#: the most of them that may be clicks: a click costs far more than a dab (a flood fill or a
#: connected-component pass over the photo; 20000 clicks took 30-47 s, made again at every
#: later edit), and a user makes tens, not thousands.
MAX_SHADOW_EDITS = 20000
MAX_SHADOW_CLICKS = 500


def shadow_edit_limit(edits: Sequence[ShadowEdit]) -> str:
    """The limit ``edits`` pass, in words (for a message), or ``""`` when they keep to both:
    at most :data:`MAX_SHADOW_CLICKS` clicks and :data:`MAX_SHADOW_EDITS` edits in all.

    Example:
        >>> shadow_edit_limit([ShadowEdit(0.5, 0.5, True)] * 3)
        ''
        >>> shadow_edit_limit([ShadowEdit(0.5, 0.5, True)] * (MAX_SHADOW_CLICKS + 1))
        'at most 500 clicks (brush dabs aside)'
    """
    if len(edits) > MAX_SHADOW_EDITS:
        return f"at most {MAX_SHADOW_EDITS} clicks and brush dabs in all"
    if sum(1 for e in edits if not e.radius) > MAX_SHADOW_CLICKS:
        return f"at most {MAX_SHADOW_CLICKS} clicks (brush dabs aside)"
    return ""


def shadow_edits_to_json(edits: Sequence[ShadowEdit]) -> list[dict[str, Any]]:
    """Edits as a project file stores them: ``[{"x": .., "y": .., "shadow": ..}, ...]``, with
    ``"r"`` (the radius) for a brush dab only and ``"start": true`` for the first dab of a
    stroke only, so files without brushes read as before.

    Example:
        >>> shadow_edits_to_json([ShadowEdit(0.25, 0.5, False, radius=0.02, start=True),
        ...                       ShadowEdit(0.26, 0.5, False, radius=0.02)])[0]
        {'x': 0.25, 'y': 0.5, 'shadow': False, 'r': 0.02, 'start': True}
    """
    out = []
    for e in edits:
        item: dict[str, Any] = {"x": round(e.x, 5), "y": round(e.y, 5), "shadow": bool(e.shadow)}
        if e.radius > 0:  # five significant digits: never rounded to 0 (a click)
            item["r"] = float(f"{e.radius:.5g}")
        if e.start:
            item["start"] = True
        out.append(item)
    return out


def shadow_edits_from_json(value: Any) -> tuple[ShadowEdit, ...]:
    """Edits from a project file's ``shadow_edits`` (None or missing: none).

    Raises:
        ValueError: not a list of ``{"x", "y", "shadow"}`` (and an optional ``"r"``, a brush
            dab's radius, and ``"start"``, true or false, true only for a dab) with the point
            inside the photo and the radius 0 to :data:`MAX_BRUSH_RADIUS`, or more of them
            than :func:`shadow_edit_limit` allows.

    Example:
        >>> shadow_edits_from_json([{"x": 0.25, "y": 0.5, "shadow": False}])
        (ShadowEdit(x=0.25, y=0.5, shadow=False),)
        >>> shadow_edits_from_json([{"x": 0.25, "y": 0.5, "shadow": True, "r": 0.01}])
        (ShadowEdit(x=0.25, y=0.5, shadow=True, radius=0.01),)
    """
    if value is None:
        return ()
    if not isinstance(value, list):
        raise ValueError(f"expected a list of shadow edits, got {type(value).__name__}")
    if len(value) > MAX_SHADOW_EDITS:  # (before reading them all)
        raise ValueError(f"expected at most {MAX_SHADOW_EDITS} shadow edits (clicks and brush "
                         f"dabs in all), got {len(value)}")
    out = []
    for item in value:
        try:
            x, y, shadow = item["x"], item["y"], item["shadow"]
        except (KeyError, TypeError):
            raise ValueError(f"expected a shadow edit {{x, y, shadow}}, got {item!r}") from None
        r, start = item.get("r", 0.0), item.get("start", False)
        if (not isinstance(shadow, bool) or not isinstance(start, bool) or any(
                isinstance(v, bool) or not isinstance(v, (int, float)) for v in (x, y, r))):
            raise ValueError(f"expected numbers x, y (and r) and true/false shadow (and "
                             f"start), got {item!r}"[:200])
        try:
            x, y, r = float(x), float(y), float(r)
        except OverflowError:  # an integer too large for a float
            raise ValueError(f"expected a point inside the photo (x, y in 0-1) and a brush "
                             f"radius 0-{MAX_BRUSH_RADIUS}, got a number too large for a "
                             f"float in {item!r}"[:200]) from None
        out.append(ShadowEdit(x, y, shadow, r, start))
    if limit := shadow_edit_limit(out):
        clicks = sum(1 for e in out if not e.radius)
        raise ValueError(f"expected {limit}, got {clicks} clicks and {len(out) - clicks} "
                         f"brush dabs")
    return tuple(out)


def shadow_edit_strokes(edits: Sequence[ShadowEdit], shape: tuple[int, int]
                        ) -> list[tuple[int, int]]:
    """The user's corrections as the user made them: ``(start, stop)`` of each click (one
    edit) and of each brush stroke (its dabs) in ``edits``, for an ``H x W`` photo (``shape``,
    any size of it: only its aspect counts).

    A dab marked :attr:`ShadowEdit.start` begins a stroke (the app marks the first dab of
    each), which holds the unmarked dabs of its kind and radius after it, wherever they lie (a
    stroke may leave the photo and come back). Unmarked (the command line's dabs, files from
    before the mark) a stroke is a run of dabs of one kind and radius, each within a radius of
    the one before (the app lays them at most half a radius apart), so a stroke begun where
    the one before of the same kind and size ended counts with it.

    Example:
        >>> dabs = [ShadowEdit(0.1 + 0.01 * i, 0.5, False, radius=0.02) for i in range(5)]
        >>> shadow_edit_strokes([ShadowEdit(0.9, 0.9, True), *dabs, *dabs], (100, 100))
        [(0, 1), (1, 6), (6, 11)]
        >>> back = dabs[::-1]  # a stroke back from where the first ended: one with it
        >>> shadow_edit_strokes([*dabs, *back], (100, 100))
        [(0, 10)]
        >>> back[0] = ShadowEdit(back[0].x, 0.5, False, radius=0.02, start=True)  # unless marked
        >>> shadow_edit_strokes([*dabs, *back], (100, 100))
        [(0, 5), (5, 10)]
    """
    h, w = shape
    side = max(h, w, 1)
    out: list[tuple[int, int]] = []
    for i, e in enumerate(edits):
        if out and e.radius > 0 and not e.start:
            p = edits[i - 1]
            if p.radius == e.radius and p.shadow == e.shadow and (
                    edits[out[-1][0]].start
                    or math.hypot((e.x - p.x) * w, (e.y - p.y) * h) <= e.radius * side * 1.01):
                out[-1] = (out[-1][0], i + 1)
                continue
        out.append((i, i + 1))
    return out


def _log_luminance(img: np.ndarray) -> np.ndarray:
    """Natural log of the linear luminance of a clean sRGB image (``H x W`` float32), as the
    photometric stage splits it."""
    return np.log(luminance(srgb_to_linear(img)) + _LOG_EPS).astype(np.float32)


def edit_luminance(image_srgb: np.ndarray) -> np.ndarray:
    """The lightly blurred log luminance a "Mark shadow" fill reads (``H x W`` float32)."""
    log_y = _log_luminance(np.nan_to_num(np.clip(np.asarray(image_srgb, np.float32), 0, 1)))
    return cv2.GaussianBlur(log_y, (0, 0), max(0.5, max(log_y.shape) / 384.0))


def shadow_edit_region(probability: np.ndarray, image_srgb: np.ndarray, sky: np.ndarray,
                       edit: ShadowEdit, log_y: np.ndarray | None = None) -> np.ndarray:
    """The pixels one :class:`ShadowEdit` changes (``H x W`` bool; may be empty).

    "Not a shadow": the found shadow (``probability > 0.5``, 8-connected) under the point, or
    the nearest one within :data:`PICK_RADIUS`, as far as it is of the brightness there: a
    flood fill inside it from that point through pixels within :data:`DROP_RANGE` of the
    log luminance round it, its texture holes closed and grown by its soft rim
    (:data:`EDIT_CLOSE`, inside the found shadow). One found region often joins several dark
    objects (a lift pylon standing in front of the pines, which run on across the frame: a
    click on the pylon dropped them all, a user trial); a click takes the one clicked, or
    those of its brightness joined to it. "A shadow": a flood fill from the point over
    the surface (never the sky) through pixels within :data:`ADD_RANGE` of the point's log
    luminance, its small holes (the surface's texture) closed; empty on the sky, when it
    would cover more than :data:`ADD_MAX_SHARE` of the surface (a leak into the lit surface),
    and when it is not darker than the surface round it (:data:`ADD_DARKER`: lit ground).
    ``log_y``: :func:`edit_luminance` of the image, when the caller has it (several edits).

    Raises:
        ValueError: a brush dab (``edit.radius > 0``): what a dab changes depends on the dabs
            of its stroke and those before it (:func:`shadow_edit_masks`).
    """
    if edit.radius > 0:
        raise ValueError(f"expected a click (radius 0), got a brush dab of radius "
                         f"{edit.radius}: shadow_edit_masks paints the dabs")
    p = np.asarray(probability, np.float32)
    sky = np.asarray(sky, bool)
    h, w = p.shape
    side = max(h, w)
    row, col = edit.pixel((h, w))
    if not edit.shadow:
        found = ((p > 0.5) & ~sky).astype(np.uint8)
        if not found.any():
            return np.zeros((h, w), bool)
        n, labels = cv2.connectedComponents(found, connectivity=8)
        label = int(labels[row, col])
        if label == 0:  # the nearest found shadow within reach
            dist, nearest = cv2.distanceTransformWithLabels(
                1 - found, cv2.DIST_L2, 5, labelType=cv2.DIST_LABEL_PIXEL)
            if dist[row, col] > max(1.0, PICK_RADIUS * side):
                return np.zeros((h, w), bool)
            ys, xs = np.nonzero(found)
            index = nearest[ys, xs]  # label of each found pixel in the distance transform
            pick = np.nonzero(index == nearest[row, col])[0]
            row, col = int(ys[pick[0]]), int(xs[pick[0]])
            label = int(labels[row, col])
        if log_y is None:
            log_y = edit_luminance(image_srgb)
        return _found_object(labels == label, np.asarray(log_y, np.float32), row, col)
    if sky[row, col]:
        return np.zeros((h, w), bool)
    if log_y is None:
        log_y = edit_luminance(image_srgb)
    log_y = np.ascontiguousarray(log_y, np.float32)  # read only (FLOODFILL_MASK_ONLY)
    fill_y = log_y
    crushed = False
    if (~sky).any():  # a crushed point: camera noise under the floor is one level
        floor = float(np.percentile(log_y[~sky], 75)) + math.log(ADD_FLOOR)
        crushed = bool(log_y[row, col] < floor + ADD_RANGE)
        if crushed:
            fill_y = np.ascontiguousarray(np.logaddexp(log_y, np.float32(floor)), np.float32)
    mask = np.zeros((h + 2, w + 2), np.uint8)
    mask[1:-1, 1:-1] = sky  # the fill never crosses the sky
    flags = 8 | cv2.FLOODFILL_FIXED_RANGE | cv2.FLOODFILL_MASK_ONLY | (2 << 8)
    cv2.floodFill(fill_y, mask, (col, row), 0, ADD_RANGE, ADD_RANGE, flags)
    region = _closed(mask[1:-1, 1:-1] == 2, max(1, round(EDIT_CLOSE * side))) & ~sky
    if not _darker_than_round(region, log_y, sky, float(np.median(log_y[region]))):
        return np.zeros((h, w), bool)
    return _with_penumbra(region, log_y, sky) if crushed else region


#: :class:`ShadowEdit` "a shadow" on a crushed point: how far (fraction of the longer side)
#: the region grows into its penumbra: the pixels round it still darker than the lit surface
#: beyond by :data:`ADD_DARKER`. Without it the soft edge of a crushed shadow, outside the
#: fill's range, stayed as a dark outline round the filled shadow (a dev photo). On every
#: click it lowered the simulated user's S_o BER (0.0815 -> 0.0802) but lifted the grown edge
#: of ordinary shadows past the ground (a pale band and a white line: a user trial), so it is
#: for crushed points only.
ADD_PENUMBRA = 1.0 / 192


def _with_penumbra(region: np.ndarray, log_y: np.ndarray, sky: np.ndarray,
                   level: float | None = None, side: int | None = None) -> np.ndarray:
    """``region`` grown by :data:`ADD_PENUMBRA` into pixels darker than the surface round it
    by :data:`ADD_DARKER`: the log luminance ``level`` when the caller has measured it (a
    found shadow's own ring, :func:`found_shade_marks`), else the median over a ring
    :data:`ADD_RING` wide beyond that reach. ``side``: the photo's longer side when the
    arrays are a window of it."""
    side = max(region.shape) if side is None else side
    k = max(1, round(ADD_PENUMBRA * side))
    reach = _grown(region, k)
    if level is None:
        ring = _grown(region, k + max(2, round(ADD_RING * side))) & ~reach & ~sky
        if not ring.any():
            return region
        level = float(np.median(log_y[ring]))
    return region | (reach & (log_y < level - ADD_DARKER) & ~sky)


def _found_object(found: np.ndarray, log_y: np.ndarray, row: int, col: int) -> np.ndarray:
    """What a "not a shadow" click at ``(row, col)`` takes of the found region ``found``
    (``H x W`` bool, 8-connected, holding the point; ``log_y``: :func:`edit_luminance`): the
    part of the brightness there (:func:`shadow_edit_region`)."""
    h, w = found.shape
    side = max(h, w)
    near = np.zeros((h, w), np.uint8)
    cv2.circle(near, (col, row), max(1, round(DROP_PICK * side)), 1, -1)
    level = float(np.median(log_y[found & (near > 0)]))
    seeded = np.array(log_y, np.float32)
    seeded[row, col] = level  # (the fill's range is round the seed's own value)
    mask = np.zeros((h + 2, w + 2), np.uint8)
    mask[1:-1, 1:-1] = ~found  # the fill never leaves the found region
    flags = 8 | cv2.FLOODFILL_FIXED_RANGE | cv2.FLOODFILL_MASK_ONLY | (2 << 8)
    cv2.floodFill(seeded, mask, (col, row), 0, DROP_RANGE, DROP_RANGE, flags)
    close = max(1, round(EDIT_CLOSE * side))
    region = _closed(mask[1:-1, 1:-1] == 2, close)
    rim = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * close + 1,) * 2)
    return (cv2.dilate(region.astype(np.uint8), rim) > 0) & found


def _darker_than_round(region: np.ndarray, log_y: np.ndarray, sky: np.ndarray, level: float
                       ) -> bool:
    """Whether an even region (``H x W`` bool, off the sky) may be a shadow at log luminance
    ``level``: it covers at most :data:`ADD_MAX_SHARE` of the surface (more: a leak into the
    lit surface) and ``level`` is darker than a ring round it (:data:`ADD_RING` wide) by
    :data:`ADD_DARKER`. A shadow is darker than the surface round it: lit ground beside a
    shadow, taken for one, the lift would brighten to glare (a user trial)."""
    if region.sum() > ADD_MAX_SHARE * max(1, int((~sky).sum())):
        return False
    ring = _grown(region, max(2, round(ADD_RING * max(region.shape)))) & ~region & ~sky
    return not ring.any() or level <= float(np.median(log_y[ring])) - ADD_DARKER


def _grown(mask: np.ndarray, radius: int) -> np.ndarray:
    """``mask`` (bool) dilated by a disc of ``radius`` pixels."""
    return cv2.dilate(mask.astype(np.uint8), cv2.getStructuringElement(
        cv2.MORPH_ELLIPSE, (2 * radius + 1,) * 2)) > 0


def _closed(mask: np.ndarray, radius: int) -> np.ndarray:
    """``mask`` (bool) with its holes and gaps narrower than about ``2 * radius`` closed."""
    return cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_CLOSE, cv2.getStructuringElement(
        cv2.MORPH_ELLIPSE, (2 * radius + 1,) * 2)) > 0


def stroke_shadow(log_y: np.ndarray, sky: np.ndarray, footprint: np.ndarray,
                  known: np.ndarray | None = None, line: np.ndarray | None = None
                  ) -> np.ndarray:
    """What a "Mark shadow" stroke adds: the shadow under it, not the whole area it covers
    (``H x W`` bool; may be empty).

    ``footprint``: the stroke's discs (``H x W`` bool); ``log_y``: :func:`edit_luminance`;
    ``known`` (``H x W`` bool, or None): what is shadow already (found, or added by the user);
    ``line`` (``H x W`` bool, or None: the footprint): the stroke's line, where the user drew
    (its dabs' discs at :data:`STROKE_LINE` of their radius).
    The log luminance under the stroke (off the sky) is split in two with Otsu's threshold.
    When the classes differ clearly (medians more than :data:`STROKE_SPLIT` apart, the dark
    one at least :data:`STROKE_MIN_SHARE` of the stroke) the stroke crossed a shadow's edge,
    and only the dark class is added (its texture holes closed, :data:`EDIT_CLOSE`): the lit
    ground it crossed is neither lifted to glare nor cut by a hard-edged disc. When at least
    half that dark class is known, the rest of the stroke (at least :data:`STROKE_MIN_SHARE`
    of it) splits clearly too and the rest's dark class holds :data:`STROKE_ALONG` of the
    stroke's line off what is known, the stroke holds three levels, and the user drew along
    the middle one: a dark object found already (a trunk's black base where its shadow
    begins), the shadow and the lit ground. The rest's dark class is added then, and not what
    is known and darker than it by more than :data:`STROKE_SPLIT` (marked, the lift would take
    the trunk at the user's word): split as a whole, a stroke down a trunk's shadow on snow
    from the trunk's base added the trunk and not the shadow (160 pixels of the 1656 under it:
    a user trial on the ski slope). Measured on the 47 dev photos (balanced working size, each
    at its best sun): strokes along the three largest missed shadows of each (30 strokes, a
    brush 1.5 times the shadow's half width, 0.01-0.04) add 0.567 of the missed shadow under
    them without the rule, 0.664 / 0.655 / 0.641 with :data:`STROKE_ALONG` 0.5 / 0.75 / 0.9
    (what they add is shadow at 0.95 throughout); random strokes across a shadow's edge (538,
    the shadow mostly found) add the darker part of the lit ground's texture: of what they add
    that was not found, 0.54 is shadow without the rule, 0.26 with it and no line's test,
    0.33 / 0.38 / 0.42 with it. Otherwise the stroke lies on one surface, and is added whole
    only where a click there would be accepted (:func:`shadow_edit_region`): the even region
    round it (within :data:`ADD_RANGE` of its median) covers at most :data:`ADD_MAX_SHARE` of
    the surface and the stroke is darker than a ring round that region by :data:`ADD_DARKER`
    (inside a wide shadow the ring round the stroke itself is shadow too); on lit ground,
    nothing.

    Measured on the 47 dev photos (human shadow masks; 2491 simulated straight strokes at the
    balanced working size, radius 0.01-0.04, a dab every half radius), :data:`STROKE_SPLIT`
    0.2 / 0.35 / 0.5 / 0.7 / 1.0: across a shadow's edge (10-90 % shadow, 561 strokes) what is
    added is shadow at a precision of 0.81 / 0.81 / 0.81 / 0.80 / 0.78 with 0.93 / 0.93 /
    0.93 / 0.90 / 0.88 of the shadow under them (the whole discs, as before: 0.37 and 1);
    inside a shadow (162) 82 / 80 / 78 / 78 / 78 % are accepted; on lit ground (1768) 67 /
    55 / 49 / 42 / 35 % add something (the whole discs: all): 42 % of those cross two
    materials more than 0.5 apart (a dark object: its darker one is added), and of those on
    one even surface (classes less than 0.2 apart, 603) 9 % are accepted, as a click there
    would be. Otsu taken again in the bright class (a trunk, its shadow and lit snow: three
    levels) added more lit ground (precision 0.64, 0.97 found), and so did adding the bright
    class too where a click on it would be accepted (0.73, 0.94).

    Example:
        >>> log_y = np.zeros((40, 40), np.float32); log_y[:, 20:] = -1.5  # shadow on the right
        >>> sky, across = np.zeros((40, 40), bool), np.zeros((40, 40), bool)
        >>> across[15:25, 10:30] = True  # a stroke across the shadow's edge
        >>> added = stroke_shadow(log_y, sky, across)
        >>> bool(added[:, 20:][across[:, 20:]].all()), bool(added[:, :20].any())
        (True, False)
        >>> lit = np.zeros((40, 40), bool); lit[15:25, 2:12] = True  # on the lit side only
        >>> bool(stroke_shadow(log_y, sky, lit).any())
        False
    """
    log_y = np.asarray(log_y, np.float32)
    sky = np.asarray(sky, bool)
    under = np.asarray(footprint, bool) & ~sky
    none = np.zeros(log_y.shape, bool)
    if not under.any():
        return none
    values = log_y[under]
    side = max(log_y.shape)
    close = max(1, round(EDIT_CLOSE * side))
    t = _otsu_threshold(values)
    dark = values < t
    if _split_clearly(values, dark):
        region, drop = under & (log_y < t), none
        if known is not None:  # the dark class found already: the split of the rest
            known = np.asarray(known, bool)
            old = known[under]
            rest = values[~old]
            if old[dark].mean() >= 0.5 and rest.size >= STROKE_MIN_SHARE * values.size:
                t_rest = _otsu_threshold(rest)
                drawn = (under if line is None else np.asarray(line, bool) & under) & ~known
                along = int(np.count_nonzero(drawn & (log_y < t_rest)))
                if (_split_clearly(rest, rest < t_rest)
                        and along >= STROKE_ALONG * drawn.sum() > 0):
                    floor = float(np.median(rest[rest < t_rest])) - STROKE_SPLIT
                    region, drop = under & (log_y < t_rest), known & (log_y < floor)
        return _closed(region, close) & under & ~drop
    level = float(np.median(values))
    even = ((np.abs(log_y - level) <= ADD_RANGE) | under) & ~sky
    n, labels = cv2.connectedComponents(even.astype(np.uint8), connectivity=8)
    touched = np.zeros(n, bool)
    touched[labels[under]] = True
    region = _closed(touched[labels], close) & ~sky  # the even region the stroke lies in
    return under if _darker_than_round(region, log_y, sky, level) else none


def _split_clearly(values: np.ndarray, dark: np.ndarray) -> bool:
    """Whether Otsu's two classes of the log luminance under a stroke (``dark``: the darker
    one's pixels) are a shadow and the lit surface beside it (:func:`stroke_shadow`)."""
    return bool(STROKE_MIN_SHARE * values.size <= dark.sum() < values.size
                and np.median(values[~dark]) - np.median(values[dark]) > STROKE_SPLIT)


#: Sub-pixel bits of a brush dab's centre and radius (``cv2.circle``'s ``shift``).
_DAB_SHIFT = 4


def _draw_dab(mask: np.ndarray, edit: ShadowEdit, origin: tuple[int, int],
              shape: tuple[int, int]) -> None:
    """Draw one brush dab's disc (255) into ``mask``, a window of an ``H x W`` (``shape``)
    image whose top-left pixel is ``origin`` (row, column) of the image; the disc's pixels
    are the same wherever the window lies."""
    h, w = shape
    one = 1 << _DAB_SHIFT
    cx = round((edit.x * w - 0.5 - origin[1]) * one)  # pixel centres at integer coordinates
    cy = round((edit.y * h - 0.5 - origin[0]) * one)
    radius = max(one // 2, round(edit.radius * max(h, w) * one))
    cv2.circle(mask, (cx, cy), radius, 255, -1, cv2.LINE_8, _DAB_SHIFT)


def _dab_box(edit: ShadowEdit, shape: tuple[int, int]) -> tuple[int, int, int, int]:
    """``(top, left, bottom, right)`` of the pixels a dab may touch (within the image)."""
    h, w = shape
    r = edit.radius * max(h, w) + 2
    cx, cy = edit.x * w - 0.5, edit.y * h - 0.5
    return (max(0, math.floor(cy - r)), max(0, math.floor(cx - r)),
            min(h, math.ceil(cy + r) + 1), min(w, math.ceil(cx + r) + 1))


def _dabs_window(dabs: Sequence[ShadowEdit], shape: tuple[int, int]
                 ) -> tuple[tuple[slice, slice], list[tuple[int, ...]]]:
    """One run of brush dabs: the window of the ``H x W`` image they cover, and each dab's box
    (:func:`_dab_box`) in the window."""
    boxes = [_dab_box(e, shape) for e in dabs]
    top, left = min(b[0] for b in boxes), min(b[1] for b in boxes)
    bottom, right = max(b[2] for b in boxes), max(b[3] for b in boxes)
    window = (slice(top, bottom), slice(left, right))
    return window, [(t - top, le - left, b - top, r - left) for t, le, b, r in boxes]


def _paint_dabs(dabs: Sequence[ShadowEdit], shape: tuple[int, int],
                window: tuple[slice, slice]) -> np.ndarray:
    """The discs of a run of brush dabs (``uint8``, drawn at once) in its window of the
    ``H x W`` image (:func:`_dabs_window`)."""
    top, left = window[0].start, window[1].start
    paint = np.zeros((window[0].stop - top, window[1].stop - left), np.uint8)
    for e in dabs:
        _draw_dab(paint, e, (top, left), shape)
    return paint


def _feathered(paint: np.ndarray, radius: float) -> np.ndarray:
    """How much a stroke's footprint (``paint``, nonzero inside, a window of the photo that
    holds the whole footprint with a margin, except where the photo's edge cuts it) covers
    each pixel (float32 in [0, 1]): :data:`STROKE_FEATHER` of the brush radius (``radius``,
    pixels) of soft edge inside the footprint's edge; the photo's edge is no edge of the
    stroke."""
    inside = (paint > 0).astype(np.uint8)
    if not inside.any():
        return np.zeros(paint.shape, np.float32)
    if inside.all():  # the footprint fills the window: no edge inside the photo
        return np.ones(paint.shape, np.float32)
    dist = cv2.distanceTransform(inside, cv2.DIST_L2, 5)
    t = np.clip((dist - 0.5) / max(STROKE_FEATHER * radius, 1e-6), 0.0, 1.0)
    return np.where(inside > 0, t * t * (3.0 - 2.0 * t), 0.0).astype(np.float32)


def _rub_out(dabs: Sequence[ShadowEdit], shape: tuple[int, int], boxes: list[tuple[int, ...]],
             window: tuple[slice, slice], changes: np.ndarray) -> tuple[list[bool], np.ndarray]:
    """A run of "not a shadow" dabs, one after another: per dab whether its disc holds any of
    ``changes`` (what such a dab would change: a bool array of the run's window, as it was
    before the run), and the discs of those that do (bool, the window). A dab that does takes
    its whole disc out of ``changes`` for the dabs after it; one that does not changes
    nothing."""
    flags = []
    changes = changes.astype(np.uint8)  # (a copy: 0 or 1)
    rubbed = np.zeros(changes.shape, np.uint8)
    for e, (t, le, b, r) in zip(dabs, boxes, strict=True):
        local = changes[t:b, le:r]
        used = local.size > 0 and cv2.countNonZero(local) > 0
        if used:  # the disc itself, only where its box holds something it could change
            disc = np.zeros(local.shape, np.uint8)
            _draw_dab(disc, e, (window[0].start + t, window[1].start + le), shape)
            used = cv2.countNonZero(cv2.bitwise_and(local, disc)) > 0
            if used:
                local[disc > 0] = 0
                rubbed[t:b, le:r] |= disc
        flags.append(used)
    return flags, rubbed > 0


def shadow_edit_masks(probability: np.ndarray, image_srgb: np.ndarray, sky: np.ndarray,
                      edits: Sequence[ShadowEdit], used: list[bool] | None = None
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Where a user's corrections add shadow and where they drop it (``H x W`` each: how much
    is added, float32 in [0, 1], and what is dropped, bool).

    In order: an "a shadow" click adds its region (:func:`shadow_edit_region`); a "not a
    shadow" click takes back a region the user added when the click lands in it (a clicked
    region, or the painted area there, 8-connected), else drops the found shadow there
    (found before any edit: a shadow the user added next to a dark pole is not dropped with
    the pole). Brush strokes paint into the masks, in order (a stroke: from a dab marked
    :attr:`ShadowEdit.start`, or the dabs of one kind and size each within a radius of the
    one before, :func:`shadow_edit_strokes`): "a shadow" adds the shadow under the stroke
    (:func:`stroke_shadow`, decided for the stroke as a whole: only the darker pixels of one
    across a shadow's edge; nothing on lit ground), fading out toward the edge of the
    stroke's footprint (:data:`STROKE_FEATHER`; clicks' regions are added whole), and takes
    back what was dropped there; a "not a shadow" dab whose disc holds something to drop (a
    found shadow probability above :data:`NOT_SHADOW_LEVEL`, or what the user added) drops
    its whole disc (the probability there becomes 0: weaker probability left a tint and some
    lift) and takes back what was added in it. The masks are made once, at the size the user
    sees the found shadows (the session's working size), and brought to other sizes
    by :func:`apply_edit_masks`, so what an export lifts is what the user marked (found again
    at another size, one click could pick another region: a dark object joined to the shadow
    beside it).

    Args:
        used: if given, one entry per edit is appended: whether it changed anything (a
            click on the sky, on lit ground or on what is already dropped does not; nor does
            a "not a shadow" dab whose disc holds nothing to drop, after the dabs before it,
            nor every dab of an "a shadow" stroke that adds (almost) nothing new: the sky,
            lit ground, what the user added already, a shadow the found shadows show and lift
            already; fewer pixels than :data:`STROKE_MIN_NEW` of a dab's disc). Leaving out
            the edits that changed nothing
            gives the same masks (the dabs of an "a shadow" stroke are all kept or all left
            out, its start with them; a "not a shadow" dab is decided alone whichever stroke
            it counts with). Only where strokes' starts are not marked (the command line's
            dabs, files from before the mark) may leaving one out make two "a shadow"
            strokes one: one begun where another ended, with an edit that changed nothing
            between them.

    Returns:
        ``(added, dropped)``: ``added`` float32 (1 in a clicked region, a stroke's soft
        cover where it painted, the most of them where they overlap); ``dropped`` bool, also
        what the lift must not take for lit surface (dark materials).

    Example:
        >>> p = np.zeros((40, 40), np.float32); p[10:30, 5:35] = 1.0  # one found shadow
        >>> img, sky, used = np.full((40, 40, 3), 0.5, np.float32), np.zeros((40, 40), bool), []
        >>> dab = ShadowEdit(0.5, 0.5, shadow=False, radius=0.1)  # 4 px round the centre
        >>> on_lit = ShadowEdit(0.5, 0.9, shadow=False, radius=0.1)  # no found shadow there
        >>> added, dropped = shadow_edit_masks(p, img, sky, [dab, on_lit], used)
        >>> int(dropped.sum()), bool(dropped[20, 20]), bool(dropped[20, 8]), used
        (60, True, False, [True, False])
    """
    found = np.clip(np.asarray(probability, np.float32), 0.0, 1.0)
    sky = np.asarray(sky, bool)
    shape = found.shape
    reach = max(1.0, PICK_RADIUS * max(shape))
    added: list[np.ndarray] = []  # the "a shadow" clicks' regions
    painted = np.zeros(shape, np.float32)  # what "a shadow" strokes added, soft-edged
    dropped = np.zeros(shape, bool)
    log_y = None
    shown = None  # what the found shadows lift (lift_probability), made for a stroke
    flags: list[bool] = []
    edits = list(edits)
    for start, stop in shadow_edit_strokes(edits, shape):
        edit = edits[start]
        if edit.radius > 0:  # a stroke: its dabs drawn at once into a window of the photo
            run = edits[start:stop]
            window, boxes = _dabs_window(run, shape)
            off_sky = ~sky[window]
            if edit.shadow:  # the shadow under the stroke, decided for the stroke as a whole
                if log_y is None:
                    log_y = edit_luminance(image_srgb)
                paint = _paint_dabs(run, shape, window)
                under = np.zeros(shape, bool)
                under[window] = paint > 0
                have = painted[window].copy()  # what the user added there already
                for clicked in added:
                    have[clicked[window]] = 1.0
                known = np.zeros(shape, bool)  # shadow already: found, or added
                known[window] = (((found[window] > 0.5) & ~dropped[window])
                                 | (marked_weight(have) >= 1.0))
                line = np.zeros(shape, bool)
                line[window] = _paint_dabs([replace(e, radius=STROKE_LINE * e.radius)
                                            for e in run], shape, window) > 0
                region = stroke_shadow(log_y, sky, under, known, line)[window]
                radius = edit.radius * max(shape)
                cover = np.where(region, _feathered(paint, radius), 0.0)
                # Where it works at full strength (apply_edit_masks doubles the cover) it takes
                # back what was dropped; under its faint rim the drop stays, and the cover
                # fades in over it (a review: the rim restored the found shadow at full
                # strength out to the footprint's edge).
                full = marked_weight(cover) >= 1.0
                if shown is None:
                    shown = lift_probability(image_srgb, found, sky)
                # More than the user added there, and more than the found shadows show (and
                # lift) there, on enough pixels to matter.
                more = ((cover > have + STROKE_NEW)
                        & (marked_weight(cover) > np.where(dropped[window], 0.0, shown[window])
                           + STROKE_NEW))
                changed = cv2.countNonZero((more | (full & dropped[window])).astype(np.uint8))
                new = changed >= max(1.0, STROKE_MIN_NEW * math.pi * radius**2)
                flags.extend([new] * len(run))
                # One that adds nothing new is left out whole, so a later "not a shadow" click
                # on a painted area takes back the same with it as without it.
                if new:
                    painted[window] = np.maximum(painted[window], cover)
                    dropped[window] &= ~full
                continue
            changes = (painted[window] > 0) | ((found[window] > NOT_SHADOW_LEVEL)
                                               & ~dropped[window])
            for region in added:
                changes |= region[window]
            dab_flags, rubbed = _rub_out(run, shape, boxes, window, changes & off_sky)
            flags.extend(dab_flags)
            rubbed &= off_sky
            painted[window][rubbed] = 0.0
            for region in added:
                region[window] &= ~rubbed
            dropped[window] |= rubbed
            continue
        row, col = edit.pixel(shape)
        if edit.shadow:
            if log_y is None:
                log_y = edit_luminance(image_srgb)
            region = shadow_edit_region(found, image_srgb, sky, edit, log_y)
            flags.append(bool(region.any()))
            if region.any():
                added.append(region)
            continue
        hit = [k for k, region in enumerate(added) if region[row, col]]
        if hit or painted[row, col] > 0:  # a click on what the user added takes that back
            added = [region for k, region in enumerate(added) if k not in hit]
            if painted[row, col] > 0:
                _, labels = cv2.connectedComponents((painted > 0).astype(np.uint8),
                                                    connectivity=8)
                painted[labels == labels[row, col]] = 0.0
            flags.append(True)
            continue
        left = found * ~dropped
        if dropped.any() and left[row, col] <= 0.5:
            # A click again on (or beside) what is already dropped changes nothing: it must
            # not reach for the next shadow within PICK_RADIUS (a double click dropped the
            # real shadow beside a black car).
            dist = cv2.distanceTransform((~dropped).astype(np.uint8), cv2.DIST_L2, 5)
            if dist[row, col] <= reach:
                flags.append(False)
                continue
        if log_y is None:
            log_y = edit_luminance(image_srgb)
        region = shadow_edit_region(left, image_srgb, sky, edit, log_y)
        flags.append(bool(region.any()))
        dropped |= region
    if used is not None:
        used.extend(flags)
    union = painted
    for region in added:
        union = np.where(region, 1.0, union)
    return np.where(sky, 0.0, union).astype(np.float32), dropped & ~sky


def marked_weight(added: np.ndarray) -> np.ndarray:
    """How much the user's "Mark shadow" counts at each pixel (float32 in [0, 1]) from
    :func:`shadow_edit_masks`' added cover: twice the cover, at most 1, as
    :func:`apply_edit_masks` sets the probability, so a stroke's mark is whole where it works
    at full strength (within the brush's dashed ring) and fades with it (a review: the raw
    cover weighed the mark at half there)."""
    return np.clip(2.0 * np.asarray(added, np.float32), 0.0, 1.0)


def edit_masks_at(added: np.ndarray, dropped: np.ndarray, shape: tuple[int, int]
                  ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`shadow_edit_masks`' ``(added, dropped)`` at another ``H x W`` size, both as
    float32 covers in [0, 1], bilinear: a stroke's soft edge stays soft, and a region's edge
    is smooth at a larger size rather than in blocks of the working size's pixels (the
    exported shadow mask stepped along a dropped pine's outline; a user trial).
    :func:`apply_edit_masks` applies them.

    Example:
        >>> added = np.zeros((4, 4), np.float32); added[:2] = 1.0
        >>> a, d = edit_masks_at(added, np.zeros((4, 4), bool), (8, 8))
        >>> a[:, 0].round(2).tolist(), float(d.sum())
        ([1.0, 1.0, 1.0, 0.75, 0.25, 0.0, 0.0, 0.0], 0.0)
    """
    shape = tuple(shape)

    def cover(m: np.ndarray) -> np.ndarray:
        m = np.clip(np.asarray(m, np.float32), 0.0, 1.0)
        if m.shape == shape:
            return m
        return np.clip(cv2.resize(m, shape[::-1], interpolation=cv2.INTER_LINEAR), 0.0, 1.0)

    return cover(added), cover(dropped)


def apply_edit_masks(probability: np.ndarray, sky: np.ndarray, added: np.ndarray,
                     dropped: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The shadow probability with :func:`shadow_edit_masks`' regions applied: added ones
    set to 1 (raised to twice a stroke's soft cover: full strength halfway through its fade),
    dropped ones (with the soft fringe of probability round them) to 0, edges soft
    (:data:`EDIT_SOFT`). Masks of another size are brought to the probability's
    (:func:`edit_masks_at`).

    Returns:
        ``(probability, not_shadow)``: ``H x W`` float32, and ``H x W`` bool, the dropped
        regions: dark materials, which the lift's statistics must not take for lit surface
        (:func:`deshadow` and the guards leave them out, as the sky).

    Example:
        >>> img = np.full((32, 32, 3), 0.8, np.float32); img[:, 16:] *= 0.3  # one dark half
        >>> sky = np.zeros((32, 32), bool)
        >>> p = photo_shadow_probability(img, sky)
        >>> masks = shadow_edit_masks(p, img, sky, [ShadowEdit(0.9, 0.5, shadow=False)])
        >>> out, dark = apply_edit_masks(p, sky, *masks)
        >>> bool(p[16, 28] > 0.9 and out[16, 28] < 0.01 and dark[16, 28] and not dark[16, 4])
        True
    """
    p = np.clip(np.asarray(probability, np.float32), 0.0, 1.0)
    sky = np.asarray(sky, bool)
    shape = p.shape
    added, dropped = edit_masks_at(added, dropped, shape)
    sigma = max(0.5, EDIT_SOFT * max(shape))
    if dropped.any():  # the region and the soft fringe of probability round it
        k = max(1, round(2 * sigma))
        grown = cv2.dilate(dropped, cv2.getStructuringElement(cv2.MORPH_ELLIPSE,
                                                              (2 * k + 1,) * 2))
        soft = cv2.GaussianBlur(grown, (0, 0), sigma)
        p = p * (1.0 - np.clip(2.0 * soft, 0.0, 1.0))
    if added.any():
        p = np.maximum(p, marked_weight(cv2.GaussianBlur(added, (0, 0), sigma)))
    return np.where(sky, 0.0, p).astype(np.float32), (dropped > 0.5) & ~sky


__all__ = [
    "MAX_BRUSH_RADIUS",
    "MAX_SHADOW_CLICKS",
    "MAX_SHADOW_EDITS",
    "NOT_SHADOW_LEVEL",
    "ShadowEdit",
    "apply_edit_masks",
    "edit_luminance",
    "edit_masks_at",
    "lift_probability",
    "marked_weight",
    "shadow_edit_masks",
    "shadow_edits_from_json",
    "shadow_edits_to_json",
    "shadow_edit_limit",
    "shadow_edit_region",
    "shadow_edit_strokes",
    "stroke_shadow",
    "deshadow",
    "deshadow_log_gain",
    "lit_surface_colour",
    "marked_lift",
    "material_guard",
    "near_predicted_shadow",
    "without_texture",
    "original_shadow_from_photo",
    "photo_shadow_probability",
    "shade_threshold",
    "warm_lift",
]
