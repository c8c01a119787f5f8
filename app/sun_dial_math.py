"""Pure maths of the sun dial (no Qt): the sky hemisphere seen from above.

The dial is a disc: its centre is the zenith, its rim the horizon, and up on screen is the
camera's view direction (azimuth 0). Azimuth runs clockwise (90 = right of the camera), and the
elevation falls linearly from 90 at the centre to 0 at the rim:

    r = R * (90 - el) / 90,   x = cx + r sin(az),   y = cy - r cos(az)

Screen coordinates have y down, as in Qt.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

MIN_ELEVATION = 0.0
MAX_ELEVATION = 90.0
#: Shadow length (in object heights) above which the ruler stops growing.
MAX_SHADOW_RATIO = 10.0


def wrap_azimuth(azimuth: float) -> float:
    """Azimuth in degrees wrapped to [0, 360).

    Example:
        >>> wrap_azimuth(-90.0), wrap_azimuth(725.0)
        (270.0, 5.0)
    """
    if not math.isfinite(azimuth):
        raise ValueError(f"expected a finite azimuth, got {azimuth}")
    a = azimuth % 360.0
    return 0.0 if a >= 360.0 else a


def azimuth_gap(a: float, b: float) -> float:
    """The angle between two azimuths in degrees, the short way round (0-180).

    Example:
        >>> azimuth_gap(350.0, 10.0), azimuth_gap(90.0, 300.0)
        (20.0, 150.0)
    """
    return abs((a - b + 180.0) % 360.0 - 180.0)


def same_sun(a: tuple[float | None, float], b: tuple[float, float], tol: float = 0.01) -> bool:
    """Whether two dial suns (azimuth, elevation in degrees) are the same within ``tol``
    degrees each (below the dial's finest nudge, 0.1: a search's sun came back 1e-14 off the
    EXIF sun the dial stood at, and was recorded as a move). ``a``'s azimuth None: any.

    Example:
        >>> same_sun((359.999, 40.0), (0.0, 40.0)), same_sun((10.0, 40.0), (10.1, 40.0))
        (True, False)
        >>> same_sun((None, 40.0), (200.0, 40.0))
        True
    """
    return ((a[0] is None or azimuth_gap(a[0], b[0]) <= tol)
            and abs(a[1] - b[1]) <= tol)


def clamp_elevation(elevation: float) -> float:
    """Elevation clamped to the dial's range [0, 90]."""
    if not math.isfinite(elevation):
        raise ValueError(f"expected a finite elevation, got {elevation}")
    return min(MAX_ELEVATION, max(MIN_ELEVATION, elevation))


def sun_to_point(
    azimuth: float, elevation: float, cx: float, cy: float, radius: float
) -> tuple[float, float]:
    """Screen point of a sun on a dial centred at ``(cx, cy)`` with rim ``radius``.

    Args:
        azimuth: degrees, 0 = up (view direction), 90 = right.
        elevation: degrees, clamped to [0, 90]; 90 is the centre.
        cx: dial centre x (pixels).
        cy: dial centre y (pixels, y down).
        radius: rim radius in pixels (> 0).

    Returns:
        ``(x, y)`` in pixels.

    Example:
        >>> [round(v, 6) for v in sun_to_point(90.0, 0.0, 100.0, 100.0, 50.0)]
        [150.0, 100.0]
    """
    if not radius > 0:
        raise ValueError(f"expected a dial radius > 0, got {radius}")
    r = radius * (MAX_ELEVATION - clamp_elevation(elevation)) / MAX_ELEVATION
    a = math.radians(wrap_azimuth(azimuth))
    return cx + r * math.sin(a), cy - r * math.cos(a)


def tilted_ring(
    elevation: float, pitch: float, roll: float, step: float = 3.0
) -> list[tuple[float, float]]:
    """The circle of suns at ``elevation`` above the true horizon, as a camera pitched ``pitch``
    and rolled ``roll`` degrees (:func:`~outcast_core.runtime.geometry.camera.camera_rotation`)
    sees them: ``(azimuth, elevation)`` on the dial's (camera-relative) angles, one every
    ``step`` degrees of true azimuth, elevations not clamped (below 0: off the dial).

    Example:
        >>> [tuple(round(v, 6) for v in p) for p in tilted_ring(0.0, -20.0, 0.0, 180.0)]
        [(0.0, 20.0), (180.0, -20.0)]
    """
    from outcast_core.runtime.geometry.camera import sun_angles, sun_vector

    if not (math.isfinite(step) and 0.0 < step <= 180.0):
        raise ValueError(f"expected a ring step in (0, 180] degrees, got {step}")
    n = max(2, round(360.0 / step))
    return [sun_angles(sun_vector(360.0 * k / n, elevation, pitch, roll)) for k in range(n)]


def point_to_sun(x: float, y: float, cx: float, cy: float, radius: float) -> tuple[float, float]:
    """Sun ``(azimuth, elevation)`` under a screen point; points beyond the rim snap to it.

    At the exact centre the azimuth is undefined and returned as 0.

    Example:
        >>> point_to_sun(100.0, 75.0, 100.0, 100.0, 50.0)
        (0.0, 45.0)
    """
    if not radius > 0:
        raise ValueError(f"expected a dial radius > 0, got {radius}")
    dx, dy = x - cx, y - cy
    r = math.hypot(dx, dy)
    az = 0.0 if r < 1e-9 else wrap_azimuth(math.degrees(math.atan2(dx, -dy)))
    el = MAX_ELEVATION * (1.0 - min(r / radius, 1.0))
    return az, el


def nudge(
    azimuth: float, elevation: float, d_azimuth: float = 0.0, d_elevation: float = 0.0
) -> tuple[float, float]:
    """Move a sun by a keyboard step: azimuth wraps, elevation clamps to [0, 90]."""
    return wrap_azimuth(azimuth + d_azimuth), clamp_elevation(elevation + d_elevation)


