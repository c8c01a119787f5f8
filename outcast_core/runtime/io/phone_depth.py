"""Depth maps that phones store inside photos: Google's GDepth XMP and Dynamic Depth (JPEG) and
HEIF depth images.

Three containers are read, each to its published field definitions:

* **JPEG with GDepth XMP** (Google's depth map metadata, namespace
  ``http://ns.google.com/photos/1.0/depthmap/``): ``GDepth:Format`` (``RangeInverse`` or
  ``RangeLinear``), ``GDepth:Near`` and ``GDepth:Far`` (in ``GDepth:Units``, default metres),
  ``GDepth:Mime`` (``image/jpeg`` or ``image/png``) and ``GDepth:Data``, the base64 depth image;
  ``GDepth:MeasureType`` says whether a value is the depth along the optical axis
  (``OpticalAxis``, the default: our z depth) or along the pixel's ray (``OpticRay``). The data
  is usually too large for the 64 KB XMP segment and sits in the *extended* XMP: further APP1
  segments (``http://ns.adobe.com/xmp/extension/``, a 32-character GUID, the full length and
  this chunk's offset) that are joined by offset. A grey value ``v`` of ``b`` bits gives
  ``d_n = v / (2^b - 1)``, and

  * ``RangeLinear``: ``d = d_n (far - near) + near``;
  * ``RangeInverse``: ``d = far near / (far - d_n (far - near))`` (``d_n = 0`` is ``near``,
    ``1`` is ``far``).

  The map is stored like the photo's pixels (before the EXIF orientation) and is "stretched to
  fit" the photo, so it is turned upright with the photo's EXIF orientation and may have
  another size than the photo (never another aspect ratio beyond a few percent).
* **JPEG with Dynamic Depth** (Google's newer container; namespaces
  ``http://ns.google.com/photos/dd/1.0/...``): a ``DepthMap`` element with the same ``Format``,
  ``Near``, ``Far``, ``Units`` and ``MeasureType`` fields and a ``DepthURI`` naming an item of the
  ``Device:Container`` directory; the items (``Item:Mime``, ``Item:Length``, ``Item:Padding``)
  are files appended after the photo, in order (:func:`dynamic_depth`).
* **HEIF/HEIC depth images** (iPhone portrait photos), read with pillow-heif: the primary
  image's ``info["depth_images"]``, each with libheif's depth representation info in
  ``info["metadata"]``: ``representation_type`` (0 uniform inverse Z, 1 uniform disparity,
  2 uniform Z, 3 non-uniform disparity) with ``z_near`` / ``z_far`` or ``d_min`` / ``d_max``.
  A value ``v`` maps linearly onto ``[d_min, d_max]`` (disparity), ``[1 / z_far, 1 / z_near]``
  (inverse Z) or ``[z_near, z_far]`` (Z). Disparity becomes depth as ``1 / disparity``: Apple
  writes disparity in 1/m, so this is metres; without ``d_min`` / ``d_max`` the map is
  relative (``v`` taken as disparity up to scale). libheif has already turned the primary image
  upright; a depth map stored sideways is turned the same way when the EXIF orientation says
  so, and refused when it still does not match.

:func:`read_phone_depth` reads either; it returns None for a photo without an embedded map and
raises :class:`PhoneDepthError` (a ``ValueError``) with a one-line reason for a map that is
there but malformed or does not match the photo, so callers can say so and fall back to the
depth model.
"""

from __future__ import annotations

import base64
import binascii
import io
import math
import os
import struct
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from PIL import Image

from outcast_core.runtime.geometry.camera import Camera

