"""The image canvas: zoom and pan, a tinted shadow overlay, and a before/after split.

Layers, painted in order (each a small overridable step):

1. ``before``: the photo (full resolution when available).
2. ``overlay``: step 1's predicted shadows, tinted, with an opacity.
3. ``after``: step 2's relit image, drawn right of the split line (or everywhere without split).

All layers are drawn into the same rectangle, whatever their own resolution, so a working-size
relit image lines up with the full-size photo; a side of it shown thinner than
``MIN_SHOWN_PX`` is stretched to that, so a strip-shaped photo stays visible (the zoom is
otherwise the same across and down). Wheel zooms about the cursor, dragging pans,
double-click fits the image to the window. With a click tool on (:meth:`ImageCanvas.set_click_tool`,
step 2's shadow corrections) a click on the image (press and release without dragging) emits
:attr:`ImageCanvas.image_clicked`, and a drag that starts on the image paints a brush stroke
(:meth:`ImageCanvas.set_brush`; drawn as a translucent path while it lasts, emitted once on
release as :attr:`ImageCanvas.stroke_painted`); the middle button still pans, and a drag that
starts on the split line or beside the image still moves the line or pans. The brush's circle
follows the cursor over the image.
"""

from __future__ import annotations

import math

import numpy as np
from PySide6.QtCore import QEvent, QLineF, QPointF, QRectF, QSize, Qt, Signal
from PySide6.QtGui import (
    QColor,
    QCursor,
    QFont,
    QFontMetrics,
    QImage,
    QMouseEvent,
    QPainter,
    QPainterPath,
    QPaintEvent,
    QPen,
    QResizeEvent,
    QWheelEvent,
)
from PySide6.QtWidgets import QApplication, QSizePolicy, QWidget

MIN_ZOOM = 0.02
MAX_ZOOM = 16.0
#: The fewest widget pixels an image is shown across either side: a thinner one is stretched
#: across its short side to this (a 1 x 4000 photo fitted at 19 % was a fifth of a pixel wide,
#: invisible); any image at least this wide and high at the zoom keeps its aspect.
MIN_SHOWN_PX = 8.0
#: The before/after labels are drawn only where the photo is shown at least this many labels
#: high (:meth:`ImageCanvas.split_label_boxes`).
LABEL_ROOM = 3.0


def shown_scale(zoom: float, width: int, height: int) -> tuple[float, float]:
    """Widget pixels per image pixel across and down for an image of ``width x height`` at
    ``zoom``: the zoom on both, except on a side shown thinner than :data:`MIN_SHOWN_PX`, which
    is stretched to it.

    Example:
        >>> shown_scale(0.19, 4000, 3000)
        (0.19, 0.19)
        >>> shown_scale(0.19, 1, 4000)
        (8.0, 0.19)
    """
    return (max(zoom, min(MIN_SHOWN_PX / max(width, 1), MAX_ZOOM)),
            max(zoom, min(MIN_SHOWN_PX / max(height, 1), MAX_ZOOM)))


def qimage_from_array(array: np.ndarray) -> QImage:
    """Wrap an ``H x W x 3`` (RGB) or ``H x W x 4`` (RGBA) uint8 array as a QImage (copied)."""
    a = np.ascontiguousarray(array)
    if a.dtype != np.uint8 or a.ndim != 3 or a.shape[2] not in (3, 4):
        raise ValueError(f"expected H x W x 3|4 uint8, got {a.shape} {a.dtype}")
    h, w, c = a.shape
    fmt = QImage.Format.Format_RGB888 if c == 3 else QImage.Format.Format_RGBA8888
    return QImage(a.data, w, h, c * w, fmt).copy()


