"""Time-lapse: sun paths (sweeps and the real sun), frame writers and the ``outcast timelapse`` CLI.

Two kinds of sun path, both relative to the camera as every other part of OutCast speaks
(azimuth 0 = straight ahead, 90 = right; elevation 0 = horizon):

* :func:`sweep_path`: azimuth and elevation from A to B over N frames with an easing curve.
* :func:`real_sun_path`: the true sun for a date and place (``astral``), turned into
  heading-relative angles with the camera's compass heading: ``relative = true_azimuth - heading``.
  The heading can be solved from the aligned original sun when the photo has GPS and a capture time
  (:func:`solve_heading`: ``heading = true_azimuth - relative_azimuth``).

The true sun's angles are measured against the horizon, the camera's against its own axes: a
camera pitched 20° down sees a sun 40° above the horizon behind it at 20° in its own frame, and
one ahead of it at 60°. The real sun's samples keep the horizon's angles and carry the camera's
pitch and roll (:attr:`SunSample.tilt`, e.g. from
:func:`~outcast_core.runtime.pipeline.auto_sun.camera_tilt`), and :func:`sun_vectors` turns them
into the camera's; :func:`exif_sun` and :func:`solve_heading` take the same tilt.

Writers (:func:`export_frames`) produce MP4 (H.264 via PyAV, even size, yuv420p), GIF and WebP
(Pillow) or a folder of PNGs. They report progress, can be cancelled, write to a temporary name
and move it into place only when complete, and never overwrite an existing file unless forced: a
cancelled or failed export leaves nothing behind.

Plain numpy / astral / av / Pillow: no Qt, no torch.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import math
import os
import re
import shutil
import tempfile
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from outcast_core.runtime.geometry.camera import sun_angles, sun_vector

ProgressFn = Callable[[str, float], None]
CancelCheck = Callable[[], bool] | Any  # a callable returning bool, or a threading.Event

FORMATS = ("mp4", "gif", "webp", "png")
EASINGS = ("linear", "ease-in-out", "ease-in", "ease-out")
DEFAULT_FPS = 12.0
#: Frame rates a time-lapse accepts (the app's dialog offers the same range).
MIN_FPS = 1.0
MAX_FPS = 60.0
#: File extensions of the video formats; a path without an extension is a PNG folder.
VIDEO_SUFFIXES = {".mp4": "mp4", ".m4v": "mp4", ".gif": "gif", ".webp": "webp"}
#: Suns below this elevation are lifted to it for rendering (a sun under the ground casts nonsense).
MIN_RENDER_ELEVATION = 0.5
#: Frame sizes: the working size of the preset (fastest), video sizes by their shorter side
#: (720p: 720 px, so a 4:3 landscape photo gives 960 x 720), or the photo's full size. A size
#: is never larger than the photo.
FRAME_SIZES = ("working", "720p", "1080p", "4k", "full")
DEFAULT_FRAME_SIZE = "1080p"
SHORT_SIDES = {"720p": 720, "1080p": 1080, "4k": 2160}
#: x264's speed preset: "veryfast" took 47 ms of CPU per 1440 x 1080 frame against 70 ms for
#: "faster", for files about 12 % larger at the same CRF (measured on this machine).
X264_PRESET = "veryfast"


class ExportCancelledError(RuntimeError):
    """Raised by :func:`export_frames` when the cancel check fires; nothing was written."""


# --------------------------------------------------------------------------------------------
# Sun paths
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SunSample:
    """One frame's sun, relative to the camera.

    Attributes:
        azimuth: degrees in [0, 360), 0 = straight ahead, 90 = right.
        elevation: degrees above the horizon.
        time: local time of the sample (real sun paths only).
        true_azimuth: degrees clockwise from true north (real sun paths only).
        tilt: the camera's ``(pitch, roll)`` in degrees against the horizon the angles are
            measured from; ``(0, 0)``: the camera's own frame (sweeps, the dial's angles).
    """

    azimuth: float
    elevation: float
    time: dt.datetime | None = None
    true_azimuth: float | None = None
    tilt: tuple[float, float] = (0.0, 0.0)


def ease(t: np.ndarray | float, easing: str = "linear") -> np.ndarray:
    """Map progress ``t`` in [0, 1] through an easing curve (monotonic, 0 -> 0, 1 -> 1).

    Args:
        t: progress values in [0, 1].
        easing: one of :data:`EASINGS`.

    Returns:
        Eased values, same shape as ``t`` (float64).

    Example:
        >>> round(float(ease(0.5, "ease-in-out")), 12)
        0.5
    """
    t = np.clip(np.asarray(t, dtype=np.float64), 0.0, 1.0)
    if easing == "linear":
        return t
    if easing == "ease-in-out":
        return 0.5 - 0.5 * np.cos(math.pi * t)
    if easing == "ease-in":
        return t * t
    if easing == "ease-out":
        return 1.0 - (1.0 - t) ** 2
    raise ValueError(f"expected an easing in {EASINGS}, got {easing!r}")


def _check_frames(frames: int) -> int:
    if isinstance(frames, bool) or not isinstance(frames, int | np.integer) or frames < 1:
        raise ValueError(f"expected a frame count >= 1, got {frames!r}")
    return int(frames)


def _check_angle(
    name: str, value: float, lo: float | None = None, hi: float | None = None
) -> float:
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"expected a finite {name}, got {value}")
    if lo is not None and hi is not None and not lo <= value <= hi:
        raise ValueError(f"expected {name} in [{lo}, {hi}], got {value}")
    return value


def sweep_path(
    start: tuple[float, float],
    end: tuple[float, float],
    frames: int,
    easing: str = "linear",
) -> list[SunSample]:
    """A sun sweep from ``start = (az, el)`` to ``end`` over ``frames`` frames.

    Azimuth is interpolated between the numbers as given, so the user picks the direction of
    travel: ``(90, 30) -> (270, 30)`` passes through 180 (behind the camera), while
    ``(90, 30) -> (-90, 30)`` passes through 0 (in front). Output azimuths are wrapped to [0, 360).

    Args:
        start: ``(azimuth_deg, elevation_deg)`` of the first frame.
        end: ``(azimuth_deg, elevation_deg)`` of the last frame.
        frames: number of frames (>= 1; one frame gives ``start``).
        easing: one of :data:`EASINGS`.

    Returns:
        ``frames`` samples.
    """
    frames = _check_frames(frames)
    az0 = _check_angle("start azimuth", start[0])
    el0 = _check_angle("start elevation", start[1], -90.0, 90.0)
    az1 = _check_angle("end azimuth", end[0])
    el1 = _check_angle("end elevation", end[1], -90.0, 90.0)
    t = np.linspace(0.0, 1.0, frames) if frames > 1 else np.zeros(1)
    s = ease(t, easing)
    az = az0 + (az1 - az0) * s
    el = el0 + (el1 - el0) * s
    return [SunSample(float(a % 360.0), float(e)) for a, e in zip(az, el, strict=True)]


def relative_azimuth(true_azimuth: float, heading: float) -> float:
    """Sun azimuth relative to the camera from its compass azimuth: ``(true - heading) mod 360``."""
    return (_check_angle("true azimuth", true_azimuth) - _check_angle("heading", heading)) % 360.0


def exif_sun(
    exif: Any, heading: float | None = None, tilt: tuple[float, float] = (0.0, 0.0)
) -> tuple[float, float] | None:
    """The photo's sun ``(azimuth, elevation)`` relative to the camera from its EXIF GPS,
    capture time and compass heading (``heading``, one the user typed, replaces the EXIF's or
    stands in for a missing one); None when one is missing or the sun is below the horizon.
    The one place the
    app's "Sun from EXIF" and ``outcast batch`` take it from.

    ``tilt`` is the camera's ``(pitch, roll)`` in degrees: the sun is returned in the camera's
    frame (the dial's and the session's angles). Its elevation there may be negative (a camera
    pitched well up can have the sun ahead of it under its own horizon); the app's dial clamps
    it, a relighting takes the vector as it is. A capture time without a zone is read at its
    longitude's (:func:`exif_capture_time`)."""
    when, _ = exif_capture_time(exif)
    lat, lon = getattr(exif, "latitude", None), getattr(exif, "longitude", None)
    exif_heading = getattr(exif, "heading_deg", None)
    heading = heading if heading is not None else exif_heading
    if when is None or lat is None or lon is None or heading is None:
        return None
    true_az, el = true_sun_position(when, lat, lon)
    if el <= 0:
        return None
    az = relative_azimuth(true_az, heading)
    if not any(tilt):
        return az, el
    return sun_angles(sun_vector(az, el, *tilt))