#: XML namespace of Google's depth map XMP properties.
GDEPTH_NS = "http://ns.google.com/photos/1.0/depthmap/"
#: Namespace of the XMP note that names the extended XMP's GUID.
XMP_NOTE_NS = "http://ns.adobe.com/xmp/note/"
#: APP1 signatures of the standard and the extended XMP segments.
XMP_SIGNATURE = b"http://ns.adobe.com/xap/1.0/\x00"
XMP_EXT_SIGNATURE = b"http://ns.adobe.com/xmp/extension/\x00"
#: Largest extended XMP we join (phones write a few MB).
MAX_EXTENDED_XMP = 64 * 1024 * 1024
#: Largest side of an embedded depth map we decode.
MAX_MAP_SIDE = 8192
#: Relative aspect-ratio difference (width / height) tolerated between map and photo.
ASPECT_TOLERANCE = 0.03
#: Unit names (GDepth:Units) -> metres per unit.
UNITS_TO_METRES = {"m": 1.0, "meters": 1.0, "metres": 1.0, "mm": 1e-3, "millimeters": 1e-3,
                   "cm": 1e-2, "centimeters": 1e-2}
#: Dynamic Depth namespaces (a depth map appended after the photo in a container).
DD_DEPTHMAP_NS = "http://ns.google.com/photos/dd/1.0/depthmap/"
DD_CONTAINER_NS = "http://ns.google.com/photos/dd/1.0/container/"
DD_ITEM_NS = "http://ns.google.com/photos/dd/1.0/item/"
#: libheif's depth representation types.
HEIF_INVERSE_Z, HEIF_DISPARITY, HEIF_Z, HEIF_NONUNIFORM_DISPARITY = 0, 1, 2, 3


class PhoneDepthError(ValueError):
    """An embedded depth map is there but cannot be used; the message says why, in one line."""


@dataclass(frozen=True)
class PhoneDepth:
    """A depth map read from a photo's own metadata.

    Attributes:
        depth: ``h x w`` float32 z depth (along the optical axis), upright, finite and > 0, at
            the map's own size (the photo's aspect ratio).
        container: where it came from: ``"GDepth RangeInverse"``, ``"HEIF disparity"``, ...
        metric: True when the values are in metres, False when only relative.
        measure: ``"axis"`` (z depth) or ``"ray"`` (distance along the ray; see
            :func:`ray_to_axis`; :attr:`depth` is then still the range until converted).
    """

    depth: np.ndarray
    container: str
    metric: bool
    measure: str = "axis"


# --------------------------------------------------------------------------------------------
# Plain conversions


def gdepth_to_depth(normalised: np.ndarray, fmt: str, near: float, far: float) -> np.ndarray:
    """Google's normalised depth ``d_n`` in ``[0, 1]`` -> depth in the map's units.

    Args:
        normalised: ``H x W`` ``d_n`` (grey value over its maximum).
        fmt: ``"RangeInverse"`` or ``"RangeLinear"``.
        near: ``GDepth:Near``, > 0.
        far: ``GDepth:Far``, > ``near``.

    Returns:
        ``H x W`` float32 depth.

    Example:
        >>> float(gdepth_to_depth(np.array([[1.0]]), "RangeInverse", 1.0, 10.0)[0, 0])
        10.0
    """
    near, far = float(near), float(far)
    if not (math.isfinite(near) and math.isfinite(far) and 0.0 < near < far):
        raise PhoneDepthError(f"expected GDepth 0 < Near < Far, got Near {near}, Far {far}")
    dn = np.clip(np.asarray(normalised, np.float64), 0.0, 1.0)
    if fmt == "RangeLinear":
        depth = dn * (far - near) + near
    elif fmt == "RangeInverse":
        depth = far * near / (far - dn * (far - near))
    else:
        raise PhoneDepthError(f"expected GDepth Format RangeInverse or RangeLinear, got {fmt!r}")
    return depth.astype(np.float32)


