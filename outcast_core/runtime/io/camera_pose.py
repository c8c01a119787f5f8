"""The camera's pitch and roll from a photo's metadata, where it records them.

Find sun applies the EXIF elevation prior (the sun's true elevation above the horizon) in the
camera's frame, so it needs the camera's tilt. Some cameras write it:

* XMP ``GPano:PosePitchDegrees`` / ``GPano:PoseRollDegrees`` (Google's photo-sphere schema,
  written by some phones and stitchers);
* XMP ``drone-dji:GimbalPitchDegree`` / ``drone-dji:GimbalRollDegree`` (DJI drones: the
  camera's gimbal; 0 is level, -90 straight down);
* Exif ``CameraElevationAngle`` (tag 0x9405, Exif 2.31: the pitch only).

All use the convention of :func:`~outcast_core.runtime.geometry.camera.camera_rotation`: pitch > 0
tilts
the camera up, roll > 0 turns it clockwise as seen by the photographer (GPano: "as roll
increases, the horizon rotates counterclockwise in the image"; DJI: roll right). A pose for the
stored (not the upright) pixels is not turned: phones that rotate by the EXIF orientation record
the pose of the photo as shown.

:func:`read_camera_pose` reads the header only (no pixels); anything missing, malformed or out
of range gives ``None`` for that angle, never an error.

Example:
    >>> pose_from_xmp('<rdf:Description GPano:PosePitchDegrees="-12.5"/>')
    CameraPose(pitch=-12.5, roll=None, source='XMP GPano')
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from typing import Any

from outcast_core.runtime.io.exif import TAG_EXIF_IFD, _sub_ifd, _to_float

#: Exif ``CameraElevationAngle`` (Exif IFD).
TAG_CAMERA_ELEVATION_ANGLE = 0x9405
#: XMP properties, ``(namespace prefix, pitch name, roll name, source)``, in order of preference.
XMP_PROPERTIES: tuple[tuple[str, str, str, str], ...] = (
    ("drone-dji", "GimbalPitchDegree", "GimbalRollDegree", "XMP DJI gimbal"),
    ("GPano", "PosePitchDegrees", "PoseRollDegrees", "XMP GPano"),
)
#: How much XMP text is searched (an XMP packet is at most 64 KB in a JPEG segment; extended
#: XMP holds depth maps and thumbnails, not the pose).
MAX_XMP_CHARS = 1 << 20


@dataclass(frozen=True)
class CameraPose:
    """A camera's tilt from its metadata.

    Attributes:
        pitch: degrees, up positive, in [-90, 90]; None when not recorded.
        roll: degrees, clockwise positive, in [-180, 180]; None when not recorded.
        source: where it came from (``"XMP GPano"``, ``"XMP DJI gimbal"``,
            ``"Exif CameraElevationAngle"``).
    """

    pitch: float | None
    roll: float | None
    source: str

    def pitch_roll(self) -> tuple[float, float] | None:
        """``(pitch, roll)`` for :func:`~outcast_core.runtime.pipeline.auto_sun.find_sun`, or None
        without a pitch (a roll alone, rare, is not enough to place the horizon); a missing
        roll counts as level."""
        if self.pitch is None:
            return None
        return self.pitch, 0.0 if self.roll is None else self.roll


def _angle(value: Any, limit: float) -> float | None:
    """A finite angle within ``[-limit, limit]`` from an XMP text or an Exif number (rational,
    1-tuple, numeric string: :func:`~outcast_core.runtime.io.exif._to_float`), or None."""
    v = _to_float(value)
    return v if v is not None and abs(v) <= limit else None


def _xmp_value(xmp: str, prefix: str, name: str) -> str | None:
    """A simple XMP property as an attribute (``p:n="v"``) or an element (``<p:n>v</p:n>``).

    Found by its usual prefix, leniently, rather than with the XML reader of
    :mod:`~outcast_core.runtime.io.phone_depth` (``parse_xmp``): that one needs well-formed XML
    with the namespaces declared (it refuses the whole packet otherwise), while a pose in a
    packet without them is read here, as it always was.
    """
    q = re.escape(f"{prefix}:{name}")
    m = re.search(rf"{q}\s*=\s*([\"'])(.*?)\1", xmp, re.S)
    if m:
        return m.group(2)
    m = re.search(rf"<{q}>(.*?)</{q}>", xmp, re.S)
    return m.group(1) if m else None


def pose_from_xmp(xmp: str | bytes | None) -> CameraPose | None:
    """The camera pose in an XMP packet (see the module docstring), or None."""
    if not xmp:
        return None
    if isinstance(xmp, bytes | bytearray):
        xmp = bytes(xmp[:MAX_XMP_CHARS]).decode("utf-8", "replace")
    xmp = xmp[:MAX_XMP_CHARS]
    for prefix, pitch_name, roll_name, source in XMP_PROPERTIES:
        pitch = _angle(_xmp_value(xmp, prefix, pitch_name), 90.0)
        roll = _angle(_xmp_value(xmp, prefix, roll_name), 180.0)
        if pitch is not None or roll is not None:
            return CameraPose(pitch, roll, source)
    return None


def pose_from_exif(exif: Any) -> CameraPose | None:
    """The pitch in Exif ``CameraElevationAngle`` (a Pillow ``Image.Exif``), or None."""
    if exif is None:
        return None
    pitch = _angle(_sub_ifd(exif, TAG_EXIF_IFD).get(TAG_CAMERA_ELEVATION_ANGLE), 90.0)
    return None if pitch is None else CameraPose(pitch, None, "Exif CameraElevationAngle")


def _xmp_of(im: Any) -> str | bytes | None:
    info = getattr(im, "info", {}) or {}
    for key in ("xmp", "XML:com.adobe.xmp"):
        if info.get(key):
            return info[key]
    tags = getattr(im, "tag_v2", None)  # TIFF: tag 700
    if tags is not None and tags.get(700):
        return tags.get(700)
    return None


def read_camera_pose(path: str | os.PathLike[str]) -> CameraPose | None:
    """The camera pose a photo file records (XMP first, then Exif), or None.

    Never raises for a missing or unreadable file or malformed metadata (the photo itself is
    read, with its errors, by :func:`~outcast_core.runtime.io.imageio.read_image`).
    """
    from outcast_core.runtime.io.imageio import open_pil

    try:
        with open_pil(path) as im:
            pose = pose_from_xmp(_xmp_of(im))
            if pose is not None and pose.pitch is not None:
                return pose
            exif_pose = pose_from_exif(im.getexif()) if im.format != "PNG" else None
    except Exception:  # noqa: BLE001 - any reader error: no pose, the load reports the rest
        return None
    return exif_pose or pose


__all__ = ["CameraPose", "pose_from_exif", "pose_from_xmp", "read_camera_pose"]