def sun_below_horizon_at_capture(exif: Any) -> str | None:
    """What happened when the photo's EXIF GPS and capture time put the sun below the horizon
    (a night photo, or a camera clock or time zone that is wrong), in words for a message;
    None when the sun was up, or without GPS or time.

    Example:
        >>> from outcast_core.runtime.io.exif import PhotoMetadata
        >>> night = dt.datetime(2026, 6, 1, 23, 30, tzinfo=dt.timezone(dt.timedelta(hours=2)))
        >>> text = sun_below_horizon_at_capture(PhotoMetadata(latitude=50.1, longitude=14.4,
        ...                                                   capture_time=night))
        >>> text.split(" below")[0], text.split("place ")[1]
        ('the sun was 15.0°', '(2026-06-01 23:30 +02:00)')
    """
    when, guessed = exif_capture_time(exif)
    lat, lon = getattr(exif, "latitude", None), getattr(exif, "longitude", None)
    if when is None or lat is None or lon is None:
        return None
    _, el = true_sun_position(when, lat, lon)
    if el > 0:
        return None
    return (f"the sun was {-el + 0.0:.1f}° below the horizon at the photo's time and place "
            f"({_capture_time_words(when, guessed)})")


def _capture_time_words(when: dt.datetime, guessed: bool = False) -> str:
    """``2026-06-01 22:14 +02:00``; a zone guessed from the longitude
    (:func:`exif_capture_time`) says so, and a time without a zone that it was read as UTC
    (as :func:`true_sun_position` reads it)."""
    offset = when.utcoffset()
    if offset is None:
        return f"{when:%Y-%m-%d %H:%M}, read as UTC: the EXIF gives no time zone"
    minutes = round(offset.total_seconds() / 60)
    sign = "-" if minutes < 0 else "+"
    words = f"{when:%Y-%m-%d %H:%M} {sign}{abs(minutes) // 60:02d}:{abs(minutes) % 60:02d}"
    if guessed:
        words += ", the time zone of its longitude: the EXIF gives none"
    return words


def exif_sun_problem(exif: Any, heading: float | None = None) -> str | None:
    """Why :func:`exif_sun` gives no sun for ``exif`` (and ``heading``), in words ("no EXIF
    compass heading", :func:`sun_below_horizon_at_capture`...); None when it gives one."""
    when = getattr(exif, "capture_time", None)  # (a zone-less one without GPS: missing GPS)
    lat, lon = getattr(exif, "latitude", None), getattr(exif, "longitude", None)
    gps = None if lat is None or lon is None else lat
    missing = [name for name, value in (("GPS position", gps), ("capture time", when),
                                        ("compass heading", heading if heading is not None
                                         else getattr(exif, "heading_deg", None)))
               if value is None]
    if lat is None or lon is None or when is None:
        return "no EXIF " + (" or ".join(missing) if len(missing) < 3
                             else f"{missing[0]}, {missing[1]} or {missing[2]}")
    night = sun_below_horizon_at_capture(exif)
    if night is not None:
        return night
    return f"no EXIF {missing[0]}" if missing else None


def exif_heading_from_sun(
    exif: Any, azimuth: float, elevation: float, tilt: tuple[float, float] = (0.0, 0.0)
) -> float | None:
    """The camera's compass heading that a sun known in the camera's frame (the sun the photo
    shows, :func:`~outcast_core.runtime.pipeline.auto_sun.sun_in_photo`) implies with the
    photo's EXIF GPS and capture time, read as :func:`exif_sun` reads them, so that
    ``exif_sun(exif, heading=..., tilt=tilt)`` gives that sun's azimuth back (and its elevation
    too with the pitch the seen sun implies, :func:`~outcast_core.runtime.pipeline.auto_sun.
    sun_frame_pitch`); None without them, or when they put the sun below the horizon.

    ``tilt``: the camera's ``(pitch, roll)`` in degrees (:func:`solve_heading`).
    """
    when, _ = exif_capture_time(exif)  # (a zone-less time was read as UTC here: a review)
    lat, lon = getattr(exif, "latitude", None), getattr(exif, "longitude", None)
    if when is None or lat is None or lon is None:
        return None
    if true_sun_position(when, lat, lon)[1] <= 0.0:  # a wrong clock: no heading from it
        return None
    return solve_heading(when, lat, lon, azimuth, original_elevation=elevation, tilt=tilt)