def heif_depth_to_depth(values: np.ndarray, bits: int, metadata: dict[str, Any] | None
                        ) -> tuple[np.ndarray, bool, str]:
    """A HEIF depth image's grey values -> depth, by its depth representation info.

    Args:
        values: ``H x W`` integer grey values.
        bits: bits per value (8 or 16).
        metadata: pillow-heif's ``HeifDepthImage.info["metadata"]`` (libheif's depth
            representation info), or None.

    Returns:
        ``(depth, metric, kind)``: ``H x W`` float32 depth (> 0; 1/disparity for disparity
        maps), whether it is in metres, and the representation's name.
    """
    meta = dict(metadata or {})
    rep = int(meta.get("representation_type", HEIF_DISPARITY))
    v = np.asarray(values, np.float64) / float(2**bits - 1)
    d_min, d_max = meta.get("d_min"), meta.get("d_max")
    z_near, z_far = meta.get("z_near"), meta.get("z_far")
    if rep in (HEIF_DISPARITY, HEIF_NONUNIFORM_DISPARITY):
        if rep == HEIF_NONUNIFORM_DISPARITY and int(
                meta.get("nonlinear_representation_model_size", 0)):
            raise PhoneDepthError("the HEIF depth image uses a non-linear disparity model, "
                                  "which OutCast cannot read")
        metric = d_min is not None and d_max is not None
        lo, hi = (float(d_min), float(d_max)) if metric else (0.0, 1.0)
        if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo and hi > 0):
            raise PhoneDepthError(f"expected HEIF disparity d_min < d_max, got {lo}, {hi}")
        disparity = lo + v * (hi - lo)
        floor = max(hi * 1e-3, 1e-9)  # zero disparity (infinitely far) -> 1000x the nearest
        return (1.0 / np.maximum(disparity, floor)).astype(np.float32), metric, "disparity"
    if rep in (HEIF_INVERSE_Z, HEIF_Z):
        if z_near is None or z_far is None:
            raise PhoneDepthError("expected z_near and z_far in the HEIF depth "
                                  "representation info, got none")
        near, far = float(z_near), float(z_far)
        if not (math.isfinite(near) and math.isfinite(far) and 0.0 < near < far):
            raise PhoneDepthError(f"expected HEIF 0 < z_near < z_far, got {near}, {far}")
        if rep == HEIF_Z:
            return (near + v * (far - near)).astype(np.float32), True, "Z"
        inv = 1.0 / far + v * (1.0 / near - 1.0 / far)  # v = 1 is nearest
        return (1.0 / inv).astype(np.float32), True, "inverse Z"
    raise PhoneDepthError(f"expected a HEIF depth representation type 0-3, got {rep}")


def orient_to_photo(depth: np.ndarray, photo_hw: tuple[int, int], orientation: int = 1,
                    *, stored: bool = True) -> np.ndarray:
    """Turn a depth map upright like its photo and check that it has the photo's shape.

    Args:
        depth: ``h x w`` map.
        photo_hw: the upright photo's ``(height, width)``.
        orientation: the photo's EXIF orientation (1-8).
        stored: True when the map is stored like the photo's pixels (before the orientation,
            as in a JPEG), so it always gets the orientation; False when the map may already be
            upright (HEIF), so it only gets it when its aspect ratio needs it.

    Returns:
        The upright map (its own size, the photo's aspect ratio).

    Raises:
        PhoneDepthError: the aspect ratios do not match either way.
    """
    from outcast_core.runtime.io.imageio import _apply_orientation  # one orientation code path

    d = np.asarray(depth)
    if stored or not _same_aspect(d.shape, photo_hw):
        turned = _apply_orientation(d, int(orientation)) if orientation in range(2, 9) else d
        if stored or _same_aspect(turned.shape, photo_hw):
            d = turned
    if not _same_aspect(d.shape, photo_hw):
        raise PhoneDepthError(
            f"the embedded depth map ({d.shape[1]}x{d.shape[0]}) does not match the photo's "
            f"shape ({photo_hw[1]}x{photo_hw[0]})")
    return np.ascontiguousarray(d)


def _same_aspect(shape: tuple[int, ...], photo_hw: tuple[int, int]) -> bool:
    a = shape[1] / shape[0]
    b = photo_hw[1] / photo_hw[0]
    return abs(a - b) <= ASPECT_TOLERANCE * b + 1.0 / min(shape[:2])


