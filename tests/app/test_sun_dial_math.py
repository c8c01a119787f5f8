"""Plain tests of the sun dial's maths (no Qt)."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from app import sun_dial_math as dm


@given(st.floats(0.0, 359.99), st.floats(0.0, 89.5))
def test_point_round_trip(az, el):
    x, y = dm.sun_to_point(az, el, 120.0, 100.0, 80.0)
    az2, el2 = dm.point_to_sun(x, y, 120.0, 100.0, 80.0)
    assert el2 == pytest.approx(el, abs=1e-6)
    diff = (az2 - az + 180.0) % 360.0 - 180.0
    assert abs(diff) < 1e-6


def test_layout_conventions():
    cx, cy, r = 100.0, 100.0, 50.0
    assert dm.sun_to_point(0.0, 0.0, cx, cy, r) == pytest.approx((100.0, 50.0))  # ahead = up
    assert dm.sun_to_point(90.0, 0.0, cx, cy, r) == pytest.approx((150.0, 100.0))  # right
    assert dm.sun_to_point(180.0, 0.0, cx, cy, r) == pytest.approx((100.0, 150.0))  # behind
    assert dm.sun_to_point(33.0, 90.0, cx, cy, r) == pytest.approx((100.0, 100.0))  # zenith
    assert dm.sun_to_point(270.0, 45.0, cx, cy, r) == pytest.approx((75.0, 100.0))


def test_points_outside_rim_snap_to_horizon_and_centre_is_zenith():
    assert dm.point_to_sun(100.0, -500.0, 100.0, 100.0, 50.0) == pytest.approx((0.0, 0.0))
    assert dm.point_to_sun(100.0, 100.0, 100.0, 100.0, 50.0) == (0.0, 90.0)


def test_nudge_wraps_and_clamps():
    assert dm.nudge(359.5, 10.0, 1.0, 0.0) == pytest.approx((0.5, 10.0))
    assert dm.nudge(0.5, 10.0, -1.0, 0.0) == pytest.approx((359.5, 10.0))
    assert dm.nudge(10.0, 89.5, 0.0, 10.0) == (10.0, 90.0)
    assert dm.nudge(10.0, 0.5, 0.0, -10.0) == (10.0, 0.0)


def test_shadow_length():
    assert dm.shadow_length_ratio(45.0) == pytest.approx(1.0)
    assert dm.shadow_length_ratio(30.0) == pytest.approx(math.sqrt(3.0))
    assert dm.shadow_length_ratio(90.0) == 0.0
    assert dm.shadow_length_ratio(0.0) == math.inf


def test_shadow_ruler_points_away_from_sun_and_caps():
    (x0, y0), (x1, y1), capped = dm.shadow_ruler(90.0, 45.0, 0.0, 0.0, 10.0)  # sun right
    assert (x0, y0) == (0.0, 0.0)
    assert (x1, y1) == pytest.approx((-10.0, 0.0))  # shadow to the left, one height long
    assert not capped
    _, (x1, y1), capped = dm.shadow_ruler(0.0, 1.0, 0.0, 0.0, 10.0)  # low sun ahead
    assert capped and (x1, y1) == pytest.approx((0.0, 10.0 * dm.MAX_SHADOW_RATIO))


def test_fov_and_sun_in_view():
    assert dm.fov_wedge(70.0) == (-35.0, 35.0)
    with pytest.raises(ValueError, match="field of view"):
        dm.fov_wedge(190.0)
    assert dm.sun_in_view(350.0, 10.0, 60.0, 45.0)
    assert not dm.sun_in_view(40.0, 10.0, 60.0, 45.0)
    assert not dm.sun_in_view(0.0, 30.0, 60.0, 45.0)


def test_hit_handle_and_description():
    assert dm.hit_handle(10.0, 10.0, 14.0, 13.0, 3.0)
    assert not dm.hit_handle(10.0, 10.0, 30.0, 10.0, 3.0)
    assert dm.describe_sun(0.0, 70.0) == "high, front"
    assert dm.describe_sun(135.0, 30.0) == "mid, back-right"
    assert dm.describe_sun(270.0, 3.0) == "at the horizon, left"


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_rejects_non_finite(bad):
    with pytest.raises(ValueError, match="expected a finite"):
        dm.wrap_azimuth(bad)
    with pytest.raises(ValueError, match="expected a finite"):
        dm.shadow_length_ratio(bad)
    with pytest.raises(ValueError, match="radius"):
        dm.sun_to_point(0.0, 0.0, 0.0, 0.0, 0.0)


def test_tilted_ring_is_the_true_elevation_seen_by_a_tilted_camera():
    from outcast_core.runtime.geometry.camera import sun_angles, sun_vector

    level = dm.tilted_ring(30.0, 0.0, 0.0, step=30.0)
    assert len(level) == 12 and all(e == pytest.approx(30.0) for _, e in level)
    ring = dm.tilted_ring(30.0, -15.0, 5.0, step=10.0)
    assert len(ring) == 36
    # Each point, turned back into the horizon's frame, is 30 degrees up.
    assert all(sun_angles(sun_vector(a, e), -15.0, 5.0)[1] == pytest.approx(30.0) for a, e in ring)
    assert max(e for _, e in ring) > 40.0 > 20.0 > min(e for _, e in ring)
    with pytest.raises(ValueError, match="step"):
        dm.tilted_ring(30.0, 0.0, 0.0, step=0.0)