def heading_from_sun(true_azimuth: float, relative_az: float) -> float:
    """Camera compass heading from the sun's true and camera-relative azimuths.

    ``heading = (true_azimuth - relative_azimuth) mod 360``; inverse of :func:`relative_azimuth`.
    """
    true_az = _check_angle("true azimuth", true_azimuth)
    return (true_az - _check_angle("azimuth", relative_az)) % 360.0


def _observer(latitude: float, longitude: float) -> Any:
    from astral import Observer

    lat = _check_angle("latitude", latitude, -90.0, 90.0)
    lon = _check_angle("longitude", longitude, -180.0, 180.0)
    return Observer(latitude=lat, longitude=lon)


def _aware(when: dt.datetime, utc_offset_hours: float | None) -> dt.datetime:
    if when.tzinfo is not None:
        return when
    offset = 0.0 if utc_offset_hours is None else float(utc_offset_hours)
    return when.replace(tzinfo=dt.timezone(dt.timedelta(hours=offset)))


def true_sun_position(
    when: dt.datetime, latitude: float, longitude: float, utc_offset_hours: float | None = None
) -> tuple[float, float]:
    """The sun's apparent ``(azimuth from true north, elevation)`` in degrees at a time and place.

    Args:
        when: the moment; a naive datetime is local time at ``utc_offset_hours`` (UTC when None).
        latitude: degrees north.
        longitude: degrees east.
        utc_offset_hours: offset of naive times from UTC.

    Returns:
        ``(azimuth_deg, elevation_deg)`` with atmospheric refraction (what the shadows show).
    """
    import astral.sun

    obs = _observer(latitude, longitude)
    moment = _aware(when, utc_offset_hours)
    return float(astral.sun.azimuth(obs, moment)), float(astral.sun.elevation(obs, moment))


class SunBelowHorizonError(ValueError):
    """:func:`solve_heading`'s sun was below the horizon at the photo's time: no heading can be
    solved from it (the one error its callers answer with the EXIF compass)."""


def solve_heading(
    capture_time: dt.datetime,
    latitude: float,
    longitude: float,
    original_azimuth: float,
    utc_offset_hours: float | None = None,
    *,
    original_elevation: float | None = None,
    tilt: tuple[float, float] = (0.0, 0.0),
) -> float:
    """Camera compass heading from the aligned original sun and the photo's time and GPS.

    Args:
        capture_time: when the photo was taken (naive: local at ``utc_offset_hours``).
        latitude: degrees north.
        longitude: degrees east.
        original_azimuth: the aligned original sun's azimuth relative to the camera, degrees.
        utc_offset_hours: offset of a naive ``capture_time`` from UTC.
        original_elevation: the aligned sun's elevation in the camera's frame; needed with a
            tilt (the horizon's azimuth of a sun depends on its height in a tilted frame).
        tilt: the camera's ``(pitch, roll)`` in degrees.

    Returns:
        Heading in degrees clockwise from true north, in [0, 360).

    Raises:
        SunBelowHorizonError: the sun was below the horizon at ``capture_time`` (a camera
            clock or time zone that is wrong: a heading from that sun's azimuth would be made
            up; a user trial's night-time copy of the pool sample solved 135.7 degrees, its
            compass 163.7). Callers fall back on the compass for this error only.
        ValueError: an angle out of range, or a tilt without ``original_elevation``.
    """
    true_az, el = true_sun_position(capture_time, latitude, longitude, utc_offset_hours)
    if el <= 0:
        raise SunBelowHorizonError(
            f"the sun was {-el + 0.0:.1f}° below the horizon at the photo's EXIF time and place "
            "(check the camera's clock and time zone), so the camera heading cannot be solved "
            "from the aligned sun")
    azimuth = original_azimuth
    if any(tilt):
        if original_elevation is None:
            raise ValueError("expected the original sun's elevation with a camera tilt")
        azimuth, _ = sun_angles(sun_vector(original_azimuth, original_elevation), *tilt)
    return heading_from_sun(true_az, azimuth)


def default_utc_offset(longitude: float) -> float:
    """A guess of the local UTC offset from longitude (whole hours of mean solar time)."""
    return float(round(_check_angle("longitude", longitude, -180.0, 180.0) / 15.0))


def photo_utc_offset(exif: Any) -> float | None:
    """The photo's own UTC offset in hours (EXIF ``OffsetTime``, or derived from its GPS time
    stamp: ``tz_offset``), or None: the zone the app's time-lapse dialog and ``outcast
    timelapse`` read a day's local times at before the longitude's guess
    (:func:`default_utc_offset`)."""
    tz = getattr(exif, "tz_offset", None)
    return None if tz is None else tz.total_seconds() / 3600.0


def exif_capture_time(exif: Any) -> tuple[dt.datetime | None, bool]:
    """The photo's capture time as an aware datetime, and whether its time zone is a guess.

    A capture time with a zone (EXIF ``OffsetTimeOriginal``, or derived from the GPS time
    stamp) is returned as it is. A camera's bare wall-clock time is local time in an unknown
    zone: it is read at the zone of its longitude (:func:`default_utc_offset`), not as UTC as
    until 2026-12-03, which put the sun of a photo taken at longitude 100 seven hours off.
    Without a capture time, or a zone-less one without a longitude: ``(None, False)``.

    Example:
        >>> from outcast_core.runtime.io.exif import PhotoMetadata
        >>> m = PhotoMetadata(latitude=13.7, longitude=100.5,
        ...                   capture_time=dt.datetime(2026, 3, 1, 10, 0))
        >>> when, guessed = exif_capture_time(m)
        >>> str(when.utcoffset()), guessed
        ('7:00:00', True)
    """
    when = getattr(exif, "capture_time", None)
    if when is None or when.tzinfo is not None:
        return when, False
    lon = getattr(exif, "longitude", None)
    if lon is None:
        return None, False
    zone = dt.timezone(dt.timedelta(hours=default_utc_offset(lon)))
    return when.replace(tzinfo=zone), True


#: :func:`daylight_range`: the sun's geometric elevation (degrees) at sunrise and sunset, its
#: disc's upper edge on the horizon seen through the air's refraction (astral's convention).
SUNRISE_ELEVATION = -0.833
#: :func:`daylight_range`: the step (minutes) of its scan of the day, refined by bisection.
DAYLIGHT_SCAN_MINUTES = 10


