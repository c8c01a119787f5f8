"""The sun's and the sky's light as the sun's elevation changes (a clear sky), for relighting.

A photo relit to another sun changes more than its shadows and the cosine term: near the
horizon the sunlight crosses more air and turns weaker and redder, and the sky dims, most of
all near the horizon. Without this, a day's time-lapse keeps the midday light's strength and
colour down to the horizon: its sunrise frames showed the ground lit by the midday sky only,
nearly black, under an unchanged blue midday sky (a user trial).

The light is the renderer's (Mitsuba's ``sunsky``: the Hosek-Wilkie sky and its sun, as
``outcast_core.data.sky`` bakes them for the training renders) at turbidity 3 and ground
albedo 0.3, tabulated per sun elevation by ``python3 scripts/daylight_table.py`` into
:mod:`~outcast_core.runtime.pipeline.daylight_table`: the sun's irradiance on a surface facing
it, the sky's irradiance on level ground, and the sky's radiance seen at a grid of view
elevations (averaged over the view's azimuth), linear RGB. Below :data:`MIN_ELEVATION` the
model's sun stops changing; lower suns are taken at it.

The photo's own light is measured (``relight.LightEstimate``: the sun over the sky, per
channel); this module gives how both change from the photo's sun to the new one, as ratios
(:func:`daylight_change`, :func:`sky_change`), so the photo's measured light is carried to the
new elevation (:func:`daylight_gain`), and two suns at one elevation change nothing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from outcast_core.runtime.geometry.colour import linear_to_srgb, srgb_to_linear
from outcast_core.runtime.pipeline import daylight_table as _t

#: The lowest sun elevation (degrees) the table holds; lower suns are taken at it (below about
#: 2 degrees the model's sun stops changing).
MIN_ELEVATION = 2.0
#: Each light's ratio between two suns is kept within ``1 / RATIO_LIMIT`` (dimming: the
#: table's blue sunlight at 2 degrees is nearly 0) and :data:`BRIGHTEN_LIMIT` (a photo of a
#: low sun relit high: with ``r = (4, 3, 2)`` from 3 to 60 degrees the blue channel of a lit
#: surface would grow x45, and an elevation aligned a few degrees low, or a camera's white
#: balance that already warmed the photo, turns that into a blue cast; a review).
RATIO_LIMIT = 64.0
BRIGHTEN_LIMIT = 4.0
#: Table entries are floored at this (linear) before a ratio is taken.
_FLOOR = 0.005


_SUN_ELEVATIONS = np.asarray(_t.SUN_ELEVATIONS, np.float64)
_VIEW_ELEVATIONS = np.asarray(_t.VIEW_ELEVATIONS, np.float64)
_SUN = np.asarray(_t.SUN, np.float64)  # sun elevation x 3
_SKY = np.asarray(_t.SKY, np.float64)  # sun elevation x 3
_SKY_SEEN = np.asarray(_t.SKY_SEEN, np.float64)  # sun elevation x view elevation x 3


@dataclass(frozen=True)
class DaylightChange:
    """Per-channel ratios (linear RGB, new over old) of the sun's irradiance (``sun``) and the
    sky's irradiance on the ground (``sky``), between two sun elevations."""

    sun: np.ndarray
    sky: np.ndarray
    elevation_old: float
    elevation_new: float

    @property
    def is_identity(self) -> bool:
        return bool(np.allclose(self.sun, 1.0) and np.allclose(self.sky, 1.0))


def _clamped(elevation_deg: float) -> float:
    if not math.isfinite(elevation_deg):
        raise ValueError(f"expected a finite elevation, got {elevation_deg}")
    return min(max(float(elevation_deg), MIN_ELEVATION), 90.0)


