"""The dial's agreement heat map: its cells (pure maths) and its painting."""

from __future__ import annotations

import pytest

from app import sun_dial_math as dm


def test_heat_cells_cover_the_dome() -> None:
    cells = dm.heat_cells([0.0, 90.0, 180.0, 270.0], [10.0, 50.0])
    assert len(cells) == 8
    row0 = [c for c in cells if c[0] == 0]
    assert all((c[4], c[5]) == (0.0, 30.0) for c in row0)  # the lowest row reaches the horizon
    assert all((c[4], c[5]) == (30.0, 90.0) for c in cells if c[0] == 1)  # the top the zenith
    assert [c[3] - c[2] for c in row0] == [90.0] * 4
    assert dm.heat_cells([], [10.0]) == []
    with pytest.raises(ValueError):
        dm.heat_cells([float("nan")], [10.0])


def test_heat_colour_ramp() -> None:
    assert dm.heat_colour(0.0)[3] == 0 and dm.heat_colour(float("nan"))[3] == 0
    alphas = [dm.heat_colour(v)[3] for v in (0.2, 0.6, 1.0, 2.0)]
    assert alphas == sorted(alphas) and alphas[-1] == alphas[-2]


def test_dial_paints_the_heat_map(qtbot) -> None:
    from app.qt_sun_dial import QtSunDial

    dial = QtSunDial()
    qtbot.addWidget(dial)
    dial.resize(240, 240)
    before = dial.grab().toImage()
    values = [[0.0] * 4, [0.0, 1.0, 0.0, 0.0]]
    dial.set_heat_map([0.0, 90.0, 180.0, 270.0], [10.0, 50.0], values)
    assert dial.has_heat_map()
    after = dial.grab().toImage()
    cx, cy, r = dial.dial_geometry()
    x, y = dm.sun_to_point(90.0, 45.0, cx, cy, r)  # inside the hot cell (azimuth 90, high)
    hot, cold = after.pixelColor(round(x), round(y)), before.pixelColor(round(x), round(y))
    assert hot.red() > cold.red() + 60
    with pytest.raises(ValueError):
        dial.set_heat_map([0.0], [10.0], [[0.1, 0.2]])
    dial.set_heat_map(None)
    assert not dial.has_heat_map()
    dial.set_prior_elevation(38.0)
    assert dial.prior_elevation() == 38.0
