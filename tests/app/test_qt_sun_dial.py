"""QtSunDial and its panel driven with simulated mouse and key events."""

from __future__ import annotations

import pytest
from PySide6.QtCore import QPoint, Qt

from app import sun_dial_math as dm
from app.qt_sun_dial import QtSunDial, SunDialPanel


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
