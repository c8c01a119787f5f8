"""Display conversions (numpy, no Qt)."""

from __future__ import annotations

import numpy as np
import pytest

from app import display


def test_overlay_tints_shadow_not_lit_or_sky():
    shadow = np.array([[0.5, 0.0, 0.0]], np.float32)
    cosine = np.array([[0.5, 0.5, 0.8]], np.float32)
    sky = np.array([[False, False, True]])
    rgba = display.shadow_overlay_rgba(shadow, sky, cosine)
    assert rgba.shape == (1, 3, 4) and rgba.dtype == np.uint8
    alpha = rgba[0, :, 3]
    assert alpha[0] == 0  # fully lit under a low sun (shadow == cosine): clear
    assert alpha[1] == 255  # cast shadow: tinted
    assert alpha[2] == 0  # sky never tinted
    assert tuple(rgba[0, 1, :3]) == display.OVERLAY_RGB


def test_overlay_surfaces_turned_away_are_tinted_lightly():
    rgba = display.shadow_overlay_rgba(np.zeros((1, 2), np.float32), None,
                                       np.array([[0.0, 0.6]], np.float32))  # fmt: skip
    assert rgba[0, 0, 3] == round(display.ATTACHED_STRENGTH * 255)
    assert rgba[0, 1, 3] == 255


def test_overlay_without_cosine_uses_shadow_directly():
    rgba = display.shadow_overlay_rgba(np.array([[0.25, 1.0]], np.float32))
    assert rgba[0, 0, 3] == round(0.75 * 255) and rgba[0, 1, 3] == 0


def test_overlay_rejects_bad_shapes():
    with pytest.raises(ValueError, match="expected a shadow"):
        display.shadow_overlay_rgba(np.zeros((2, 2, 3)))
    with pytest.raises(ValueError, match="sky mask"):
        display.shadow_overlay_rgba(np.zeros((2, 2)), np.zeros((3, 3), bool))


def test_buffers_to_rgb():
    depth = np.linspace(0, 1, 12, dtype=np.float32).reshape(3, 4)
    sky = np.zeros((3, 4), bool)
    sky[0, 0] = True
    d = display.buffer_to_rgb("depth", depth, sky)
    assert d.shape == (3, 4, 3) and d.dtype == np.uint8 and (d[0, 0] == 0).all()
    assert not np.array_equal(d[1, 1], d[2, 3])  # near and far differ
    n = display.buffer_to_rgb("normals", np.full((3, 4, 3), 0.5, np.float32))
    assert (n == 128).all()
    s = display.buffer_to_rgb("new_shadow", np.full((3, 4), 1.0, np.float32))
    assert (s == 255).all()
    o = display.buffer_to_rgb("output", np.full((3, 4, 3), 2.0, np.float32))
    assert (o == 255).all()
