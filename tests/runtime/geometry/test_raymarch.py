"""The screen-space light-ray sampler: exact maths, every side of the camera, and the extremes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from outcast_core.runtime.geometry.camera import Camera, sun_vector
from outcast_core.runtime.geometry.raymarch import (
    MAX_RATIO,
    RaySampler,
    march_coordinates,
    steps_to_leave,
)
from outcast_core.runtime.geometry.shadows import direct_shadow

unit_vectors = hnp.arrays(np.float64, 3, elements=st.floats(-1, 1)).filter(
    lambda v: np.linalg.norm(v) > 1e-3
).map(lambda v: v / np.linalg.norm(v))

SPECIAL_SUNS = [
    (0.0, 0.0, 1.0),  # exactly along the optical axis, in front (backlit)
    (0.0, 0.0, -1.0),  # exactly behind the camera
    (0.0, -1.0, 0.0),  # straight up
    tuple(sun_vector(90.0, 0.0)),  # on the horizon, to the right
    tuple(sun_vector(30.0, -10.0)),  # below the horizon
    tuple(sun_vector(180.0, 0.001)),  # grazing, behind
    tuple(sun_vector(0.0, 89.999)),  # almost overhead
]


@settings(max_examples=300, deadline=None)
@given(
    w=unit_vectors,
    px=st.floats(-2, 2), py=st.floats(-2, 2), pz=st.floats(0.01, 1e3),
    s=st.floats(0.1, 500),
)
def test_ray_point_is_exact(w: np.ndarray, px: float, py: float, pz: float, s: float) -> None:
    """The sample at distance s lies on the 3D ray P + t w, t > 0, at depth Pz / factor."""
    f, cx, cy = 100.0, 64.0, 48.0
    u, v = f * px + cx, f * py + cy  # (px, py): normalised image coordinates of P
    P = np.array([(u - cx) / f * pz, (v - cy) / f * pz, pz])
    qu, qv, factor, ok = march_coordinates(np, np.float64(u), np.float64(v), tuple(w), f, cx, cy, s)
    assume(bool(ok) and factor > 1e-3)
    D = pz / factor
    X = D * np.array([(qu - cx) / f, (qv - cy) / f, 1.0])
    d = X - P
    t = d @ w
    assert t > -1e-6 * max(1.0, pz)
    np.testing.assert_allclose(d, t * w, atol=1e-6 * max(1.0, np.abs(X).max(), pz))
    # And the step really has length s in the image.
    assert math.hypot(qu - u, qv - v) == pytest.approx(s, rel=1e-9)


def test_sun_in_front_stops_at_vanishing_point() -> None:
    cam = Camera.from_fov(64, 64, 60.0)
    w = sun_vector(10.0, 20.0)  # in front, up-right
    vp = np.array([cam.cx + cam.focal * w[0] / w[2], cam.cy + cam.focal * w[1] / w[2]])
    sampler = RaySampler(np.full((64, 64), 3.0, np.float32), cam)
    for st_ in sampler.iter_steps(w, steps=200, step=1 / 64):
        # Valid samples approach the vanishing point and never pass it.
        d_start = np.hypot(sampler.u - vp[0], sampler.v - vp[1])
        d_now = np.hypot(st_.qu - vp[0], st_.qv - vp[1])
        ok = st_.factor > 0
        assert np.all(d_now[ok] < d_start[ok] + 1e-3)
        assert not st_.valid[~ok].any()


def test_sun_behind_runs_away_from_antivanishing_point() -> None:
    cam = Camera.from_fov(64, 64, 60.0)
    w = sun_vector(160.0, 30.0)  # behind the camera
    avp = np.array([cam.cx + cam.focal * w[0] / w[2], cam.cy + cam.focal * w[1] / w[2]])
    sampler = RaySampler(np.full((64, 64), 3.0, np.float32), cam)
    prev = np.hypot(sampler.u - avp[0], sampler.v - avp[1])
    for st_ in sampler.iter_steps(w, steps=20, step=1 / 64):
        now = np.hypot(st_.qu - avp[0], st_.qv - avp[1])
        assert np.all(now > prev)
        assert np.all(st_.factor > 1.0)  # the ray point comes closer to the camera
        prev = now


def test_end_on_ray_is_invalid_and_lit() -> None:
    # A 1x1 image: the only pixel's viewing line is the optical axis; sun exactly along it.
    for w in ((0.0, 0.0, 1.0), (0.0, 0.0, -1.0)):
        cam = Camera.from_fov(1, 1, 60.0)
        vol = RaySampler(np.ones((1, 1), np.float32), cam).volume(w, steps=4, step=0.5)
        assert not vol["valid"].any()
        assert np.all(vol["ratio"] == MAX_RATIO)
        assert direct_shadow(np.ones((1, 1), np.float32), cam, w)[0, 0] >= 0.0


def test_ratio_on_a_plane_is_exact() -> None:
    """On a fronto-parallel wall the ray toward a sun behind the camera is in front: ratio > 1,
    and equal to the analytic depth ratio."""
    cam = Camera.from_fov(32, 32, 60.0)
    w = sun_vector(180.0, 30.0)
    sampler = RaySampler(np.full((32, 32), 7.0, np.float32), cam)
    for st_ in sampler.iter_steps(w, steps=8, step=1 / 32):
        np.testing.assert_allclose(st_.ratio[st_.valid], np.minimum(st_.factor[st_.valid],
                                                                    MAX_RATIO), rtol=1e-5)


def test_steps_to_leave_bounds_the_march() -> None:
    cam = Camera.from_fov(40, 60, 60.0)
    for w in SPECIAL_SUNS + [tuple(sun_vector(45, 45)), tuple(sun_vector(200, 10))]:
        n = steps_to_leave(cam, w, step=1 / 60, max_steps=1000)
        vol = RaySampler(np.ones((40, 60), np.float32), cam).volume(w, steps=n + 3, step=1 / 60)
        assert not vol["valid"][n:].any()


@settings(max_examples=60, deadline=None)
@given(
    w=st.one_of(unit_vectors, st.sampled_from(SPECIAL_SUNS)),
    h=st.integers(1, 24), wd=st.integers(1, 24),
    data=st.data(),
)
def test_extremes_give_finite_in_range_output(w, h: int, wd: int, data) -> None:
    special = st.sampled_from([0.0, -1.0, np.nan, np.inf, -np.inf, 1e-30, 1e30, 1e-6, 1e6])
    depth = data.draw(hnp.arrays(np.float32, (h, wd),
                                 elements=st.one_of(st.floats(0.0009765625, 1024.0, width=32,
                                                           exclude_min=True), special)))
    image = data.draw(hnp.arrays(np.float32, (h, wd, 3), elements=st.floats(0, 1, width=32)))
    cam = Camera.from_fov(h, wd, 60.0)
    vol = RaySampler(depth, cam).volume(w, steps=5, step=1 / 8, image=image)
    assert np.all(np.isfinite(vol["ratio"])) and np.all(np.isfinite(vol["rgb"]))
    assert vol["ratio"].min() >= 0 and vol["ratio"].max() <= MAX_RATIO
    assert vol["rgb"].min() >= 0 and vol["rgb"].max() <= 1
    s = direct_shadow(depth, cam, w, steps=16)
    assert s.shape == (h, wd) and np.all(np.isfinite(s))
    assert s.min() >= 0 and s.max() <= 1
    bad = ~(np.isfinite(depth) & (depth > 0))
    assert np.all(s[bad] == 0)


def test_dynamic_range_of_1e6() -> None:
    cam = Camera.from_fov(32, 32, 60.0)
    depth = np.full((32, 32), 1e6, np.float32)
    depth[10:20, 10:20] = 1.0  # a near box in front of a very far wall
    s = direct_shadow(depth, cam, sun_vector(150, 30))
    assert np.all(np.isfinite(s)) and s.min() >= 0 and s.max() <= 1


@pytest.mark.parametrize("bad", [(0, 0, 0), (np.nan, 0, 1), (np.inf, 0, 0), (1, 2)])
def test_bad_sun_raises(bad) -> None:
    cam = Camera.from_fov(4, 4, 60.0)
    with pytest.raises(ValueError, match="sun direction"):
        RaySampler(np.ones((4, 4), np.float32), cam).volume(bad, 2, 0.1)


@pytest.mark.parametrize("steps", [0, -1, 2.5, True])
def test_bad_steps_raise(steps) -> None:
    cam = Camera.from_fov(4, 4, 60.0)
    with pytest.raises(ValueError, match="steps"):
        RaySampler(np.ones((4, 4), np.float32), cam).volume((0, -1, 0), steps, 0.1)


def test_bad_depth_shape_raises() -> None:
    cam = Camera.from_fov(4, 4, 60.0)
    with pytest.raises(ValueError, match="depth"):
        RaySampler(np.ones((4, 5), np.float32), cam)
    with pytest.raises(ValueError, match="depth"):
        RaySampler(np.ones((4, 4, 1), np.float32), cam)
