"""An extremely thin photo stays visible on the canvas: a side shown thinner than
``MIN_SHOWN_PX`` is stretched to it (a 1 x 4000 photo fitted at about 15 % was a fifth of a
pixel wide); every other photo keeps its aspect, and clicks map to the photo as it is drawn."""

from __future__ import annotations

import numpy as np
import pytest
from PySide6.QtCore import QPointF, Qt
from PySide6.QtGui import QImage

from app.canvas import MIN_SHOWN_PX, ImageCanvas, qimage_from_array

COLOUR = (250, 200, 40)  # far from the canvas's dark grey


def _canvas(qtbot, image: QImage) -> ImageCanvas:
    canvas = ImageCanvas()
    qtbot.addWidget(canvas)
    canvas.resize(640, 480)
    canvas.show()
    canvas.set_image(image)
    return canvas


def _photo(h: int, w: int) -> QImage:
    return qimage_from_array(np.broadcast_to(np.array(COLOUR, np.uint8), (h, w, 3)).copy())


def _shown(canvas: ImageCanvas) -> np.ndarray:
    """Where the grabbed canvas shows the photo's colour (``H x W`` bool, widget pixels)."""
    img = canvas.grab().toImage().convertToFormat(QImage.Format.Format_RGB888)
    img = img.scaled(canvas.width(), canvas.height())  # (a high-DPI grab to widget pixels)
    rows = np.frombuffer(img.constBits(), np.uint8).reshape(img.height(), img.bytesPerLine())
    rgb = rows[:, : 3 * img.width()].reshape(img.height(), img.width(), 3).astype(int)
    return np.abs(rgb - np.array(COLOUR)).max(axis=-1) < 40


@pytest.mark.parametrize("h, w", [(4000, 1), (1, 4000), (4000, 3)])
def test_a_thin_photo_is_shown_at_least_min_shown_px_thick(qtbot, h: int, w: int) -> None:
    canvas = _canvas(qtbot, _photo(h, w))
    zoom = canvas.zoom()
    assert min(h, w) * zoom < 1.0  # as its zoom alone would show it: under a pixel
    rect = canvas.image_rect()
    long_side = rect.height() if h > w else rect.width()
    assert long_side == pytest.approx(max(h, w) * zoom)  # the long side as zoomed
    assert min(rect.width(), rect.height()) == pytest.approx(MIN_SHOWN_PX)
    assert rect.center().x() == pytest.approx(canvas.width() / 2)  # fitted: centred
    assert rect.center().y() == pytest.approx(canvas.height() / 2)
    shown = _shown(canvas)
    thick = shown.sum(axis=1).max() if h > w else shown.sum(axis=0).max()
    assert thick >= MIN_SHOWN_PX - 1  # drawn, not a fraction of a pixel
    assert shown.sum() >= (MIN_SHOWN_PX - 1) * (long_side - 2)
    # Clicks and strokes map to the photo as drawn: its middle is the photo's middle.
    centre = rect.center()
    x, y = canvas.image_fraction(centre)
    assert (x, y) == (pytest.approx(0.5, abs=0.01), pytest.approx(0.5, abs=0.01))
    pt = QPointF(0.25 * w, 0.75 * h)
    back = canvas.widget_to_image(canvas.image_to_widget(pt))
    assert (back.x(), back.y()) == (pytest.approx(pt.x()), pytest.approx(pt.y()))
    with qtbot.waitSignal(canvas.image_clicked) as clicked:
        canvas.set_click_tool(True)
        qtbot.mouseClick(canvas, Qt.MouseButton.LeftButton, pos=centre.toPoint())
    assert all(0.0 <= f < 1.0 for f in clicked.args)
    # Zooming about a point keeps the photo's point under it, the thin side still stretched.
    anchor = QPointF(centre.x(), rect.top() + 0.3 * rect.height())
    before = canvas.widget_to_image(anchor)
    canvas.set_zoom(2 * zoom, anchor)
    after = canvas.widget_to_image(anchor)
    assert (after.x(), after.y()) == (pytest.approx(before.x()), pytest.approx(before.y()))
    assert min(canvas.image_rect().width(), canvas.image_rect().height()) == pytest.approx(
        MIN_SHOWN_PX)


@pytest.mark.parametrize("h, w", [(3000, 4000), (4000, 100), (96, 128)])
def test_other_photos_keep_their_aspect(qtbot, h: int, w: int) -> None:
    """A normal photo, and a narrow one still wider than MIN_SHOWN_PX as fitted, are drawn
    at the zoom on both sides."""
    canvas = _canvas(qtbot, _photo(h, w))
    zoom = canvas.zoom()
    assert canvas.scale() == (zoom, zoom)
    rect = canvas.image_rect()
    assert (rect.width(), rect.height()) == (pytest.approx(w * zoom), pytest.approx(h * zoom))