def ray_to_axis(range_map: np.ndarray, camera: Camera) -> np.ndarray:
    """Distance along each pixel's ray -> z depth: ``z = r f / sqrt(f^2 + x^2 + y^2)``.

    Args:
        range_map: ``H x W`` range, at the ``camera``'s size.
        camera: intrinsics of the map.

    Returns:
        ``H x W`` float32 z depth.
    """
    r = np.asarray(range_map, np.float32)
    if r.shape != (camera.height, camera.width):
        raise ValueError(f"expected a range map of the camera's size "
                         f"{(camera.height, camera.width)}, got {r.shape}")
    x = (np.arange(camera.width) + 0.5 - camera.cx) / camera.focal
    y = (np.arange(camera.height) + 0.5 - camera.cy) / camera.focal
    cos = 1.0 / np.sqrt(1.0 + x[None, :] ** 2 + y[:, None] ** 2)
    return (r * cos).astype(np.float32)


# --------------------------------------------------------------------------------------------
# JPEG: XMP segments


def jpeg_xmp_packets(data: bytes) -> tuple[bytes | None, dict[str, bytes]]:
    """The standard XMP packet and the extended XMP (joined per GUID) of a JPEG's APP1 segments.

    Args:
        data: the JPEG file's bytes.

    Returns:
        ``(standard, extended)``: the standard packet (None when absent) and ``{guid: packet}``.

    Raises:
        PhoneDepthError: an extended XMP chunk lies outside its declared length.
    """
    standard: bytes | None = None
    chunks: dict[str, tuple[int, dict[int, bytes]]] = {}
    if data[:2] != b"\xff\xd8":
        return None, {}
    pos = 2
    while pos + 4 <= len(data):
        if data[pos] != 0xFF:
            break
        marker = data[pos + 1]
        if marker == 0xFF:  # fill byte
            pos += 1
            continue
        if marker in (0xD9, 0xDA):  # end of image, start of scan: no metadata after
            break
        if 0xD0 <= marker <= 0xD7 or marker == 0x01:
            pos += 2
            continue
        (length,) = struct.unpack(">H", data[pos + 2:pos + 4])
        payload = data[pos + 4:pos + 2 + length]
        pos += 2 + length
        if marker != 0xE1:
            continue
        if payload.startswith(XMP_SIGNATURE) and standard is None:
            standard = payload[len(XMP_SIGNATURE):]
        elif payload.startswith(XMP_EXT_SIGNATURE):
            body = payload[len(XMP_EXT_SIGNATURE):]
            if len(body) < 40:
                continue
            guid = body[:32].decode("ascii", "replace")
            total, offset = struct.unpack(">II", body[32:40])
            if total > MAX_EXTENDED_XMP or offset + len(body) - 40 > total:
                raise PhoneDepthError(f"the extended XMP chunk at offset {offset} does not fit "
                                      f"its declared length {total}")
            chunks.setdefault(guid, (total, {}))[1][offset] = body[40:]
    extended: dict[str, bytes] = {}
    for guid, (total, parts) in chunks.items():
        buf = bytearray(total)
        for offset, part in parts.items():
            buf[offset:offset + len(part)] = part
        extended[guid] = bytes(buf)
    return standard, extended


def parse_xmp(packet: bytes) -> ET.Element:
    """An XMP packet's XML tree (parse a packet once; read it with :func:`tree_properties`).

    Raises:
        PhoneDepthError: the packet is not well-formed XML.
    """
    try:
        return ET.fromstring(packet.strip(b"\x00 \t\r\n"))
    except ET.ParseError as exc:
        raise PhoneDepthError(f"the photo's XMP metadata is not well-formed XML ({exc})") from exc