class ImageCanvas(QWidget):
    """Zoomable, pannable view of the photo with overlay and before/after split.

    Signals:
        zoom_changed(zoom): the zoom factor (1.0 = one image pixel per screen pixel).
        split_dragged(fraction): the user dragged the before/after line.
        image_clicked(x, y): with a click tool on, a click on the image, as fractions (0-1) of
            its width and height.
        stroke_painted(points, radius): with a click tool on, a drag painted on the image:
            the brush dabs' centres, ``[(x, y), ...]`` fractions as for ``image_clicked``, at
            most half the brush's radius apart (a dab whose centre is off the image but whose
            disc reaches it is moved onto the image's edge; those that miss it are left out),
            and the brush's radius when the stroke began (the whole stroke is painted with
            it, whatever ``[`` and ``]`` do meanwhile).
    """

    zoom_changed = Signal(float)
    split_dragged = Signal(float)
    image_clicked = Signal(float, float)
    #: A click tool's click that fell on the before | after line (which took it, to move the
    #: line) and did not move it: the window says so (a user trial's click there did nothing).
    split_clicked = Signal()
    stroke_painted = Signal(object, float)

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self._before: QImage | None = None
        self._after: QImage | None = None
        self._overlay: QImage | None = None
        self._overlay_opacity = 0.6
        self._overlay_least = 0.0
        self._split: float | None = None
        self._labels = ("Before", "After")
        self._zoom = 1.0
        self._offset = QPointF(0.0, 0.0)  # widget position of the image's top-left corner
        self._fit = True
        self._pan_from: QPointF | None = None
        self._dragging_split = False
        self._split_press: QPointF | None = None  # where a press on the split line was
        self._click_tool = False
        #: With a click tool on: where the left button went down (widget coordinates) and the
        #: image point under it then (the pan may move the image a pixel or two before release).
        self._press: tuple[QPointF, QPointF] | None = None
        #: The brush: radius (fraction of the image's longer side) and the colour of a stroke.
        self._brush = 0.02
        self._brush_colour = QColor(255, 255, 255)
        self._brush_soft = 0.0
        #: A stroke being painted: the dabs' centres and the mouse's path (image pixels), the
        #: last mouse point, how far the path went since the last dab, and the brush's radius
        #: when it began (the stroke's, to its end).
        self._stroke: list[QPointF] | None = None
        self._stroke_brush = 0.0
        self._stroke_path = QPainterPath()
        self._stroke_last = QPointF()
        self._stroke_carry = 0.0
        self._hover: QPointF | None = None  # where the brush's circle is drawn (widget)
        self._empty_text = "Open a photo (Ctrl+O) or drop one here"
        self.overlay_updates = 0  # counted for tests and the benchmark
        self.after_updates = 0  # relit images shown (step 2), counted likewise
        #: Display-size copies of images shown smaller than they are (key: image, size), so a
        #: repaint (every preview while dragging) blits instead of filtering the whole photo.
        self._scaled: dict[tuple[int, int, int], QImage] = {}
        self.setMinimumSize(320, 240)
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Expanding)
        self.setMouseTracking(False)
        self.setAutoFillBackground(False)
        self.setFocusPolicy(Qt.FocusPolicy.ClickFocus)
        self.setAccessibleName("Image canvas")

    # ------------------------------------------------------------------ content
    def set_empty_text(self, text: str) -> None:
        self._empty_text = text
        self.update()

    def set_image(self, image: QImage | None, fit: bool = True) -> None:
        """Set the base photo; clears overlay and after-image."""
        self._before = image
        self._after = None
        self._overlay = None
        self._split = None
        if fit:
            self.fit()
        self.update()

    def image_size(self) -> QSize:
        return QSize() if self._before is None else self._before.size()

    def before(self) -> QImage | None:
        return self._before

    def after(self) -> QImage | None:
        return self._after

    def overlay(self) -> QImage | None:
        return self._overlay

    def set_after(self, image: QImage | None) -> None:
        self._after = image
        self.after_updates += 1
        self.update()

    def set_overlay(self, image: QImage | None, least_opacity: float = 0.0) -> None:
        """Draw ``image`` over the photo at the overlay opacity, or at ``least_opacity`` where
        that is higher (step 2's found shadows: the view is the tint, and step 1's opacity
        slider at 0 left it blank with no control in step 2: a user trial)."""
        self._overlay = image
        self._overlay_least = float(min(1.0, max(0.0, least_opacity)))
        self.overlay_updates += 1
        self.update()

    def overlay_opacity(self) -> float:
        """The opacity the overlay is drawn at (the slider's, or the overlay's least)."""
        return max(self._overlay_opacity, self._overlay_least)

    def set_overlay_opacity(self, opacity: float) -> None:
        self._overlay_opacity = float(min(1.0, max(0.0, opacity)))
        self.update()

    def set_split(self, fraction: float | None, labels: tuple[str, str] = ("Before", "After")):
        """Before/after split at ``fraction`` of the width (None: the after-image everywhere)."""
        self._split = None if fraction is None else float(min(1.0, max(0.0, fraction)))
        self._labels = labels
        self.update()

    def split(self) -> float | None:
        return self._split

    def split_labels(self) -> tuple[str, str]:
        """The split's labels (left, right side)."""
        return self._labels

    def set_click_tool(self, on: bool) -> None:
        """Turn the click tool on or off: a crosshair and the brush's circle over the image; a
        click there emits :attr:`image_clicked`, a drag :attr:`stroke_painted`."""
        self._click_tool = bool(on)
        self._press = None
        self._end_stroke()
        self.setMouseTracking(self._click_tool)  # the cursor follows the image's edge
        self._update_cursor(self.mapFromGlobal(QCursor.pos()).toPointF())

    def click_tool(self) -> bool:
        return self._click_tool

    def set_brush(self, radius: float, colour: QColor | None = None,
                  soft: float | None = None) -> None:
        """The brush: its radius as a fraction of the image's longer side (its circle follows
        the cursor), the colour a stroke is drawn in while painted, and ``soft``: the share of
        the radius, inward from its edge, over which what the brush does fades in (0: a hard
        brush, one circle; above 0, a dashed inner circle shows where it works at full
        strength). None keeps the colour and softness as they are."""
        self._brush = max(0.0, float(radius))
        if colour is not None:
            self._brush_colour = QColor(colour)
        if soft is not None:
            self._brush_soft = min(1.0, max(0.0, float(soft)))
        self.update()

    def brush_soft(self) -> float:
        """The share of the brush's radius over which it fades in (:meth:`set_brush`)."""
        return self._brush_soft

    def brush(self) -> float:
        return self._brush

    def brush_pixels(self, radius: float | None = None) -> float:
        """The brush's radius (or ``radius``, a fraction of the longer side) in image pixels
        (0 without an image)."""
        if self._before is None or self._before.isNull():
            return 0.0
        radius = self._brush if radius is None else radius
        return radius * max(self._before.width(), self._before.height())

    def painting(self) -> bool:
        """Whether a stroke is being painted (the left button held after a drag)."""
        return self._stroke is not None

    def cancel_stroke(self) -> bool:
        """Drop the stroke being painted, or the click tool's press not yet released (its
        release then adds nothing), as ending the tool does; returns whether there was one."""
        busy = self._stroke is not None or self._press is not None
        self._press = None
        self._end_stroke()
        return busy

    def image_fraction(self, pos: QPointF) -> tuple[float, float] | None:
        """The image point under ``pos`` (widget coordinates) as fractions of its width and
        height, or None outside the image."""
        if self._before is None or self._before.isNull():
            return None
        pt = self.widget_to_image(pos)
        x, y = pt.x() / self._before.width(), pt.y() / self._before.height()
        return (x, y) if 0.0 <= x < 1.0 and 0.0 <= y < 1.0 else None

    def _update_cursor(self, pos: QPointF) -> None:
        on_image = self._click_tool and self.image_fraction(pos) is not None
        if on_image:
            self.setCursor(Qt.CursorShape.CrossCursor)
        else:
            self.unsetCursor()
        self._move_hover(pos if on_image else None)

    def _brush_rect(self, centre: QPointF) -> QRectF:
        """The widget area the brush's circle at ``centre`` covers."""
        r = self.brush_pixels() * max(self.scale()) + 3.0
        return QRectF(centre.x() - r, centre.y() - r, 2 * r, 2 * r)

    def _move_hover(self, pos: QPointF | None) -> None:
        """Draw the brush's circle at ``pos`` (None: nowhere), repainting only round it."""
        if pos == self._hover:
            return
        for centre in (self._hover, pos):
            if centre is not None:
                self.update(self._brush_rect(centre).toAlignedRect())
        self._hover = pos

    # ------------------------------------------------------------------ view transform
    def zoom(self) -> float:
        return self._zoom

    def scale(self) -> tuple[float, float]:
        """Widget pixels per image pixel across and down (:func:`shown_scale`): the zoom, but
        for a side of the image shown thinner than :data:`MIN_SHOWN_PX`."""
        if self._before is None or self._before.isNull():
            return self._zoom, self._zoom
        return shown_scale(self._zoom, self._before.width(), self._before.height())

    def fit(self) -> None:
        """Fit the whole image in the widget."""
        self._fit = True
        if self._before is None or self._before.isNull():
            return
        iw, ih = self._before.width(), self._before.height()
        margin = 8.0
        z = min((self.width() - 2 * margin) / iw, (self.height() - 2 * margin) / ih)
        self._zoom = float(min(MAX_ZOOM, max(MIN_ZOOM, z)))
        sx, sy = self.scale()
        self._offset = QPointF((self.width() - iw * sx) / 2, (self.height() - ih * sy) / 2)
        self.zoom_changed.emit(self._zoom)
        self.update()

    def set_zoom(self, zoom: float, anchor: QPointF | None = None) -> None:
        """Zoom keeping the image point under ``anchor`` (widget coordinates) in place."""
        if self._before is None:
            return
        zoom = float(min(MAX_ZOOM, max(MIN_ZOOM, zoom)))
        if anchor is None:
            anchor = QPointF(self.width() / 2.0, self.height() / 2.0)
        img_pt = self.widget_to_image(anchor)
        self._zoom = zoom
        sx, sy = self.scale()
        self._offset = anchor - QPointF(img_pt.x() * sx, img_pt.y() * sy)
        self._fit = False
        self.zoom_changed.emit(self._zoom)
        self.update()

    def image_rect(self) -> QRectF:
        """Where the image lies in widget coordinates."""
        if self._before is None:
            return QRectF()
        sx, sy = self.scale()
        return QRectF(
            self._offset.x(),
            self._offset.y(),
            self._before.width() * sx,
            self._before.height() * sy,
        )

    def widget_to_image(self, pos: QPointF) -> QPointF:
        sx, sy = self.scale()
        d = pos - self._offset
        return QPointF(d.x() / sx, d.y() / sy)

    def image_to_widget(self, pt: QPointF) -> QPointF:
        sx, sy = self.scale()
        return self._offset + QPointF(pt.x() * sx, pt.y() * sy)

    # ------------------------------------------------------------------ painting
    def paintEvent(self, event: QPaintEvent) -> None:
        p = QPainter(self)
        p.fillRect(self.rect(), QColor(38, 38, 40))
        if self._before is None:
            self.paint_empty_state(p)
            p.end()
            return
        p.setRenderHint(QPainter.RenderHint.SmoothPixmapTransform, self._zoom < 2.0)
        rect = self.image_rect()
        self.paint_before(p, rect)
        self.paint_overlay(p, rect)
        self.paint_after(p, rect)
        self.paint_brush(p)
        p.end()

    def paint_empty_state(self, p: QPainter) -> None:
        p.setPen(QColor(170, 170, 170))
        font = QFont(self.font())
        font.setPointSizeF(font.pointSizeF() * 1.3)
        p.setFont(font)
        p.drawText(self.rect(), Qt.AlignmentFlag.AlignCenter, self._empty_text)

    def display_copy(self, image: QImage, rect: QRectF) -> QImage:
        """``image`` at the device size of ``rect`` when shown smaller than it is (smoothly
        scaled once and kept for the next repaints), else ``image`` itself."""
        dpr = self.devicePixelRatioF()
        tw, th = round(rect.width() * dpr), round(rect.height() * dpr)
        if tw < 1 or th < 1 or (tw >= image.width() and th >= image.height()):
            return image
        key = (image.cacheKey(), tw, th)
        scaled = self._scaled.get(key)
        if scaled is None:
            scaled = image.scaled(tw, th, Qt.AspectRatioMode.IgnoreAspectRatio,
                                  Qt.TransformationMode.SmoothTransformation)
            while len(self._scaled) >= 4:  # the photo and the relit image at one or two zooms
                self._scaled.pop(next(iter(self._scaled)))
            self._scaled[key] = scaled
        return scaled

    def paint_before(self, p: QPainter, rect: QRectF) -> None:
        shown = self.display_copy(self._before, rect)
        p.drawImage(rect, shown, QRectF(shown.rect()))

    def paint_overlay(self, p: QPainter, rect: QRectF) -> None:
        opacity = self.overlay_opacity()
        if self._overlay is None or opacity <= 0.0:
            return
        p.save()
        p.setOpacity(opacity)
        p.drawImage(rect, self._overlay)
        p.restore()

    def paint_after(self, p: QPainter, rect: QRectF) -> None:
        if self._after is None:
            return
        after = self.display_copy(self._after, rect)
        if self._split is None:
            p.drawImage(rect, after, QRectF(after.rect()))
            return
        x = rect.left() + rect.width() * self._split
        right = QRectF(x, rect.top(), rect.right() - x, rect.height())
        src_x = after.width() * self._split
        src = QRectF(src_x, 0.0, after.width() - src_x, after.height())
        p.drawImage(right, after, src)
        p.setPen(QPen(QColor(255, 255, 255, 220), 2.0))
        top, bottom = max(rect.top(), 0.0), min(rect.bottom(), float(self.height()))
        p.drawLine(QPointF(x, top), QPointF(x, bottom))
        self.paint_split_labels(p, x, top, max(rect.left(), 0.0),
                                min(rect.right(), float(self.width())), bottom)

    def paint_brush(self, p: QPainter) -> None:
        """The stroke being painted (a translucent band the brush's width along the mouse's
        path), and the brush's circle under the cursor."""
        radius = self.brush_pixels()
        if radius <= 0:
            return
        p.save()
        p.setRenderHint(QPainter.RenderHint.Antialiasing, True)
        if self._stroke is not None:
            p.save()
            p.translate(self._offset)
            p.scale(*self.scale())
            colour = QColor(self._brush_colour)
            colour.setAlpha(110)
            pen = QPen(colour, 2.0 * self.brush_pixels(self._stroke_brush),
                       Qt.PenStyle.SolidLine, Qt.PenCapStyle.RoundCap,
                       Qt.PenJoinStyle.RoundJoin)
            p.setPen(pen)
            p.setBrush(Qt.BrushStyle.NoBrush)
            p.drawPath(self._stroke_path)
            p.restore()
        if self._hover is not None:
            r = radius * self._zoom
            p.setBrush(Qt.BrushStyle.NoBrush)
            for colour, width in ((QColor(0, 0, 0, 160), 3.0), (QColor(255, 255, 255), 1.0)):
                p.setPen(QPen(colour, width))
                p.drawEllipse(self._hover, r, r)
            inner = r * (1.0 - self._brush_soft)
            if self._brush_soft > 0 and inner >= 3.0:  # a soft brush: full strength within
                for colour, width in ((QColor(0, 0, 0, 120), 2.0),
                                      (QColor(255, 255, 255, 200), 1.0)):
                    p.setPen(QPen(colour, width, Qt.PenStyle.DashLine))
                    p.drawEllipse(self._hover, inner, inner)
        p.restore()

    def split_label_boxes(self, x: float, top: float, left: float, right: float,
                          bottom: float | None = None) -> list[tuple[str, QRectF]]:
        """The split's labels and their boxes beside the line at ``x``; a label whose side of
        the photo (``left`` .. ``right``: its visible part) is too narrow to hold it whole is
        left out (at the split's end one showed as a cut-off sliver: a user trial), and so
        are both where the photo's visible height (``top`` .. ``bottom``) is less than
        :data:`LABEL_ROOM` labels high (a 20:1 strip shown 47 px high was mostly label, a
        user trial)."""
        font = QFont(self.font())
        font.setBold(True)
        fm = QFontMetrics(font)
        if bottom is not None and bottom - top < LABEL_ROOM * (fm.height() + 6):
            return []
        boxes = []
        for text, right_side in ((self._labels[0], False), (self._labels[1], True)):
            w = fm.horizontalAdvance(text) + 12
            h = fm.height() + 6
            bx = x + 8 if right_side else x - 8 - w
            if bx < left or bx + w > right:
                continue
            boxes.append((text, QRectF(bx, top + 8, w, h)))
        return boxes

    def paint_split_labels(self, p: QPainter, x: float, top: float, left: float,
                           right: float, bottom: float | None = None) -> None:
        font = QFont(self.font())
        font.setBold(True)
        p.setFont(font)
        for text, box in self.split_label_boxes(x, top, left, right, bottom):
            p.setPen(Qt.PenStyle.NoPen)
            p.setBrush(QColor(0, 0, 0, 140))
            p.drawRoundedRect(box, 4, 4)
            p.setPen(QColor(255, 255, 255))
            p.drawText(box, Qt.AlignmentFlag.AlignCenter, text)

    # ------------------------------------------------------------------ events
    def resizeEvent(self, event: QResizeEvent) -> None:
        if self._fit:
            self.fit()
        super().resizeEvent(event)

    def wheelEvent(self, event: QWheelEvent) -> None:
        steps = event.angleDelta().y() / 120.0
        if steps and self._before is not None:
            self.set_zoom(self._zoom * (1.25**steps), event.position())
        event.accept()

    def _split_x(self) -> float | None:
        if self._split is None or self._after is None or self._before is None:
            return None
        rect = self.image_rect()
        return rect.left() + rect.width() * self._split

    def mousePressEvent(self, event: QMouseEvent) -> None:
        if self._press is not None:
            if event.button() != Qt.MouseButton.LeftButton:
                event.accept()  # another button while the left one paints or clicks: ignored
                return
            self._lost_release()  # a left press again: the last one's release never came
        x = self._split_x()
        near_split = x is not None and abs(event.position().x() - x) <= 6.0
        self._press = None
        self._split_press = None
        if event.button() == Qt.MouseButton.LeftButton and near_split:
            self._dragging_split = True
            self._split_press = event.position()
            self.setCursor(Qt.CursorShape.SplitHCursor)
            event.accept()
        elif (self._click_tool and event.button() == Qt.MouseButton.LeftButton
              and self.image_fraction(event.position()) is not None):
            # On the image: a click, or (once it moves) a brush stroke; no pan.
            self._press = (event.position(), self.widget_to_image(event.position()))
            event.accept()
        elif event.button() in (Qt.MouseButton.LeftButton, Qt.MouseButton.MiddleButton):
            self._pan_from = event.position()
            self.setCursor(Qt.CursorShape.ClosedHandCursor)
            event.accept()
        else:
            super().mousePressEvent(event)

    def mouseMoveEvent(self, event: QMouseEvent) -> None:
        if self._dragging_split:
            rect = self.image_rect()
            fraction = (event.position().x() - rect.left()) / max(rect.width(), 1e-9)
            self.set_split(fraction, self._labels)
            self.split_dragged.emit(self._split)
            event.accept()
        elif self._pan_from is not None:
            self._offset += event.position() - self._pan_from
            self._pan_from = event.position()
            self._fit = False
            self.update()
            event.accept()
        elif self._press is not None:  # a click tool's press: a stroke once it moves
            if not event.buttons() & Qt.MouseButton.LeftButton:
                self._lost_release()  # (a modal box took it)
                self._update_cursor(event.position())
                return
            if self._stroke is None:
                moved = (event.position() - self._press[0]).manhattanLength()
                if moved < QApplication.startDragDistance():
                    return
                self._begin_stroke(self._press[1])
            self._extend_stroke(self.widget_to_image(event.position()))
            self._move_hover(event.position())
            event.accept()
        elif self._click_tool:  # (mouse tracking) crosshair over the image only
            self._update_cursor(event.position())

    def mouseReleaseEvent(self, event: QMouseEvent) -> None:
        if self._press is not None and event.button() != Qt.MouseButton.LeftButton:
            event.accept()  # (its press was ignored: the left button paints on)
            return
        press, self._press = self._press, None
        split_press, self._split_press = self._split_press, None
        self._pan_from = None
        self._dragging_split = False
        self.unsetCursor()
        if self._stroke is not None and event.button() == Qt.MouseButton.LeftButton:
            self._finish_stroke(self.widget_to_image(event.position()))
        elif press is not None and event.button() == Qt.MouseButton.LeftButton:
            moved = (event.position() - press[0]).manhattanLength()
            if moved < QApplication.startDragDistance() and self._before is not None:
                # a click, not a drag: the image point under the press
                x = press[1].x() / self._before.width()
                y = press[1].y() / self._before.height()
                if 0.0 <= x < 1.0 and 0.0 <= y < 1.0:
                    self.image_clicked.emit(x, y)
        elif (split_press is not None and self._click_tool
              and event.button() == Qt.MouseButton.LeftButton
              and (event.position() - split_press).manhattanLength()
              < QApplication.startDragDistance()):
            self.split_clicked.emit()
        self._update_cursor(event.position())
        super().mouseReleaseEvent(event)

    def leaveEvent(self, event: QEvent) -> None:
        self._move_hover(None)
        super().leaveEvent(event)

    def _lost_release(self) -> None:
        """The left button is up but its release never came (a modal box opened during the
        drag took it): a stroke ends where the mouse was last seen with it down and is added,
        as painted (what the band showed is what is added, one undo away; dropped, the
        painting would vanish unsaid); a press not yet a stroke is no click (where it ended
        is not known)."""
        self._press = None
        self._finish_stroke()

    # ------------------------------------------------------------------ brush strokes
    def _begin_stroke(self, start: QPointF) -> None:
        self._stroke = [QPointF(start)]
        self._stroke_path = QPainterPath(start)
        self._stroke_last = QPointF(start)
        self._stroke_carry = 0.0
        self._stroke_brush = self._brush  # the stroke's radius, to its end

    def _finish_stroke(self, point: QPointF | None = None) -> None:
        """End the stroke being painted at ``point`` (image pixels; None: its last point) and
        emit :attr:`stroke_painted` (unless no dab reaches the image)."""
        if self._stroke is None:
            return
        self._extend_stroke(self._stroke_last if point is None else point, last=True)
        points, radius = self._stroke_points(), self._stroke_brush
        self._end_stroke()
        if points:
            self.stroke_painted.emit(points, radius)

    def _extend_stroke(self, point: QPointF, last: bool = False) -> None:
        """Carry the stroke on to ``point`` (image pixels): a dab every half radius along the
        way, whatever the distance between mouse events (a fast drag leaves no gap); ``last``:
        one more at ``point`` itself, where the stroke ends."""
        assert self._stroke is not None
        radius = self.brush_pixels(self._stroke_brush)
        spacing = max(0.5, 0.5 * radius)
        start = self._stroke_last
        length = QLineF(start, point).length()
        if length > 0:
            step = (point - start) / length
            at = spacing - self._stroke_carry  # how far along to the next dab
            while at <= length:
                self._stroke.append(start + step * at)
                at += spacing
            self._stroke_carry = length - (at - spacing)
            self._stroke_path.lineTo(point)
            self._stroke_last = QPointF(point)
            # Repaint only round the new piece of the path (the mouse moves often).
            pad = radius * max(self.scale()) + 3.0
            a, b = self.image_to_widget(start), self.image_to_widget(point)
            self.update(QRectF(a, b).normalized().adjusted(-pad, -pad, pad, pad).toAlignedRect())
        if last and self._stroke_carry > 0:
            self._stroke.append(QPointF(point))
            self._stroke_carry = 0.0

    def _stroke_points(self) -> list[tuple[float, float]]:
        """The stroke's dabs as fractions of the image's width and height: those whose disc
        reaches the image (as the band drawn along the path does), a centre off the image
        moved onto its edge (such dabs were left out: a drag just outside the edge painted
        nothing along it, though the band covered it); one moved onto the dab before it is
        left out."""
        if self._stroke is None or self._before is None or self._before.isNull():
            return []
        w, h = self._before.width(), self._before.height()
        reach = self.brush_pixels(self._stroke_brush)
        out: list[tuple[float, float]] = []
        for pt in self._stroke:
            x, y = min(max(pt.x(), 0.0), w), min(max(pt.y(), 0.0), h)
            if math.hypot(pt.x() - x, pt.y() - y) > reach:
                continue  # its disc misses the image
            point = (x / w, y / h)
            if not out or out[-1] != point:
                out.append(point)
        return out

    def _end_stroke(self) -> None:
        if self._stroke is not None:
            self._stroke = None
            self._stroke_path = QPainterPath()
            self.update()

    def mouseDoubleClickEvent(self, event: QMouseEvent) -> None:
        self.fit()
        event.accept()