def daylight_range(
    day: dt.date, latitude: float, longitude: float, utc_offset_hours: float | None = None
) -> tuple[dt.datetime, dt.datetime]:
    """Sunrise and sunset (aware datetimes at ``utc_offset_hours``) of a date and place: the
    stretch of sun above the horizon that covers most of the local day, from its sunrise (the
    day before's, in a zone far from the longitude's) to its sunset (the next day's, past
    midnight).

    Found by scanning the sun's elevation over the local day and half a day either side
    (:data:`DAYLIGHT_SCAN_MINUTES`; a night or a day shorter than that, on the eve of a polar
    day or night, can be missed) and bisecting each crossing of :data:`SUNRISE_ELEVATION`.
    astral's own sunrise and sunset failed on ordinary days where the local day straddles the
    UTC date (40 N, 80 E on 2021-04-17, a review), and its failure was then taken for a polar
    day.

    Raises:
        ValueError: when the sun does not rise or set that day (polar day: give a start and
            an end time; polar night: no daylight at all).

    Example:
        >>> rise, sset = daylight_range(dt.date(2021, 4, 17), 40.0, 80.0, 5.0)
        >>> f"{rise:%H:%M}", f"{sset:%H:%M}"
        ('04:59', '18:20')
    """
    import astral.sun

    if not FIRST_DAY <= day <= LAST_DAY:  # (the scan looks at the days either side)
        raise ValueError(f"expected a date from {FIRST_DAY} to {LAST_DAY}, got {day}")
    offset = default_utc_offset(longitude) if utc_offset_hours is None else float(utc_offset_hours)
    tz = dt.timezone(dt.timedelta(hours=offset))
    obs = _observer(latitude, longitude)
    start = dt.datetime.combine(day, dt.time(0), tzinfo=tz)

    def height(t: dt.datetime) -> float:  # above the sunrise elevation
        return float(astral.sun.elevation(obs, t, with_refraction=False)) - SUNRISE_ELEVATION

    step = dt.timedelta(minutes=DAYLIGHT_SCAN_MINUTES)
    per_day = 24 * 60 // DAYLIGHT_SCAN_MINUTES
    where = f"at {latitude:.3f}, {longitude:.3f} on {day.isoformat()}"

    def none(up: bool) -> ValueError:  # (a user trial followed "give a start and end time"
        # in a polar night and was told the sun was down all the time)
        return ValueError(
            f"expected a day with a sunrise and a sunset {where}, got none: the sun does not "
            + ("set that day (polar day); give a start and end time instead" if up else
               "rise that day (polar night), so there is no daylight to film; choose another "
               "date"))

    # Half a day either side of the local day (clipped at the calendar's ends): its daylight
    # is the stretch of sun above the horizon that covers most of it, with the sunrise before
    # and the sunset after it, even where one of them falls on the day before or after (a
    # zone far from the longitude's).
    lo, hi = -(per_day // 2), per_day + per_day // 2
    # (clipped where the time in UTC would leave the calendar: its first and last days)
    margin = dt.timedelta(hours=1)
    first_utc = dt.datetime.min.replace(tzinfo=dt.UTC) + margin
    last_utc = dt.datetime.max.replace(tzinfo=dt.UTC) - margin
    lo = max(lo, math.ceil((first_utc - start) / step))
    hi = min(hi, math.floor((last_utc - start) / step))
    cut = lo > -(per_day // 2) or hi < per_day + per_day // 2
    calendar_end = ValueError(f"expected a day with a sunrise and a sunset {where}, got a day "
                              "too near the calendar's end to look for them; give a start and "
                              "end time instead")
    if lo > 0 or hi < per_day:  # (not even the day itself)
        raise calendar_end
    times = [start + i * step for i in range(lo, hi + 1)]
    up = np.array([height(t) > 0.0 for t in times])
    day_part = up[-lo:-lo + per_day + 1]
    if day_part.all() or not day_part.any():
        raise none(bool(day_part[0]))
    runs = []  # (first, last) indices of each stretch of up samples
    i = 0
    while i < len(up):
        if up[i]:
            j = i
            while j + 1 < len(up) and up[j + 1]:
                j += 1
            runs.append((i, j))
            i = j + 1
        else:
            i += 1

    def overlap(run: tuple[int, int]) -> int:
        return max(0, min(run[1], -lo + per_day) - max(run[0], -lo) + 1)

    first, last = max(runs, key=overlap)
    if first == 0 or last == len(up) - 1:  # it rose or sets beyond what was scanned
        raise calendar_end if cut else none(True)

    def crossing(k: int) -> dt.datetime:  # between times[k] and times[k + 1]
        a, b = times[k], times[k + 1]
        rising = height(a) <= 0.0
        for _ in range(12):  # (10 min / 4096: well under a second)
            mid = a + (b - a) / 2
            if (height(mid) > 0.0) == rising:
                b = mid
            else:
                a = mid
        return a + (b - a) / 2

    return crossing(first - 1), crossing(last)


#: :func:`real_sun_path`'s first and last days (a day either side is looked at).
FIRST_DAY = dt.date.min + dt.timedelta(days=1)
LAST_DAY = dt.date.max - dt.timedelta(days=1)


def real_sun_path(
    day: dt.date,
    latitude: float,
    longitude: float,
    heading: float,
    frames: int,
    start: dt.time | None = None,
    end: dt.time | None = None,
    utc_offset_hours: float | None = None,
    tilt: tuple[float, float] = (0.0, 0.0),
) -> list[SunSample]:
    """The real sun over a day, relative to a camera facing ``heading``.

    Args:
        day: the date.
        latitude: degrees north.
        longitude: degrees east.
        heading: camera compass heading, degrees clockwise from true north.
        frames: number of frames (>= 2), evenly spaced in time.
        start: local start time; sunrise when None.
        end: local end time; sunset when None.
        utc_offset_hours: local time's offset from UTC; guessed from longitude when None.
        tilt: the camera's ``(pitch, roll)`` in degrees (:attr:`SunSample.tilt`).

    Returns:
        ``frames`` samples with ``time`` and ``true_azimuth`` set, at the horizon's angles.

    Raises:
        ValueError: among others, a day at the very end of the calendar (the first or last
            day Python dates have: sunrise and sunset are looked for a day either side).
    """
    frames = _check_frames(frames)
    if frames < 2:
        raise ValueError(f"expected at least 2 frames for a sun path, got {frames}")
    if not FIRST_DAY <= day <= LAST_DAY:  # (an OverflowError's traceback: a user trial)
        raise ValueError(f"expected a date from {FIRST_DAY} to {LAST_DAY}, got {day}")
    heading = _check_angle("heading", heading)
    tilt = (_check_angle("pitch", tilt[0], -90.0, 90.0), _check_angle("roll", tilt[1]))
    offset = default_utc_offset(longitude) if utc_offset_hours is None else float(utc_offset_hours)
    tz = dt.timezone(dt.timedelta(hours=offset))
    if start is None or end is None:
        rise, sset = daylight_range(day, latitude, longitude, offset)
    t0 = dt.datetime.combine(day, start, tzinfo=tz) if start is not None else rise
    t1 = dt.datetime.combine(day, end, tzinfo=tz) if end is not None else sset
    if t1 <= t0:
        raise ValueError(
            f"expected the end time after the start time, got {t0:%H:%M} -> {t1:%H:%M}"
        )
    samples = []
    for i in range(frames):
        when = t0 + (t1 - t0) * (i / (frames - 1))
        true_az, el = true_sun_position(when, latitude, longitude)
        samples.append(SunSample(relative_azimuth(true_az, heading), el, when, true_az, tilt))
    return samples


def sun_vectors(
    samples: Sequence[SunSample], min_elevation: float = MIN_RENDER_ELEVATION
) -> list[np.ndarray]:
    """Camera-space unit sun vectors to render (each sample in its :attr:`SunSample.tilt`);
    elevations under ``min_elevation`` (above the horizon, for the real sun) are lifted."""
    return [sun_vector(s.azimuth, max(s.elevation, min_elevation), *s.tilt) for s in samples]


# --------------------------------------------------------------------------------------------
# Frame writers
# --------------------------------------------------------------------------------------------


def format_from_path(path: str | os.PathLike[str]) -> str:
    """Output format from a path: ``.mp4``/``.m4v``, ``.gif``, ``.webp``; no extension: PNG folder.

    Raises:
        ValueError: any other extension (``out.avi`` would otherwise become a folder of PNGs).
    """
    suffix = Path(path).suffix.lower()
    if not suffix:
        return "png"
    if suffix not in VIDEO_SUFFIXES:
        raise ValueError(
            f"expected a time-lapse output ending in {', '.join(VIDEO_SUFFIXES)} or a folder "
            f"name without an extension (PNG frames), got '{Path(path).name}'"
        )
    return VIDEO_SUFFIXES[suffix]


def to_uint8(frame: np.ndarray) -> np.ndarray:
    """An ``H x W x 3`` sRGB frame (float in [0, 1] or uint8) as contiguous uint8."""
    a = np.asarray(frame)
    if a.ndim != 3 or a.shape[2] not in (3, 4):
        raise ValueError(f"expected a frame of shape H x W x 3, got {a.shape}")
    a = a[..., :3]
    if a.dtype != np.uint8:
        a = np.clip(np.nan_to_num(a.astype(np.float32), nan=0.0) * 255.0 + 0.5, 0, 255)
        a = a.astype(np.uint8)
    return np.ascontiguousarray(a)


def _is_cancelled(cancel: CancelCheck | None) -> bool:
    if cancel is None:
        return False
    if hasattr(cancel, "is_set"):
        return bool(cancel.is_set())
    return bool(cancel())


def _follow_umask(path: Path, folder: bool = False) -> None:
    """Give a temp file (0600) or folder (0700) the mode a plain ``open`` would: 0666 / 0777 less
    the umask, like every other output (stills, depth maps)."""
    from outcast_core.runtime.io.imageio import _umask

    os.chmod(path, (0o777 if folder else 0o666) & ~_umask())


def _commit_file(tmp: Path, final: Path, force: bool) -> None:
    """Move a finished temp file into place; no-clobber unless ``force``."""
    _follow_umask(tmp)
    if force:
        os.replace(tmp, final)
        return
    try:
        os.link(tmp, final)  # atomic and fails if final exists
    except FileExistsError:
        tmp.unlink(missing_ok=True)
        raise FileExistsError(f"{final} already exists; choose another name or force") from None
    except OSError:  # file system without hard links
        if final.exists():
            tmp.unlink(missing_ok=True)
            raise FileExistsError(f"{final} already exists; choose another name or force") from None
        os.replace(tmp, final)
        return
    tmp.unlink(missing_ok=True)


class FrameWriter(ABC):
    """Base writer: collects frames into a temp name, :meth:`commit` moves it into place.

    Args:
        path: the final file (or folder for PNG sequences).
        fps: frames per second.
        force: overwrite an existing file.
    """

    def __init__(self, path: str | os.PathLike[str], fps: float = DEFAULT_FPS, force: bool = False):
        self.path = Path(path)
        if not (math.isfinite(fps) and MIN_FPS <= fps <= MAX_FPS):
            raise ValueError(f"expected fps in [{MIN_FPS:g}, {MAX_FPS:g}], got {fps}")
        self.fps = float(fps)
        self.force = bool(force)
        if self.path.exists() and not self.force:
            raise FileExistsError(f"{self.path} already exists; choose another name or force")
        if not self.path.parent.is_dir():
            raise FileNotFoundError(f"folder {self.path.parent} does not exist")
        self.frames_written = 0
        self._tmp: Path | None = None

    def _make_tmp_file(self) -> Path:
        fd, name = tempfile.mkstemp(
            prefix=f".{self.path.stem}.", suffix=".part" + self.path.suffix, dir=self.path.parent
        )
        os.close(fd)
        return Path(name)

    @abstractmethod
    def write(self, frame: np.ndarray) -> None:
        """Append one ``H x W x 3`` sRGB frame (float in [0, 1] or uint8)."""

    @abstractmethod
    def commit(self) -> Path:
        """Finish and move the output into place; returns the final path."""

    def abort(self) -> None:
        """Drop everything written so far."""
        if self._tmp is not None:
            if self._tmp.is_dir():
                shutil.rmtree(self._tmp, ignore_errors=True)
            else:
                self._tmp.unlink(missing_ok=True)
            self._tmp = None


class Mp4Writer(FrameWriter):
    """H.264 MP4 through PyAV; odd sizes are padded to even by edge replication, yuv420p."""

    def __init__(self, path, fps=DEFAULT_FPS, force=False, crf: int = 18):
        super().__init__(path, fps, force)
        self.crf = int(crf)
        self._container: Any = None
        self._stream: Any = None
        self._size: tuple[int, int] | None = None

    def write(self, frame: np.ndarray) -> None:
        import av

        img = to_uint8(frame)
        h, w = img.shape[:2]
        if self._container is None:
            self._tmp = self._make_tmp_file()
            self._size = (h, w)
            self._container = av.open(str(self._tmp), mode="w", format="mp4")
            rate = dt_fraction(self.fps)
            self._stream = self._container.add_stream(
                "libx264", rate=rate, options={"crf": str(self.crf), "preset": X264_PRESET}
            )
            self._stream.width = w + (w % 2)
            self._stream.height = h + (h % 2)
            self._stream.pix_fmt = "yuv420p"
        elif (h, w) != self._size:
            raise ValueError(f"expected every frame of size {self._size}, got {(h, w)}")
        if h % 2 or w % 2:
            img = np.pad(img, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")  # even H x W x 3
        vf = av.VideoFrame.from_ndarray(img, format="rgb24")
        for packet in self._stream.encode(vf):
            self._container.mux(packet)
        self.frames_written += 1

    def _close(self) -> None:
        if self._container is not None:
            try:
                for packet in self._stream.encode(None):
                    self._container.mux(packet)
            finally:
                self._container.close()
                self._container = None

    def commit(self) -> Path:
        if self._container is None:
            raise RuntimeError("no frames were written")
        self._close()
        if self._tmp is None:
            raise RuntimeError("the MP4 writer lost its temporary file")
        _commit_file(self._tmp, self.path, self.force)
        self._tmp = None
        return self.path

    def abort(self) -> None:
        if self._container is not None:
            with contextlib.suppress(Exception):  # a broken container; the file goes anyway
                self._container.close()
            self._container = None
        super().abort()


def dt_fraction(fps: float) -> Any:
    """Frame rate as a Fraction (PyAV wants a rational)."""
    from fractions import Fraction

    return Fraction(fps).limit_denominator(1001)


def frame_durations(frames: int, fps: float, tick_ms: int = 1, least_ms: int = 1) -> list[int]:
    """Each frame's display time in milliseconds, whole ``tick_ms`` each (GIF's delays are
    centiseconds: 10), at least ``least_ms``, so that frame ``i`` starts within half a tick of
    ``i / fps``: 12 fps as a GIF alternates 80 and 90 ms (all 80 ms played 12.5 fps, a user
    trial).

    Example:
        >>> frame_durations(6, 12.0, tick_ms=10)
        [80, 90, 80, 80, 90, 80]
    """
    if frames < 1:
        return []
    step = 1000.0 / float(fps)

    def at(i: int) -> int:
        return int(math.floor(i * step / tick_ms + 0.5)) * tick_ms

    return [max(least_ms, at(i + 1) - at(i)) for i in range(frames)]


#: GIF frame delays: centiseconds, and browsers play a delay under 2 cs as 10 cs, so a GIF
#: plays at most 50 fps (faster rates are written at 20 ms a frame).
GIF_TICK_MS = 10
GIF_LEAST_MS = 20


class _PillowAnimWriter(FrameWriter):
    """Animated GIF / WebP through Pillow (frames are kept in memory until commit)."""

    pil_format = ""
    tick_ms = 1
    least_ms = 1

    def __init__(self, path, fps=DEFAULT_FPS, force=False):
        super().__init__(path, fps, force)
        self._frames: list[Any] = []
        self._size: tuple[int, int] | None = None

    def _convert(self, img: np.ndarray) -> Any:
        from PIL import Image

        return Image.fromarray(img, "RGB")

    def write(self, frame: np.ndarray) -> None:
        img = to_uint8(frame)
        if self._size is None:
            self._size = img.shape[:2]
        elif img.shape[:2] != self._size:
            raise ValueError(f"expected every frame of size {self._size}, got {img.shape[:2]}")
        self._frames.append(self._convert(img))
        self.frames_written += 1

    def _save_kwargs(self) -> dict[str, Any]:
        return {}

    def commit(self) -> Path:
        if not self._frames:
            raise RuntimeError("no frames were written")
        self._tmp = self._make_tmp_file()
        duration = frame_durations(len(self._frames), self.fps, self.tick_ms, self.least_ms)
        self._frames[0].save(
            self._tmp,
            format=self.pil_format,
            save_all=True,
            append_images=self._frames[1:],
            duration=duration,
            loop=0,
            **self._save_kwargs(),
        )
        self._frames = []
        _commit_file(self._tmp, self.path, self.force)
        self._tmp = None
        return self.path

    def abort(self) -> None:
        self._frames = []
        super().abort()


class GifWriter(_PillowAnimWriter):
    pil_format = "GIF"
    tick_ms = GIF_TICK_MS
    least_ms = GIF_LEAST_MS

    def _convert(self, img: np.ndarray) -> Any:
        # An adaptive palette per frame; dithering keeps skies from banding.
        return super()._convert(img).quantize(colors=256, method=2, dither=1)

    def _save_kwargs(self) -> dict[str, Any]:
        return {"optimize": False, "disposal": 1}


class WebpWriter(_PillowAnimWriter):
    pil_format = "WEBP"

    def _save_kwargs(self) -> dict[str, Any]:
        return {"quality": 90, "method": 4}


#: The files of a PNG sequence (:class:`PngSequenceWriter`); a folder holding anything else is
#: never written into nor emptied.
FRAME_FILE = re.compile(r"frame_\d{4,}\.png")
#: Files a file manager leaves in a folder it showed; they neither block nor go.
DESKTOP_FILES = frozenset({".DS_Store", "Thumbs.db", "desktop.ini", ".directory"})
#: Prefix of the hidden folder a sequence is written to inside an existing output folder.
PART_PREFIX = ".outcast-part-"


def _is_frame(p: Path) -> bool:
    return bool(FRAME_FILE.fullmatch(p.name)) and p.is_file()


def _frame_files(folder: Path) -> list[Path]:
    return [p for p in folder.iterdir() if _is_frame(p)]


def frames_folder_problem(path: str | os.PathLike[str]) -> str | None:
    """Why an existing folder cannot receive a PNG sequence, or None when it can (it does not
    exist, is empty, or holds only earlier ``frame_NNNN.png`` files, which ``force`` replaces;
    a file manager's own files (:data:`DESKTOP_FILES`) are ignored and left).

    A folder with any other file or folder in it is refused even with ``force``: replacing the
    sequence must never delete what the user keeps there (``-o . --force`` once emptied the
    working folder)."""
    folder = Path(path)
    if not folder.is_dir():
        return None
    others = sorted(p.name for p in folder.iterdir()
                    if not _is_frame(p) and p.name not in DESKTOP_FILES
                    and not p.name.startswith(PART_PREFIX))
    if not others:
        return None
    listed = ", ".join(others[:3]) + (", ..." if len(others) > 3 else "")
    return (f"{folder} already holds other files ({listed}); a PNG sequence goes into a new or "
            "empty folder, or one holding only an earlier sequence's frame_*.png")


def _remove_dead_parts(folder: Path) -> None:
    """Remove the temp folders (:data:`PART_PREFIX`) that exports killed before they finished
    left in ``folder``: those whose process is gone."""
    for part in folder.glob(f"{PART_PREFIX}*"):
        pid = part.name[len(PART_PREFIX):].split("-", 1)[0]
        if not pid.isdigit() or int(pid) == os.getpid():
            continue
        try:
            os.kill(int(pid), 0)
        except ProcessLookupError:  # gone: its frames will never be moved in
            shutil.rmtree(part, ignore_errors=True)
        except OSError:  # alive (another user's): leave it
            pass


class PngSequenceWriter(FrameWriter):
    """A folder of ``frame_0001.png`` ... written to a temp folder and moved in when complete.

    A new folder is written as a hidden temp folder beside it and renamed. An existing folder
    may be empty or hold only an earlier sequence (replaced with ``force``); the frames are then
    written to a hidden temp folder inside it (the same file system, so the moves cannot fail
    half-way for a mount point or a link to another disk), moved in, and only then are the
    earlier sequence's surplus ``frame_*.png`` removed: nothing else in the folder is touched
    (:func:`frames_folder_problem` refuses a folder with other files)."""

    def __init__(self, path, fps=DEFAULT_FPS, force=False):
        path = Path(path).absolute()  # "." has no name for the temp folder
        problem = frames_folder_problem(path)
        if problem:
            raise FileExistsError(problem)
        # An existing folder is checked here and again at commit (frames, not its existence).
        super().__init__(path, fps=fps, force=force or path.is_dir())
        self.force = bool(force)
        if path.is_dir() and _frame_files(path) and not self.force:
            raise FileExistsError(f"{path} already holds a sequence; choose another name or force")

    def write(self, frame: np.ndarray) -> None:
        from PIL import Image

        img = to_uint8(frame)
        if self._tmp is None:
            if self.path.is_dir():  # the process id tells a killed export's leftovers
                self._tmp = Path(tempfile.mkdtemp(prefix=f"{PART_PREFIX}{os.getpid()}-",
                                                  dir=self.path))
            else:
                self._tmp = Path(tempfile.mkdtemp(prefix=f".{self.path.name}.part-",
                                                  dir=self.path.parent))
        Image.fromarray(img, "RGB").save(self._tmp / f"frame_{self.frames_written + 1:04d}.png")
        self.frames_written += 1

    def commit(self) -> Path:
        if self._tmp is None:
            raise RuntimeError("no frames were written")
        inside = self._tmp.parent == self.path
        if not inside and self.path.exists():
            if self.path.is_dir() or not self.force:  # appeared meanwhile, or a file
                self.abort()
                raise FileExistsError(f"{self.path} already exists; choose another name or "
                                      "force")
            self.path.unlink()  # a file where the folder goes, with force
        if not inside:
            _follow_umask(self._tmp, folder=True)
            os.rename(self._tmp, self.path)
            self._tmp = None
            return self.path
        problem = frames_folder_problem(self.path)  # files may have appeared meanwhile
        old = _frame_files(self.path)
        if problem or (old and not self.force):
            self.abort()
            raise FileExistsError(problem or f"{self.path} already holds a sequence; choose "
                                  "another name or force")
        _remove_dead_parts(self.path)
        new = sorted(self._tmp.iterdir())
        for f in new:  # the same file system: renames, each replacing its namesake
            _follow_umask(f)
            os.replace(f, self.path / f.name)
        names = {f.name for f in new}
        for f in old:
            if f.name not in names:
                f.unlink(missing_ok=True)
        self._tmp.rmdir()
        self._tmp = None
        return self.path


WRITERS: dict[str, type[FrameWriter]] = {
    "mp4": Mp4Writer,
    "gif": GifWriter,
    "webp": WebpWriter,
    "png": PngSequenceWriter,
}


def export_frames(
    render_frame: Callable[[int], np.ndarray],
    n_frames: int,
    path: str | os.PathLike[str],
    *,
    fps: float = DEFAULT_FPS,
    fmt: str | None = None,
    force: bool = False,
    progress: ProgressFn | None = None,
    cancel: CancelCheck | None = None,
) -> Path:
    """Render and write ``n_frames`` frames; all or nothing.

    Frames are rendered in this thread, in order, and encoded in a second one (write-behind,
    at most :data:`WRITE_AHEAD` frames waiting), so encoding frame ``i`` overlaps rendering
    frame ``i + 1``.

    Args:
        render_frame: ``i -> H x W x 3`` sRGB frame (float in [0, 1] or uint8), called for
            ``i = 0, 1, ...`` in order.
        n_frames: number of frames (>= 1).
        path: output file (``.mp4``, ``.gif``, ``.webp``) or folder (PNG sequence).
        fps: frames per second.
        fmt: one of :data:`FORMATS`; from the path's extension when None.
        force: overwrite an existing output.
        progress: called with ``("timelapse", fraction)`` after every frame.
        cancel: a callable returning True (or a ``threading.Event``) to stop; checked per frame.

    Returns:
        The written path.

    Raises:
        ExportCancelledError: when cancelled (nothing is left on disk).
        FileExistsError: the output exists and ``force`` is False.
    """
    n_frames = _check_frames(n_frames)
    fmt = format_from_path(path) if fmt is None else fmt
    if fmt not in WRITERS:
        raise ValueError(f"expected a format in {FORMATS}, got {fmt!r}")
    writer = WRITERS[fmt](path, fps=fps, force=force)
    behind = _WriteBehind(writer)
    try:
        for i in range(n_frames):
            if _is_cancelled(cancel):
                raise ExportCancelledError(f"export of {path} cancelled after {i} frames")
            behind.put(render_frame(i))
            if progress is not None:
                progress("timelapse", (i + 1) / n_frames)
        behind.finish()
        if _is_cancelled(cancel):
            raise ExportCancelledError(f"export of {path} cancelled")
        return writer.commit()
    except BaseException:
        behind.stop()
        writer.abort()
        raise


#: Frames a time-lapse's encoder thread may have waiting.
WRITE_AHEAD = 2


class _WriteBehind:
    """A thread that feeds frames to a :class:`FrameWriter` in order; its errors come back to
    the caller at the next :meth:`put` or at :meth:`finish`."""

    _DONE = object()

    def __init__(self, writer: FrameWriter) -> None:
        import queue
        import threading

        self.writer = writer
        self._queue: queue.Queue = queue.Queue(maxsize=WRITE_AHEAD)
        self._error: BaseException | None = None
        self._stopped = False
        self._thread = threading.Thread(target=self._run, name="outcast-encode", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while True:
            frame = self._queue.get()
            if frame is self._DONE:
                return
            if self._error is not None or self._stopped:
                continue  # drain: the caller is told at its next call
            try:
                self.writer.write(frame)
            except BaseException as exc:  # handed to the caller's thread
                self._error = exc

    def _raise(self) -> None:
        if self._error is not None:
            raise self._error

    def put(self, frame: np.ndarray) -> None:
        self._raise()
        self._queue.put(frame)

    def finish(self) -> None:
        """Wait until every frame is written; raise the encoder's error if it had one."""
        self._queue.put(self._DONE)
        self._thread.join()
        self._raise()

    def stop(self) -> None:
        """Drop what is waiting and end the thread (after an error or a cancel)."""
        self._stopped = True
        if self._thread.is_alive():
            self._queue.put(self._DONE)
            self._thread.join()


def frame_shape(
    size: str, photo_shape: tuple[int, int], working_shape: tuple[int, int]
) -> tuple[int, int]:
    """``(H, W)`` of a time-lapse's frames for one of :data:`FRAME_SIZES`.

    Args:
        size: ``"working"``, ``"720p"``, ``"1080p"``, ``"4k"`` or ``"full"``.
        photo_shape: the photo's ``(H, W)``.
        working_shape: the session's working ``(H, W)``.

    Returns:
        The frame size; video sizes keep the photo's aspect ratio, with the shorter side 720,
        1080 or 2160 (even numbers, for H.264), and are never larger than the photo.

    Example:
        >>> frame_shape("1080p", (3000, 4000), (288, 384))
        (1080, 1440)
    """
    if size not in FRAME_SIZES:
        raise ValueError(f"expected a frame size in {FRAME_SIZES}, got {size!r}")
    h, w = photo_shape
    if size == "working":
        return tuple(working_shape)  # type: ignore[return-value]
    if size == "full" or SHORT_SIDES[size] >= min(h, w):
        return h, w
    scale = SHORT_SIDES[size] / min(h, w)
    return max(2, 2 * round(h * scale / 2)), max(2, 2 * round(w * scale / 2))


def describe_seconds(seconds: float) -> str:
    """``"about 40 s"``, ``"about 3 min"``, ``"about 1 h 5 min"``."""
    if seconds < 60:
        return f"about {max(1, round(seconds))} s"
    minutes = round(seconds / 60)
    if minutes < 60:
        return f"about {minutes} min"
    return f"about {minutes // 60} h {minutes % 60} min"


def _frame_maker(session: Any, size: str) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """``(working-size relit frame, its sun) -> frame at size`` (uint8 above the working
    size): moved onto the photo at the frame's size (its detail kept) with the banded 8-bit
    transfer, the photo resized to that size once, and a sun the photo shows taken out there
    too when the frame's sun leaves the frame (as a relit still)."""
    from outcast_core.runtime.pipeline.relight import transfer_to_full_resolution
    from outcast_core.runtime.pipeline.session import resize

    full = session.full_image_srgb
    work = session.image_srgb
    shape = frame_shape(size, full.shape[:2], work.shape[:2])
    if size == "working" or shape == work.shape[:2]:
        return lambda relit, _sun: relit
    if shape[0] * shape[1] <= work.shape[0] * work.shape[1]:
        return lambda relit, _sun: resize(relit, shape)
    photo = full if shape == full.shape[:2] else resize(full, shape)  # once, uint8 if 8-bit
    sky = session.sky
    marked = session.relight_fills()  # a marked crushed shadow: filled, as in stills

    def make(relit: np.ndarray, sun: np.ndarray) -> np.ndarray:
        out = transfer_to_full_resolution(photo, work, relit, out_dtype=np.uint8, sky=sky,
                                          fills=marked)
        return session.without_old_sun_full(out, relit, sun)

    return make


def render_timelapse(
    session: Any,
    samples: Sequence[SunSample],
    path: str | os.PathLike[str],
    *,
    fps: float = DEFAULT_FPS,
    full_resolution: bool = False,
    size: str | None = None,
    fmt: str | None = None,
    force: bool = False,
    progress: ProgressFn | None = None,
    cancel: CancelCheck | None = None,
    exposure: str | None = None,
) -> Path:
    """Relight ``session``'s photo along a sun path and write the frames.

    Args:
        session: a :class:`~outcast_core.runtime.pipeline.session.RelightSession` with the original
        sun set.
        samples: the sun path.
        path: output file or folder.
        fps: frames per second.
        full_resolution: the same as ``size="full"`` (kept for callers of earlier versions).
        size: one of :data:`FRAME_SIZES` (see :func:`frame_shape`); default ``"working"``, or
            ``"full"`` with ``full_resolution``.
        fmt: output format; from the extension when None.
        force: overwrite an existing output.
        progress: ``(stage, fraction)`` callback.
        cancel: cancel check.
        exposure: the frames' exposure (``RelightSession.relight``'s; default the session's).

    Returns:
        The written path.
    """
    if not samples:
        raise ValueError("expected at least one sun sample, got none")
    if getattr(session, "original_sun", None) is None:
        raise RuntimeError("set the original sun before rendering a time-lapse")
    if size is None:
        size = "full" if full_resolution else "working"
    suns = sun_vectors(samples)
    # Two stages at once (the next sun's shadow while this one is relit), and each frame made
    # at its own size from the working-size result (never via full resolution).
    to_frame = _frame_maker(session, size)
    stream = session.relight_stream(suns, exposure=exposure)

    def render_frame(i: int) -> np.ndarray:
        return to_frame(next(stream), suns[i])

    try:
        return export_frames(
            render_frame,
            len(suns),
            path,
            fps=fps,
            fmt=fmt,
            force=force,
            progress=progress,
            cancel=cancel,
        )
    finally:
        stream.close()  # a cancelled export: the shadow thread ends here