def tree_properties(root: ET.Element, namespace: str) -> dict[str, str]:
    """Every property of ``namespace`` in a parsed XMP packet, as attributes or as elements.

    Args:
        root: from :func:`parse_xmp`.
        namespace: the namespace URI.

    Returns:
        ``{local name: text}``, the first of each name in document order.
    """
    prefix = "{" + namespace + "}"
    props: dict[str, str] = {}
    for element in root.iter():
        for key, value in element.attrib.items():
            if key.startswith(prefix):
                props.setdefault(key[len(prefix):], value)
        if isinstance(element.tag, str) and element.tag.startswith(prefix):
            props.setdefault(element.tag[len(prefix):], (element.text or "").strip())
    return props


def xmp_properties(packet: bytes, namespace: str) -> dict[str, str]:
    """Every property of ``namespace`` in an XMP packet, as attributes or as elements.

    Args:
        packet: the XMP packet (XML bytes).
        namespace: the namespace URI.

    Returns:
        ``{local name: text}``.

    Raises:
        PhoneDepthError: the packet is not well-formed XML.
    """
    return tree_properties(parse_xmp(packet), namespace)


class JpegXmp:
    """A JPEG's XMP packets (:func:`jpeg_xmp_packets`), each parsed at most once, when first
    needed: the GDepth and the Dynamic Depth readers share them.

    Args:
        data: the JPEG file's bytes.

    Raises:
        PhoneDepthError: an extended XMP chunk lies outside its declared length.
    """

    def __init__(self, data: bytes) -> None:
        self.standard_packet, self.extended_packets = jpeg_xmp_packets(data)
        self._standard: ET.Element | None = None
        self._extended: dict[str, ET.Element] = {}

    def standard(self) -> ET.Element | None:
        """The standard packet's tree (None without one); :class:`PhoneDepthError` if it is
        not well-formed."""
        if self._standard is None and self.standard_packet is not None:
            self._standard = parse_xmp(self.standard_packet)
        return self._standard

    def extended(self, guid: str) -> ET.Element:
        """The tree of the extended packet ``guid`` (a key of :attr:`extended_packets`)."""
        if guid not in self._extended:
            self._extended[guid] = parse_xmp(self.extended_packets[guid])
        return self._extended[guid]

    def trees(self) -> list[ET.Element]:
        """Every packet's tree, the standard one first."""
        standard = self.standard()
        extended = [self.extended(guid) for guid in self.extended_packets]
        return ([standard] if standard is not None else []) + extended


def gdepth_properties(data: bytes | JpegXmp) -> dict[str, str]:
    """The GDepth properties of a JPEG, the standard and the extended XMP merged ({} if none).

    Args:
        data: the JPEG file's bytes, or its :class:`JpegXmp` (its packets parsed once).
    """
    xmp = data if isinstance(data, JpegXmp) else JpegXmp(data)
    standard = xmp.standard()
    if standard is None:
        return {}
    props = tree_properties(standard, GDEPTH_NS)
    if not props:
        return {}
    guid = tree_properties(standard, XMP_NOTE_NS).get("HasExtendedXMP", "")
    guids = [guid] if guid in xmp.extended_packets else list(xmp.extended_packets)
    for g in guids:
        for key, value in tree_properties(xmp.extended(g), GDEPTH_NS).items():
            props.setdefault(key, value)
    return props


def decode_gdepth(props: dict[str, str]) -> PhoneDepth:
    """GDepth properties -> the depth map they describe (still as stored, not yet upright).

    Args:
        props: ``{name: text}`` of the GDepth namespace (``Format``, ``Near``, ``Far``,
            ``Mime``, ``Data``, optional ``Units``, ``MeasureType``).

    Returns:
        A :class:`PhoneDepth` (metres when the units are known).

    Raises:
        PhoneDepthError: a required field is missing or malformed, or the data is not an image.
    """
    missing = [k for k in ("Near", "Far", "Data") if not props.get(k)]
    if missing:
        raise PhoneDepthError(f"the photo's GDepth metadata lacks {', '.join(missing)}")
    try:
        raw = base64.b64decode("".join(props["Data"].split()), validate=True)
    except (binascii.Error, ValueError) as exc:
        raise PhoneDepthError("the photo's GDepth Data is not valid base64") from exc
    return _decode_range_map(props, raw, "GDepth", props.get("Mime", "image/jpeg"))


