"""Photo metadata from EXIF: focal length, GPS position, capture time, camera heading.

Only what OutCast needs to place the sun is read: the focal length (field of view), the GPS
position and the capture time (sun position), and the camera heading (sun azimuth relative to the
view). Everything is optional: a missing, blank or malformed tag gives ``None``, never an error.

Capture time, in order of preference:

1. ``DateTimeOriginal`` (or ``DateTimeDigitized``, or ``DateTime``) with its explicit EXIF 2.31
   offset (``OffsetTimeOriginal`` / ``OffsetTimeDigitized`` / ``OffsetTime``): an aware datetime
   in that offset.
2. ``GPSDateStamp`` + ``GPSTimeStamp``, which are UTC by definition: an aware datetime in UTC.
3. The camera's wall-clock time alone: a naive datetime (local time, zone unknown).

When there is no explicit offset but both the wall-clock time and the GPS stamp are present, the
time-zone offset is derived from their difference, rounded to 15 minutes (``tz_offset_source ==
"gps"``), provided the difference is within 14 hours and 5 minutes of a 15-minute step.

Example:
    >>> from PIL import Image
    >>> with Image.open("samples/exif_001_cz_fieldpath.jpg") as im:
    ...     meta = metadata_from_exif(im.getexif())
    >>> round(meta.latitude, 4), meta.capture_time.isoformat()
    (50.2996, '2018-07-25T16:34:23+02:00')
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta, timezone
from typing import Any

# Base IFD tags.
TAG_MAKE = 0x010F
TAG_MODEL = 0x0110
TAG_ORIENTATION = 0x0112
TAG_DATETIME = 0x0132
TAG_EXIF_IFD = 0x8769
TAG_GPS_IFD = 0x8825
# Exif IFD tags.
TAG_DATETIME_ORIGINAL = 0x9003
TAG_DATETIME_DIGITIZED = 0x9004
TAG_OFFSET_TIME = 0x9010
TAG_OFFSET_TIME_ORIGINAL = 0x9011
TAG_OFFSET_TIME_DIGITIZED = 0x9012
TAG_SUBSEC_TIME = 0x9290
TAG_SUBSEC_TIME_ORIGINAL = 0x9291
TAG_SUBSEC_TIME_DIGITIZED = 0x9292
TAG_FOCAL_LENGTH = 0x920A
TAG_FOCAL_35MM = 0xA405
# GPS IFD tags.
GPS_LATITUDE_REF = 0x01
GPS_LATITUDE = 0x02
GPS_LONGITUDE_REF = 0x03
GPS_LONGITUDE = 0x04
GPS_ALTITUDE_REF = 0x05
GPS_ALTITUDE = 0x06
GPS_TIMESTAMP = 0x07
GPS_STATUS = 0x09
GPS_IMG_DIRECTION_REF = 0x10
GPS_IMG_DIRECTION = 0x11
GPS_DATESTAMP = 0x1D

_MAX_TZ = timedelta(hours=14)
_TZ_STEP = timedelta(minutes=15)
_TZ_TOLERANCE = timedelta(minutes=5)
_DATETIME_RE = re.compile(
    r"^\s*(\d{4})[:\-](\d{1,2})[:\-](\d{1,2})[ T](\d{1,2}):(\d{1,2}):(\d{1,2})(?:\.(\d+))?"
)
_DATE_RE = re.compile(r"^\s*(\d{4})[:\-](\d{1,2})[:\-](\d{1,2})")
_OFFSET_RE = re.compile(r"^\s*([+-])(\d{1,2}):?(\d{2})\s*$")


@dataclass(frozen=True)
class PhotoMetadata:
    """What OutCast uses from a photo's EXIF. Every field is ``None`` when unknown.

    Attributes:
        make: camera maker, stripped.
        model: camera model, stripped.
        focal_mm: real focal length in millimetres (``FocalLength``).
        focal_35mm: 35 mm equivalent focal length (``FocalLengthIn35mmFilm``; 0 means unknown).
        latitude: degrees, north positive.
        longitude: degrees, east positive.
        altitude_m: metres above sea level (negative below).
        capture_time: when the photo was taken; aware when the zone is known (see module doc),
            naive local wall-clock time otherwise.
        capture_time_source: ``"exif_offset"``, ``"gps"`` or ``"local"``: which clock gave
            ``capture_time``.
        local_time: the camera's naive wall-clock time, as recorded.
        tz_offset: the photo's UTC offset, from EXIF or derived from the GPS stamp.
        tz_offset_source: ``"exif"`` or ``"gps"``.
        heading_deg: camera heading (``GPSImgDirection``) in degrees clockwise from north.
        heading_ref: ``"T"`` (true north) or ``"M"`` (magnetic north).
        orientation: the raw EXIF orientation tag (1..8; 1 when absent). Readers in
            :mod:`imageio` have already applied it to the pixels.
    """

    make: str | None = None
    model: str | None = None
    focal_mm: float | None = None
    focal_35mm: float | None = None
    latitude: float | None = None
    longitude: float | None = None
    altitude_m: float | None = None
    capture_time: datetime | None = None
    capture_time_source: str | None = None
    local_time: datetime | None = None
    tz_offset: timedelta | None = None
    tz_offset_source: str | None = None
    heading_deg: float | None = None
    heading_ref: str | None = None
    orientation: int = 1

    @property
    def has_gps(self) -> bool:
        """True when both latitude and longitude are known."""
        return self.latitude is not None and self.longitude is not None

    @property
    def capture_time_utc(self) -> datetime | None:
        """``capture_time`` converted to UTC, or ``None`` when it is unknown or naive."""
        if self.capture_time is None or self.capture_time.tzinfo is None:
            return None
        return self.capture_time.astimezone(UTC)


def metadata_from_exif(exif: Mapping[int, Any] | None) -> PhotoMetadata:
    """Parse the metadata OutCast needs from a Pillow ``Image.Exif``.

    Args:
        exif: the result of ``PIL.Image.Image.getexif()`` (a plain mapping of the base IFD also
            works; sub-IFDs are then read from nested mappings, if any), or ``None``.

    Returns:
        A :class:`PhotoMetadata`; fields whose tags are missing or malformed are ``None``.
    """
    if exif is None:
        return PhotoMetadata()
    base = exif
    exif_ifd = _sub_ifd(exif, TAG_EXIF_IFD)
    gps = _sub_ifd(exif, TAG_GPS_IFD)

    orientation = _to_int(base.get(TAG_ORIENTATION))
    if orientation is None or not 1 <= orientation <= 8:
        orientation = 1

    focal_mm = _positive(_to_float(exif_ifd.get(TAG_FOCAL_LENGTH)))
    focal_35mm = _positive(_to_float(exif_ifd.get(TAG_FOCAL_35MM)))

    latitude, longitude = _gps_position(gps)
    altitude = _to_float(gps.get(GPS_ALTITUDE))
    if altitude is not None and _to_str(gps.get(GPS_ALTITUDE_REF)) in ("1", "\x01"):
        altitude = -altitude

    heading = _to_float(gps.get(GPS_IMG_DIRECTION))
    heading_ref = _to_str(gps.get(GPS_IMG_DIRECTION_REF))
    if heading is not None and 0.0 <= heading <= 360.0:
        heading = heading % 360.0
        heading_ref = heading_ref.upper() if heading_ref and heading_ref.upper() in "TM" else None
    else:
        heading, heading_ref = None, None

    local_time, offset = _local_time_and_offset(base, exif_ifd)
    gps_time = _gps_time(gps)

    tz_offset, tz_source = (offset, "exif") if offset is not None else (None, None)
    if tz_offset is None and local_time is not None and gps_time is not None:
        tz_offset = _derive_offset(local_time, gps_time)
        tz_source = "gps" if tz_offset is not None else None

    if local_time is not None and offset is not None:
        capture_time, source = local_time.replace(tzinfo=timezone(offset)), "exif_offset"
    elif gps_time is not None:
        capture_time, source = gps_time, "gps"
        if tz_offset is not None:
            capture_time = capture_time.astimezone(timezone(tz_offset))
    elif local_time is not None:
        capture_time, source = local_time, "local"
    else:
        capture_time, source = None, None

    return PhotoMetadata(
        make=_clean_text(base.get(TAG_MAKE)),
        model=_clean_text(base.get(TAG_MODEL)),
        focal_mm=focal_mm,
        focal_35mm=focal_35mm,
        latitude=latitude,
        longitude=longitude,
        altitude_m=altitude,
        capture_time=capture_time,
        capture_time_source=source,
        local_time=local_time,
        tz_offset=tz_offset,
        tz_offset_source=tz_source,
        heading_deg=heading,
        heading_ref=heading_ref,
        orientation=orientation,
    )


# --------------------------------------------------------------------------------------------
# Helpers (all total: malformed input gives None).


def _sub_ifd(exif: Mapping[int, Any], tag: int) -> Mapping[int, Any]:
    get_ifd = getattr(exif, "get_ifd", None)
    if get_ifd is not None:
        try:
            ifd = get_ifd(tag)
        except Exception:  # a corrupt sub-IFD must not break reading the pixels
            return {}
        return ifd if isinstance(ifd, Mapping) else {}
    value = exif.get(tag)
    return value if isinstance(value, Mapping) else {}


def _to_float(value: Any) -> float | None:
    """A finite float from an EXIF number, rational, 1-tuple or numeric string."""
    if value is None:
        return None
    if isinstance(value, tuple | list):
        if len(value) == 2 and all(isinstance(v, int) for v in value):
            num, den = value
            return None if den == 0 else _finite(num / den)
        if len(value) == 1:
            return _to_float(value[0])
        return None
    if isinstance(value, bytes):
        value = value.decode("ascii", errors="ignore")
    if isinstance(value, str):
        value = value.strip("\x00 ")
    try:
        return _finite(float(value))
    except (TypeError, ValueError, ZeroDivisionError, OverflowError):
        return None


def _finite(x: float) -> float | None:
    return x if math.isfinite(x) else None


def _positive(x: float | None) -> float | None:
    return x if x is not None and x > 0 else None


def _to_int(value: Any) -> int | None:
    x = _to_float(value)
    return None if x is None else int(round(x))


def _to_str(value: Any) -> str | None:
    if value is None:
        return None
    if isinstance(value, bytes):
        if len(value) == 1 and value[0] < 32:  # e.g. GPSAltitudeRef stored as a BYTE
            return str(value[0])
        value = value.decode("utf-8", errors="ignore")
    if isinstance(value, int):
        return str(value)
    if not isinstance(value, str):
        return None
    return value.strip("\x00 ") or None


def _clean_text(value: Any) -> str | None:
    text = _to_str(value)
    return " ".join(text.split()) if text else None


def _dms(value: Any) -> float | None:
    """Degrees from an EXIF (degrees, minutes, seconds) triple (or a single value)."""
    if isinstance(value, tuple | list) and len(value) == 3:
        parts = [_to_float(v) for v in value]
        if any(p is None or p < 0 for p in parts):
            return None
        d, m, s = parts
        return d + m / 60.0 + s / 3600.0
    return _to_float(value)


def _gps_position(gps: Mapping[int, Any]) -> tuple[float | None, float | None]:
    if (_to_str(gps.get(GPS_STATUS)) or "A").upper() == "V":  # "V": measurement void
        return None, None
    lat = _dms(gps.get(GPS_LATITUDE))
    lon = _dms(gps.get(GPS_LONGITUDE))
    if lat is None or lon is None:
        return None, None
    lat_ref = (_to_str(gps.get(GPS_LATITUDE_REF)) or "N").upper()
    lon_ref = (_to_str(gps.get(GPS_LONGITUDE_REF)) or "E").upper()
    if lat_ref.startswith("S"):
        lat = -abs(lat)
    if lon_ref.startswith("W"):
        lon = -abs(lon)
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
        return None, None
    if lat == 0.0 and lon == 0.0:  # cameras without a fix write zeros; nobody shoots at 0N 0E
        return None, None
    return lat, lon


def _parse_datetime(text: Any, subsec: Any = None) -> datetime | None:
    text = _to_str(text)
    if not text:
        return None
    match = _DATETIME_RE.match(text)
    if match is None:
        return None
    year, month, day, hour, minute, second = (int(g) for g in match.groups()[:6])
    frac = match.group(7) or _digits(_to_str(subsec))
    micro = int((frac + "000000")[:6]) if frac else 0
    try:
        return datetime(year, month, day, hour, minute, min(second, 59), micro)
    except ValueError:  # 0000:00:00 and friends
        return None


def _digits(text: str | None) -> str | None:
    if not text:
        return None
    text = text.strip()
    return text if text.isdigit() else None


def _parse_offset(value: Any) -> timedelta | None:
    text = _to_str(value)
    match = _OFFSET_RE.match(text) if text else None
    if match is None:
        return None
    sign, hours, minutes = match.groups()
    offset = timedelta(hours=int(hours), minutes=int(minutes))
    if offset > _MAX_TZ or int(minutes) >= 60:
        return None
    return -offset if sign == "-" else offset


def _local_time_and_offset(
    base: Mapping[int, Any], exif_ifd: Mapping[int, Any]
) -> tuple[datetime | None, timedelta | None]:
    """The first readable wall-clock time and the offset recorded with that same time."""
    candidates = (
        (exif_ifd.get(TAG_DATETIME_ORIGINAL), exif_ifd.get(TAG_SUBSEC_TIME_ORIGINAL),
         exif_ifd.get(TAG_OFFSET_TIME_ORIGINAL)),
        (exif_ifd.get(TAG_DATETIME_DIGITIZED), exif_ifd.get(TAG_SUBSEC_TIME_DIGITIZED),
         exif_ifd.get(TAG_OFFSET_TIME_DIGITIZED)),
        (base.get(TAG_DATETIME), exif_ifd.get(TAG_SUBSEC_TIME), exif_ifd.get(TAG_OFFSET_TIME)),
    )
    for text, subsec, offset in candidates:
        when = _parse_datetime(text, subsec)
        if when is not None:
            return when, _parse_offset(offset)
    return None, None


def _gps_time(gps: Mapping[int, Any]) -> datetime | None:
    date_text = _to_str(gps.get(GPS_DATESTAMP))
    stamp = gps.get(GPS_TIMESTAMP)
    if not date_text or not isinstance(stamp, tuple | list) or len(stamp) != 3:
        return None
    match = _DATE_RE.match(date_text)
    parts = [_to_float(v) for v in stamp]
    if match is None or any(p is None or p < 0 for p in parts):
        return None
    hours, minutes, seconds = parts
    try:
        day = datetime(*(int(g) for g in match.groups()), tzinfo=UTC)
    except ValueError:
        return None
    if hours >= 24 or minutes >= 60 or seconds >= 61:
        return None
    return day + timedelta(hours=hours, minutes=minutes, seconds=seconds)


def _derive_offset(local_time: datetime, gps_time: datetime) -> timedelta | None:
    """The UTC offset implied by a naive wall-clock time and the GPS (UTC) time, or None."""
    diff = local_time - gps_time.replace(tzinfo=None)
    steps = round(diff / _TZ_STEP)
    offset = steps * _TZ_STEP
    if abs(offset) > _MAX_TZ or abs(diff - offset) > _TZ_TOLERANCE:
        return None
    return offset
