"""Scene layouts (no Mitsuba): the landscape kind, and that the standard mix is unchanged."""

from __future__ import annotations

import math

import numpy as np
import pytest

from outcast_core.data import props as pr
from outcast_core.data.scene import (
    EXTRA_KINDS,
    _landscape_camera,
    generate_scene,
    landscape,
    landscape_stand_clear,
)

# Fingerprints of standard-mix scenes (train, dev and test seeds), recorded before the landscape
# kind existed: kind, parts, materials, camera (heading, pitch, fov), first sun's azimuth, last
# sun's elevation, sum of |vertex coordinates|, sum of texture means. Any change to the standard
# generator's draws changes these, and the standard sets would no longer re-create bit for bit.
STANDARD = [
    (0, "plaza", 88, 50, (80.995804, 6.250209, 76.456285), (49.695343, 83.226750), 676865.884,
     14.819280),
    (1, "plaza", 71, 29, (-109.157028, 6.373803, 44.812262), (236.575891, 44.847891),
     591249.261, 6.118528),
    (2, "street", 301, 143, (-176.067725, -50.000000, 55.760905), (277.837981, 80.069461),
     4523012.600, 33.464104),
    (3, "street", 208, 78, (173.183638, -8.915667, 50.019702), (29.128876, 59.772215),
     2464416.498, 20.671893),
    (500000, "plaza", 118, 58, (-85.858153, 4.634283, 64.951554), (249.480297, 57.917652),
     780567.961, 15.254637),
    (1000000, "plaza", 93, 47, (-75.625266, 12.945651, 58.206473), (43.350489, 47.028727),
     859441.971, 12.567328),
    (1000001, "street", 168, 96, (-50.976725, -4.204207, 43.791198), (73.252062, 70.054959),
     1862045.807, 23.058042),
]


@pytest.mark.parametrize("row", STANDARD, ids=[str(r[0]) for r in STANDARD])
def test_standard_mix_is_unchanged(row) -> None:
    seed, kind, parts, mats, cam, sun, vsum, tsum = row
    s = generate_scene(seed, 4)
    c = s.camera
    assert (s.kind, len(s.parts), len(s.materials)) == (kind, parts, mats)
    assert (c.heading_deg, c.pitch_deg, c.fov_deg) == pytest.approx(cam, abs=1e-5)
    assert (s.suns[0].azimuth_deg, s.suns[-1].elevation_deg) == pytest.approx(sun, abs=1e-5)
    assert sum(float(np.abs(m.vertices).sum()) for m, _ in s.parts) == pytest.approx(vsum,
                                                                                    rel=1e-9)
    assert sum(float(m.texture.image.mean()) for m in s.materials) == pytest.approx(tsum,
                                                                                  rel=1e-6)


def test_landscape_is_deterministic_and_checked() -> None:
    a, b = generate_scene(42, 2, "landscape"), generate_scene(42, 2, "landscape")
    assert a.kind == "landscape" and "landscape" in EXTRA_KINDS
    assert len(a.parts) == len(b.parts)
    for (ma, ia), (mb, ib) in zip(a.parts, b.parts, strict=True):
        assert ia == ib
        np.testing.assert_array_equal(ma.vertices, mb.vertices)
    with pytest.raises(ValueError, match="scene kind"):
        generate_scene(1, 1, "moonscape")


def _ground_height(spec, x: float, y: float) -> float:
    """Height of the ground plane (the first part: a quad of four corners) at ``x, y``."""
    v = spec.parts[0][0].vertices
    coef, *_ = np.linalg.lstsq(np.c_[v[:, :2], np.ones(len(v))], v[:, 2], rcond=None)
    return float(coef[0] * x + coef[1] * y + coef[2])


@pytest.mark.parametrize("seed", range(7_000_000, 7_000_040, 4))
def test_landscape_camera_stands_on_the_ground_below_the_horizon(seed: int) -> None:
    spec = generate_scene(seed, 1, "landscape")
    cam = spec.camera
    x, y, z = cam.origin
    h = spec.info["camera_height_m"]
    assert 1.3 <= h <= 8.0
    assert z - _ground_height(spec, x, y) == pytest.approx(h)
    # The vanishing line of the ground ahead is inside the (square) frame's vertical view.
    fwd = cam.rotation[:, 2]
    level = fwd[:2] / np.linalg.norm(fwd[:2])
    ax, ay = x + 10.0 * level[0], y + 10.0 * level[1]
    rise = math.degrees(math.atan2(_ground_height(spec, ax, ay) - (z - h), 10.0))
    tilt = math.degrees(math.asin(fwd[2]))
    assert abs(tilt - rise) <= cam.fov_deg / 2
    # No slope falls away ahead: the ground (not the environment under the horizon) fills the
    # frame below the true horizon.
    assert rise >= -math.degrees(math.atan(0.03 * math.sqrt(2))) - 1e-9


def test_landscape_camera_never_stands_in_a_field_hedge_or_prop() -> None:
    stood_on_path = 0
    for seed in range(80):
        b = pr.SceneBuilder(np.random.default_rng(seed))
        landscape(b)
        pose, target, _ = _landscape_camera(b, 50.0)
        x, y = pose.origin[:2]
        assert landscape_stand_clear(b, x, y) or (x, y) == (-10.0, 0.0), seed
        for x0, x1, y0, y1 in b.blockers:
            if (x0, x1, y0, y1) not in b.walkable:
                assert not (x0 <= x <= x1 and y0 <= y <= y1), seed
        for it in b.items:
            assert math.hypot(it.centre[0] - x, it.centre[1] - y) >= it.radius, seed
        stood_on_path += bool(b.walkable) and abs(y) <= b.walkable[0][3]
        assert target == ("path" if b.walkable else "open ground")
    assert stood_on_path > 0  # the path is not a blocker for the photographer


def test_stand_clear_rejects_raised_slabs_not_paths() -> None:
    b = pr.SceneBuilder(np.random.default_rng(0))
    b.blockers += [(0.0, 10.0, -1.0, 1.0), (0.0, 10.0, 2.0, 5.0)]
    b.walkable.append((0.0, 10.0, -1.0, 1.0))
    assert landscape_stand_clear(b, 5.0, 0.0)  # on the path
    assert not landscape_stand_clear(b, 5.0, 3.0)  # in the crop field
    assert not landscape_stand_clear(b, 5.0, 1.7)  # within the margin of it
    pr.bollard(b, 5.0, 0.0, 0.0)
    assert not landscape_stand_clear(b, 5.0, 0.0)  # on a prop