def _decode_range_map(props: dict[str, str], raw: bytes, container: str, mime: str
                      ) -> PhoneDepth:
    """A RangeInverse / RangeLinear map (GDepth or Dynamic Depth fields) -> depth."""
    fmt = {"rangeinverse": "RangeInverse", "rangelinear": "RangeLinear"}.get(
        props.get("Format", "RangeInverse").strip().lower(), props.get("Format", ""))
    try:
        near, far = float(props["Near"]), float(props["Far"])
    except (KeyError, ValueError) as exc:
        raise PhoneDepthError(f"expected numbers for {container} Near and Far, got "
                              f"{props.get('Near')!r} and {props.get('Far')!r}") from exc
    mime = mime.strip().lower()
    if mime not in ("image/jpeg", "image/png"):
        raise PhoneDepthError(f"expected {container} Mime image/jpeg or image/png, got {mime!r}")
    values, bits = _decode_grey(raw, container)
    depth = gdepth_to_depth(values / float(2**bits - 1), fmt, near, far)
    units = props.get("Units", "m").strip().lower()
    scale = UNITS_TO_METRES.get(units)
    if scale is not None:
        depth = depth * np.float32(scale)
    measure = props.get("MeasureType", "OpticalAxis")
    if measure not in ("OpticalAxis", "OpticRay", "OpticalRay"):
        raise PhoneDepthError(f"expected {container} MeasureType OpticalAxis or OpticRay, "
                              f"got {measure!r}")
    return PhoneDepth(depth, f"{container} {fmt}", scale is not None,
                      "axis" if measure == "OpticalAxis" else "ray")


# --------------------------------------------------------------------------------------------
# JPEG: Dynamic Depth (the depth map is a file appended after the photo)


def _element_props(element: ET.Element, namespace: str) -> dict[str, str]:
    """An element's properties of ``namespace``, as attributes or as child elements."""
    prefix = "{" + namespace + "}"
    props = {k[len(prefix):]: v for k, v in element.attrib.items() if k.startswith(prefix)}
    for child in element:
        if isinstance(child.tag, str) and child.tag.startswith(prefix) and len(child) == 0:
            props.setdefault(child.tag[len(prefix):], (child.text or "").strip())
    return props


def _primary_end(data: bytes) -> int:
    """Where the first JPEG image of ``data`` ends (after its first EOI following a scan)."""
    pos = 2
    while pos + 4 <= len(data) and data[pos] == 0xFF:
        marker = data[pos + 1]
        if marker == 0xFF:
            pos += 1
            continue
        if marker == 0xDA:
            end = data.find(b"\xff\xd9", pos)  # entropy-coded data never holds FF D9
            return len(data) if end < 0 else end + 2
        if 0xD0 <= marker <= 0xD7 or marker == 0x01:
            pos += 2
            continue
        (length,) = struct.unpack(">H", data[pos + 2:pos + 4])
        pos += 2 + length
    return len(data)


