"""QtSunDial and its panel driven with simulated mouse and key events."""

from __future__ import annotations

import math

import pytest
from PySide6.QtCore import QPoint, QPointF, QRectF, Qt

from app import sun_dial_math as dm
from app.qt_sun_dial import FOCUS_RING_WIDTH, LABEL_GAP, QtSunDial, SunDialPanel


@pytest.fixture
def dial(qtbot):
    d = QtSunDial()
    qtbot.addWidget(d)
    d.resize(240, 240)
    d.show()
    qtbot.waitExposed(d)
    return d


def _point(dial, az, el) -> QPoint:
    cx, cy, r = dial.dial_geometry()
    x, y = dm.sun_to_point(az, el, cx, cy, r)
    return QPoint(round(x), round(y))


def test_drag_handle_moves_sun_and_signals(qtbot, dial):
    dial.set_sun(135.0, 45.0)
    changes, finished = [], []
    dial.sun_changed.connect(lambda a, e: changes.append((a, e, dial.is_dragging())))
    dial.drag_finished.connect(lambda a, e: finished.append((a, e)))
    qtbot.mousePress(dial, Qt.MouseButton.LeftButton, pos=_point(dial, 135.0, 45.0))
    for az in (150.0, 170.0, 200.0):
        qtbot.mouseMove(dial, _point(dial, az, 30.0))
    qtbot.mouseRelease(dial, Qt.MouseButton.LeftButton, pos=_point(dial, 200.0, 30.0))
    assert len(changes) >= 3 and all(drag for *_, drag in changes[:-1])
    az, el = dial.sun()
    assert az == pytest.approx(200.0, abs=1.0) and el == pytest.approx(30.0, abs=1.0)
    assert finished == [dial.sun()]


def test_click_on_sky_jumps_and_outside_ignored(qtbot, dial):
    dial.set_sun(0.0, 80.0)
    qtbot.mouseClick(dial, Qt.MouseButton.LeftButton, pos=_point(dial, 270.0, 10.0))
    az, el = dial.sun()
    assert az == pytest.approx(270.0, abs=1.5) and el == pytest.approx(10.0, abs=1.5)
    qtbot.mouseClick(dial, Qt.MouseButton.LeftButton, pos=QPoint(1, 1))  # corner, off the disc
    assert dial.sun() == (az, el)


def test_keyboard_nudges(qtbot, dial):
    dial.set_sun(359.5, 89.5)
    committed = []
    dial.sun_committed.connect(lambda a, e: committed.append((a, e)))
    dial.setFocus()
    qtbot.keyClick(dial, Qt.Key.Key_Right)
    assert dial.sun() == pytest.approx((0.5, 89.5))
    qtbot.keyClick(dial, Qt.Key.Key_Up)
    assert dial.elevation() == 90.0
    qtbot.keyClick(dial, Qt.Key.Key_Down, Qt.KeyboardModifier.ShiftModifier)
    assert dial.elevation() == pytest.approx(80.0)
    qtbot.keyClick(dial, Qt.Key.Key_Left, Qt.KeyboardModifier.ControlModifier)
    assert dial.azimuth() == pytest.approx(0.4)
    assert len(committed) == 4


def test_panel_fields_follow_dial_and_drive_it(qtbot):
    panel = SunDialPanel("Sun")
    qtbot.addWidget(panel)
    panel.resize(260, 380)
    panel.show()
    panel.set_sun(90.0, 45.0)
    assert panel.azimuth_box.value() == 90.0 and panel.elevation_box.value() == 45.0
    assert "1.00 × height" in panel.shadow_label.text()
    got = []
    panel.sun_committed.connect(lambda a, e: got.append((a, e)))
    panel.elevation_box.setValue(30.0)
    assert panel.sun() == (90.0, 30.0) and got == [(90.0, 30.0)]
    assert "1.73 × height" in panel.shadow_label.text()
    panel.dial.set_reference((10.0, 20.0))
    assert not panel.dial.grab().isNull()  # paints with a reference sun


def test_panel_says_when_sun_is_in_frame(qtbot):
    panel = SunDialPanel("Sun")
    qtbot.addWidget(panel)
    panel.set_fov(70.0, 50.0)
    panel.set_sun(10.0, 15.0)  # ahead, low: inside a 70 x 50 degree frame
    assert panel.dial.sun_in_view() and "in the frame" in panel.shadow_label.text()
    panel.set_sun(180.0, 15.0)
    assert not panel.dial.sun_in_view() and "in the frame" not in panel.shadow_label.text()


