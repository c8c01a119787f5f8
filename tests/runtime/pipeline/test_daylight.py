"""The new sun's daylight: the sunlight and the sky change with the sun's elevation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from outcast_core.runtime.geometry.camera import camera_rotation, sun_vector
from outcast_core.runtime.io.models import ModelRegistry
from outcast_core.runtime.pipeline import daylight as dl
from outcast_core.runtime.pipeline.session import RelightSession
from tests.runtime.scenes import noisy_box_photo

LEVEL_UP = np.array([0.0, -1.0, 0.0])


@pytest.mark.parametrize("el", [2.0, 7.5, 30.0, 89.0])
def test_one_elevation_changes_nothing(el: float) -> None:
    change = dl.daylight_change(el, el)
    assert change.is_identity
    lit = np.ones((3, 4), np.float32)
    gain = dl.daylight_gain(lit, np.zeros((3, 4), bool), np.full(3, 5.0), change)
    np.testing.assert_allclose(gain, 1.0, atol=1e-6)
    dirs = np.array([[0.0, -1.0, 1.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    np.testing.assert_allclose(dl.sky_change(dirs, LEVEL_UP, el, el), 1.0, atol=1e-6)


def test_a_lower_sun_is_weaker_and_redder_and_its_sky_dimmer() -> None:
    low = dl.daylight_change(45.0, 4.0)
    assert low.sun[2] < low.sun[1] < low.sun[0] < 1.0  # blue fades most
    assert np.all(low.sky < 1.0)
    high = dl.daylight_change(4.0, 45.0)  # and back, where no limit holds it
    free = high.sun < dl.BRIGHTEN_LIMIT
    assert free[0] and not free[2]  # the blue sunlight's growth is bounded
    np.testing.assert_allclose((low.sun * high.sun)[free], 1.0, rtol=1e-5)
    free = high.sky < dl.BRIGHTEN_LIMIT
    np.testing.assert_allclose((low.sky * high.sky)[free], 1.0, rtol=1e-5)
    # Dusk: the sky near the horizon dims less in red than in blue, and dims overall.
    horizon = np.array([[0.0, -math.sin(math.radians(3)), math.cos(math.radians(3))]])
    k = dl.sky_change(horizon, LEVEL_UP, 45.0, 4.0)[0]
    assert k[0] > k[2] and k.max() < 1.0


def test_suns_below_the_table_are_taken_at_its_lowest() -> None:
    a, b = dl.daylight_change(-10.0, 40.0), dl.daylight_change(dl.MIN_ELEVATION, 40.0)
    np.testing.assert_array_equal(a.sun, b.sun)
    np.testing.assert_array_equal(a.sky, b.sky)
    with pytest.raises(ValueError, match="finite"):
        dl.daylight_change(float("nan"), 40.0)


def test_elevation_is_taken_against_the_horizon_not_the_camera() -> None:
    assert dl.elevation_above(sun_vector(70.0, 25.0), LEVEL_UP) == pytest.approx(25.0)
    pitched = camera_rotation(-20.0, 0.0) @ LEVEL_UP  # a camera looking 20 deg down
    w = sun_vector(180.0, 30.0, pitch_deg=-20.0)  # a sun 30 deg up, behind it
    assert dl.elevation_above(w, pitched) == pytest.approx(30.0, abs=1e-6)
    with pytest.raises(ValueError):
        dl.elevation_above((0.0, 0.0, 0.0), LEVEL_UP)


def test_the_gain_follows_the_light_model() -> None:
    change = dl.daylight_change(40.0, 8.0)
    s = np.array([[0.0, 1.0]], np.float32)  # a shadowed and a fully lit pixel
    r = np.array([4.0, 3.0, 2.0], np.float32)
    sky = np.array([[False, False]])
    g = dl.daylight_gain(s, sky, r, change)
    np.testing.assert_allclose(g[0, 0], change.sky, rtol=1e-5)  # the sky's light alone
    np.testing.assert_allclose(g[0, 1], (change.sky + r * change.sun) / (1 + r), rtol=1e-5)
    sky_gain = np.full((1, 2, 3), 0.5, np.float32)
    g = dl.daylight_gain(s, np.array([[True, False]]), r, change, sky_gain)
    np.testing.assert_allclose(g[0, 0], 0.5)
    with pytest.raises(ValueError, match="sky gain"):
        dl.daylight_gain(s, sky, r, change, np.ones((2, 2, 3), np.float32))


def test_the_table_is_the_renderers_clear_sky() -> None:
    """The shipped table's shapes, and a midday sun whiter and stronger than a low one."""
    from outcast_core.runtime.pipeline import daylight_table as t

    n, m = len(t.SUN_ELEVATIONS), len(t.VIEW_ELEVATIONS)
    assert np.shape(t.SUN) == np.shape(t.SKY) == (n, 3)
    assert np.shape(t.SKY_SEEN) == (n, m, 3)
    assert t.SUN_ELEVATIONS[0] == dl.MIN_ELEVATION
    sun = np.asarray(t.SUN)
    assert np.all(sun[-1] > sun[0]) and sun[-1, 2] / sun[-1, 0] > sun[5, 2] / sun[5, 0]


