"""Direct shadows against an independent exact ray cast of a scene the depth map fully describes:
blocks on the ground seen from high above, looking straight down."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from outcast_core.runtime.geometry.camera import Camera, backproject
from outcast_core.runtime.geometry.shadows import DirectStats, direct_shadow, direct_visibility
from tests.runtime.scenes import box_scene_depth, box_scene_visibility

GROUND_Z = 60.0
BOXES = [  # x0, x1, y0, y1, height (metres); the camera is 60 m above the ground
    (-9.0, -4.0, -7.0, -2.0, 3.0),
    (3.0, 7.0, 2.0, 6.0, 5.0),
    (-2.0, 1.0, 5.0, 8.0, 1.5),
    (5.0, 9.0, -9.0, -5.0, 4.0),
    (-1.0, 0.0, -1.0, 0.0, 6.0),  # a thin tall pole near the centre
]


def _sun_down_camera(az_deg: float, el_deg: float) -> np.ndarray:
    """Sun direction for a camera looking straight down (camera z = world down)."""
    a, e = math.radians(az_deg), math.radians(el_deg)
    return np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), -math.sin(e)])


def _iou_away_from_edges(pred: np.ndarray, gt: np.ndarray, band: int = 2) -> float:
    k = np.ones((2 * band + 1, 2 * band + 1), np.uint8)
    edge = np.zeros(gt.shape, bool)
    for m in (pred, gt):
        m8 = m.astype(np.uint8)
        edge |= cv2.dilate(m8, k) != cv2.erode(m8, k)
    keep = ~edge
    union = ((pred | gt) & keep).sum()
    return float((pred & gt & keep).sum() / max(union, 1))


@pytest.mark.parametrize(
    ("az", "el"), [(30, 70), (120, 40), (200, 25), (300, 50), (90, 15), (250, 10)]
)
def test_direct_matches_exact_ray_cast(az: float, el: float) -> None:
    cam = Camera.from_fov(160, 160, 30.0)
    depth = box_scene_depth(160, 160, cam.focal, GROUND_Z, BOXES)
    w = _sun_down_camera(az, el)
    gt_shadow = ~box_scene_visibility(backproject(depth, cam), w, GROUND_Z, BOXES)
    stats = DirectStats(0, 0, "")
    vis = direct_visibility(depth, cam, w, thickness=math.inf, stats=stats)
    pred_shadow = vis < 0.5
    assert gt_shadow.mean() > 0.01  # the scene really casts shadows
    assert _iou_away_from_edges(pred_shadow, gt_shadow) >= 0.9


def test_direct_early_exit_marches_less_for_high_sun() -> None:
    cam = Camera.from_fov(96, 96, 30.0)
    depth = box_scene_depth(96, 96, cam.focal, GROUND_Z, BOXES)
    high, low = DirectStats(0, 0, ""), DirectStats(0, 0, "")
    direct_visibility(depth, cam, _sun_down_camera(40, 80), stats=high)
    direct_visibility(depth, cam, _sun_down_camera(40, 10), stats=low)
    assert high.stop_reason == "no pixel can change"
    assert high.steps_marched < low.steps_marched <= 256


def test_early_exit_does_not_change_result() -> None:
    cam = Camera.from_fov(96, 96, 30.0)
    depth = box_scene_depth(96, 96, cam.focal, GROUND_Z, BOXES)
    w = _sun_down_camera(140, 35)
    a = direct_visibility(depth, cam, w, steps=256)
    # Marching exactly as far as the early exit did gives the same image as marching all.
    stats = DirectStats(0, 0, "")
    direct_visibility(depth, cam, w, steps=256, stats=stats)
    b = direct_visibility(depth, cam, w, steps=stats.steps_marched)
    np.testing.assert_array_equal(a, b)


def test_shadow_is_cosine_times_visibility_and_zero_on_sky() -> None:
    cam = Camera.from_fov(64, 64, 30.0)
    depth = box_scene_depth(64, 64, cam.focal, GROUND_Z, BOXES)
    sky = np.zeros(depth.shape, bool)
    sky[:5] = True
    w = _sun_down_camera(200, 30)
    s = direct_shadow(depth, cam, w, sky=sky)
    assert s.dtype == np.float32
    assert np.all(s[sky] == 0)
    # Lit ground facing up: cosine = sin(elevation).
    ground = ((np.abs(depth - GROUND_Z) < 1e-3) & ~sky).astype(np.uint8)
    interior = cv2.erode(ground, np.ones((3, 3), np.uint8), borderType=cv2.BORDER_REPLICATE) > 0
    lit = (s > 0) & interior
    assert lit.sum() > 1000
    np.testing.assert_allclose(s[lit], math.sin(math.radians(30)), atol=2e-3)


def test_finite_thickness_shortens_shadows() -> None:
    cam = Camera.from_fov(96, 96, 30.0)
    depth = box_scene_depth(96, 96, cam.focal, GROUND_Z, BOXES)
    w = _sun_down_camera(90, 20)
    solid = direct_visibility(depth, cam, w, thickness=math.inf)
    thin = direct_visibility(depth, cam, w, thickness=0.01)
    assert (thin >= solid).all()
    assert thin.mean() > solid.mean()