def daylight(elevation_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """``(sun, sky)`` linear RGB at a sun elevation (degrees above the horizon): the sun's
    irradiance on a surface facing it and the sky's on level ground, interpolated in the
    table; below :data:`MIN_ELEVATION` taken at it, above 90 at 90.

    Example:
        >>> sun, sky = daylight(45.0)
        >>> bool(sun[0] > sun[2] and sky[2] > sky[0])  # a warm sun, a blue sky
        True
    """
    el = _clamped(elevation_deg)
    return tuple(np.array([np.interp(el, _SUN_ELEVATIONS, t[:, c]) for c in range(3)])
                 for t in (_SUN, _SKY))  # type: ignore[return-value]


def sky_seen(elevation_deg: float, view_elevation: np.ndarray) -> np.ndarray:
    """The clear sky's radiance (linear RGB, ``... x 3``) seen ``view_elevation`` degrees above
    the horizon, averaged over the view's azimuth, for a sun at ``elevation_deg``: bilinear in
    the table's elevations. The azimuth is averaged out so that a sun moved round the horizon
    at one elevation leaves the sky as it is (the relit photo's sky changes with the sun's
    height only)."""
    el = _clamped(elevation_deg)
    at_sun = np.array([[np.interp(el, _SUN_ELEVATIONS, _SKY_SEEN[:, i, c]) for c in range(3)]
                       for i in range(len(_VIEW_ELEVATIONS))])  # view x 3
    v = np.clip(np.asarray(view_elevation, np.float64), _VIEW_ELEVATIONS[0],
                _VIEW_ELEVATIONS[-1])
    return np.stack([np.interp(v, _VIEW_ELEVATIONS, at_sun[:, c]) for c in range(3)], -1)


def sky_change(view_dirs: np.ndarray, up: Any, elevation_old: float, elevation_new: float
               ) -> np.ndarray:
    """Per pixel (``H x W x 3``, linear RGB), how the clear sky seen along ``view_dirs``
    (camera-space unit rays) changes from a sun at ``elevation_old`` to one at
    ``elevation_new`` (degrees): :func:`sky_seen` new over old, kept within
    :data:`RATIO_LIMIT` and :data:`BRIGHTEN_LIMIT`; the ray's elevation is taken against ``up`` (as
    :func:`elevation_above`'s)."""
    d = np.asarray(view_dirs, np.float64)
    u = np.asarray(up, np.float64).reshape(3)
    u = u / max(float(np.linalg.norm(u)), 1e-12)
    v = np.degrees(np.arcsin(np.clip(d @ u, -1.0, 1.0)))
    old, new = sky_seen(elevation_old, v), sky_seen(elevation_new, v)
    k = np.maximum(new, _FLOOR) / np.maximum(old, _FLOOR)
    return np.clip(k, 1.0 / RATIO_LIMIT, BRIGHTEN_LIMIT).astype(np.float32)


def daylight_change(elevation_old: float, elevation_new: float) -> DaylightChange:
    """How the sun's and the sky's light change from one sun elevation to another (degrees).

    Example:
        >>> low = daylight_change(40.0, 5.0)
        >>> bool(low.sun[2] < low.sun[0] < 1.0 and low.sky.max() < 1.0)  # weaker, redder
        True
        >>> daylight_change(30.0, 30.0).is_identity
        True
    """
    old, new = daylight(elevation_old), daylight(elevation_new)
    k = [np.clip((np.maximum(b, _FLOOR) / np.maximum(a, _FLOOR)), 1.0 / RATIO_LIMIT,
                 BRIGHTEN_LIMIT) for a, b in zip(old, new, strict=True)]
    return DaylightChange(k[0].astype(np.float32), k[1].astype(np.float32),
                          _clamped(elevation_old), _clamped(elevation_new))


def elevation_above(w: Any, up: Any) -> float:
    """A camera-space sun direction's elevation (degrees) above the horizon whose upward
    direction, in camera space, is ``up`` (the ground plane's normal; ``(0, -1, 0)`` for a
    level camera, whose image y points down)."""
    v = np.asarray(w, np.float64).reshape(3)
    u = np.asarray(up, np.float64).reshape(3)
    nv, nu = float(np.linalg.norm(v)), float(np.linalg.norm(u))
    if not (nv > 0 and nu > 0 and math.isfinite(nv) and math.isfinite(nu)):
        raise ValueError(f"expected non-zero finite vectors, got {v.tolist()} and {u.tolist()}")
    return math.degrees(math.asin(max(-1.0, min(1.0, float(v @ u) / (nv * nu)))))


def daylight_gain(shadow_new: np.ndarray, sky: np.ndarray, ratio: np.ndarray,
                  change: DaylightChange, sky_gain: np.ndarray | None = None) -> np.ndarray:
    """The per-pixel linear gain (``H x W x 3``) that carries a relit photo, made with the
    photo's own light, to the new sun's daylight.

    A surface pixel is ``A a (1 + r S)`` (albedo ``A``, sky light ``a``, the measured sun over
    sky ``r``, the shadow image ``S``); under the new elevation's light the sky gives ``a
    k_sky`` and the sun ``r a k_sun``, so the pixel is multiplied, per channel, by ``(k_sky + r
    k_sun S_n) / (1 + r S_n)``. The sky's pixels take ``sky_gain`` (:func:`sky_change`; None:
    1).

    Args:
        shadow_new: ``H x W`` in [0, 1] (the new sun's); sky: ``H x W`` bool; ratio: the
        photo's ``r`` (3 channels); change: :func:`daylight_change`; sky_gain: ``H x W x 3``
        or None.
    """
    s = np.clip(np.nan_to_num(np.asarray(shadow_new, np.float32)), 0.0, 1.0)
    sk = np.asarray(sky, bool)
    if s.ndim != 2 or sk.shape != s.shape:
        raise ValueError(f"expected H x W shadow and sky of one size, got {s.shape}, {sk.shape}")
    r = np.clip(np.nan_to_num(np.asarray(ratio, np.float32).reshape(1, 1, 3)), 0.0, None)
    sn = s[..., None]
    gain = (change.sky.reshape(1, 1, 3) + r * change.sun.reshape(1, 1, 3) * sn) / (1.0 + r * sn)
    if sky_gain is not None:
        g = np.asarray(sky_gain, np.float32)
        if g.shape != s.shape + (3,):
            raise ValueError(f"expected a sky gain of shape {s.shape + (3,)}, got {g.shape}")
        return np.where(sk[..., None], g, gain).astype(np.float32)
    return np.where(sk[..., None], np.float32(1.0), gain).astype(np.float32)


def in_new_daylight(relit_srgb: np.ndarray, gain: np.ndarray) -> np.ndarray:
    """``relit_srgb`` (``H x W x 3`` sRGB) times :func:`daylight_gain`'s ``gain`` in linear
    light, clipped to [0, 1].

    Example:
        >>> img = np.full((4, 4, 3), 0.5, np.float32); lit = np.ones((4, 4), np.float32)
        >>> sky = np.zeros((4, 4), bool); r = np.full(3, 4.0, np.float32)
        >>> g = daylight_gain(lit, sky, r, daylight_change(40.0, 5.0))
        >>> dusk = in_new_daylight(img, g)
        >>> bool(dusk[0, 0, 0] > dusk[0, 0, 2] and dusk[0, 0, 1] < 0.5)  # dimmer, warmer
        True
    """
    relit = np.asarray(relit_srgb, np.float32)
    g = np.asarray(gain, np.float32)
    if relit.ndim != 3 or relit.shape[-1] != 3 or g.shape != relit.shape:
        raise ValueError(f"expected an H x W x 3 image and gain of one shape, got {relit.shape} "
                         f"and {g.shape}")
    return linear_to_srgb(np.clip(srgb_to_linear(relit) * g, 0.0, 1.0)).astype(np.float32)
