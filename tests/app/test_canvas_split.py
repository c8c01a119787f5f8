"""The before/after split's labels: each is drawn whole on its own side of the photo or not at
all (at the split's end the empty side's label showed as a cut-off sliver: a user trial)."""

from __future__ import annotations

import numpy as np
import pytest

from app.canvas import ImageCanvas, qimage_from_array


def _drawn(qtbot, split: float, zoom: float | None = None,
           shape: tuple[int, int] = (300, 400)) -> list[str]:
    canvas = ImageCanvas()
    qtbot.addWidget(canvas)
    canvas.resize(640, 480)
    canvas.show()
    canvas.set_image(qimage_from_array(np.full((*shape, 3), 90, np.uint8)))
    canvas.set_after(qimage_from_array(np.full((*shape, 3), 200, np.uint8)))
    if zoom is not None:
        canvas.set_zoom(zoom)
    canvas.set_split(split, ("Original", "Relit"))
    shown: list[str] = []
    real = canvas.split_label_boxes

    def spy(*args):
        boxes = real(*args)
        shown.extend(text for text, _ in boxes)
        left, right = args[2], args[3]
        assert all(left <= box.left() and box.right() <= right for _, box in boxes)
        return boxes

    canvas.split_label_boxes = spy  # type: ignore[method-assign]
    canvas.grab()
    return shown


@pytest.mark.parametrize("split, labels", [(0.0, ["Relit"]), (0.5, ["Original", "Relit"]),
                                           (1.0, ["Original"]), (0.01, ["Relit"])])
def test_a_label_is_whole_or_not_drawn(qtbot, split: float, labels: list[str]) -> None:
    assert _drawn(qtbot, split) == labels


def test_labels_keep_to_the_visible_part_of_a_zoomed_photo(qtbot) -> None:
    """Zoomed in, the photo runs past the canvas: a label is kept within what is seen (the
    split near the canvas's left edge leaves no room for "Original" there, however much of
    the photo runs off to the left)."""
    assert _drawn(qtbot, 0.5, zoom=4.0) == ["Original", "Relit"]
    assert _drawn(qtbot, 0.31, zoom=4.0) == ["Relit"]


def test_a_strip_too_low_for_its_labels_shows_none(qtbot) -> None:
    """A 20:1 photo fitted to the canvas is 32 px high: the labels would cover most of it (a
    user trial), so neither is drawn; a 4:1 one (160 px) keeps both."""
    assert _drawn(qtbot, 0.5, shape=(30, 600)) == []
    assert _drawn(qtbot, 0.5, shape=(150, 600)) == ["Original", "Relit"]
