"""The renderer holds to OutCast's conventions (tiny images, low spp: a few seconds in total)."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("mitsuba")

from outcast_core.data import textures as tx  # noqa: E402
from outcast_core.data.meshes import Mesh, box  # noqa: E402
from outcast_core.data.props import Material  # noqa: E402
from outcast_core.data.render import cull_to_frustum, render_view  # noqa: E402
from outcast_core.data.scene import CameraPose, SceneSpec, Sun, generate_scene  # noqa: E402
from outcast_core.runtime.geometry.camera import (  # noqa: E402
    Camera,
    backproject,
    cosine_term,
    normals_from_depth,
    project,
    sun_angles,
)


def _ground() -> Mesh:
    s = 300.0
    v = np.array([[-s, -s, 0], [s, -s, 0], [s, s, 0], [-s, s, 0]], np.float64)
    return Mesh(v, np.array([[0, 1, 2], [0, 2, 3]]), v[:, :2].copy())


def _spec(parts: list[tuple[Mesh, int]], camera: CameraPose, suns: list[Sun]) -> SceneSpec:
    rng = np.random.default_rng(0)
    mats = [
        Material(tx.plain(rng, np.array([0.4, 0.4, 0.4]), 0.0)),
        Material(tx.plain(rng, np.array([0.6, 0.3, 0.2]), 0.0)),
    ]
    return SceneSpec("test", mats, parts, camera, suns, turbidity=3.0, sky_albedo=0.2)


def _to_world(points_cam: np.ndarray, camera: CameraPose) -> np.ndarray:
    return points_cam.astype(np.float64) @ camera.rotation.T + camera.origin


# A box standing on the ground to the right of the optical axis: an x-flip would move it left.
BOX_CENTRE = np.array([6.0, -1.5, 0.0])
BOX_SIZE = np.array([1.0, 1.0, 1.5])


def _box_scene(camera: CameraPose, suns: list[Sun]) -> SceneSpec:
    b = box(*BOX_SIZE).transformed(np.eye(3), BOX_CENTRE)
    return _spec([(_ground(), 0), (b, 1)], camera, suns)


def _on_box(p: np.ndarray, tol: float) -> np.ndarray:
    lo = BOX_CENTRE + np.array([-BOX_SIZE[0] / 2, -BOX_SIZE[1] / 2, 0.0]) - tol
    hi = BOX_CENTRE + np.array([BOX_SIZE[0] / 2, BOX_SIZE[1] / 2, BOX_SIZE[2]]) + tol
    return np.all((p >= lo) & (p <= hi), axis=-1)


@pytest.fixture(scope="module")
def street_level() -> tuple[SceneSpec, dict]:
    cam = CameraPose(
        np.array([0.0, 0.0, 1.6]), heading_deg=-8.0, pitch_deg=-12.0, roll_deg=3.0, fov_deg=60.0
    )
    spec = _box_scene(cam, [Sun(250.0, 35.0), Sun(100.0, 20.0)])
    return spec, render_view(spec, (36, 48), spp=4, seed=1)


def test_depth_backprojects_onto_geometry(street_level: tuple[SceneSpec, dict]) -> None:
    spec, out = street_level
    depth = out["depth"]
    cam = Camera.from_fov(36, 48, out["fov_deg"])
    pts = _to_world(backproject(depth, cam), spec.camera)  # H x W x 3
    surf = ~out["sky"]
    on_ground = np.abs(pts[..., 2]) < 1e-3 * np.maximum(depth, 1.0)
    on_box = _on_box(pts, 1e-3 * np.maximum(depth, 1.0).max())
    assert surf.sum() > 0.5 * surf.size
    assert np.all((on_ground | on_box)[surf])
    # The box is to the right of the camera: it shows in the right half of the image only.
    cols = np.nonzero(on_box & surf & ~on_ground)[1]
    assert cols.size > 10 and cols.min() >= 24
    # Sky exactly where the pixel-centre ray rises above the horizon (no ground beyond).
    assert np.all(np.isinf(depth[out["sky"]]))
    rays = _to_world(backproject(np.ones_like(depth), cam), spec.camera) - spec.camera.origin
    assert not np.any(out["sky"] & (rays[..., 2] < -0.02))
    assert np.all(out["sky"][rays[..., 2] > 0])


def test_normals_agree_with_depth_normals(street_level: tuple[SceneSpec, dict]) -> None:
    spec, out = street_level
    cam = Camera.from_fov(36, 48, out["fov_deg"])
    n_depth = normals_from_depth(out["depth"], cam)
    n = out["normals"]
    assert np.allclose(np.linalg.norm(n[~out["sky"]], axis=-1), 1.0, atol=1e-4)
    # Facing the camera: n . p < 0 for every surface pixel.
    p = backproject(out["depth"], cam)
    assert np.all(np.sum(n * p, axis=-1)[~out["sky"]] < 0)
    # Planar interiors: pixels whose 3x3 neighbourhood has the same stored normal.
    same = np.ones(n.shape[:2], bool)
    pad = np.pad(n, ((1, 1), (1, 1), (0, 0)), mode="edge")
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            nb = pad[1 + dy : 1 + dy + n.shape[0], 1 + dx : 1 + dx + n.shape[1]]
            same &= np.sum(nb * n, axis=-1) > 0.999
    same &= ~out["sky"]
    same[[0, -1], :] = False
    same[:, [0, -1]] = False
    ang = np.degrees(np.arccos(np.clip(np.sum(n * n_depth, axis=-1)[same], -1, 1)))
    assert same.sum() > 100
    assert np.median(ang) < 5.0
    # Ground normal is world up.
    up_cam = spec.camera.rotation.T @ np.array([0.0, 0.0, 1.0])
    ground = same & (np.abs(n @ up_cam - 1) < 1e-3)
    assert ground.sum() > 50


def test_shadow_bounded_by_cosine_term(street_level: tuple[SceneSpec, dict]) -> None:
    _, out = street_level
    for k in range(len(out["sun"])):
        cos = cosine_term(out["normals"], out["sun"][k])
        s = out["shadow"][k]
        assert np.all(s <= cos + 1e-4)
        assert np.all(s[cos <= 0] == 0)
        assert np.all(s[out["sky"]] == 0)
        lit = s > 0
        assert np.allclose(s[lit], cos[lit], atol=2e-3)  # lit pixels: exactly the cosine term
        assert (cos > 0.05).sum() > (s > 0.05).sum()  # and some pixels are in shadow


def test_sun_vectors_follow_design_convention(street_level: tuple[SceneSpec, dict]) -> None:
    spec, out = street_level
    for k, sun in enumerate(spec.suns):
        w_world = sun.world_direction(spec.camera)
        assert math.isclose(w_world[2], math.sin(math.radians(sun.elevation_deg)), abs_tol=1e-9)
        np.testing.assert_allclose(out["sun"][k], spec.camera.rotation.T @ w_world, atol=1e-6)
        az, el = sun_angles(out["sun"][k], spec.camera.pitch_deg, spec.camera.roll_deg)
        np.testing.assert_allclose([az, el], out["sun_azel"][k], atol=1e-3)


def test_box_shadow_has_analytic_length() -> None:
    el = 30.0
    cam = CameraPose(
        np.array([6.0, -2.5, 9.0]), heading_deg=0.0, pitch_deg=-90.0, roll_deg=0.0, fov_deg=50.0
    )
    # Heading 0 looks along +x, so the camera's right is -y and the world's +y is azimuth 270.
    sun = Sun(270.0, el)
    spec = _box_scene(cam, [sun])
    w = sun.world_direction(cam)
    assert w[1] > 0.86  # the sun lies toward +y
    out = render_view(spec, 64, spp=1, seed=0)
    cam_i = Camera.from_fov(64, 64, out["fov_deg"])
    pts = _to_world(backproject(out["depth"], cam_i), cam)
    ground = (np.abs(pts[..., 2]) < 1e-3) & ~out["sky"]
    dark = ground & (out["shadow"][0] == 0)
    # The shadow lies on the side away from the sun (-y) and reaches h / tan(el) beyond the box.
    y_edge = BOX_CENTRE[1] - BOX_SIZE[1] / 2
    reach = y_edge - pts[..., 1][dark]
    expected = BOX_SIZE[2] / math.tan(math.radians(el))
    pixel = 2 * 9.0 * math.tan(math.radians(25.0)) / 64
    assert dark.sum() > 20
    assert abs(reach.max() - expected) < 1.5 * pixel
    assert reach.min() > -pixel  # nothing in shadow on the sunny side of the box


def test_shadowed_pixels_darker_in_rgb(street_level: tuple[SceneSpec, dict]) -> None:
    spec, out = street_level
    cam = Camera.from_fov(36, 48, out["fov_deg"])
    pts = _to_world(backproject(out["depth"], cam), spec.camera)
    ground = (np.abs(pts[..., 2]) < 1e-3) & ~out["sky"]
    lum = out["rgb"] @ np.array([0.2126, 0.7152, 0.0722], np.float32)  # K x H x W
    checked = 0
    for k in range(len(out["sun"])):
        shade = ground & (out["shadow"][k] == 0)
        lit = ground & (out["shadow"][k] > 0.2)
        if shade.sum() >= 3 and lit.sum() >= 3:
            assert lum[k][shade].mean() < 0.6 * lum[k][lit].mean()
            checked += 1
    assert checked >= 1


def test_offscreen_geometry_casts_nothing() -> None:
    cam = CameraPose(
        np.array([0.0, 0.0, 1.6]), heading_deg=0.0, pitch_deg=-25.0, roll_deg=0.0, fov_deg=45.0
    )
    sun = Sun(90.0, 20.0)  # low sun from the right
    # A tall wall just right of the frustum: its shadow would fall across the visible ground.
    wall = box(2.0, 2.0, 8.0).transformed(np.eye(3), [5.0, -7.0, 0.0])
    with_wall = _spec([(_ground(), 0), (wall, 1)], cam, [sun])
    without = _spec([(_ground(), 0)], cam, [sun])
    assert len(cull_to_frustum(with_wall, 24, 32)) == 1  # the wall is culled
    a = render_view(with_wall, (24, 32), spp=2, seed=3)
    b = render_view(without, (24, 32), spp=2, seed=3)
    np.testing.assert_array_equal(a["shadow"], b["shadow"])
    np.testing.assert_array_equal(a["rgb"], b["rgb"])
    # Without culling the wall would shade the view: the test scene is meaningful.
    c = render_view(with_wall, (24, 32), spp=2, seed=3, cull=False)
    assert (c["shadow"] < a["shadow"] - 0.1).sum() > 10


def test_same_seed_same_images() -> None:
    a = render_view(generate_scene(123, 2), 24, spp=2, seed=123)
    b = render_view(generate_scene(123, 2), 24, spp=2, seed=123)
    for key in ("rgb", "shadow", "depth", "normals", "sky", "sun", "sun_azel"):
        np.testing.assert_array_equal(a[key], b[key])
    c = render_view(generate_scene(124, 2), 24, spp=2, seed=124)
    assert not np.array_equal(a["depth"], c["depth"])


def test_baked_sky_matches_mitsuba_sunsky() -> None:
    """The envmap + directional bake lights the ground like Mitsuba's own sunsky emitter."""
    import mitsuba as mi

    from outcast_core.data.render import _sensor

    cam = CameraPose(
        np.array([0.0, 0.0, 1.6]), heading_deg=30.0, pitch_deg=-20.0, roll_deg=0.0, fov_deg=60.0
    )
    sun = Sun(120.0, 35.0)
    spec = _spec([(_ground(), 0)], cam, [sun])
    ours = render_view(spec, 24, spp=64, seed=5)
    ref_scene = mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "path", "max_depth": 5},
            "sensor": _sensor(mi, spec, 24, 24, {"type": "independent", "sample_count": 64}),
            "sky": {
                "type": "sunsky",
                "sun_direction": sun.world_direction(cam).tolist(),
                "turbidity": spec.turbidity,
                "albedo": spec.sky_albedo,
            },
            "g": {
                "type": "rectangle",
                "to_world": mi.ScalarTransform4f().scale(300.0),
                "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.4}},
            },
        }
    )
    ref = np.array(mi.render(ref_scene), np.float64)[..., :3]
    ground = ~ours["sky"]
    assert ground.sum() > 100 and (~ground).sum() > 50
    np.testing.assert_allclose(ours["rgb"][0][ground].mean(0), ref[ground].mean(0), rtol=0.03)
    np.testing.assert_allclose(ours["rgb"][0][~ground].mean(0), ref[~ground].mean(0), rtol=0.05)


def test_visible_sun_disc_lands_on_the_sun_direction() -> None:
    cam = CameraPose(
        np.array([0.0, 0.0, 1.6]), heading_deg=0.0, pitch_deg=10.0, roll_deg=0.0, fov_deg=40.0
    )
    out = render_view(_spec([(_ground(), 0)], cam, [Sun(8.0, 14.0)]), 48, spp=2, seed=0)
    lum = out["rgb"][0] @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    j, i = np.unravel_index(np.argmax(lum), lum.shape)
    u, v = project(out["sun"][0][None], Camera.from_fov(48, 48, out["fov_deg"]))
    assert abs(i + 0.5 - u[0]) <= 1.0 and abs(j + 0.5 - v[0]) <= 1.0
    assert lum[j, i] > 100 * np.median(lum[out["sky"]])
