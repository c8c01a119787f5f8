"""The canvas keeps a display-size copy of an image shown smaller than it is, so repaints while
dragging (a new preview each time) do not filter the whole photo again."""

from __future__ import annotations

import numpy as np
from PySide6.QtGui import QImage

from app.canvas import ImageCanvas, qimage_from_array


def _image(h: int, w: int, seed: int) -> QImage:
    rng = np.random.default_rng(seed)
    return qimage_from_array(rng.integers(0, 256, (h, w, 3), dtype=np.uint8))


def test_big_photo_is_scaled_once_for_many_repaints(qtbot) -> None:
    canvas = ImageCanvas()
    qtbot.addWidget(canvas)
    canvas.resize(400, 300)
    canvas.show()
    photo = _image(1500, 2000, 0)
    canvas.set_image(photo)
    canvas.grab()
    copies = dict(canvas._scaled)
    assert len(copies) == 1
    (key, shown), = copies.items()
    assert key[0] == photo.cacheKey()
    assert shown.width() < 500 and shown.height() < 400  # display size, not 2000 x 1500
    for k in range(5):  # previews arriving while dragging: small after-images, split view
        canvas.set_after(_image(96, 128, k + 1))
        canvas.set_split(0.5, ("Original", "Relit"))
        canvas.grab()
    assert canvas._scaled[key] is shown  # the photo was not scaled again
    assert len(canvas._scaled) == 1  # small images are drawn as they are


def test_display_copy_only_when_shown_smaller(qtbot) -> None:
    canvas = ImageCanvas()
    qtbot.addWidget(canvas)
    small = _image(30, 40, 3)
    from PySide6.QtCore import QRectF

    assert canvas.display_copy(small, QRectF(0, 0, 80, 60)) is small
    big = canvas.display_copy(small, QRectF(0, 0, 20, 15))
    assert (big.width(), big.height()) == (round(20 * canvas.devicePixelRatioF()),
                                           round(15 * canvas.devicePixelRatioF()))