@pytest.fixture
def scene() -> tuple[np.ndarray, np.ndarray]:
    return noisy_box_photo(2)


@pytest.mark.parametrize("mode", ["classic", "learned"])
def test_a_session_relit_toward_dusk_is_darker_and_warmer(scene, tmp_path, mode: str) -> None:
    """Relit to a sun low over the horizon, the photo is darker and redder than without the
    new daylight; relit round the horizon at the photo's elevation, nothing changes."""
    image, depth = scene
    registry = ModelRegistry(tmp_path) if mode == "classic" else ModelRegistry()
    s = RelightSession(registry=registry, mode=mode, preset="fast")
    s.set_image(image, depth=depth)
    s.set_original_sun(sun_vector(100.0, 40.0))
    dusk, side = sun_vector(200.0, 4.0), sun_vector(220.0, 40.0)
    on_dusk, on_side = s.relight(dusk), s.relight(side)
    s.daylight = False  # clears the relit cache
    off_dusk, off_side = s.relight(dusk), s.relight(side)
    np.testing.assert_array_equal(on_side, off_side)
    surface = ~s.sky
    # Physics is carried to the dusk light whole; the learned relighting follows it where the
    # floor takes physics' level (a sun at 4 degrees lights too little for the anchor).
    darker = 0.9 if mode == "classic" else 0.99
    assert on_dusk[surface].mean() < darker * off_dusk[surface].mean()
    warm = on_dusk[surface][:, 0] / np.maximum(on_dusk[surface][:, 2], 1e-3)
    warm_off = off_dusk[surface][:, 0] / np.maximum(off_dusk[surface][:, 2], 1e-3)
    assert warm.mean() > 1.05 * warm_off.mean()


def test_keep_light_on_the_command_line(scene, tmp_path) -> None:
    """``relight --keep-light`` keeps the photo's light; without it a sun moved low dims it."""
    from outcast_core.runtime.cli.main import main
    from outcast_core.runtime.io.imageio import read_image, write_depth, write_image

    image, depth = scene
    photo, dpath = tmp_path / "p.png", tmp_path / "d.npy"
    write_image(photo, image)
    write_depth(dpath, depth)
    outs = {}
    for name, extra in (("new", []), ("kept", ["--keep-light"])):
        out = tmp_path / f"{name}.png"
        assert main(["relight", str(photo), "--from", "100,40", "--to", "200,4", "--depth",
                     str(dpath), "--mode", "physics", "--preset", "fast", "-o", str(out),
                     "-q", *extra]) == 0
        outs[name] = read_image(out).image_srgb
    assert outs["new"].mean() < 0.9 * outs["kept"].mean()


def test_a_given_camera_tilt_sets_the_horizon(scene, tmp_path) -> None:
    """``set_camera_tilt`` (the tilt the EXIF suns are placed with) is the daylight's horizon,
    forgotten with the photo; a new tilt clears the relit photos made with the old one."""
    image, depth = scene
    s = RelightSession(registry=ModelRegistry(tmp_path), mode="classic", preset="fast")
    s.set_image(image, depth=depth)
    s.set_original_sun(sun_vector(100.0, 40.0))
    before = s.relight(sun_vector(200.0, 20.0))
    s.set_camera_tilt(-30.0, 0.0)
    np.testing.assert_allclose(s.horizon_up(), camera_rotation(-30.0, 0.0) @ LEVEL_UP)
    after = s.relight(sun_vector(200.0, 20.0))
    assert not np.allclose(before, after)  # other elevations, other daylight
    with pytest.raises(ValueError, match="finite"):
        s.set_camera_tilt(float("nan"))
    s.set_image(image, depth=depth)
    assert s._tilt is None


def test_a_low_sun_relit_high_is_bounded() -> None:
    """From 3 degrees to 60 the blue sunlight would grow x100; no light grows past
    BRIGHTEN_LIMIT (an aligned elevation a little low would turn the photo blue)."""
    change = dl.daylight_change(3.0, 60.0)
    assert change.sun.max() <= dl.BRIGHTEN_LIMIT and change.sky.max() <= dl.BRIGHTEN_LIMIT
    assert change.sun[2] == pytest.approx(dl.BRIGHTEN_LIMIT)