def dynamic_depth(data: bytes, packets: Sequence[bytes | ET.Element]) -> PhoneDepth | None:
    """The depth map of a Dynamic Depth JPEG, or None when the XMP describes none.

    The XMP (``Device:Container``) lists the files appended after the photo in order
    (``Item:Mime``, ``Item:Length``, ``Item:Padding``, ``Item:DataURI``; the first is the photo
    itself); a ``DepthMap`` element (``Format``, ``Near``, ``Far``, ``Units``, ``MeasureType``,
    ``DepthURI``) names the item that holds the depth image.

    Args:
        data: the JPEG file's bytes.
        packets: its XMP packets (standard and extended), as bytes or already parsed
            (:func:`parse_xmp`).

    Raises:
        PhoneDepthError: the depth item is missing or lies outside the file, or a packet is
            not well-formed XML.
    """
    depth_props: dict[str, str] = {}
    items: list[dict[str, str]] = []
    for packet in packets:
        root = packet if isinstance(packet, ET.Element) else parse_xmp(packet)
        for element in root.iter():
            if element.tag == "{" + DD_CONTAINER_NS + "}Item":
                items.append(_element_props(element, DD_ITEM_NS))
            props = _element_props(element, DD_DEPTHMAP_NS)
            if (not depth_props and "DepthURI" in props
                    and props.get("ItemSemantic", "Depth") == "Depth"):
                depth_props = props
    if not depth_props:
        return None
    uri = depth_props["DepthURI"]
    try:
        sizes = [(int(it.get("Length", "0") or 0), int(it.get("Padding", "0") or 0))
                 for it in items]
    except ValueError as exc:
        raise PhoneDepthError("expected whole numbers for the Dynamic Depth item lengths") from exc
    index = next((i for i, it in enumerate(items) if it.get("DataURI") == uri), None)
    if index is None or index == 0 or any(n < 0 or p < 0 for n, p in sizes):
        raise PhoneDepthError(f"the photo's Dynamic Depth container has no item {uri!r}")
    length = sizes[index][0]
    # Items follow the photo in order, each followed by its padding; where the photo ends is
    # found from its EOI, and checked against the end of the file (the last item ends there).
    starts = [_primary_end(data) + sizes[0][1] + sum(n + p for n, p in sizes[1:index])]
    starts.append(len(data) - sum(n + p for n, p in sizes[index:]))
    for start in starts:
        raw = data[start:start + length]
        if length > 0 and start >= 0 and len(raw) == length and (
                raw.startswith(b"\x89PNG") or raw.startswith(b"\xff\xd8")):
            return _decode_range_map(depth_props, raw, "Dynamic Depth",
                                     items[index].get("Mime", "image/jpeg"))
    raise PhoneDepthError(f"the photo's Dynamic Depth item {uri!r} ({length} bytes) is not "
                          "where the container says")


def _decode_grey(raw: bytes, what: str) -> tuple[np.ndarray, int]:
    """An embedded PNG/JPEG -> ``(H x W grey values, bits)``."""
    try:
        with Image.open(io.BytesIO(raw)) as im:
            w, h = im.size
            if max(w, h) > MAX_MAP_SIDE:
                raise PhoneDepthError(f"the {what} depth map is {w}x{h}, larger than "
                                      f"{MAX_MAP_SIDE} px on a side")
            if im.mode in ("I;16", "I;16B", "I;16L", "I"):
                values, bits = np.asarray(im, dtype=np.float64), 16
            else:
                values, bits = np.asarray(im.convert("L"), dtype=np.float64), 8
    except PhoneDepthError:
        raise
    except Exception as exc:  # Pillow raises many types for broken data
        raise PhoneDepthError(f"the {what} depth data is not a readable image "
                              f"({type(exc).__name__})") from exc
    return values, bits


# --------------------------------------------------------------------------------------------
# HEIF depth images


def heif_depth_from_image(depth_image: Any) -> PhoneDepth:
    """A pillow-heif ``HeifDepthImage`` (or anything with ``info["metadata"]`` and
    ``to_pillow()``) -> :class:`PhoneDepth` (as stored: see :func:`orient_to_photo`)."""
    meta = getattr(depth_image, "info", {}).get("metadata")
    try:
        pil = depth_image.to_pillow()
    except Exception as exc:  # libheif errors on a broken item
        raise PhoneDepthError(f"the HEIF depth image cannot be decoded "
                              f"({type(exc).__name__})") from exc
    if max(pil.size) > MAX_MAP_SIDE:
        raise PhoneDepthError(f"the HEIF depth image is {pil.size[0]}x{pil.size[1]}, larger "
                              f"than {MAX_MAP_SIDE} px on a side")
    if pil.mode in ("I;16", "I;16B", "I;16L", "I"):
        values, bits = np.asarray(pil, np.float64), 16
    else:
        values, bits = np.asarray(pil.convert("L"), np.float64), 8
    depth, metric, kind = heif_depth_to_depth(values, bits, meta)
    return PhoneDepth(depth, f"HEIF {kind}", metric)


