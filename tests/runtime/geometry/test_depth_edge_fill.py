"""DepthEdgeFill: the learned shadow's bleed across depth edges taken out on the far side only."""

from __future__ import annotations

import numpy as np
import pytest

from outcast_core.runtime.geometry.camera import normalize_sun
from outcast_core.runtime.geometry.shadows import (
    EDGE_FILL_REACH,
    DepthEdgeFill,
)
from outcast_core.runtime.pipeline.session import RelightSession
from tests.runtime.scenes import box_scene_depth


def _pole_scene() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A far wall (depth 10) with a near pole (depth 6) in columns 10-13; the truth: the pole's
    right face lit, everything else in shade except the wall left of column 4."""
    depth = np.full((20, 24), 10.0, np.float32)
    depth[:, 10:14] = 6.0
    truth = np.zeros((20, 24), np.float32)
    truth[:, 12:14] = 1.0  # the pole's sunlit face
    truth[:, :4] = 0.8  # a lit patch of wall far from the pole
    return depth, truth, depth < 8.0


def test_a_lit_face_bled_onto_the_shade_behind_is_taken_back() -> None:
    depth, truth, pole = _pole_scene()
    bled = truth.copy()
    bled[:, 14:16] = 0.9  # the network spread the lit face two pixels onto the wall
    bled[:, 8:10] = 0.3  # and darkened the wall left of the pole a little
    fill = DepthEdgeFill(depth)
    out = fill(bled)
    far_side = (~pole) & (np.abs(np.arange(24) - 11.5) < 4.5)[None, :]
    assert np.array_equal(fill.band, far_side)  # the wall within reach, not the pole
    assert np.abs(out[:, 14:16]).max() < 1e-6  # the wall's own shade
    assert np.abs(out[:, 8:10]).max() < 1e-6
    assert np.array_equal(out[pole], bled[pole])  # the nearer surface keeps its own
    assert np.array_equal(out[~fill.band], bled[~fill.band])  # away from the edge: unchanged
    assert out is not bled and np.array_equal(bled[:, 14:16], np.full((20, 2), 0.9, np.float32))


def test_a_smooth_surface_and_the_sky_are_left_alone() -> None:
    # A ground plane seen from 1.5 m, its horizon 30 rows above the frame (focal 40 px):
    # depth 1.5 * 40 / (rows below the horizon), 2 to 4 m; log depth falls 0.07 over two rows.
    rows = (1.5 * 40.0 / (np.arange(32, dtype=np.float32) + 30.0)).astype(np.float32)
    ground = np.repeat(rows[::-1, None], 16, axis=1)
    rng = np.random.default_rng(3)
    shadow = rng.random((32, 16)).astype(np.float32)
    fill = DepthEdgeFill(ground)
    assert not fill.band.any()
    assert np.array_equal(fill(shadow), shadow)
    # The sky is no nearer surface: a roof against it keeps its shadow, and the sky gives none.
    roofed = ground.copy()
    roofed[:8] = np.inf
    fill = DepthEdgeFill(roofed)
    assert not fill.band.any()
    assert np.array_equal(fill(shadow), shadow)


def test_a_gap_with_too_little_of_its_own_surface_keeps_its_shadow() -> None:
    depth = np.full((16, 16), 5.0, np.float32)
    depth[:, 7] = 9.0  # one far column seen between two near walls: all of it is band
    shadow = np.zeros((16, 16), np.float32)
    shadow[:, 7] = 0.6
    fill = DepthEdgeFill(depth)
    assert fill.band[:, 7].all() and fill.band.sum() == 16
    assert np.array_equal(fill(shadow), shadow)


@pytest.mark.parametrize("shape", [(1, 1), (1, 9), (9, 1), (2, 2)])
def test_tiny_and_degenerate_depth_maps(shape: tuple[int, int]) -> None:
    depth = np.full(shape, 5.0, np.float32)
    depth.flat[0] = 2.0  # one near pixel
    shadow = np.random.default_rng(0).random(shape).astype(np.float32)
    out = DepthEdgeFill(depth)(shadow)
    assert out.shape == shape and np.isfinite(out).all()
    assert out.min() >= shadow.min() - 1e-6 and out.max() <= shadow.max() + 1e-6  # a mean
    for bad in (np.nan, -1.0, 0.0, np.inf):  # no surface at all: nothing to fill
        assert not DepthEdgeFill(np.full(shape, bad, np.float32)).band.any()


def test_shapes_are_checked() -> None:
    with pytest.raises(ValueError, match="H x W"):
        DepthEdgeFill(np.ones((4, 4, 1), np.float32))
    with pytest.raises(ValueError, match="shape"):
        DepthEdgeFill(np.ones((4, 4), np.float32))(np.ones((4, 5), np.float32))
    assert EDGE_FILL_REACH >= 1


def test_the_sessions_learned_shadows_are_filled_at_depth_edges() -> None:
    # A tower 20 m tall on the ground, seen from 60 m above: its top a third nearer.
    depth = box_scene_depth(60, 80, 80 / (2 * np.tan(np.radians(15))), 60.0,
                            [(-4.0, 2.0, -3.0, 3.0, 20.0)])
    rng = np.random.default_rng(1)
    image = np.clip(0.5 + 0.05 * rng.standard_normal((60, 80, 3)), 0, 1).astype(np.float32)
    s = RelightSession(preset="fast", shadow_mode="learned")
    s.set_image(image, depth=depth, fov_deg=30.0)
    w = normalize_sun((0.6, -0.5, -0.6))
    d = np.where(s.sky, np.inf, s.depth).astype(np.float32)
    raw = s._learned_shadow(s.image_srgb, d, s.normals, s.camera, w)
    fill = DepthEdgeFill(d, s.image_srgb)
    assert fill.band.any()
    got = s.shadow(w)
    assert np.allclose(got, fill(raw), atol=1e-6)
    assert not np.allclose(got, raw, atol=1e-3)  # the box's edges changed something
    assert np.array_equal(got[~fill.band], raw[~fill.band])
    assert (s._depth_edge_fill(False, d, s.image_srgb)
            is s._depth_edge_fill(False, d, s.image_srgb))  # once per depth map
    s.shadow(w, preview=True)
    assert "edge_fill" in s._preview_state()
    direct = RelightSession(preset="fast", shadow_mode="direct")
    direct.set_image(image, depth=depth, fov_deg=30.0)
    direct.shadow(w)
    assert direct._edge_fill is None  # Direct, marched per pixel, has no bleed to take out


def test_with_the_photo_a_small_depth_step_at_a_luminance_edge_is_an_edge() -> None:
    """A rough depth map barely separates a pole from the floor behind it (the pool sample:
    log depth -0.28 against -0.34), and the lit strip the network spread beside the pole
    stayed. With the photo, a 5 % step where the luminance jumps is an edge; the fill reads
    the floor's own luminance; a textured floor with no depth step, and the depth alone, are
    left as before; a photo of another size is refused."""
    depth = np.full((20, 24), 10.0, np.float32)
    depth[:, 10:14] = 9.5  # 5 % nearer: no edge by depth alone
    photo = np.full((20, 24, 3), 0.8, np.float32)
    photo[:, 10:14] = 0.05  # a dark pole before a bright floor
    floor = np.zeros((20, 24), np.float32)  # the floor in shade, the pole too
    bled = floor.copy()
    bled[:, 14:16] = 0.9  # the network's lit strip beside the pole
    assert not DepthEdgeFill(depth).band.any()
    fill = DepthEdgeFill(depth, photo)
    assert fill.band[:, 14:16].all() and not fill.band[:, 10:14].any()
    assert np.abs(fill(bled)[:, 14:16]).max() < 1e-6
    rng = np.random.default_rng(2)
    textured = np.clip(0.4 + 0.3 * rng.standard_normal((20, 24, 3)), 0, 1).astype(np.float32)
    flat = np.full((20, 24), 10.0, np.float32)
    assert not DepthEdgeFill(flat, textured).band.any()
    with pytest.raises(ValueError, match="photo"):
        DepthEdgeFill(depth, photo[:, :-1])
