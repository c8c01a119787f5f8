"""Image, shadow and depth files: reading photos, writing results atomically.

Reading (:func:`read_image`) turns any supported photo into ``image_srgb``, a float32
``H x W x 3`` array in ``[0, 1]``, upright (EXIF orientation applied), plus its metadata
(:class:`~outcast_core.runtime.io.exif.PhotoMetadata`):

* Formats: JPEG (and MPO, the multi-picture JPEG phones write), PNG 8/16 bit, TIFF 8/16 bit,
  WebP, BMP, HEIC/HEIF (``pillow-heif``). 16-bit PNG/TIFF colour images are decoded with OpenCV so
  the 16 bits survive (Pillow would truncate them to 8); 16-bit grey images with Pillow (``I;16``).
* Grey images become 3 equal channels; palette, CMYK and YCbCr images are converted to RGB.
  **Alpha is composited onto white.** An embedded ICC profile other than sRGB (Display P3,
  Adobe RGB, CMYK press profiles) is converted to sRGB with LittleCMS (a 16-bit colour file
  through its conversion sampled on a grid and interpolated, so its precision stays; a profile
  LittleCMS cannot parse is ignored).
* ``max_pixels`` loads at a working resolution (area ``<= max_pixels``, aspect kept) without
  materialising the full-size float32 array: JPEG is decoded at 1/2, 1/4 or 1/8 scale by libjpeg
  (``Image.draft``), other formats are decoded at 8 (or 16) bits and reduced before the float
  conversion.
* Pillow's decompression-bomb guard (about 89 MP warns, 179 MP fails) would reject real photos
  from large sensors; it is replaced by :data:`MAX_DECODE_PIXELS` (160 MP), checked from the
  header before any pixel is decoded (a PNG's EXIF is found by walking its chunks, not by
  decoding it), so a decompression bomb costs milliseconds and no memory.
* Every failure is an :class:`ImageReadError` (a ``ValueError``) with a one-line message
  for a person, a machine-readable :class:`ImageReadReason` and, apart, the decoder's own
  words; the library exception is chained as ``__cause__``.

Writing is atomic: :func:`atomic_output` yields a temporary path in the destination folder and
renames it over the destination only when the writer succeeded; an existing file is only
replaced with ``force=True``.

Depth files (:func:`read_depth`, :func:`write_depth`), float32 ``H x W``, invalid/sky ``+inf``:

* ``.npy``: float32 array, stored as is (``inf`` included).
* ``.exr``: one float32 channel ``Z`` (read: ``Z``, else ``Y``, else ``R``, else the only
  channel), stored as is.
* ``.png``: 16-bit grey. A valid pixel stores ``round(depth / max_depth * 65535)`` (at least 1),
  where ``max_depth`` is the largest finite positive depth; 0 marks invalid/sky pixels (read back
  as ``+inf``). ``max_depth`` is kept in a ``outcast:depth_scale`` text chunk so reading restores
  the original scale (error <= 0.5 / 65535 of ``max_depth``; depths below one step are stored as
  the smallest code, 1). A 16-bit PNG without that
  chunk (written by another tool) reads as relative depth ``value / 65535``.
"""

from __future__ import annotations

import contextlib
import functools
import io
import os
import struct
import tempfile
import threading
import warnings
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path
from typing import BinaryIO

import cv2
import numpy as np
import pillow_heif
from PIL import Image, ImageCms, PngImagePlugin, UnidentifiedImageError

from outcast_core.runtime.geometry.colour import XYZ_TO_SRGB, linear_to_srgb
from outcast_core.runtime.io.exif import TAG_ORIENTATION, PhotoMetadata, metadata_from_exif

pillow_heif.register_heif_opener()

MAX_DECODE_PIXELS = 160_000_000
"""Largest image (in pixels) :func:`read_image` agrees to decode.

Sized to what the full-resolution pipeline holds: ``outcast relight`` peaks at about 60 bytes
per pixel (6.4 GB for a 108 MP photo), so about 10 GB here; the largest camera sensors (151 MP)
fit. Checked from the header, before any pixel is decoded."""

READ_FORMATS = frozenset({"JPEG", "MPO", "PNG", "TIFF", "WEBP", "HEIF", "BMP"})
"""Pillow format names :func:`read_image` accepts."""

#: zlib level of written PNG photos: a 27-megapixel photo took 11.1 s at 6 (PIL's default),
#: 4.2 s at 3 for a file 5 % larger (26.8 / 28.2 MB), 3.0 s at 1 (30.0 MB); a user trial's
#: "Shadows removed" export sat at "writing 80 %" for 11 s.
PNG_COMPRESS_LEVEL = 3
WRITE_EXTENSIONS = {
    ".png": "PNG",
    ".jpg": "JPEG",
    ".jpeg": "JPEG",
    ".tif": "TIFF",
    ".tiff": "TIFF",
    ".webp": "WEBP",
}
"""File extensions :func:`write_image` understands, and the format each selects."""

DEPTH_EXTENSIONS = (".npy", ".png", ".exr")
DEPTH_SCALE_KEY = "outcast:depth_scale"

_RAW_EXTENSIONS = frozenset(
    {".cr2", ".cr3", ".nef", ".nrw", ".arw", ".srf", ".sr2", ".dng", ".raf", ".orf", ".rw2",
     ".pef", ".srw", ".x3f", ".3fr", ".iiq", ".raw", ".rwl"}
)
_READABLE_NAMES = "JPEG, PNG, TIFF, WebP, HEIC/HEIF or BMP"
_PIL_LIMIT_LOCK = threading.Lock()


class ImageReadReason(StrEnum):
    """Why a file could not be read as an image or a depth map (:attr:`ImageReadError.reason`),
    for choosing what to tell the user without reading the message's words."""

    MISSING = "missing"
    """No file by that name."""
    NO_ACCESS = "no-access"
    """The file is there but cannot be read (permissions, a disconnected disk...)."""
    DAMAGED = "damaged"
    """Empty, cut short or corrupt."""
    UNSUPPORTED_LAYOUT = "unsupported-layout"
    """A 16-bit file in a layout the decoder cannot read (or damaged: the two cannot be told)."""
    NOT_AN_IMAGE = "not-an-image"
    """Not an image (or not a depth map) at all, or a folder."""
    UNSUPPORTED_FORMAT = "unsupported-format"
    """An image format OutCast does not read (GIF, OpenEXR as a photo...)."""
    CAMERA_RAW = "camera-raw"
    """A camera RAW file."""
    TOO_LARGE = "too-large"
    """More pixels than :data:`MAX_DECODE_PIXELS`."""
    OUT_OF_MEMORY = "out-of-memory"
    """Decoding ran out of memory."""
    NO_VALID_DEPTH = "no-valid-depth"
    """A depth map whose every pixel is invalid (zero, negative, NaN or infinite)."""


class ImageReadError(ValueError):
    """A file could not be read as an image (or depth map).

    ``str(exc)`` is :attr:`message`, the one line every front end shows (the app's dialog, the
    command line, a batch report's line); the decoder's :attr:`detail` is kept apart, for a
    batch report's ``details`` and a developer's traceback (the decoder's exception is the
    ``__cause__``). Its words ("OSError: image file is truncated (5 bytes not processed)") say
    nothing more to a photographer (a user trial).

    Attributes:
        message: one line for a person, naming the file and saying what is wrong in words a
            photographer knows (with what is worth knowing, such as byte counts), without the
            decoder's own words.
        reason: why, as an :class:`ImageReadReason`.
        detail: the decoder's own words (``"OSError: image file is truncated (35 bytes not
            processed)"``), or ``""``.

    Example:
        >>> err = ImageReadError("cannot read image 'a.jpg': the file is truncated or corrupt",
        ...                      ImageReadReason.DAMAGED, "OSError: image file is truncated")
        >>> err.reason == "damaged", str(err) == err.message, err.detail
        (True, True, 'OSError: image file is truncated')
    """

    def __init__(self, message: str, reason: ImageReadReason | str, detail: str = "") -> None:
        super().__init__(message, reason, detail)  # all three: a pickled copy is the same
        self.message = message
        self.reason = ImageReadReason(reason)
        self.detail = detail

    def __str__(self) -> str:
        return self.message


#: Pillow modes of a one-channel (black-and-white) file, with or without transparency.
GREY_MODES = ("1", "L", "LA", "La", "I;16", "I;16B", "I;16L", "I;16N", "I", "F")