def heif_depth_images(path: str | os.PathLike[str]) -> tuple[list[Any], int]:
    """The primary image's depth images of a HEIF file and the photo's EXIF orientation."""
    import pillow_heif

    info = pillow_heif.open_heif(os.fspath(path), convert_hdr_to_8bit=False).info  # primary
    orientation = int(info.get("original_orientation") or 1)
    if info.get("exif") and "original_orientation" not in info:
        exif = Image.Exif()
        try:
            exif.load(info["exif"])
            orientation = int(exif.get(0x0112, 1) or 1)
        except Exception:  # a broken EXIF block: no turn
            orientation = 1
    return list(info.get("depth_images") or []), orientation


# --------------------------------------------------------------------------------------------
# One entry point


def read_phone_depth(path: str | os.PathLike[str], photo_hw: tuple[int, int] | None = None
                     ) -> PhoneDepth | None:
    """The depth map stored inside a photo, upright, or None when it has none.

    Args:
        path: a JPEG (GDepth XMP) or HEIF/HEIC (depth image) photo; other formats give None.
        photo_hw: the upright photo's ``(height, width)``: the map is checked against it
            (default: read from the file's header).

    Returns:
        A :class:`PhoneDepth` with the photo's aspect ratio, or None.

    Raises:
        PhoneDepthError: the photo has a depth map that is malformed or does not match it.
    """
    path = Path(path)
    with open(path, "rb") as f:
        head = f.read(12)
    if head[:2] == b"\xff\xd8":
        data = path.read_bytes()
        xmp = JpegXmp(data)  # segments found and each packet parsed once for both readers
        props = gdepth_properties(xmp)
        if props:
            found = decode_gdepth(props)
        else:
            trees = xmp.trees()
            dd = dynamic_depth(data, trees) if trees else None
            if dd is None:
                return None
            found = dd
        orientation = _jpeg_orientation(path)
        stored = True
    elif head[4:8] == b"ftyp":
        try:
            images, orientation = heif_depth_images(path)
        except Exception:  # not a HEIF pillow-heif can open: the photo reader will say why
            return None
        if not images:
            return None
        found = heif_depth_from_image(images[0])
        stored = False
    else:
        return None
    if photo_hw is None:
        from outcast_core.runtime.io.imageio import read_image_size

        w, h = read_image_size(path)
        photo_hw = (h, w)
    depth = orient_to_photo(found.depth, photo_hw, orientation, stored=stored)
    if not (np.isfinite(depth) & (depth > 0)).all():
        raise PhoneDepthError(f"the embedded {found.container} depth map has values that are "
                              "not finite and positive")
    return PhoneDepth(depth, found.container, found.metric, found.measure)


def _jpeg_orientation(path: Path) -> int:
    from outcast_core.runtime.io.imageio import open_pil

    try:
        with open_pil(path) as im:
            return int(im.getexif().get(0x0112, 1) or 1)
    except Exception:
        return 1


def phone_depth_at(phone: PhoneDepth, camera: Camera) -> np.ndarray:
    """The phone's map at the camera's size (bilinear in inverse depth), as z depth.

    Args:
        phone: from :func:`read_phone_depth`.
        camera: intrinsics of the working image (the photo's field of view).

    Returns:
        ``H x W`` float32 z depth, finite and > 0.
    """
    inv = 1.0 / np.asarray(phone.depth, np.float32)
    inv = cv2.resize(inv, (camera.width, camera.height),
                     interpolation=cv2.INTER_AREA if inv.shape[0] > camera.height
                     else cv2.INTER_LINEAR)
    depth = 1.0 / np.maximum(inv, np.float32(1e-12))
    if phone.measure == "ray":
        depth = ray_to_axis(depth, camera)
    return depth.astype(np.float32)