def test_a_tilted_camera_shades_the_suns_under_the_horizon(qtbot):
    """Pitched 20 degrees down, the true horizon ahead lies 20 degrees up on the dial: a sun
    there at 10 degrees is under the ground, and the panel says so; the EXIF ring follows."""
    panel = SunDialPanel("Sun")
    qtbot.addWidget(panel)
    panel.resize(300, 380)
    panel.dial.set_prior_elevation(40.0)
    panel.set_sun(0.0, 10.0)
    level = panel.dial.grab().toImage()
    assert not panel.dial.below_horizon(0.0, 10.0) and "horizon" not in panel.shadow_label.text()
    panel.set_tilt(-20.0, 0.0)
    assert panel.dial.tilt() == (-20.0, 0.0)
    assert panel.dial.below_horizon(0.0, 10.0) and not panel.dial.below_horizon(0.0, 25.0)
    assert not panel.dial.below_horizon(180.0, 1.0)  # behind: the horizon is off the dial
    assert "under the horizon" in panel.shadow_label.text()
    tilted = panel.dial.grab().toImage()
    # Ahead, between the rim and 20 degrees up, the dial is painted as ground now.
    cx, cy, r = panel.dial.dial_geometry()
    x, y = (round(v) for v in dm.sun_to_point(30.0, 5.0, cx, cy, r))  # beside the sun
    before, after = level.pixelColor(x, y), tilted.pixelColor(x, y)
    assert after.blue() < before.blue() - 40 and after.red() >= after.blue()  # brown, not blue
    with pytest.raises(ValueError, match="pitch"):
        panel.dial.set_tilt(float("nan"), 0.0)


#: Dial sizes from the side panel's: its smallest (150 px high, as narrow as that or as wide as
#: the panel at 1024 x 700) to its largest (300 px high in a panel about as wide).
DIAL_SIZES = [(150, 150), (290, 150), (302, 300), (240, 240), (300, 220), (500, 300)]


def _distance_to_rect(x: float, y: float, rect) -> float:
    """From a point to the nearest point of ``rect`` (0 inside it)."""
    nx = min(max(x, rect.left()), rect.right())
    ny = min(max(y, rect.top()), rect.bottom())
    return math.hypot(nx - x, ny - y)


@pytest.mark.parametrize("size", DIAL_SIZES)
def test_direction_labels_stand_outside_the_disc_at_every_size(qtbot, dial, size):
    """A user trial: in a narrow panel "right" was moved into the disc to stay in the widget
    (clipped by the circle), and the labels stood a fixed 22 px from the widget's edges. Each
    label is inside the widget and LABEL_GAP clear of the rim, the focus ring between them."""
    dial.resize(*size)
    cx, cy, r = dial.dial_geometry()
    bounds = QRectF(dial.rect())
    rects = dial.label_rects()
    assert sorted(rects) == [0, 90, 180, 270]
    ring_out = dial.focus_ring_radius() + FOCUS_RING_WIDTH / 2.0
    for az, rect in rects.items():
        assert bounds.contains(rect), (az, rect, bounds)
        gap = _distance_to_rect(cx, cy, rect)
        assert gap >= r + LABEL_GAP - 0.01, (az, gap, r)
        assert ring_out < gap
    # Each where it says: front above the disc, right to its right, ...
    assert rects[0].bottom() <= cy - r and rects[180].top() >= cy + r
    assert rects[90].left() >= cx + r and rects[270].right() <= cx - r


@pytest.mark.parametrize("size", DIAL_SIZES)
@pytest.mark.parametrize("sun", [(0.0, 5.0), (354.0, 15.0), (135.0, 10.0), (90.0, 2.0)])
def test_a_long_shadow_ruler_stops_inside_the_rim(qtbot, dial, size, sun):
    """A low sun's shadow is longer than the disc: its ruler ran to the rim and its "…" was
    drawn outside, on the "behind" label (a user trial). It ends inside the disc (its
    arrowhead too) and, ticks and all, crosses no label."""
    from PySide6.QtGui import QPainterPath, QPainterPathStroker

    from app.qt_sun_dial import RULER_INSET, RULER_REACH

    dial.resize(*size)
    dial.set_sun(*sun)
    cx, cy, r = dial.dial_geometry()
    line, capped = dial.shadow_ruler_line()
    assert capped
    assert line.p1().toTuple() == pytest.approx((cx, cy))
    assert math.hypot(line.x2() - cx, line.y2() - cy) == pytest.approx(r - RULER_INSET)
    path = QPainterPath(line.p1())
    path.lineTo(line.p2())
    stroker = QPainterPathStroker()
    stroker.setWidth(2.0 * RULER_REACH)
    ruler = stroker.createStroke(path)
    for az, rect in dial.label_rects().items():
        assert not ruler.intersects(rect), az


def test_a_short_shadow_ruler_keeps_its_length(qtbot, dial):
    dial.set_sun(200.0, 60.0)
    cx, cy, r = dial.dial_geometry()
    line, capped = dial.shadow_ruler_line()
    assert not capped
    assert line.length() == pytest.approx(r / 3.0 / math.tan(math.radians(60.0)), rel=1e-3)


