"""What identifies a photo: its pixel size and a cheap fingerprint of its content.

A project file (the app's ``NAME.outcast.json``) records the identity of the photo it was saved
with; the app asks before using it with another picture, and ``outcast batch`` fails that
photo, saying why (the project's suns and shadow corrections were made for that picture).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

#: :func:`photo_fingerprint`: the mean brightness of 8 x 8 cells of the photo (one byte each),
#: from a grid of 128 x 128 of its pixels (cheap at any size).
FINGERPRINT_CELLS = 8
FINGERPRINT_SAMPLES = 128
#: Two fingerprints whose cells differ by at most this much on average (of 255) are the same
#: photo: a JPEG saved again differs by under 0.5, a copy cropped by 10 px and scaled back by
#: about 3; another photo by 40-50 and the same one mirrored or 10 % brighter by 10 or more
#: (the samples).
FINGERPRINT_TOLERANCE = 4.0


@dataclass(frozen=True)
class PhotoIdentity:
    """What identifies a project's photo: its pixel size (upright) and a fingerprint of its
    content (:func:`photo_fingerprint`; ``""``: not known)."""

    width: int
    height: int
    fingerprint: str = ""

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"expected a positive whole number of pixels, got {v!r}")
        fp = self.fingerprint
        cells = FINGERPRINT_CELLS * FINGERPRINT_CELLS
        if not isinstance(fp, str) or fp and (len(fp) != 2 * cells or not _is_hex(fp)):
            raise ValueError(f"expected {2 * cells} hexadecimal digits, got {fp!r}")

    @classmethod
    def of(cls, image: np.ndarray) -> PhotoIdentity:
        """The identity of a photo as read (``H x W x C``, uint8 or float in [0, 1])."""
        return cls(int(image.shape[1]), int(image.shape[0]), photo_fingerprint(image))

    def mismatch(self, other: PhotoIdentity) -> str:
        """How ``other`` (the photo opened now) differs from this one (the project's), in
        words; ``""`` when it is the same photo as far as can be told (a fingerprint missing on
        either side compares the sizes only).

        Example:
            >>> PhotoIdentity(2016, 1512).mismatch(PhotoIdentity(1012, 759))
            "it is 1012 × 759 pixels, the project's photo 2016 × 1512"
        """
        if (self.width, self.height) != (other.width, other.height):
            return (f"it is {other.width} × {other.height} pixels, the project's photo "
                    f"{self.width} × {self.height}")
        if self.fingerprint and other.fingerprint and (
                fingerprint_distance(self.fingerprint, other.fingerprint)
                > FINGERPRINT_TOLERANCE):
            return "its picture is not the one the project was saved with"
        return ""

    def to_dict(self) -> dict[str, Any]:
        return {"width": self.width, "height": self.height, "fingerprint": self.fingerprint}

    @classmethod
    def from_any(cls, value: Any) -> PhotoIdentity | None:
        """From ``None`` (a project saved before identities) or a ``{width, height,
        fingerprint}`` object (the fingerprint may be missing)."""
        if value is None:
            return None
        if not isinstance(value, dict) or "width" not in value or "height" not in value:
            raise ValueError(f"expected {{width, height, fingerprint}}, got {value!r}")
        return cls(value["width"], value["height"], value.get("fingerprint", ""))


def photo_fingerprint(image: np.ndarray) -> str:
    """A cheap fingerprint of a photo's content: the mean brightness of
    :data:`FINGERPRINT_CELLS` squared cells, from a grid of :data:`FINGERPRINT_SAMPLES` squared
    pixels (under a millisecond at any size), as hexadecimal digits, one byte a cell.

    Args:
        image: ``H x W`` or ``H x W x C`` (RGB first), uint8, or float in [0, 1].
    """
    h, w = image.shape[:2]
    n, cells = FINGERPRINT_SAMPLES, FINGERPRINT_CELLS
    ys = np.linspace(0, h - 1, n).round().astype(np.intp)
    xs = np.linspace(0, w - 1, n).round().astype(np.intp)
    grid = image[np.ix_(ys, xs)].astype(np.float32)
    if image.dtype == np.uint8:
        grid /= 255.0
    elif image.dtype == np.uint16:
        grid /= 65535.0
    if grid.ndim == 3:
        grid = (grid[..., :3] @ np.array([0.299, 0.587, 0.114], np.float32) if grid.shape[2] >= 3
                else grid[..., 0])
    step = n // cells
    means = grid.reshape(cells, step, cells, step).mean(axis=(1, 3))
    return bytes(np.rint(np.clip(means, 0.0, 1.0) * 255.0).astype(np.uint8).ravel()).hex()


def fingerprint_distance(a: str, b: str) -> float:
    """The mean difference (of 255) between two :func:`photo_fingerprint` cells."""
    x, y = bytes.fromhex(a), bytes.fromhex(b)
    if len(x) != len(y) or not x:
        raise ValueError("expected two fingerprints of the same length")
    return sum(abs(i - j) for i, j in zip(x, y, strict=True)) / len(x)


def _is_hex(text: str) -> bool:
    return all(c in "0123456789abcdefABCDEF" for c in text)


__all__ = ["FINGERPRINT_CELLS", "FINGERPRINT_SAMPLES", "FINGERPRINT_TOLERANCE", "PhotoIdentity",
           "fingerprint_distance", "photo_fingerprint"]