def shadow_length_ratio(elevation: float) -> float:
    """Length of the shadow of a vertical object on flat ground, in object heights: 1/tan(el).

    Returns ``inf`` at or below the horizon.

    Example:
        >>> round(shadow_length_ratio(45.0), 6)
        1.0
    """
    if not math.isfinite(elevation):
        raise ValueError(f"expected a finite elevation, got {elevation}")
    if elevation <= 0.0:
        return math.inf
    if elevation >= 90.0:
        return 0.0
    return 1.0 / math.tan(math.radians(elevation))


def shadow_ruler(
    azimuth: float, elevation: float, cx: float, cy: float, unit: float
) -> tuple[tuple[float, float], tuple[float, float], bool]:
    """Segment showing the shadow cast by a vertical pole standing at the dial centre.

    The shadow points away from the sun (azimuth + 180); its length is ``unit`` pixels per object
    height, capped at :data:`MAX_SHADOW_RATIO` heights.

    Args:
        azimuth: sun azimuth in degrees.
        elevation: sun elevation in degrees.
        cx: pole foot x.
        cy: pole foot y.
        unit: pixels per object height.

    Returns:
        ``(start, end, capped)``: the segment's end points and whether the length was capped.
    """
    ratio = shadow_length_ratio(elevation)
    capped = ratio > MAX_SHADOW_RATIO
    length = unit * min(ratio, MAX_SHADOW_RATIO)
    a = math.radians(wrap_azimuth(azimuth) + 180.0)
    return (cx, cy), (cx + length * math.sin(a), cy - length * math.cos(a)), capped


def fov_wedge(fov_deg: float) -> tuple[float, float]:
    """Azimuth range ``(left, right)`` in degrees covered by the camera's horizontal view.

    Example:
        >>> fov_wedge(60.0)
        (-30.0, 30.0)
    """
    if not (math.isfinite(fov_deg) and 0.0 < fov_deg < 180.0):
        raise ValueError(f"expected a field of view in (0, 180) degrees, got {fov_deg}")
    return -fov_deg / 2.0, fov_deg / 2.0


def sun_in_view(azimuth: float, elevation: float, hfov_deg: float, vfov_deg: float) -> bool:
    """Whether a sun lies inside a level camera's frame (approximate: per-axis angles)."""
    a = (wrap_azimuth(azimuth) + 180.0) % 360.0 - 180.0  # -180 .. 180, 0 = ahead
    return abs(a) <= hfov_deg / 2.0 and 0.0 <= elevation <= vfov_deg / 2.0


def hit_handle(
    x: float, y: float, hx: float, hy: float, handle_radius: float, slack: float = 4.0
) -> bool:
    """Whether a press at ``(x, y)`` grabs the handle drawn at ``(hx, hy)``."""
    return math.hypot(x - hx, y - hy) <= handle_radius + slack


def describe_sun(azimuth: float, elevation: float) -> str:
    """A short words-only description for photographers, e.g. ``"high, front-right"``."""
    a = wrap_azimuth(azimuth)
    sides = ["front", "front-right", "right", "back-right", "behind", "back-left", "left",
             "front-left"]  # fmt: skip
    side = sides[int(((a + 22.5) % 360.0) // 45.0)]
    if elevation >= 60.0:
        height = "high"
    elif elevation >= 25.0:
        height = "mid"
    elif elevation >= 8.0:
        height = "low"
    else:
        height = "at the horizon"
    return f"{height}, {side}"


def heat_cells(
    azimuths: Sequence[float], elevations: Sequence[float]
) -> list[tuple[int, int, float, float, float, float]]:
    """Cells of an agreement map on the dial: one annular sector per (elevation, azimuth) sample.

    Each sample's cell reaches half-way to its neighbours: in azimuth half the (uniform) step
    either side; in elevation half-way to the next rows, the lowest row down to the horizon and
    the highest up to the zenith.

    Args:
        azimuths: ``A`` sample azimuths in degrees, increasing, evenly spaced around the circle.
        elevations: ``E`` sample elevations in degrees, increasing.

    Returns:
        ``(row, col, az_from, az_to, el_from, el_to)`` per cell (degrees).

    Example:
        >>> heat_cells([0.0, 180.0], [45.0])[1]
        (0, 1, 90.0, 270.0, 0.0, 90.0)
    """
    az = [float(a) for a in azimuths]
    el = [float(e) for e in elevations]
    if not az or not el:
        return []
    if any(not math.isfinite(v) for v in (*az, *el)):
        raise ValueError("expected finite azimuths and elevations")
    half = 180.0 if len(az) == 1 else (360.0 / len(az)) / 2.0
    bounds = [0.0] + [(a + b) / 2.0 for a, b in zip(el, el[1:], strict=False)] + [90.0]
    return [(r, c, a - half, a + half, clamp_elevation(bounds[r]), clamp_elevation(bounds[r + 1]))
            for r in range(len(el)) for c, a in enumerate(az)]


def heat_colour(value: float) -> tuple[int, int, int, int]:
    """RGBA of a normalised agreement in [0, 1]: clear below 0.05, then a warm ramp from a faint
    orange to an opaque red-magenta at the best.

    Example:
        >>> heat_colour(0.0)[3], heat_colour(1.0)[3] > heat_colour(0.5)[3]
        (0, True)
    """
    if not math.isfinite(value) or value <= 0.05:
        return (0, 0, 0, 0)
    v = min(1.0, value)
    r = 255
    g = round(200 * (1.0 - v) + 20 * v)
    b = round(40 * (1.0 - v) + 120 * v)
    return (r, g, b, round(40 + 170 * v))