@pytest.mark.parametrize("size", DIAL_SIZES)
@pytest.mark.parametrize("sun", [(354.0, 15.0), (0.0, 40.0), (180.0, 20.0), (10.0, 65.0)])
def test_ring_labels_keep_off_the_sun_and_the_ruler(qtbot, dial, size, sun):
    """At 1024 x 700 the sun sat on the "30°" label (a user trial: the labels always stood in
    front of the camera). They stand on a side the sun, its rays and the shadow ruler leave
    free, inside the disc, each outside its ring."""
    from PySide6.QtGui import QPainterPath, QPainterPathStroker

    from app.qt_sun_dial import RAY_RADIUS

    dial.resize(*size)
    dial.set_sun(*sun)
    cx, cy, r = dial.dial_geometry()
    placed = dial.ring_label_rects()
    if size[0] >= 240:  # (a dial 150 px wide has no room for them inside its disc)
        assert [text for text, _ in placed] == ["30°", "60°"]
    sun_disc = QPainterPath()
    sun_disc.addEllipse(dial.handle_position(), RAY_RADIUS, RAY_RADIUS)
    line, _ = dial.shadow_ruler_line()
    path = QPainterPath(line.p1())
    path.lineTo(line.p2())
    stroker = QPainterPathStroker()
    stroker.setWidth(8.0)  # its ticks reach 4 px to each side
    ruler = stroker.createStroke(path)
    for text, rect in placed:
        assert not sun_disc.intersects(rect), (text, rect)
        assert not ruler.intersects(rect), (text, rect)
        for corner in (rect.topLeft(), rect.topRight(), rect.bottomLeft(), rect.bottomRight()):
            assert math.hypot(corner.x() - cx, corner.y() - cy) <= r, (text, rect)


def test_ring_labels_stand_in_front_where_they_were_when_nothing_is_there(qtbot, dial):
    dial.resize(302, 300)
    dial.set_sun(135.0, 45.0)
    cx, cy, r = dial.dial_geometry()
    placed = dict(dial.ring_label_rects())
    for text, el in (("30°", 30.0), ("60°", 60.0)):
        rect = placed[text]
        assert rect.left() > cx and rect.bottom() <= cy - r * (90.0 - el) / 90.0 + 0.01


def _ring_pixels(dial):
    """The colours along the top of where the focus ring is drawn."""
    cx, cy, _ = dial.dial_geometry()
    top = cy - dial.focus_ring_radius()
    image = dial.grab().toImage()
    return [image.pixelColor(round(cx), y) for y in range(math.floor(top) - 1, math.ceil(top) + 2)]


def test_a_focus_ring_shows_while_the_dial_has_the_focus(qtbot):
    """The dial takes the arrow keys once Tab reaches it, but showed nothing of it (a user
    trial): a ring in the highlight colour goes round the disc while it has the focus."""
    panel = SunDialPanel("Sun")
    qtbot.addWidget(panel)
    panel.resize(300, 400)
    panel.show()
    qtbot.waitExposed(panel)
    dial = panel.dial
    highlight = dial.palette().highlight().color()

    def ringed() -> bool:
        return any(abs(c.red() - highlight.red()) + abs(c.green() - highlight.green())
                   + abs(c.blue() - highlight.blue()) < 60 for c in _ring_pixels(dial))

    panel.elevation_box.setFocus(Qt.FocusReason.OtherFocusReason)
    qtbot.waitUntil(panel.elevation_box.hasFocus)
    assert not dial.focus_ring_visible() and not ringed()
    dial.setFocus(Qt.FocusReason.BacktabFocusReason)
    qtbot.waitUntil(dial.hasFocus)
    assert dial.focus_ring_visible() and ringed()
    panel.azimuth_box.setFocus(Qt.FocusReason.TabFocusReason)
    qtbot.waitUntil(lambda: not dial.hasFocus())
    assert not dial.focus_ring_visible() and not ringed()


@pytest.mark.parametrize("pitch", [0.0, 12.0, 25.0])
@pytest.mark.parametrize("sun", [(354.0, 15.0), (0.0, 40.0), (180.0, 20.0)])
def test_ring_labels_keep_off_the_camera_the_arrowhead_and_the_ground(qtbot, dial, pitch, sun):
    """On a small dial of a pitched camera (the ski slope at 1024 x 700) the labels sat on
    the camera and on the band of suns under the horizon (a user trial): a label stands clear
    of the camera, the shadow ruler's arrowhead and that band, or is not drawn."""
    from PySide6.QtGui import QPainterPath

    dial.resize(200, 200)
    dial.set_tilt(pitch, 0.0)
    dial.set_sun(*sun)
    cx, cy, r = dial.dial_geometry()
    line, capped = dial.shadow_ruler_line()
    for text, rect in dial.ring_label_rects():
        assert not rect.intersects(QRectF(cx - 7.0, cy - 7.0, 14.0, 14.0)), text
        if capped:  # the arrowhead's half-width, 4 px, each side of its tip
            tip = QRectF(line.p2().x() - 4.0, line.p2().y() - 4.0, 8.0, 8.0)
            assert not rect.intersects(tip), text
        if pitch:
            disc = QPainterPath()
            disc.addEllipse(QPointF(cx, cy), r, r)
            ground = disc.subtracted(dial._ring_path(0.0, cx, cy, r, closed=True))
            assert not ground.intersects(rect), text
