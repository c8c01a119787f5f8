"""Geometry against closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from outcast_core.runtime.geometry.camera import (
    Camera,
    backproject,
    camera_rotation,
    cosine_term,
    focal_from_35mm,
    focal_from_fov,
    network_depth,
    normals_from_depth,
    project,
    sun_angles,
    sun_vector,
    view_directions,
)


def plane_depth(cam: Camera, normal: np.ndarray, offset: float) -> np.ndarray:
    """z depth of the plane n . X = offset (exact ray-plane intersection per pixel centre)."""
    uu, vv = np.meshgrid(np.arange(cam.width) + 0.5, np.arange(cam.height) + 0.5)
    rays = np.stack([(uu - cam.cx) / cam.focal, (vv - cam.cy) / cam.focal, np.ones_like(uu)], -1)
    return (offset / (rays @ normal)).astype(np.float32)


def test_focal_from_fov_and_35mm() -> None:
    assert focal_from_fov(200, 90.0) == pytest.approx(100.0)
    assert Camera.from_fov(10, 640, 60.0).fov_deg == pytest.approx(60.0)
    assert focal_from_35mm(4000, 3000, 36.0) == pytest.approx(4000.0)
    assert focal_from_35mm(3000, 4000, 18.0) == pytest.approx(2000.0)  # portrait: longer side
    for bad in (0.0, 180.0, float("nan"), -5.0):
        with pytest.raises(ValueError, match="field of view"):
            focal_from_fov(100, bad)


@pytest.mark.parametrize("tilt", [0.0, 20.0, 45.0, 62.0])
@pytest.mark.parametrize("yaw", [0.0, 60.0, 150.0])
def test_plane_normals_at_any_tilt(tilt: float, yaw: float) -> None:
    cam = Camera.from_fov(48, 64, 40.0)  # the whole view hits the plane up to 65 deg of tilt
    t, y = math.radians(tilt), math.radians(yaw)
    # A plane facing the camera (normal has negative z), tilted by `tilt` toward direction `yaw`.
    n = np.array([math.sin(t) * math.cos(y), math.sin(t) * math.sin(y), -math.cos(t)])
    depth = plane_depth(cam, n, -5.0)
    assert np.all(depth > 0)
    normals = normals_from_depth(depth, cam)
    np.testing.assert_allclose(normals[2:-2, 2:-2], np.broadcast_to(n, (44, 60, 3)), atol=2e-4)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=-1), 1.0, atol=1e-5)


def test_sphere_normals() -> None:
    cam = Camera.from_fov(96, 96, 40.0)
    c, r = np.array([0.0, 0.0, 10.0]), 3.0
    uu, vv = np.meshgrid(np.arange(96) + 0.5, np.arange(96) + 0.5)
    d = np.stack([(uu - cam.cx) / cam.focal, (vv - cam.cy) / cam.focal, np.ones_like(uu)], -1)
    a = np.sum(d * d, -1)
    b = -2 * d @ c
    disc = b * b - 4 * a * (c @ c - r * r)
    hit = disc > 0
    t = np.where(hit, (-b - np.sqrt(np.maximum(disc, 0))) / (2 * a), np.inf)
    depth = t.astype(np.float32)  # z = t because d_z = 1
    normals = normals_from_depth(depth, cam)
    pts = backproject(depth, cam)
    expected = (pts - c) / r
    # Interior of the sphere's image, away from the silhouette.
    inner = (disc > 0.5 * disc.max())
    ang = np.degrees(np.arccos(np.clip(np.sum(normals * expected, -1), -1, 1)))
    assert np.median(ang[inner]) < 1.0
    assert np.percentile(ang[inner], 95) < 3.0
    assert np.all(normals[~hit] == 0)


def test_backprojection_round_trip() -> None:
    cam = Camera.from_fov(30, 40, 55.0)
    rng = np.random.default_rng(0)
    depth = rng.uniform(0.1, 1e4, (30, 40)).astype(np.float32)
    u, v = project(backproject(depth, cam), cam)
    uu, vv = np.meshgrid(np.arange(40) + 0.5, np.arange(30) + 0.5)
    np.testing.assert_allclose(u, uu, atol=1e-3)
    np.testing.assert_allclose(v, vv, atol=1e-3)
    np.testing.assert_allclose(backproject(depth, cam)[..., 2], depth, rtol=1e-6)


def test_view_directions_are_unit_and_centred() -> None:
    cam = Camera.from_fov(2, 2, 90.0)
    psi = view_directions(cam)
    np.testing.assert_allclose(np.linalg.norm(psi, axis=-1), 1.0, atol=1e-6)
    assert np.all(psi[..., 2] > 0)
    np.testing.assert_allclose(psi[0, 0], -psi[1, 1] * np.array([1, 1, -1]), atol=1e-6)


def test_sun_convention() -> None:
    np.testing.assert_allclose(sun_vector(0, 0), [0, 0, 1], atol=1e-12)  # straight ahead
    np.testing.assert_allclose(sun_vector(90, 0), [1, 0, 0], atol=1e-12)  # to the right
    np.testing.assert_allclose(sun_vector(180, 0), [0, 0, -1], atol=1e-12)  # behind the camera
    np.testing.assert_allclose(sun_vector(33, 90), [0, -1, 0], atol=1e-12)  # zenith: y is down
    # Camera pitched up by 30 deg: the zenith is 60 deg above its optical axis.
    w = sun_vector(0, 90, pitch_deg=30)
    assert math.degrees(math.acos(w[2])) == pytest.approx(60.0)
    assert w[1] < 0


@settings(max_examples=200, deadline=None)
@given(
    st.floats(0, 359.999), st.floats(-89.9, 89.9), st.floats(-30, 30), st.floats(-30, 30)
)
def test_sun_angles_round_trip(az: float, el: float, pitch: float, roll: float) -> None:
    w = sun_vector(az, el, pitch, roll)
    assert np.linalg.norm(w) == pytest.approx(1.0)
    az2, el2 = sun_angles(w, pitch, roll)
    assert el2 == pytest.approx(el, abs=1e-6)
    diff = (az2 - az + 180) % 360 - 180
    assert abs(diff) < 1e-5 * max(1.0, 1 / max(math.cos(math.radians(el)), 1e-9))


def test_camera_rotation_is_orthonormal() -> None:
    r = camera_rotation(12.0, -7.0)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0)


def test_cosine_term() -> None:
    n = np.zeros((2, 2, 3), np.float32)
    n[0, 0] = [0, -1, 0]
    n[0, 1] = [0, 1, 0]
    c = cosine_term(n, sun_vector(0, 30))
    assert c[0, 0] == pytest.approx(0.5)
    assert c[0, 1] == 0 and c[1, 0] == 0
    for bad in ([0, 0, 0], [np.nan, 1, 0], [1, 2]):
        with pytest.raises(ValueError, match="sun direction"):
            cosine_term(n, bad)


@pytest.mark.parametrize("scale", [1e-30, 1e-3, 1.0, 1e6, 1e30])
def test_network_depth_is_unit_free_finite_and_zero_off_surfaces(scale: float) -> None:
    rng = np.random.default_rng(0)
    depth = (1.0 + 9.0 * rng.random((6, 8))).astype(np.float32)
    depth[0] = np.inf  # sky
    depth[1, :2] = (0.0, np.nan)  # degenerate pixels: no surface
    ref = network_depth(depth)
    got = network_depth((depth.astype(np.float64) * scale).astype(np.float32))
    assert got.dtype == np.float32 and np.isfinite(got).all()
    assert (got[0] == 0).all() and (got[1, :2] == 0).all()
    np.testing.assert_allclose(got, ref, rtol=1e-5)
    assert np.median(got[2:]) == pytest.approx(1.0, rel=0.2)