def in_file_channels(image: np.ndarray, loaded: LoadedImage | None) -> np.ndarray:
    """``image`` (``H x W x 3``) as the photo's file holds it: one channel (the channels' mean)
    for a black-and-white file (:attr:`LoadedImage.grey`), else as it is. A greyscale JPEG
    came back as three equal channels (a user trial).

    Example:
        >>> img = np.full((2, 2, 3), 0.5, np.float32)
        >>> in_file_channels(img, None).shape
        (2, 2, 3)
    """
    a = np.asarray(image)
    if loaded is None or not getattr(loaded, "grey", False) or a.ndim != 3:
        return a
    if a.dtype == np.uint8:
        return ((a.astype(np.uint16).sum(axis=2) + 1) // 3).astype(np.uint8)
    return a.mean(axis=2, dtype=np.float32)


@dataclass
class LoadedImage:
    """A photo as read from disk.

    Attributes:
        image_srgb: float32 ``H x W x 3`` in ``[0, 1]``, sRGB-encoded, upright. At the working
            resolution when ``max_pixels`` was given. uint8 (``0..255``) instead when read with
            ``keep_uint8`` from an 8-bit file (a quarter of the memory, no conversion).
        path: the file it came from.
        original_size: ``(width, height)`` of the full-resolution upright image.
        exif: the parsed metadata.
        exif_bytes: the raw EXIF block with its orientation reset to 1 (the pixels are upright),
            for copying into an output file; ``None`` when the file had no EXIF.
        format: Pillow's format name (``"JPEG"``, ``"PNG"``, ...).
        bit_depth: bits per sample in the file (8 or 16; 32 for float TIFF).
        has_alpha: some pixel of the file is not fully opaque (composited on white: a relit
            photo has no transparency).
        grey: the file holds one channel (black and white; :data:`GREY_MODES`): what is made
            of it is written with one too (:func:`in_file_channels`).
    """

    image_srgb: np.ndarray
    path: Path
    original_size: tuple[int, int]
    exif: PhotoMetadata = field(default_factory=PhotoMetadata)
    exif_bytes: bytes | None = None
    format: str = ""
    bit_depth: int = 8
    has_alpha: bool = False
    grey: bool = False

    @property
    def size(self) -> tuple[int, int]:
        """``(width, height)`` of ``image_srgb``."""
        return int(self.image_srgb.shape[1]), int(self.image_srgb.shape[0])

    @property
    def scale(self) -> float:
        """Working width over original width (1.0 at full resolution)."""
        return self.size[0] / self.original_size[0]


# --------------------------------------------------------------------------------------------
# Reading


def read_image(
    path: str | os.PathLike[str], max_pixels: int | None = None, *, keep_uint8: bool = False
) -> LoadedImage:
    """Read a photo as upright sRGB float32 with its EXIF metadata.

    Args:
        path: the image file.
        max_pixels: if given and the image has more pixels, it is loaded at the largest size
            with ``width * height <= max_pixels`` and the original aspect ratio (each side at
            least 1 pixel). ``None`` loads full resolution.
        keep_uint8: an 8-bit file's pixels stay uint8 (``0..255``; what the session and the
            full-resolution stages read fastest); deeper files are float32 either way.

    Returns:
        A :class:`LoadedImage`.

    Shape:
        ``image_srgb``: ``H x W x 3`` float32.

    Raises:
        ImageReadError: missing, empty, truncated or corrupt file, not an image, an unsupported
            format, or an image larger than :data:`MAX_DECODE_PIXELS`.
        ValueError: ``max_pixels`` is not a positive integer.

    Example:
        >>> photo = read_image("samples/exif_001_cz_fieldpath.jpg", max_pixels=256 * 192)
        >>> photo.image_srgb.shape, photo.original_size
        ((192, 255, 3), (1012, 759))
    """
    if max_pixels is not None and (not isinstance(max_pixels, int | np.integer) or max_pixels < 1):
        raise ValueError(f"expected max_pixels to be a positive int or None, got {max_pixels!r}")
    path = Path(path)
    _check_input_file(path)
    try:
        with _open_pil(path) as im:
            fmt, exif, exif_bytes = _checked_header(im, path)
            meta = metadata_from_exif(exif)
            stored_w, stored_h = _stored_size(im, meta.orientation)
            _check_jpeg_size(path, fmt, stored_w, stored_h)
            if fmt == "PNG":
                _check_png_chunks(path)
            target = _fit_size(stored_w, stored_h, max_pixels)
            bits = _bits_per_sample(im, path)
            alpha = _has_transparency(im)
            grey = im.mode in GREY_MODES
            # Some decoders turn a TIFF upright themselves: then it is decoded at the upright
            # target size and not turned again.
            turned = None if target is None else _upright_size(target, meta.orientation)
            if bits > 8 and im.mode not in ("I;16", "I;16B", "I;16L", "I;16N", "I", "F"):
                upright = _turns_upright("opencv", fmt, meta.orientation)
                image = _decode_cv2(path, turned if upright else target)
                image = _convert_icc_float(image, im.info.get("icc_profile"))
            else:
                upright = _turns_upright("pillow", fmt, meta.orientation)
                size = turned if upright else target
                try:
                    image = _decode_pil(im, size, keep_uint8=keep_uint8)
                except OSError:
                    whole = _jpeg_lacking_only_its_end(path, fmt)
                    if whole is None:
                        raise
                    with _open_pil(path, whole) as im_whole:
                        image = _decode_pil(im_whole, size, keep_uint8=keep_uint8)
    except ImageReadError:
        raise
    except UnidentifiedImageError as exc:
        if _starts_like_a_photo(path):  # cut short before Pillow could tell what it is
            raise ImageReadError(f"cannot read image '{path}': the file is truncated or corrupt",
                                 ImageReadReason.DAMAGED, _one_line(exc)) from exc
        raise ImageReadError(
            f"cannot read image '{path}': not an image file, or a format OutCast cannot read "
            f"(expected {_READABLE_NAMES})", ImageReadReason.NOT_AN_IMAGE
        ) from exc
    except MemoryError as exc:
        raise ImageReadError(
            f"cannot read image '{path}': not enough memory", ImageReadReason.OUT_OF_MEMORY,
            "load it with a smaller max_pixels"
        ) from exc
    except Exception as exc:  # Pillow/OpenCV/libheif raise many types for broken files
        raise ImageReadError(
            f"cannot read image '{path}': the file is truncated or corrupt",
            ImageReadReason.DAMAGED, _one_line(exc)
        ) from exc
    if not upright:
        image = _apply_orientation(image, meta.orientation)
    original = _upright_size((stored_w, stored_h), meta.orientation)
    return LoadedImage(
        image_srgb=image,
        path=path,
        original_size=original,
        exif=meta,
        exif_bytes=exif_bytes,
        format=fmt,
        bit_depth=bits,
        has_alpha=alpha,
        grey=grey,
    )


def read_metadata(path: str | os.PathLike[str]) -> PhotoMetadata:
    """A photo's EXIF metadata (GPS, time, heading, focal length...) without decoding its
    pixels: a PNG's ``eXIf`` chunk is found by walking the chunks, as :func:`read_image` does.
    A file without EXIF gives empty metadata.

    Raises:
        ImageReadError: the file cannot be opened as an image.
    """
    path = Path(path)
    try:
        with _open_pil(path) as im:
            exif, _ = _exif_of(im, path)
    except (OSError, UnidentifiedImageError) as exc:
        raise _error_for(exc, path, f"cannot read '{path}'") from exc
    return metadata_from_exif(exif)


def same_file(a: str | os.PathLike[str] | None, b: str | os.PathLike[str] | None) -> bool:
    """Whether ``a`` and ``b`` name one existing file, through links and other spellings too
    (an output must never replace an input, whatever its name)."""
    return bool(a and b and os.path.exists(a) and os.path.exists(b) and os.path.samefile(a, b))


def read_image_size(path: str | os.PathLike[str]) -> tuple[int, int]:
    """``(width, height)`` of the upright image, from the header only (no pixel decoding).

    Raises:
        ImageReadError: as :func:`read_image`, for problems visible in the header.
    """
    path = Path(path)
    _check_input_file(path)
    try:
        with _open_pil(path) as im:
            _, exif, _ = _checked_header(im, path)
            orientation = metadata_from_exif(exif).orientation
            stored = _stored_size(im, orientation)
    except ImageReadError:
        raise
    except Exception as exc:  # noqa: BLE001 - Pillow raises many types for broken headers
        raise _error_for(exc, path, f"cannot read image '{path}'") from exc
    return _upright_size(stored, orientation)


def check_photo_file(path: str | os.PathLike[str]) -> None:
    """Refuse a file that cannot be a photo, from its first bytes and header (format and
    pixel count; no EXIF), and a JPEG cut short: quick enough for a window to call before it
    asks anything (:func:`read_image_size` reads a PNG's chunks looking for EXIF, most of a
    big file).

    A JPEG that does not end with its end-of-image marker is decoded at 1/8 size (the
    entropy-coded data read once, a few hundredths of a second for a 12 MP photo) and
    refused when that stops short, unless only the marker is missing
    (:func:`_jpeg_lacking_only_its_end`): a truncated JPEG passed the header check, so the
    app asked to save the open photo's changes before it said the new one was damaged (a user
    trial). A PNG's chunks are walked (:func:`_check_png_chunks`). Other formats are checked
    when their pixels are read.

    Raises:
        ImageReadError: as :func:`read_image`, for what the header shows.
    """
    path = Path(path)
    try:
        _check_input_file(path)
        with _open_pil(path) as im:
            fmt = _checked_format(im, path)
            if fmt in ("JPEG", "MPO"):
                _check_jpeg_size(path, fmt, *im.size)
                _check_jpeg_complete(im, path, fmt)
            elif fmt == "PNG":
                _check_png_chunks(path)
    except ImageReadError:
        raise
    except Exception as exc:  # noqa: BLE001 - Pillow raises many types for broken headers
        raise _error_for(exc, path, f"cannot read image '{path}'") from exc


def _check_jpeg_complete(im: Image.Image, path: Path, fmt: str) -> None:
    """:func:`check_photo_file`'s test of an opened JPEG ``im`` for data cut short."""
    with open(path, "rb") as f:
        f.seek(max(0, path.stat().st_size - 4096))
        tail = f.read()
    if tail.rstrip(b"\x00").endswith(b"\xff\xd9"):
        return  # (the usual case: nothing to decode)
    try:
        im.draft("RGB", (max(1, im.width // 8), max(1, im.height // 8)))
        im.load()
    except OSError as exc:
        if _jpeg_lacking_only_its_end(path, fmt) is None:
            raise ImageReadError(f"cannot read image '{path}': the file is truncated or "
                                 "corrupt", ImageReadReason.DAMAGED, _one_line(exc)) from exc


def _starts_like_a_photo(path: Path) -> bool:
    """Whether the file starts as a JPEG, PNG, TIFF, WebP, HEIF or BMP file does.

    Pillow cannot identify such a file when it was cut short before what it reads first (a
    TIFF's directory is often written after its pixels): damaged, not "not an image".
    """
    try:
        with open(path, "rb") as f:
            head = f.read(16)
    except OSError:
        return False
    return (head.startswith((b"\xff\xd8\xff", b"\x89PNG\r\n\x1a\n", b"II*\x00", b"MM\x00*",
                             b"BM"))
            or (head[:4] == b"RIFF" and head[8:12] == b"WEBP")
            or (head[4:8] == b"ftyp" and head[8:12] in _HEIF_BRANDS))


#: The ISO-BMFF brands of HEIC/HEIF still images (an MP4 or MOV video has ``ftyp`` too).
_HEIF_BRANDS = frozenset({b"heic", b"heix", b"heim", b"heis", b"hevc", b"hevx", b"mif1",
                          b"msf1"})


def _error_for(exc: BaseException, path: Path, what: str) -> ImageReadError:
    """The :class:`ImageReadError` for a library's ``exc`` raised while reading ``path``.

    Args:
        exc: what the library raised.
        path: the file.
        what: the start of the message, naming the file (``"cannot read image 'a.jpg'"``).
    """
    if isinstance(exc, UnidentifiedImageError) and not _starts_like_a_photo(path):
        return ImageReadError(f"{what}: not an image file", ImageReadReason.NOT_AN_IMAGE)
    if isinstance(exc, FileNotFoundError):
        return ImageReadError(f"{what}: file not found", ImageReadReason.MISSING)
    if isinstance(exc, PermissionError):
        return ImageReadError(f"{what}: permission denied", ImageReadReason.NO_ACCESS)
    if isinstance(exc, MemoryError):
        return ImageReadError(f"{what}: not enough memory", ImageReadReason.OUT_OF_MEMORY)
    return ImageReadError(f"{what}: the file is truncated or corrupt", ImageReadReason.DAMAGED,
                          _one_line(exc))


#: The fewest bytes per pixel a complete JPEG can have: a flat frame at any quality still
#: spends a few bits per 8 x 8 block (Pillow: 0.012 bytes per pixel grey, 0.016 colour); far
#: fewer means the file was cut short, and libjpeg would fill the rest with grey without an
#: error.
MIN_JPEG_BYTES_PER_PIXEL = 0.001


def _check_jpeg_size(path: Path, fmt: str, width: int, height: int) -> None:
    """Refuse a JPEG whose data are far too short for its declared size (a user trial: a
    693-byte file whose header says 9000 x 9000 was read as a flat grey photo)."""
    if fmt not in ("JPEG", "MPO"):
        return
    size = path.stat().st_size
    if size < MIN_JPEG_BYTES_PER_PIXEL * width * height:
        raise ImageReadError(
            f"cannot read image '{path}': the file is truncated or corrupt: its {size:,} bytes "
            f"cannot hold the {width} x {height} JPEG its header declares",
            ImageReadReason.DAMAGED)


def _jpeg_lacking_only_its_end(path: Path, fmt: str) -> bytes | None:
    """A JPEG's bytes with the end-of-image marker it lacks, when that is all it lacks; else
    None (not a JPEG, the marker is there, or its data stop before the last block).

    Some writers leave the marker off; every block of the image is there, and viewers show
    it, but Pillow calls such a file truncated (a user trial's file was refused). Cut short,
    a baseline JPEG decodes with its missing blocks flat mid-grey (libjpeg zeroes their
    coefficients), so the last block, decoded at 1/8 size (one pixel per 8 x 8 block, its
    mean), tells: exactly (128, 128, 128) there is taken as cut short. A progressive JPEG
    (its first scan holds every block's mean) or a CMYK one (zero is not mid-grey there)
    cannot be told so: those stay refused (found by a review).
    """
    if fmt not in ("JPEG", "MPO"):
        return None
    data = path.read_bytes()
    if data.rstrip(b"\x00").endswith(b"\xff\xd9"):
        return None
    data += b"\xff\xd9"
    try:
        with _open_pil(path, data) as im:
            if im.info.get("progressive") or im.info.get("progression") or (
                    im.mode not in ("L", "RGB")):
                return None
            im.draft("RGB", (max(1, im.width // 8), max(1, im.height // 8)))
            im.load()
            last = np.asarray(im.convert("RGB"))[-1, -1]
    except Exception:  # noqa: BLE001 - still unreadable: the caller's error stands
        return None
    return None if bool((last == 128).all()) else data


def _upright_size(size: tuple[int, int], orientation: int) -> tuple[int, int]:
    """``(width, height)`` of a stored image once EXIF ``orientation`` has turned it upright."""
    return (size[1], size[0]) if orientation >= 5 else (size[0], size[1])


@functools.lru_cache(maxsize=2)
def _decoder_turns_tiff_upright(decoder: str) -> bool:
    """Whether ``decoder`` ("pillow" or "opencv") turns a TIFF upright by its EXIF orientation
    as it decodes it.

    Pillow 13 does (and reports the upright size before loading), earlier Pillows do not;
    OpenCV's TIFF reader does. Turning such a TIFF again put it on its side (found by a user
    trial). Probed once per decoder on a 2 x 1 TIFF made in memory.
    """
    exif = Image.Exif()
    exif[TAG_ORIENTATION] = 6
    buf = io.BytesIO()
    Image.new("RGB", (2, 1)).save(buf, "TIFF", exif=exif)
    if decoder == "opencv":
        array = cv2.imdecode(np.frombuffer(buf.getvalue(), np.uint8), cv2.IMREAD_UNCHANGED)
        return array is not None and array.shape[:2] == (2, 1)
    buf.seek(0)
    with Image.open(buf) as im:
        return im.size == (1, 2)


def _turns_upright(decoder: str, fmt: str, orientation: int) -> bool:
    """Whether ``decoder`` applies EXIF ``orientation`` itself to an image of format ``fmt``."""
    return fmt == "TIFF" and orientation >= 2 and _decoder_turns_tiff_upright(decoder)


def _stored_size(im: Image.Image, orientation: int) -> tuple[int, int]:
    """The ``(width, height)`` the pixels are stored at (Pillow reports a TIFF it turns
    upright at its upright size)."""
    if _turns_upright("pillow", im.format or "", orientation):
        return _upright_size(im.size, orientation)  # the same swap undoes itself
    return im.size


def _checked_header(
    im: Image.Image, path: Path
) -> tuple[str, Image.Exif | None, bytes | None]:
    """An opened image's format, Exif and raw Exif bytes, with the format and the pixel count
    checked (:class:`ImageReadError` otherwise; :func:`_stored_size` gives its size)."""
    fmt = _checked_format(im, path)
    exif, exif_bytes = _exif_of(im, path)
    return fmt, exif, exif_bytes


def _checked_format(im: Image.Image, path: Path) -> str:
    """An opened image's format, checked with its pixel count (:class:`ImageReadError`
    otherwise)."""
    fmt = im.format or "unknown"
    if fmt not in READ_FORMATS:
        raise ImageReadError(
            f"cannot read image '{path}': unsupported format {fmt}; expected {_READABLE_NAMES}",
            ImageReadReason.UNSUPPORTED_FORMAT,
        )
    _check_pixel_count(path, *im.size)
    return fmt


def _check_input_file(path: Path) -> None:
    if not path.exists():
        raise ImageReadError(f"cannot read '{path}': file not found", ImageReadReason.MISSING)
    if path.is_dir():
        raise ImageReadError(f"cannot read '{path}': it is a folder, not a file",
                             ImageReadReason.NOT_AN_IMAGE)
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise ImageReadError(f"cannot read '{path}': {exc.strerror or 'the file is unreadable'}",
                             ImageReadReason.NO_ACCESS, _one_line(exc)) from exc
    if size == 0:
        raise ImageReadError(f"cannot read '{path}': the file is empty", ImageReadReason.DAMAGED)
    suffix = path.suffix.lower()
    if suffix in _RAW_EXTENSIONS:
        raise ImageReadError(
            f"cannot read '{path}': camera RAW files are not supported; "
            f"export a JPEG, PNG or 16-bit TIFF first", ImageReadReason.CAMERA_RAW
        )
    if suffix in (".exr", ".hdr", ".pfm", ".npy"):
        raise ImageReadError(
            f"cannot read '{path}' as a photo: {suffix} is not a supported photo format; "
            f"expected {_READABLE_NAMES}", ImageReadReason.UNSUPPORTED_FORMAT
        )
    if not os.access(path, os.R_OK):
        raise ImageReadError(f"cannot read '{path}': permission denied",
                             ImageReadReason.NO_ACCESS)


@contextlib.contextmanager
def _open_pil(path: Path, data: bytes | None = None) -> Iterator[Image.Image]:
    """``Image.open`` with Pillow's bomb guard replaced by :data:`MAX_DECODE_PIXELS`.

    The file is opened as a file object, never by name: by name, Pillow 13 maps an
    uncompressed grey, 16-bit, RGBA or CMYK TIFF into memory and then reports the upright size
    of an oriented one without turning its pixels (found by a code review), while through a
    file object it decodes and turns it as it does every other TIFF. ``data``: the file's
    bytes, amended (read instead of ``path``).
    """
    f = open(path, "rb") if data is None else io.BytesIO(data)  # noqa: SIM115 -- closed below
    try:
        with _PIL_LIMIT_LOCK:
            previous = Image.MAX_IMAGE_PIXELS
            Image.MAX_IMAGE_PIXELS = None  # our own limit is checked by the callers
            try:
                im = Image.open(f)
            finally:
                Image.MAX_IMAGE_PIXELS = previous
        try:
            yield im
        finally:
            im.close()
    finally:
        f.close()


@contextlib.contextmanager
def open_pil(path: str | os.PathLike[str]) -> Iterator[Image.Image]:
    """A photo opened by Pillow (header only, lazily decoded) for reading its metadata, with
    Pillow's decompression-bomb warning (from 89 MP) replaced by OutCast's own limit
    (:data:`MAX_DECODE_PIXELS`, checked where the pixels are read): a 108 MP photo, which
    OutCast relights, printed Pillow's warning when its camera pose was read (a user trial).
    Raises what ``Image.open`` raises."""
    with _open_pil(Path(path)) as im:
        yield im


def _check_pixel_count(path: Path, width: int, height: int) -> None:
    """Refuse an image larger than :data:`MAX_DECODE_PIXELS` (from its header size)."""
    if width * height > MAX_DECODE_PIXELS:
        raise ImageReadError(
            f"cannot read '{path}': {width}x{height} is larger than the "
            f"{MAX_DECODE_PIXELS / 1e6:.0f} MP limit", ImageReadReason.TOO_LARGE
        )


def _exif_of(im: Image.Image, path: Path) -> tuple[Image.Exif | None, bytes | None]:
    """The image's EXIF and its bytes with orientation 1; (None, None) when absent/corrupt.

    Never decodes pixels: Pillow's ``PngImageFile.getexif`` decodes the whole image to find an
    ``eXIf`` chunk stored after the pixel data, so for PNG the chunks are walked instead.
    """
    try:
        if im.format == "PNG" and "exif" not in im.info:
            exif = Image.Exif()
            data = _png_exif_chunk(path)
            if data:
                exif.load(data)
        else:
            exif = im.getexif()
    except Exception:  # corrupt EXIF must not stop reading the pixels
        return None, None
    if len(exif) == 0:
        return exif, None
    try:
        upright = Image.Exif()
        upright.load(exif.tobytes())
        upright[TAG_ORIENTATION] = 1
        data = upright.tobytes()
    except Exception:
        data = None
    return exif, data


PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: How many of a PNG's chunks :func:`_check_png_chunks` walks (a 12 MP PNG has a few hundred).
PNG_CHECKED_CHUNKS = 100_000


def _png_chunks(f: BinaryIO, max_chunks: int) -> Iterator[tuple[bytes, int, int]]:
    """``(kind, length, end)`` of each chunk of an open PNG file after its signature, up to
    ``IEND``, the end of the file or ``max_chunks``; ``end`` is where its data ends. The file
    is at the chunk's data when it is yielded (the walk seeks on, whatever the caller reads)."""
    pos = f.tell()
    for _ in range(max_chunks):
        f.seek(pos)
        head = f.read(8)
        if len(head) < 8:
            return
        length, kind = int.from_bytes(head[:4], "big"), head[4:]
        yield kind, length, pos + 8 + length
        if kind == b"IEND":
            return
        pos += 12 + length  # head, data and CRC


def _png_exif_chunk(path: Path, max_chunks: int = 10_000) -> bytes | None:
    """The data of a PNG's ``eXIf`` chunk, found by seeking from chunk to chunk (no decoding).

    Returns None when there is none, the file is truncated (a chunk that says it runs past
    the end is not read: a review's ``eXIf`` claiming 1.5 GB was allocated before the file
    was found short), or after ``max_chunks`` chunks.
    """
    size = path.stat().st_size
    with open(path, "rb", buffering=0) as f:
        if f.read(8) != PNG_SIGNATURE:
            return None
        for kind, length, end in _png_chunks(f, max_chunks):
            if kind == b"eXIf":
                if end > size:
                    return None
                data = f.read(length)
                return data if len(data) == length else None
    return None


def _check_png_chunks(path: Path) -> None:
    """Refuse a PNG one of whose chunks says it is longer than the rest of the file (no
    decoding). Pillow reads what such a length says before it finds the file short: a 60-byte
    PNG whose image-data chunk claimed 84 MB made it allocate 84 MB (a fuzz test), and a length
    may say 2 GB. Not a PNG, or cut short between chunks (its end missing), passes."""
    size = path.stat().st_size
    with open(path, "rb", buffering=0) as f:  # (a buffer refilled at each seek read half a
        if f.read(8) != PNG_SIGNATURE:        # large PNG: a review)
            return
        for kind, _, end in _png_chunks(f, PNG_CHECKED_CHUNKS):
            if end > size:
                name = kind.decode("latin-1") if kind.isalpha() else repr(kind)
                raise ImageReadError(
                    f"cannot read image '{path}': the file is truncated or corrupt: its "
                    f"{size:,} bytes stop before the end of the PNG", ImageReadReason.DAMAGED,
                    f"its {name} chunk runs {end - size:,} bytes past the end of the file")


def _fit_size(width: int, height: int, max_pixels: int | None) -> tuple[int, int] | None:
    """The largest size with the same aspect and area <= max_pixels, or None if it fits."""
    if max_pixels is None or width * height <= max_pixels:
        return None
    scale = (max_pixels / (width * height)) ** 0.5
    w = max(1, int(width * scale))
    h = max(1, int(height * scale))
    while w * h > max_pixels and (w > 1 or h > 1):  # float rounding guard
        if w >= h:
            w -= 1
        else:
            h -= 1
    return w, h


def _bits_per_sample(im: Image.Image, path: Path) -> int:
    if im.mode in ("I;16", "I;16B", "I;16L", "I;16N"):
        return 16
    if im.mode in ("I", "F"):
        return 32
    if im.format == "PNG":
        with open(path, "rb") as f:
            header = f.read(25)
        return header[24] if len(header) == 25 and header[12:16] == b"IHDR" else 8
    if im.format == "TIFF":
        bits = getattr(im, "tag_v2", {}).get(258, (8,))
        bits = bits if isinstance(bits, tuple) else (bits,)
        return int(max(bits))
    return 8


def _decode_pil(
    im: Image.Image, target: tuple[int, int] | None, *, keep_uint8: bool = False
) -> np.ndarray:
    """Decode with Pillow to float32 H x W x 3 (8-bit and grey 16/32-bit images); uint8 for
    8-bit images with ``keep_uint8``."""
    if target is not None and im.format in ("JPEG", "MPO"):
        im.draft(None, target)  # libjpeg DCT scaling: decodes at >= target, 1/2..1/8 size
    im.load()
    im = _convert_icc_to_srgb(im)
    mode = im.mode
    if mode in ("I;16", "I;16B", "I;16L", "I;16N", "I", "F"):
        # native uint16 for I;16 (I;16B is big-endian), float32 for 32-bit int/float
        grey = np.asarray(im).astype(np.uint16 if mode.startswith("I;16") else np.float32)
        if target is not None:
            grey = cv2.resize(grey, target, interpolation=cv2.INTER_AREA)
        scale = 1.0 if mode == "F" else 65535.0
        grey = np.clip(grey.astype(np.float32) / np.float32(scale), 0.0, 1.0)
        return np.repeat(grey[:, :, None], 3, axis=2)
    if mode == "P":
        mode_to = "RGBA" if "transparency" in im.info else "RGB"
        im = im.convert(mode_to)
    elif mode == "PA":
        im = im.convert("RGBA")
    if im.mode in ("RGBA", "LA", "La", "RGBa"):
        im = _composite_on_white(im)
    elif im.mode == "1":
        im = im.convert("L")
    elif im.mode not in ("RGB", "L"):
        im = im.convert("RGB")  # CMYK, YCbCr, LAB, HSV, RGBX
    if target is not None and im.size != target:
        im = im.resize(target, Image.Resampling.LANCZOS, reducing_gap=2.0)
    if keep_uint8:
        u8 = np.asarray(im)  # H x W (x 3) uint8
        return np.repeat(u8[:, :, None], 3, axis=2) if u8.ndim == 2 else u8
    out = np.asarray(im).astype(np.float32)  # H x W (x 3)
    out /= np.float32(255.0)
    if out.ndim == 2:
        out = np.repeat(out[:, :, None], 3, axis=2)
    return out


def _non_srgb_profile(icc: bytes | None) -> ImageCms.ImageCmsProfile | None:
    """The embedded profile to convert from, or None (none, sRGB, or one LittleCMS cannot
    parse: the pixels are then used as stored). Raises nothing."""
    if not icc:
        return None
    try:
        source = ImageCms.ImageCmsProfile(io.BytesIO(icc))
        name = ImageCms.getProfileDescription(source).strip().lower().replace(" ", "")
    except (ImageCms.PyCMSError, OSError, ValueError, TypeError):
        return None
    return None if name.startswith("srgb") else source


def _convert_icc_to_srgb(im: Image.Image) -> Image.Image:
    """Convert an RGB/RGBA/CMYK image with a non-sRGB embedded ICC profile to sRGB."""
    if im.mode not in ("RGB", "RGBA", "CMYK"):
        return im
    source = _non_srgb_profile(im.info.get("icc_profile"))
    if source is None:
        return im
    try:
        converted = ImageCms.profileToProfile(
            im, source, _srgb_profile(), outputMode="RGBA" if im.mode == "RGBA" else "RGB"
        )
    except (ImageCms.PyCMSError, OSError, ValueError, TypeError):
        return im  # an unreadable profile: use the pixels as stored
    return converted if converted is not None else im


#: :func:`_convert_icc_float`: the 8-bit step of the grid on which a profile's conversion is
#: sampled for 16-bit images (LittleCMS converts 8-bit pixels only through Pillow); 255 is a
#: multiple of it, so the grid is uniform: 0, 5, ..., 255.
ICC_GRID_STEP = 5


@functools.lru_cache(maxsize=4)
def _icc_grid(icc: bytes) -> np.ndarray | None:
    """A profile's conversion to sRGB sampled on the 8-bit grid of :data:`ICC_GRID_STEP`:
    ``L x L x L x 3`` float32 in [0, 1] (``L = 255 / step + 1``), or None for no conversion."""
    source = _non_srgb_profile(icc)
    if source is None:
        return None
    levels = np.arange(0, 256, ICC_GRID_STEP, dtype=np.uint8)
    n = levels.size
    r, g, b = np.meshgrid(levels, levels, levels, indexing="ij")
    grid = np.stack([r, g, b], -1).reshape(n * n, n, 3)  # an image LittleCMS can convert
    try:
        out = ImageCms.profileToProfile(Image.fromarray(grid), source, _srgb_profile(),
                                        outputMode="RGB")
    except (ImageCms.PyCMSError, OSError, ValueError, TypeError):
        return None
    if out is None:
        return None
    return np.asarray(out, np.float32).reshape(n, n, n, 3) / np.float32(255.0)


#: Bradford adaptation from the ICC connection space's D50 white to sRGB's D65 (then CIE XYZ
#: to linear sRGB: :data:`~outcast_core.runtime.geometry.colour.XYZ_TO_SRGB`).
_D50_TO_D65 = np.array([[0.9555766, -0.0230393, 0.0631636],
                        [-0.0282895, 1.0099416, 0.0210077],
                        [0.0122982, -0.0204830, 1.3299098]])
#: Samples of a tone curve in :func:`_matrix_shaper` (linear interpolation between them).
_CURVE_SAMPLES = 4096


def _icc_curve(data: bytes, off: int) -> np.ndarray | None:
    """An ICC ``curv`` or ``para`` tone curve at ``off``, sampled at :data:`_CURVE_SAMPLES`
    points of [0, 1]; None for another type."""
    x = np.linspace(0.0, 1.0, _CURVE_SAMPLES)
    kind = data[off:off + 4]
    if kind == b"curv":
        n = int.from_bytes(data[off + 8:off + 12], "big")
        if n == 0:
            return x
        if n == 1:
            return x ** (int.from_bytes(data[off + 12:off + 14], "big") / 256.0)
        table = np.frombuffer(data, ">u2", n, off + 12).astype(np.float64) / 65535.0
        return np.interp(x, np.linspace(0.0, 1.0, n), table)
    if kind == b"para":
        ftype = int.from_bytes(data[off + 8:off + 10], "big")
        count = {0: 1, 1: 3, 2: 4, 3: 5, 4: 7}.get(ftype)
        if count is None:
            return None
        p = np.frombuffer(data, ">i4", count, off + 12) / 65536.0
        g, a, b, c, d, e, f = list(p) + [0.0] * (7 - count)
        if ftype == 0:
            return x ** g
        if a <= 0.0:  # a curve that never rises: not a tone curve
            return None
        if ftype == 1:  # (a x + b)^g above -b/a, else 0
            return np.where(x >= -b / a, np.maximum(a * x + b, 0.0) ** g, 0.0)
        if ftype == 2:
            return np.where(x >= -b / a, np.maximum(a * x + b, 0.0) ** g + c, c)
        if ftype == 3:  # sRGB's form
            return np.where(x >= d, np.maximum(a * x + b, 0.0) ** g, c * x)
        return np.where(x >= d, np.maximum(a * x + b, 0.0) ** g + e, c * x + f)
    return None


@functools.lru_cache(maxsize=4)
def _matrix_shaper(icc: bytes) -> tuple[np.ndarray, np.ndarray] | None:
    """A matrix/TRC RGB profile (Adobe RGB, ProPhoto, Display P3, most camera and editor
    exports) read from its tags: its three tone curves as tables over the 65536 16-bit codes
    (``65536 x 3``) and the matrix from its linear RGB to linear sRGB (its D50 colorants,
    Bradford-adapted to D65). None when the profile has no such tags, or also has an ``A2B0``
    table (LittleCMS converts 8-bit pixels through that table: the 16-bit path must agree), or
    they do not parse."""
    try:
        if len(icc) < 132 or icc[16:20] != b"RGB ":  # data colour space
            return None
        count = int.from_bytes(icc[128:132], "big")
        tags = {}
        for i in range(min(count, 200)):
            entry = icc[132 + 12 * i:144 + 12 * i]
            tags[entry[:4]] = int.from_bytes(entry[4:8], "big")
        need = (b"rXYZ", b"gXYZ", b"bXYZ", b"rTRC", b"gTRC", b"bTRC")
        if not all(t in tags for t in need) or b"A2B0" in tags:
            return None
        cols = [np.frombuffer(icc, ">i4", 3, tags[t] + 8) / 65536.0 for t in need[:3]]
        curves = [_icc_curve(icc, tags[t]) for t in need[3:]]
    except (ValueError, IndexError):
        return None
    if any(c is None or not np.all(np.isfinite(c)) for c in curves):
        return None
    to_srgb = XYZ_TO_SRGB @ _D50_TO_D65 @ np.stack(cols, axis=1)  # src linear -> sRGB linear
    if not np.all(np.isfinite(to_srgb)):
        return None
    codes = np.linspace(0.0, 1.0, 65536)
    x = np.linspace(0.0, 1.0, _CURVE_SAMPLES)
    tables = np.stack([np.interp(codes, x, c) for c in curves], 1).astype(np.float32)
    return tables, to_srgb.astype(np.float32)


@functools.cache
def _srgb_encode_table() -> np.ndarray:
    """sRGB's curve over 65536 linear steps (its output moves by at most 0.05/255 between
    them)."""
    return linear_to_srgb(np.linspace(0.0, 1.0, 65536, dtype=np.float32))


def _convert_icc_float(image: np.ndarray, icc: bytes | None) -> np.ndarray:
    """Convert a float ``H x W x 3`` image (in [0, 1], RGB) from its embedded profile to sRGB,
    in place, keeping its precision (16-bit files; LittleCMS converts 8-bit pixels only
    through Pillow).

    A matrix/TRC profile (:func:`_matrix_shaper`) is converted exactly: its tone curves, its
    matrix to linear sRGB, then sRGB's curve (colours outside sRGB clipped, as LittleCMS
    does). Other profiles go through :func:`_icc_grid`'s samples of LittleCMS's conversion,
    interpolated (trilinear; within 2/255 of it inside sRGB's gamut, up to about 10/255 near
    its edge, where LittleCMS's clip bends the conversion between two grid points). A 16-bit
    Adobe RGB or ProPhoto TIFF (Lightroom's usual export) was read as sRGB before: its
    colours came out about 16 % less saturated (found by a user trial).
    """
    if not icc or _non_srgb_profile(bytes(icc)) is None:
        return image
    flat = image.reshape(-1, 3)  # converted in place, in bands: no second full-size copy
    shaper = _matrix_shaper(bytes(icc))
    if shaper is not None:  # both curves as 16-bit tables: 12 MP in under a second
        tables, to_srgb = shaper
        encode = _srgb_encode_table()
        for start in range(0, flat.shape[0], 1 << 20):
            band = flat[start:start + (1 << 20)]
            q = np.rint(np.clip(band, 0.0, 1.0) * 65535.0).astype(np.int32)
            lin = np.stack([tables[q[:, c], c] for c in range(3)], 1)  # N x 3 linear
            lin = cv2.transform(lin[:, None, :], to_srgb)[:, 0, :]
            band[:] = encode[np.rint(np.clip(lin, 0.0, 1.0) * 65535.0).astype(np.int32)]
        return image
    lut = _icc_grid(bytes(icc))
    if lut is None:
        return image
    n = lut.shape[0]
    flat_lut = lut.reshape(-1, 3)
    offsets = [((c >> 2) & 1) * n * n + ((c >> 1) & 1) * n + (c & 1) for c in range(8)]
    for start in range(0, flat.shape[0], 1 << 19):
        band = flat[start:start + (1 << 19)]
        x = np.clip(band, 0.0, 1.0) * np.float32(n - 1)  # N x 3
        i0 = np.minimum(x.astype(np.int32), n - 2)
        t = x - i0  # N x 3 in [0, 1]
        base = (i0[:, 0] * n + i0[:, 1]) * n + i0[:, 2]
        tr, tg, tb = t[:, 0:1], t[:, 1:2], t[:, 2:3]
        # Interpolate along blue, then green, then red (corner c: bits r, g, b = c >> 2, 1, 0).
        v = [flat_lut[base + o] for o in offsets]
        v = [a + (b - a) * tb for a, b in zip(v[0::2], v[1::2], strict=True)]
        v = [a + (b - a) * tg for a, b in zip(v[0::2], v[1::2], strict=True)]
        band[:] = v[0] + (v[1] - v[0]) * tr  # between samples in [0, 1]: in [0, 1]
    return image


@functools.cache
def _srgb_profile() -> ImageCms.ImageCmsProfile:
    return ImageCms.ImageCmsProfile(ImageCms.createProfile("sRGB"))


def _has_transparency(im: Image.Image) -> bool:
    """Whether a pixel of ``im`` is not fully opaque where the decoder composites it on white
    (an alpha channel, or a palette's transparent entry; an opaque RGBA export is not)."""
    if im.mode in ("RGBA", "LA", "PA", "La", "RGBa"):
        return im.getchannel("A").getextrema()[0] < 255
    if im.mode == "P" and "transparency" in im.info:
        return im.convert("RGBA").getchannel("A").getextrema()[0] < 255
    return False


def _composite_on_white(im: Image.Image) -> Image.Image:
    rgba = im.convert("RGBA")
    white = Image.new("RGBA", rgba.size, (255, 255, 255, 255))
    return Image.alpha_composite(white, rgba).convert("RGB")


def _decode_cv2(path: Path, target: tuple[int, int] | None) -> np.ndarray:
    """Decode a 16-bit colour PNG/TIFF with OpenCV, keeping the precision."""
    data = np.fromfile(path, dtype=np.uint8)
    if data[:8].tobytes() == b"\x89PNG\r\n\x1a\n" and b"IEND" not in data[-4096:].tobytes() \
            and b"IEND" not in data.tobytes():  # (bytes may follow the IEND chunk)
        # Cut short: said here, before libpng prints its own error line on stderr.
        raise ImageReadError(f"cannot read image '{path}': the file is truncated or corrupt: "
                             f"its {data.size:,} bytes stop before the end of the PNG",
                             ImageReadReason.DAMAGED, "no IEND chunk")
    array = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)
    if array is None:
        raise ImageReadError(f"cannot read image '{path}': this 16-bit file is stored in a way "
                             "OutCast cannot decode, or it is damaged",
                             ImageReadReason.UNSUPPORTED_LAYOUT, "cv2.imdecode returned None")
    if target is not None:
        array = cv2.resize(array, target, interpolation=cv2.INTER_AREA)
    if array.dtype == np.uint16:
        top = np.float32(65535.0)
    elif array.dtype == np.uint8:
        top = np.float32(255.0)
    else:
        top = np.float32(1.0)
    out = array.astype(np.float32)  # H x W (x C), BGR(A) order
    del array
    out /= top
    if out.ndim == 2:
        out = out[:, :, None]
    channels = out.shape[2]
    if channels in (2, 4):  # grey+alpha or BGRA: composite on white
        alpha = np.clip(out[:, :, -1:], 0.0, 1.0)
        out = out[:, :, :-1] * alpha + (1.0 - alpha)
    # grey -> 3 equal channels; BGR -> RGB
    out = np.repeat(out, 3, axis=2) if out.shape[2] == 1 else out[:, :, 2::-1]
    return np.ascontiguousarray(np.clip(out, 0.0, 1.0), dtype=np.float32)


def _apply_orientation(image: np.ndarray, orientation: int) -> np.ndarray:
    """Make an image stored with EXIF ``orientation`` upright (same result as exif_transpose)."""
    if orientation == 2:
        image = image[:, ::-1]
    elif orientation == 3:
        image = image[::-1, ::-1]
    elif orientation == 4:
        image = image[::-1]
    elif orientation == 5:
        image = image.swapaxes(0, 1)
    elif orientation == 6:
        image = np.rot90(image, k=-1)
    elif orientation == 7:
        image = image[::-1, ::-1].swapaxes(0, 1)
    elif orientation == 8:
        image = np.rot90(image, k=1)
    return np.ascontiguousarray(image)


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


# --------------------------------------------------------------------------------------------
# Writing


@contextlib.contextmanager
def atomic_output(
    path: str | os.PathLike[str], force: bool = False, *, make_parents: bool = False
) -> Iterator[Path]:
    """Write a file atomically: yield a temporary path next to ``path``, then rename it.

    The temporary file lives in the destination folder (so the final ``os.replace`` is atomic)
    and has the destination's extension (so writers that pick a format by extension work). If
    the ``with`` body raises, the temporary file is removed and ``path`` is untouched.

    Args:
        path: the destination file.
        force: replace ``path`` if it exists. Without it an existing file raises
            ``FileExistsError`` (before anything is written).
        make_parents: create missing parent folders instead of raising ``FileNotFoundError``.

    Yields:
        The temporary path to write (it exists, empty).

    Example::

        with atomic_output("out.mp4", force=True) as tmp:
            write_video(tmp, frames)  # any writer that takes a path
    """
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(f"cannot write '{path}': it is a folder")
    if path.exists() and not path.is_file():
        raise ValueError(f"cannot write '{path}': it is not a regular file (a device or pipe)")
    if path.exists() and not force:
        raise FileExistsError(f"'{path}' already exists; use --force to overwrite it")
    parent = path.parent
    if not parent.is_dir():
        if not make_parents:
            raise FileNotFoundError(f"cannot write '{path}': folder '{parent}' does not exist")
        parent.mkdir(parents=True, exist_ok=True)
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=f".tmp{path.suffix}",
                                        dir=parent)
    except OSError as exc:
        _raise_for_destination(exc, path)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        if not tmp.exists():
            raise FileNotFoundError(f"the writer for '{path}' removed its temporary file")
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.chmod(tmp, 0o666 & ~_umask())
        if not force and path.exists():
            raise FileExistsError(f"'{path}' already exists; use --force to overwrite it")
        os.replace(tmp, path)
    except OSError as exc:
        _raise_for_destination(exc, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


def _raise_for_destination(exc: OSError, path: Path) -> None:
    """Re-raise ``exc`` naming the destination instead of the hidden temporary file.

    An error with no file name (``No space left on device``) or naming the temporary file or
    the folder is raised again as the same type naming ``path``; any other error as it is.
    """
    name = "" if exc.filename is None else str(exc.filename)
    ours = name in ("", str(path.parent)) or name.startswith(str(path.parent / f".{path.stem}."))
    if exc.errno is None or not ours:
        raise exc
    raise type(exc)(exc.errno, exc.strerror or os.strerror(exc.errno), str(path)) from exc


def _umask() -> int:
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    return 0o022


def output_bit_depth(path: str | os.PathLike[str], source_bits: int = 8) -> int:
    """Bits per sample to write an image made from a photo of ``source_bits``: 16 for TIFF,
    and for a PNG made from a 16-bit photo (8 bits would throw away its precision); else 8.

    Example:
        >>> output_bit_depth("a.tif"), output_bit_depth("a.png", 16), output_bit_depth("a.png")
        (16, 16, 8)
    """
    suffix = Path(path).suffix.lower()
    return 16 if suffix in (".tif", ".tiff") or (suffix == ".png" and source_bits > 8) else 8


def write_image(
    path: str | os.PathLike[str],
    image_srgb: np.ndarray,
    *,
    bit_depth: int = 8,
    force: bool = False,
    quality: int = 95,
    exif: bytes | None = None,
    make_parents: bool = False,
) -> Path:
    """Write an sRGB image; the format follows the extension.

    Args:
        path: ``.png``, ``.jpg``/``.jpeg``, ``.tif``/``.tiff`` or ``.webp``.
        image_srgb: float ``H x W x 3`` (or ``H x W`` grey) sRGB values; values outside
            ``[0, 1]`` are clipped, NaN is an error. uint8 (``0..255``) is written as it is.
        bit_depth: 8, or 16 for PNG and TIFF.
        force: replace an existing file.
        quality: JPEG/WebP quality, 1..100 (WebP 100 is lossless).
        exif: raw EXIF bytes to embed (e.g. ``LoadedImage.exif_bytes``), in every format
            (16-bit files: an ``eXIf`` chunk, or the TIFF's EXIF and GPS directories).
        make_parents: create missing parent folders.

    Returns:
        The written path.

    Raises:
        ValueError: unknown extension, bad array, bit depth the format cannot hold.
        FileExistsError: ``path`` exists and ``force`` is False.
    """
    path = Path(path)
    fmt = WRITE_EXTENSIONS.get(path.suffix.lower())
    if fmt is None:
        got = f"'{path.suffix}'" if path.suffix else f"a name without one ('{path.name}')"
        raise ValueError(
            f"expected an output extension {_or_list(sorted(WRITE_EXTENSIONS))}, got {got}")
    if bit_depth not in (8, 16):
        raise ValueError(f"expected bit_depth 8 or 16, got {bit_depth}")
    if bit_depth == 16 and fmt not in ("PNG", "TIFF"):
        raise ValueError(f"expected bit_depth 8 for {fmt} (16 bits: use .png or .tif)")
    if not 1 <= int(quality) <= 100:
        raise ValueError(f"expected quality in 1..100, got {quality}")
    array = _quantise(image_srgb, bit_depth)
    with atomic_output(path, force, make_parents=make_parents) as tmp:
        if bit_depth == 16:
            bgr = array[:, :, ::-1] if array.ndim == 3 else array
            _write_cv2(tmp, bgr, path.suffix.lower(), exif)
        else:
            im = Image.fromarray(array)
            kwargs: dict[str, object] = {}
            if exif is not None:
                kwargs["exif"] = exif
            if fmt == "JPEG":
                kwargs.update(quality=int(quality), subsampling=0 if quality >= 90 else 2)
            elif fmt == "WEBP":
                kwargs.update(quality=int(quality), lossless=int(quality) == 100, method=4)
            elif fmt == "PNG":
                kwargs.update(compress_level=PNG_COMPRESS_LEVEL)
            elif fmt == "TIFF":
                kwargs.update(compression="tiff_deflate")
            im.save(tmp, format=fmt, **kwargs)
    return path


def _or_list(items: list[str]) -> str:
    """``['.a', '.b', '.c']`` -> ``".a, .b or .c"`` (for messages)."""
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " or " + items[-1]


def _quantise(image: np.ndarray, bit_depth: int) -> np.ndarray:
    """Float [0, 1] -> uint8/uint16, rounded; checks shape and values."""
    image = np.asarray(image)
    if image.ndim not in (2, 3) or (image.ndim == 3 and image.shape[2] not in (1, 3)):
        raise ValueError(f"expected an H x W x 3 or H x W image, got shape {image.shape}")
    if image.shape[0] < 1 or image.shape[1] < 1:
        raise ValueError(f"expected a non-empty image, got shape {image.shape}")
    if image.dtype == np.uint8:  # already quantised (8 bits), e.g. relight_full(dtype=uint8)
        if image.ndim == 3 and image.shape[2] == 1:
            image = image[:, :, 0]
        if bit_depth == 16:
            return np.ascontiguousarray(image.astype(np.uint16) * np.uint16(257))
        return np.ascontiguousarray(image)
    if not np.issubdtype(image.dtype, np.floating):
        raise ValueError(f"expected a float image in [0, 1] or uint8, got dtype {image.dtype}")
    if np.isnan(image).any():
        raise ValueError("expected an image without NaN values, got NaN")
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[:, :, 0]
    top = 65535.0 if bit_depth == 16 else 255.0
    dtype = np.uint16 if bit_depth == 16 else np.uint8
    return np.ascontiguousarray(np.rint(np.clip(image, 0.0, 1.0) * top).astype(dtype))


def _write_cv2(path: Path, array: np.ndarray, ext: str, exif: bytes | None = None) -> None:
    """Encode a 16-bit image with OpenCV (Pillow cannot write 16-bit colour), with ``exif``
    put into the file (:func:`_png_with_exif`, :func:`_tiff_with_exif`)."""
    params: list[int] = []
    if ext == ".png":
        params = [cv2.IMWRITE_PNG_COMPRESSION, 6]
    ok, encoded = cv2.imencode(".tif" if ext == ".tiff" else ext, array, params)
    if not ok:
        raise OSError(f"OpenCV could not encode '{path}'")
    data = encoded.tobytes()
    if exif:
        try:
            data = _png_with_exif(data, exif) if ext == ".png" else _tiff_with_exif(data, exif)
        except Exception as exc:  # Pillow's EXIF reader and IFD writer raise many types
            warnings.warn(f"'{path.name}': the photo's EXIF could not be written into the "
                          f"16-bit file, which is written without it ({_one_line(exc)})",
                          RuntimeWarning, stacklevel=3)
    path.write_bytes(data)


def _png_with_exif(png: bytes, exif: bytes) -> bytes:
    """A PNG with an ``eXIf`` chunk (the EXIF's TIFF structure) right after its header."""
    body = exif[6:] if exif.startswith(b"Exif\0\0") else exif
    chunk = b"eXIf" + body
    if png[12:16] != b"IHDR":
        raise OSError("OpenCV wrote a PNG without its header first")
    return (png[:33] + struct.pack(">I", len(body)) + chunk
            + struct.pack(">I", zlib.crc32(chunk) & 0xFFFFFFFF) + png[33:])


#: The photo's first-directory tags :func:`_tiff_with_exif` keeps: description, camera make
#: and model, software, date and time, artist, copyright (the rest describes its pixels).
_TIFF_IFD0_METADATA = (270, 271, 272, 305, 306, 315, 33432)
#: EXIF-directory tags it leaves out: the interoperability pointer (an offset into the source
#: file) and the maker note (a camera's private block whose offsets point into the source).
_TIFF_EXIF_DROPPED = (0xA005, 0x927C)
#: Tags written as UNDEFINED (type 7), as EXIF defines them (Pillow writes bytes as BYTE):
#: ExifVersion, ComponentsConfiguration, UserComment, FlashpixVersion, FileSource, SceneType,
#: CFAPattern, and GPS's ProcessingMethod and AreaInformation.
_TIFF_UNDEFINED = {0x8769: (0x9000, 0x9101, 0x9286, 0xA000, 0xA300, 0xA301, 0xA302),
                   0x8825: (0x001B, 0x001C)}


def _tiff_with_exif(tiff: bytes, exif: bytes) -> bytes:
    """A little-endian TIFF (as OpenCV writes it) with a photo's EXIF: its camera tags, and
    its EXIF and GPS directories appended, in a new first directory that also holds every
    entry of the old one (their values stay where they are)."""
    from PIL.TiffImagePlugin import ImageFileDirectory_v2

    data = bytearray(tiff)
    if data[:4] != b"II*\x00":
        raise OSError("OpenCV wrote a TIFF that is not little-endian")
    source = Image.Exif()
    source.load(exif)

    def aligned() -> int:
        if len(data) % 2:
            data.extend(b"\0")
        return len(data)

    new = ImageFileDirectory_v2(prefix=b"II")
    for tag in _TIFF_IFD0_METADATA:
        if tag in source:
            new[tag] = source[tag]
    for pointer in (0x8769, 0x8825):  # the EXIF and GPS directories
        tags = {k: v for k, v in source.get_ifd(pointer).items() if k not in _TIFF_EXIF_DROPPED}
        if tags:
            sub = ImageFileDirectory_v2(prefix=b"II")
            for k, v in tags.items():
                sub[k] = v
                if k in _TIFF_UNDEFINED[pointer] and isinstance(v, bytes):
                    sub.tagtype[k] = 7
            at = aligned()
            data.extend(sub.tobytes(at))
            new[pointer] = at
            new.tagtype[pointer] = 4  # LONG
    old = struct.unpack_from("<I", data, 4)[0]
    n_old = struct.unpack_from("<H", data, old)[0]
    entries = [bytes(data[old + 2 + 12 * i:old + 14 + 12 * i]) for i in range(n_old)]
    for tag in {struct.unpack_from("<H", e)[0] for e in entries} & set(new.keys()):
        del new[tag]
    at = aligned()
    # Laid out as if the old entries came first, so its value offsets are right once merged.
    blob = new.tobytes(at + 12 * n_old)
    n_new = struct.unpack_from("<H", blob)[0]
    entries += [blob[2 + 12 * i:14 + 12 * i] for i in range(n_new)]
    entries.sort(key=lambda e: struct.unpack_from("<H", e)[0])
    data.extend(struct.pack("<H", len(entries)) + b"".join(entries) + struct.pack("<I", 0)
                + blob[2 + 12 * n_new + 4:])
    struct.pack_into("<I", data, 4, at)
    return bytes(data)


def write_shadow_png(
    path: str | os.PathLike[str], shadow: np.ndarray, force: bool = False
) -> Path:
    """Write a shadow image as a 16-bit grey PNG (0..1 mapped to 0..65535).

    Args:
        path: a ``.png`` path.
        shadow: float ``H x W`` in ``[0, 1]`` (clipped); NaN is an error.
        force: replace an existing file.

    Shape:
        ``shadow``: ``H x W``.
    """
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise ValueError(f"expected a .png path for a shadow image, got '{path.suffix}'")
    shadow = np.asarray(shadow)
    if shadow.ndim != 2:
        raise ValueError(f"expected an H x W shadow image, got shape {shadow.shape}")
    array = _quantise(shadow, 16)
    with atomic_output(path, force) as tmp:
        _write_cv2(tmp, array, ".png")
    return path


def read_shadow_png(path: str | os.PathLike[str]) -> np.ndarray:
    """Read a shadow PNG written by :func:`write_shadow_png` as float32 ``H x W`` in [0, 1]."""
    image = read_image(path).image_srgb
    return np.ascontiguousarray(image[:, :, 0])


# --------------------------------------------------------------------------------------------
# Depth


def write_depth(path: str | os.PathLike[str], depth: np.ndarray, force: bool = False) -> Path:
    """Write a depth map as ``.npy``, ``.exr`` (exact) or 16-bit ``.png`` (quantised).

    Args:
        path: destination; the extension selects the format (see the module doc).
        depth: float ``H x W``; ``+inf``/NaN/non-positive values are invalid (sky).
        force: replace an existing file.

    Shape:
        ``depth``: ``H x W``.

    Raises:
        ValueError: wrong shape or dtype, unknown extension.
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in DEPTH_EXTENSIONS:
        raise ValueError(f"expected a depth extension in {DEPTH_EXTENSIONS}, got '{path.suffix}'")
    depth = _check_depth(np.asarray(depth), "depth")
    with atomic_output(path, force) as tmp:
        if ext == ".npy":
            with open(tmp, "wb") as f:
                np.save(f, depth, allow_pickle=False)
        elif ext == ".exr":
            _write_exr(tmp, depth)
        else:
            _write_depth_png(tmp, depth)
    return path


def read_depth(path: str | os.PathLike[str]) -> np.ndarray:
    """Read a depth map written by :func:`write_depth` (or a compatible file).

    Returns:
        float32 ``H x W``; invalid/sky pixels are ``+inf``.

    Raises:
        ImageReadError: missing, empty, corrupt or unreadable file.
        ValueError: the file holds something that is not an ``H x W`` float depth map.
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in DEPTH_EXTENSIONS:
        raise ValueError(f"expected a depth extension in {DEPTH_EXTENSIONS}, got '{path.suffix}'")
    if not path.is_file():
        raise ImageReadError(f"cannot read depth '{path}': file not found",
                             ImageReadReason.MISSING)
    if path.stat().st_size == 0:
        raise ImageReadError(f"cannot read depth '{path}': the file is empty",
                             ImageReadReason.DAMAGED)
    try:
        if ext == ".npy":
            depth = _read_npy(path)
        elif ext == ".exr":
            depth = _read_exr(path)
        else:
            depth = _read_depth_png(path)
    except (ImageReadError, _DepthContentError):
        raise
    except UnidentifiedImageError as exc:
        raise ImageReadError(f"cannot read depth '{path}': not a PNG file",
                             ImageReadReason.NOT_AN_IMAGE) from exc
    except Exception as exc:  # numpy/OpenEXR/Pillow errors for broken files
        raise ImageReadError(
            f"cannot read depth '{path}': not a {ext} depth file, or truncated/corrupt",
            ImageReadReason.DAMAGED, _one_line(exc)
        ) from exc
    depth = _check_depth(np.asarray(depth), f"depth in '{path}'")
    depth = depth.copy()
    depth[~(depth > 0)] = np.inf  # NaN and non-positive are invalid, like sky
    if not np.isfinite(depth).any():
        raise ImageReadError(
            f"cannot use depth '{path}': no valid pixel (every value is zero, negative, NaN or "
            "infinite, which would make the whole frame sky)", ImageReadReason.NO_VALID_DEPTH
        )
    return depth


class _DepthContentError(ValueError):
    """A readable depth file whose content is not a depth map (wrong channels, mode...)."""


def _check_depth(depth: np.ndarray, what: str) -> np.ndarray:
    if depth.ndim != 2 or depth.shape[0] < 1 or depth.shape[1] < 1:
        raise ValueError(f"expected {what} to be a non-empty H x W array, got shape {depth.shape}")
    if not np.issubdtype(depth.dtype, np.floating):
        raise ValueError(f"expected {what} to be a float array, got dtype {depth.dtype}")
    return np.ascontiguousarray(depth, dtype=np.float32)


def _write_exr(path: Path, depth: np.ndarray) -> None:
    import OpenEXR

    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    OpenEXR.File(header, {"Z": depth}).write(str(path))


def _read_npy(path: Path) -> np.ndarray:
    """A ``.npy`` depth map; the header (magic, dtype, shape, size) is checked before loading."""
    with open(path, "rb") as f:
        try:
            version = np.lib.format.read_magic(f)
            if version == (1, 0):
                shape, _, dtype = np.lib.format.read_array_header_1_0(f)
            elif version == (2, 0):
                shape, _, dtype = np.lib.format.read_array_header_2_0(f)
            else:
                raise ValueError(f"unsupported .npy version {version}")
        except ValueError as exc:
            raise ImageReadError(
                f"cannot read depth '{path}': not a NumPy .npy file",
                ImageReadReason.NOT_AN_IMAGE, _one_line(exc)
            ) from exc
        header_bytes = f.tell()
    if dtype.kind != "f" or len(shape) != 2:
        raise _DepthContentError(
            f"expected depth in '{path}' to be an H x W float array, got {dtype} of shape {shape}"
        )
    _check_pixel_count(path, shape[1], shape[0])
    size, whole = path.stat().st_size, header_bytes + dtype.itemsize * shape[0] * shape[1]
    if size < whole:
        raise ImageReadError(f"cannot read depth '{path}': the file is truncated: it ends "
                             f"after {size:,} of {whole:,} bytes", ImageReadReason.DAMAGED)
    return np.load(path, allow_pickle=False)


def _read_exr(path: Path) -> np.ndarray:
    import OpenEXR

    with OpenEXR.File(str(path), header_only=True) as exr:
        (x0, y0), (x1, y1) = (np.asarray(c, dtype=np.int64) for c in exr.header()["dataWindow"])
    _check_pixel_count(path, int(x1 - x0 + 1), int(y1 - y0 + 1))
    with OpenEXR.File(str(path), separate_channels=True) as exr:
        channels = exr.channels()
        for name in ("Z", "Y", "R", "depth.Z", "depth.Y", "depth.R"):
            if name in channels:
                return np.asarray(channels[name].pixels)
        if len(channels) == 1:
            return np.asarray(next(iter(channels.values())).pixels)
    raise _DepthContentError(
        f"expected a depth EXR with a 'Z', 'Y' or 'R' channel, got channels {sorted(channels)}"
    )


def _write_depth_png(path: Path, depth: np.ndarray) -> None:
    valid = np.isfinite(depth) & (depth > 0)
    codes = np.zeros(depth.shape, dtype=np.uint16)
    scale = float(depth[valid].max()) if valid.any() else 1.0
    if valid.any():
        scaled = np.rint(depth[valid].astype(np.float64) / scale * 65535.0)
        codes[valid] = np.clip(scaled, 1, 65535).astype(np.uint16)
    info = PngImagePlugin.PngInfo()
    info.add_text(DEPTH_SCALE_KEY, repr(scale))
    Image.fromarray(codes).save(path, format="PNG", pnginfo=info, compress_level=6)


#: How a depth map's wrong kind of image is named (a 16-bit colour PNG reads as Pillow's "RGB",
#: so "mode RGB" read oddly for it: a user trial).
_PIL_MODE_WORDS = {"1": "black and white", "L": "8-bit grey", "LA": "grey with alpha",
                   "P": "a palette's colours", "RGB": "colour",
                   "RGBA": "RGBA (colour, or grey with alpha)",
                   "CMYK": "CMYK colour", "F": "32-bit float grey"}


def _read_depth_png(path: Path) -> np.ndarray:
    with _open_pil(path) as im:
        if im.format != "PNG" or im.mode not in ("I;16", "I;16B", "I;16L", "I"):
            kind = _PIL_MODE_WORDS.get(im.mode, f"mode {im.mode}")
            raise _DepthContentError(
                f"expected a 16-bit grey PNG depth map, got a {im.format} image in {kind}"
            )
        _check_pixel_count(path, *im.size)
        codes = np.asarray(im).astype(np.float64)
        text = im.info.get(DEPTH_SCALE_KEY)
    try:
        scale = float(text) if text is not None else 1.0
    except ValueError:
        scale = float("nan")
    if not (np.isfinite(scale) and 0 < scale <= float(np.finfo(np.float32).max)):
        raise _DepthContentError(
            f"expected a positive '{DEPTH_SCALE_KEY}' that float32 can hold, got {text!r}"
        )
    depth = (codes / 65535.0 * scale).astype(np.float32)
    depth[codes == 0] = np.inf
    return depth

