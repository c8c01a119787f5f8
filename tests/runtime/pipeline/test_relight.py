"""Physics relighting by shading ratios, and the full-resolution transfer."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from outcast_core.runtime.geometry.colour import linear_to_srgb, srgb_to_linear
from outcast_core.runtime.pipeline.relight import (
    PRIOR_RATIO,
    estimate_light,
    estimate_light_on_surfaces,
    physics_relight,
    shading_ratio,
    transfer_to_full_resolution,
)


def synthetic_photo(ratio: np.ndarray, seed: int = 0):
    """Albedo x (1 + r S): a random-albedo scene with a shadowed half and a lit half."""
    rng = np.random.default_rng(seed)
    albedo = rng.uniform(0.05, 0.4, (64, 64, 3)).astype(np.float32)
    s_o = np.zeros((64, 64), np.float32)
    s_o[:, 32:] = 0.7
    lin = albedo * (1 + ratio * s_o[..., None]) / (1 + ratio.max())
    return lin.astype(np.float32), s_o, albedo


def test_estimate_light_recovers_the_ratio() -> None:
    r = np.array([6.0, 4.5, 3.0], np.float32)
    lin, s_o, _ = synthetic_photo(r)
    est = estimate_light(lin, s_o)
    assert est.measured
    np.testing.assert_allclose(est.ratio, r, rtol=0.15)


def test_estimate_light_falls_back_without_shadows() -> None:
    lin, _, _ = synthetic_photo(np.array([5.0, 5.0, 5.0], np.float32))
    est = estimate_light(lin, np.full((64, 64), 0.8, np.float32))
    assert not est.measured
    np.testing.assert_array_equal(est.ratio, PRIOR_RATIO)


def test_relight_swaps_shading_exactly_and_keeps_sky() -> None:
    r = np.array([6.0, 4.5, 3.0], np.float32)
    lin, s_o, albedo = synthetic_photo(r)
    s_n = s_o[:, ::-1].copy()  # the shadow moves to the other half
    sky = np.zeros((64, 64), bool)
    sky[:4] = True
    out = physics_relight(linear_to_srgb(lin), s_o, s_n, sky, snap=False)
    expected = albedo * (1 + r * s_n[..., None]) / (1 + r.max())
    got = srgb_to_linear(out)
    np.testing.assert_allclose(got[4:], expected[4:], rtol=0.2, atol=2e-3)
    np.testing.assert_allclose(out[:4], linear_to_srgb(lin)[:4], atol=1e-6)


def test_shading_ratio_is_guarded() -> None:
    s = np.array([[0.0, 1.0, np.nan]], np.float32)
    g = shading_ratio(s, s[:, ::-1], np.array([5.0, 5.0, 5.0]))
    assert np.all(np.isfinite(g)) and g.min() > 0


def test_transfer_keeps_detail_and_applies_gain() -> None:
    rng = np.random.default_rng(2)
    full = rng.uniform(0.2, 0.8, (301, 403, 3)).astype(np.float32)  # fine detail everywhere
    small_before = np.full((30, 40, 3), 0.5, np.float32)
    small_after = linear_to_srgb(srgb_to_linear(small_before) * 0.5)  # halve the light
    out = transfer_to_full_resolution(full, small_before, small_after, band_rows=64)
    np.testing.assert_allclose(srgb_to_linear(out), srgb_to_linear(full) * 0.5, rtol=0.01,
                               atol=2e-3)
    with pytest.raises(ValueError):
        transfer_to_full_resolution(full, small_before, small_after[:5])


def test_light_estimate_on_surfaces_leaves_out_pixels_without_normals() -> None:
    from outcast_core.runtime.geometry.colour import linear_to_srgb

    rng = np.random.default_rng(5)
    shadow = (rng.random((20, 30)) > 0.5).astype(np.float32)
    lin = 0.1 * (1.0 + np.array([3.0, 2.0, 1.5], np.float32) * shadow[..., None])
    lin[:12] = (0.9, 0.05, 0.05)  # a "sky" that would break the ratio if it were counted
    shadow[:12] = 1.0
    normals = np.zeros((20, 30, 3), np.float32)
    normals[12:, :, 1] = -1.0
    got = estimate_light_on_surfaces(linear_to_srgb(lin), shadow, normals)
    want = estimate_light(lin, shadow, np.arange(20)[:, None].repeat(30, 1) < 12)
    assert got.measured
    np.testing.assert_allclose(got.ratio, want.ratio, rtol=1e-3)
    np.testing.assert_allclose(got.ratio, [3.0, 2.0, 1.5], rtol=2e-2)
    with_sky = estimate_light(lin, shadow)
    assert np.abs(with_sky.ratio - got.ratio).max() > 0.1


def test_keep_photo_colour_where_both_suns_light_the_surface() -> None:
    from outcast_core.runtime.pipeline.relight import keep_photo_colour

    h, w = 8, 12
    image = np.full((h, w, 3), [0.6, 0.5, 0.4], np.float32)
    relit = np.full((h, w, 3), [0.8, 0.5, 0.3], np.float32)  # brighter and tinted orange
    s_old = np.full((h, w), 0.8, np.float32)
    s_new = np.full((h, w), 0.8, np.float32)
    s_new[:, 6:] = 0.0  # newly shadowed on the right: the relit colour stands there
    sky = np.zeros((h, w), bool)
    sky[0] = True
    out = keep_photo_colour(image, relit, s_old, s_new, sky, keep_sky=True)
    lab = [cv2.cvtColor(np.ascontiguousarray(x[4:5, 2:3]), cv2.COLOR_RGB2Lab)[0, 0]
           for x in (image, relit, out)]
    np.testing.assert_allclose(lab[2][1:], lab[0][1:], atol=0.3)  # the photo's a*, b*
    np.testing.assert_allclose(lab[2][0], lab[1][0], atol=0.3)  # the relit lightness L*
    assert out[4, 2].mean() > image[4, 2].mean()
    np.testing.assert_allclose(out[4, 9], relit[4, 9], atol=1e-3)
    np.testing.assert_allclose(out[0], image[0], atol=1e-3)  # the sky is the photo's
    out = keep_photo_colour(image, relit, s_old, s_new, sky, keep_sky=False)
    assert not np.allclose(out[0, 9], image[0, 9], atol=1e-2)


def test_shadow_contrast_floor_darkens_new_shadows_at_least_as_physics_does() -> None:
    from outcast_core.runtime.geometry.colour import luminance, srgb_to_linear
    from outcast_core.runtime.pipeline.relight import (
        estimate_light,
        physics_relight,
        shadow_contrast_floor,
    )

    h, w = 6, 9
    image = np.full((h, w, 3), [0.5, 0.45, 0.4], np.float32)
    s_old = np.full((h, w), 0.8, np.float32)
    s_new = np.full((h, w), 0.8, np.float32)
    s_old[:, :3] = 0.0  # columns 0-2: newly lit
    s_new[:, 6:] = 0.0  # columns 6-8: newly shadowed; 3-5 lit under both suns
    s_old[:2, :3] = 0.8  # ... and a lit patch for the light estimate
    image[2:, :3] *= 0.3
    light = estimate_light(srgb_to_linear(image), s_old)
    relit = image.copy()
    relit[:, :3] *= 1.2  # the learned image: a timid change
    relit[:, 6:] *= 0.9
    relit[:, 3:6] = [0.55, 0.45, 0.35]  # lit under both suns: left to the other guard
    physics = physics_relight(image, s_old, s_new, None, light=light, snap=False)
    out = shadow_contrast_floor(image, relit, physics, s_old, s_new)
    lifted = shadow_contrast_floor(image, relit, physics, s_old, s_new, lift=True)
    bold = image.copy()
    bold[:, 6:] *= 0.1
    bold_out = shadow_contrast_floor(image, bold, physics, s_old, s_new)

    def y(img: np.ndarray, rows: slice, cols: slice) -> float:
        return float(luminance(srgb_to_linear(img[rows, cols])).mean())

    new_shd, new_lit = (slice(None), slice(6, 9)), (slice(2, None), slice(0, 3))
    assert y(physics, *new_shd) < y(relit, *new_shd)  # the case: physics darkens more
    assert y(out, *new_shd) == pytest.approx(y(physics, *new_shd), rel=1e-2)
    np.testing.assert_allclose(out[:, :6], relit[:, :6], atol=1e-4)  # no lift by default
    assert y(physics, *new_lit) > y(relit, *new_lit)
    assert y(lifted, *new_lit) == pytest.approx(y(physics, *new_lit), rel=1e-2)
    def chromaticity(px: np.ndarray) -> np.ndarray:
        lin = srgb_to_linear(px)
        return lin / lin.sum()

    # A newly shadowed surface takes physics' colour (the photo's own shade colour); a newly
    # lit one keeps the learned colour.
    np.testing.assert_allclose(chromaticity(out[3, 7]), chromaticity(physics[3, 7]), atol=1e-3)
    assert np.abs(chromaticity(relit[3, 7]) - chromaticity(physics[3, 7])).max() > 0.01
    np.testing.assert_allclose(chromaticity(lifted[3, 1]), chromaticity(relit[3, 1]), atol=1e-3)
    # A learned new shadow darker than physics' keeps its darkness.
    assert y(bold_out, *new_shd) == pytest.approx(y(bold, *new_shd), rel=0.05)  # Y 0.004
    with pytest.raises(ValueError, match="relit image"):
        shadow_contrast_floor(image, relit[:3], physics, s_old, s_new)


def test_new_shade_is_at_least_as_dark_as_the_photo_s_own_shade_round_it() -> None:
    """``shade_ratio``: a newly shadowed surface ends at least the photo's own local shade
    ratio below the photo (physics' one sun/sky ratio left it lighter), never lighter than
    physics makes it; nothing else moves."""
    from outcast_core.runtime.geometry.colour import luminance, srgb_to_linear
    from outcast_core.runtime.pipeline.photo_shadows import shade_log_ratio
    from outcast_core.runtime.pipeline.relight import (
        estimate_light,
        guard_learned_relight,
        shadow_contrast_floor,
    )

    h, w = 24, 36
    image = np.full((h, w, 3), [0.6, 0.55, 0.5], np.float32)
    s_old = np.ones((h, w), np.float32)
    s_old[12:, :18] = 0.0  # the photo's own shade: 8 x darker than its lit surface
    image[12:, :18] /= 8.0
    s_new = s_old.copy()
    s_new[12:, 18:26] = 0.0  # newly shadowed, beside it
    sky = np.zeros((h, w), bool)
    physics = image.copy()
    physics[12:, 18:26] *= 0.5  # a timid physics (its one sun/sky ratio: 2)
    ratio = shade_log_ratio(image, 1.0 - s_old, sky)

    def y(img: np.ndarray, rows: slice, cols: slice) -> float:
        return float(luminance(srgb_to_linear(img[rows, cols])).mean())

    new_shd = (slice(14, None), slice(19, 25))
    local = float(np.exp(-ratio[new_shd].mean()))
    assert local < 0.3  # the photo's own shade round it: far darker than physics' 0.5
    plain = shadow_contrast_floor(image, image, physics, s_old, s_new)
    out = shadow_contrast_floor(image, image, physics, s_old, s_new, shade_ratio=ratio)
    assert y(out, *new_shd) == pytest.approx(local * y(image, *new_shd), rel=0.05)
    assert y(out, *new_shd) < 0.6 * y(plain, *new_shd)
    np.testing.assert_allclose(out[:12], plain[:12], atol=1e-5)  # lit under both suns
    np.testing.assert_allclose(out[:, :18], plain[:, :18], atol=1e-5)  # shade under both
    # A shade physics made darker stays as dark.
    deep = image.copy()
    deep[12:, 18:26] *= 0.02
    out = shadow_contrast_floor(image, image, deep, s_old, s_new, shade_ratio=ratio)
    assert y(out, *new_shd) == pytest.approx(y(deep, *new_shd), rel=0.05)
    # The guard reads it from S_o and the photo (a light estimate of a milder photo: physics
    # too light here).
    mild = np.full((h, w, 3), [0.6, 0.55, 0.5], np.float32)
    mild[12:, :18] /= 2.0
    light = estimate_light(srgb_to_linear(mild), s_old)
    kw = dict(keep_sky=True, colour=False, anchor=False, detail=False)
    guarded = guard_learned_relight(image, image, s_old, s_new, sky, light, **kw)
    unguarded = guard_learned_relight(image, image, s_old, s_new, sky, light, **kw,
                                      local_shade=False)
    assert y(guarded, *new_shd) < 0.6 * y(unguarded, *new_shd)
    with pytest.raises(ValueError, match="shade ratio"):
        shadow_contrast_floor(image, image, physics, s_old, s_new, shade_ratio=ratio[:3])


def test_anchor_exposure_takes_the_exposure_of_physics_on_surfaces_lit_under_both_suns() -> None:
    from outcast_core.runtime.pipeline.relight import (
        anchor_exposure,
        estimate_light,
        physics_relight,
    )

    h, w = 12, 16
    rng = np.random.default_rng(0)
    image = np.clip(0.5 + 0.05 * rng.standard_normal((h, w, 3)), 0, 1).astype(np.float32)
    s_old = np.full((h, w), 0.9, np.float32)
    s_new = np.full((h, w), 0.9, np.float32)
    s_new[:, 12:] = 0.0  # a new shadow on the right
    sky = np.zeros((h, w), bool)
    sky[0] = True
    light = estimate_light(srgb_to_linear(image), s_old)
    physics = physics_relight(image, s_old, s_new, sky, light=light, snap=False)
    drifted = np.clip(image * 1.4, 0, 1)  # L's exposure drift: everything brighter
    drifted[0] = [0.2, 0.4, 0.9]  # its sky
    out = anchor_exposure(image, drifted, physics, s_old, s_new, sky)
    both = ~sky & (s_new > 0.5)
    ratio = srgb_to_linear(out)[both].mean() / srgb_to_linear(physics)[both].mean()
    assert ratio == pytest.approx(1.0, abs=0.03)
    np.testing.assert_allclose(out[0], drifted[0], atol=1e-5)  # the sky is not re-exposed
    # Too few pixels lit under both suns: unchanged.
    dark = np.zeros((h, w), np.float32)
    np.testing.assert_allclose(anchor_exposure(image, drifted, physics, dark, s_new, sky), drifted)
    with pytest.raises(ValueError, match="relit image"):
        anchor_exposure(image, drifted[:4], physics, s_old, s_new, sky)


def test_anchor_exposure_does_not_darken_what_the_new_sun_newly_lights() -> None:
    """A gain below 1 (``L`` brighter than physics where both suns light the surface) fades to
    1 where the new sun newly lights it: ``L`` brightens those surfaces less than physics and
    the truth already (held-out renders: newly lit x1.727 -> x1.764 with this alone). A gain
    above 1 applies everywhere off the sky."""
    from outcast_core.runtime.pipeline.relight import anchor_exposure

    h, w = 12, 16
    image = np.full((h, w, 3), 0.4, np.float32)
    s_old = np.full((h, w), 0.9, np.float32)
    s_old[:, :4] = 0.0  # newly lit: shadowed under the old sun, lit under the new
    s_new = np.full((h, w), 0.9, np.float32)
    sky = np.zeros((h, w), bool)
    relit = np.full((h, w, 3), 0.6, np.float32)
    physics = np.full((h, w, 3), 0.5, np.float32)  # L too bright on both-lit: gain < 1
    out = anchor_exposure(image, relit, physics, s_old, s_new, sky)
    np.testing.assert_allclose(out[:, :4], relit[:, :4], atol=1e-5)  # newly lit: kept
    np.testing.assert_allclose(out[:, 4:], physics[:, 4:], atol=2e-3)  # both lit: anchored
    dim = anchor_exposure(image, np.full_like(relit, 0.4), physics, s_old, s_new, sky)
    assert dim[:, :4].mean() > 0.45 and dim[:, 4:].mean() == pytest.approx(0.5, abs=2e-3)


def test_the_lift_ceiling_lets_a_cast_shadow_rise_to_physics() -> None:
    """Where ``lift_ceiling`` says the geometry casts a shadow at the photo's sun, the lift
    rises past the de-shadowed ceiling to physics' level; elsewhere the ceiling holds."""
    from outcast_core.runtime.geometry.colour import luminance, srgb_to_linear
    from outcast_core.runtime.pipeline.relight import shadow_contrast_floor

    h, w = 6, 8
    image = np.full((h, w, 3), 0.2, np.float32)
    s_old = np.zeros((h, w), np.float32)  # all shadowed under the old sun
    s_new = np.full((h, w), 0.9, np.float32)  # all lit under the new
    relit = np.full((h, w, 3), 0.3, np.float32)  # L: timid
    physics = np.full((h, w, 3), 0.8, np.float32)
    cap = np.full((h, w, 3), 0.5, np.float32)  # the de-shadowed photo relit: lower
    ceiling = np.zeros((h, w), np.float32)
    ceiling[:, 4:] = 1.0  # the geometry's cast shadow on the right half
    kw = {"lift": True, "lift_cap_srgb": cap}
    out = shadow_contrast_floor(image, relit, physics, s_old, s_new, lift_ceiling=ceiling, **kw)
    plain = shadow_contrast_floor(image, relit, physics, s_old, s_new, **kw)

    def y(img: np.ndarray) -> np.ndarray:
        return luminance(srgb_to_linear(img))

    np.testing.assert_allclose(y(out[:, 4:]), y(physics[:, 4:]), rtol=3e-3)
    np.testing.assert_allclose(out[:, :4], plain[:, :4], atol=1e-6)
    np.testing.assert_allclose(y(plain), y(cap), rtol=3e-3)  # without it: the ceiling
    with pytest.raises(ValueError, match="lift ceiling"):
        shadow_contrast_floor(image, relit, physics, s_old, s_new, lift_ceiling=ceiling[:2],
                              **kw)


@pytest.mark.parametrize("drift", [0.4, 2.5])
def test_new_shadows_stay_as_dark_as_physics_whatever_the_anchors_gain(drift: float) -> None:
    """The anchor corrects ``L``'s exposure before the floor compares it with physics, so its
    gain, read where both suns light the surface, no longer scales what the floor set: a gain
    above 1 left new shadows lighter than physics, one below 1 (``L`` too bright on a small
    patch both suns light: the pool sample relit to a sun on the horizon) crushed them."""
    from outcast_core.runtime.pipeline import relight

    h, w = 24, 32
    rng = np.random.default_rng(1)
    image = np.clip(0.55 + 0.04 * rng.standard_normal((h, w, 3)), 0, 1).astype(np.float32)
    s_old = np.full((h, w), 0.9, np.float32)
    s_new = np.zeros((h, w), np.float32)  # newly shadowed almost everywhere...
    s_new[:8, :8] = 0.9  # ...but for a patch both suns light
    sky = np.zeros((h, w), bool)
    light = relight.estimate_light(srgb_to_linear(image), s_old)
    learned = image.copy()  # L: the photo as it was, its exposure off by `drift` on the patch
    learned[:8, :8] = np.clip(linear_to_srgb(srgb_to_linear(image[:8, :8]) * drift), 0, 1)
    physics = relight.physics_relight(image, s_old, relight.smooth_new_shadow(s_new), sky,
                                      light=light, snap=False)
    out = relight.guard_learned_relight(image, learned, s_old, s_new, sky, light,
                                        keep_sky=False, colour=False, detail=False)
    y = srgb_to_linear(out) @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    y_p = srgb_to_linear(physics) @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    shade = (slice(14, None), slice(14, None))  # deep in the new shadow, off the patch's blur
    assert np.median(y[shade] / y_p[shade]) == pytest.approx(1.0, abs=0.02)
    # With the order before 2026-12-04 the anchor's gain reached the new shadow too.
    old_order = relight.ANCHOR_FIRST
    try:
        relight.ANCHOR_FIRST = False
        before = relight.guard_learned_relight(image, learned, s_old, s_new, sky, light,
                                               keep_sky=False, colour=False, detail=False)
    finally:
        relight.ANCHOR_FIRST = old_order
    y_b = srgb_to_linear(before) @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    assert abs(np.median(y_b[shade] / y_p[shade]) - 1.0) > 0.3


def test_guarded_relight_keeps_the_photos_colour_where_both_suns_light_it() -> None:
    """The colour guard acts last: neither the exposure anchor's gain nor the shade floor moves
    the ``a*, b*`` it keeps on surfaces lit under both suns (the anchor's gain alone moved them
    before: Lab ``a*, b*`` grow with lightness)."""
    from outcast_core.runtime.geometry.colour import linear_to_lab
    from outcast_core.runtime.pipeline.relight import guard_learned_relight

    rng = np.random.default_rng(2)
    h, w = 16, 24
    image = rng.uniform(0.25, 0.6, (h, w, 3)).astype(np.float32)
    image[..., 1] *= 1.25  # greener, where a gain moves a* most (in gamut: the sRGB cube
    # clips the most saturated colours when their lightness changes)
    relit = np.clip(image * np.array([1.25, 0.9, 0.8], np.float32), 0, 1)  # tinted
    s_old = np.full((h, w), 0.9, np.float32)
    s_new = np.full((h, w), 0.6, np.float32)  # lit, but less: the relit image may darken
    s_new[:, 16:] = 0.0  # newly shadowed there: its colour is the relighting's
    sky = np.zeros((h, w), bool)
    light = estimate_light(srgb_to_linear(image), s_old)
    out = guard_learned_relight(image, relit, s_old, s_new, sky, light, keep_sky=True)
    lab_i, lab_o = linear_to_lab(srgb_to_linear(image)), linear_to_lab(srgb_to_linear(out))
    both = np.s_[:, :10]  # away from the new shadow's smoothed edge
    np.testing.assert_allclose(lab_o[both][..., 1:], lab_i[both][..., 1:], atol=0.5)
    assert np.abs(lab_o[both][..., 0] - lab_i[both][..., 0]).mean() > 1.0  # brightness moved
    newly = np.s_[:, 20:]
    assert np.abs(lab_o[newly][..., 1:] - lab_i[newly][..., 1:]).mean() > 1.0


def test_guarded_relight_is_physics_where_the_user_marked_a_material() -> None:
    """``physics_at``: where the user said "not a shadow" (a dark material), the learned
    relighting gives way to physics', which follows the correction (``L`` bleached the
    ski-slope sample's backlit pines whatever ``S_o`` said of them: a user trial); elsewhere
    nothing changes, and a mask of another size is refused."""
    from outcast_core.runtime.pipeline.relight import guard_learned_relight, physics_relight

    h, w = 16, 24
    image = np.full((h, w, 3), 0.12, np.float32)  # a dark material, lit under both suns
    bleached = np.full((h, w, 3), 0.7, np.float32)  # what L made of it
    lit = np.ones((h, w), np.float32)
    sky = np.zeros((h, w), bool)
    light = estimate_light(srgb_to_linear(image), lit)
    held = np.zeros((h, w), np.float32)
    held[:, :8] = 1.0
    kw = {"keep_sky": True, "colour": False, "floor": False, "anchor": False, "detail": False}
    out = guard_learned_relight(image, bleached, lit, lit, sky, light, physics_at=held, **kw)
    physics = physics_relight(image, lit, lit, sky, light=light, snap=False)
    np.testing.assert_allclose(out[:, :8], physics[:, :8], atol=1e-4)
    assert np.abs(out[:, :8] - image[:, :8]).max() < 0.01  # lit under both: the photo's
    np.testing.assert_allclose(out[:, 8:], bleached[:, 8:], atol=1e-6)
    none = guard_learned_relight(image, bleached, lit, lit, sky, light,
                                 physics_at=np.zeros((h, w), np.float32), **kw)
    np.testing.assert_allclose(none, bleached, atol=1e-6)
    with pytest.raises(ValueError, match="physics_at"):
        guard_learned_relight(image, bleached, lit, lit, sky, light,
                              physics_at=np.ones((4, 4), np.float32), **kw)


def _textured(h: int = 128, w: int = 192, seed: int = 3) -> np.ndarray:
    """A smooth ramp with fine sRGB texture on it."""
    rng = np.random.default_rng(seed)
    ramp = np.linspace(0.3, 0.6, w, dtype=np.float32)[None, :, None]
    return np.clip(ramp + 0.08 * rng.standard_normal((h, w, 3)), 0.02, 1).astype(np.float32)


def test_restore_detail_puts_the_photos_texture_back_where_no_shadow_changes() -> None:
    """``L`` blurs; where both suns light a surface the relit image takes the photo's fine
    band and keeps its own coarse level (a brighter relighting stays brighter); where a
    shadow comes or goes ``L``'s own image stays, and so does the sky."""
    from outcast_core.runtime.pipeline.relight import restore_detail

    photo = _textured()
    h, w = photo.shape[:2]
    relit = np.clip(cv2.GaussianBlur(photo, (0, 0), 1.5) * 1.3, 0, 1)  # blurred, brighter
    s_old = np.full((h, w), 0.8, np.float32)
    s_new = np.full((h, w), 0.8, np.float32)
    s_new[:, 150:] = 0.0  # newly shadowed there
    sky = np.zeros((h, w), bool)
    sky[:20] = True
    out = restore_detail(photo, relit, s_old, s_new, sky)

    def fine(x: np.ndarray) -> np.ndarray:
        return x - cv2.GaussianBlur(x, (0, 0), 2.0)

    both = np.s_[30:-10, 10:130]
    corr = np.corrcoef(fine(out)[both].ravel(), fine(photo)[both].ravel())[0, 1]
    corr_before = np.corrcoef(fine(relit)[both].ravel(), fine(photo)[both].ravel())[0, 1]
    assert corr > 0.9 > corr_before + 0.2
    assert abs(out[both].mean() / relit[both].mean() - 1.0) < 0.03  # L's level kept
    np.testing.assert_allclose(out[30:, 160:], relit[30:, 160:], atol=1e-4)  # shadow changed
    np.testing.assert_allclose(out[:20], relit[:20], atol=1e-4)  # sky
    np.testing.assert_allclose(restore_detail(photo, relit, s_old, s_new, sky, sigma=0.0),
                               relit)
    with pytest.raises(ValueError, match="sky mask"):
        restore_detail(photo, relit, s_old, s_new, sky[:4])
    with pytest.raises(ValueError, match="lifted photo"):
        restore_detail(photo, relit, s_old, s_new, sky, photo[:4])


def test_restore_detail_takes_the_lifted_texture_where_the_new_sun_lights() -> None:
    """Where the new sun lights the surface the band is the lifted photo's (the photo's
    shadow edges are not put back), where it shades it the photo's own."""
    from outcast_core.runtime.pipeline.relight import restore_detail

    photo, lifted = _textured(seed=5), _textured(seed=6)
    h, w = photo.shape[:2]
    relit = cv2.GaussianBlur(photo, (0, 0), 1.5)
    shade = np.zeros((h, w), np.float32)
    lit = np.full((h, w), 0.8, np.float32)
    sky = np.zeros((h, w), bool)

    def fine(x: np.ndarray) -> np.ndarray:
        return (x - cv2.GaussianBlur(x, (0, 0), 2.0))[10:-10, 10:-10].ravel()

    def corr(a: np.ndarray, b: np.ndarray) -> float:
        return float(np.corrcoef(fine(a), fine(b))[0, 1])

    lit_out = restore_detail(photo, relit, lit, lit, sky, lifted)
    assert corr(lit_out, lifted) > 0.8 > corr(lit_out, photo) + 0.4
    kept = restore_detail(photo, relit, shade, shade, sky, lifted)  # shadow under both
    assert corr(kept, photo) > 0.8 > corr(kept, lifted) + 0.4


def test_guarded_relight_restores_detail_only_when_asked() -> None:
    """``detail`` runs :func:`restore_detail` first, from the de-shadowed photo when the lift
    gives one; without it the guards are as before."""
    from outcast_core.runtime.pipeline.relight import guard_learned_relight, restore_detail

    photo = _textured()
    h, w = photo.shape[:2]
    relit = cv2.GaussianBlur(photo, (0, 0), 1.5)
    lit = np.full((h, w), 0.8, np.float32)
    sky = np.zeros((h, w), bool)
    light = estimate_light(srgb_to_linear(photo), lit)
    kw = {"keep_sky": True, "floor": False, "anchor": False, "colour": False}
    np.testing.assert_allclose(
        guard_learned_relight(photo, relit, lit, lit, sky, light, detail=False, **kw), relit)
    np.testing.assert_allclose(
        guard_learned_relight(photo, relit, lit, lit, sky, light, **kw),
        restore_detail(photo, relit, lit, lit, sky), atol=1e-6)
    other = _textured(seed=9)  # the lift's de-shadowed photo is the lifted texture
    np.testing.assert_allclose(
        guard_learned_relight(photo, relit, lit, lit, sky, light,
                              lift_base=(other, lit), **kw),
        restore_detail(photo, relit, lit, lit, sky, other), atol=1e-6)


def test_guarded_relight_lifts_newly_lit_surfaces_to_physics_only_when_asked() -> None:
    from outcast_core.runtime.geometry.colour import luminance
    from outcast_core.runtime.pipeline.relight import guard_learned_relight, physics_relight

    h, w = 40, 40
    image = np.full((h, w, 3), 0.6, np.float32)
    s_old = np.full((h, w), 0.9, np.float32)
    image[:, :20] *= 0.35  # the photo's shadow on the left half
    s_old[:, :20] = 0.0
    s_new = np.full((h, w), 0.9, np.float32)  # the new sun lights everything
    sky = np.zeros((h, w), bool)
    light = estimate_light(srgb_to_linear(image), s_old)
    timid = image.copy()  # a relighting that did not lift the old shadow
    off = guard_learned_relight(image, timid, s_old, s_new, sky, light, keep_sky=True)
    on = guard_learned_relight(image, timid, s_old, s_new, sky, light, keep_sky=True,
                               lift=True)
    physics = physics_relight(image, s_old, s_new, sky, light=light, snap=False)

    def y(x: np.ndarray) -> float:
        return float(luminance(srgb_to_linear(x))[10:30, 5:12].mean())

    assert y(off) < 0.8 * y(physics)
    assert y(on) >= 0.97 * y(physics)


def test_lift_stops_where_the_material_guard_says_the_darkness_is_material() -> None:
    from outcast_core.runtime.geometry.colour import luminance
    from outcast_core.runtime.pipeline.photo_shadows import (
        material_guard,
        photo_shadow_probability,
    )
    from outcast_core.runtime.pipeline.relight import guard_learned_relight, physics_relight

    h, w = 48, 48
    image = np.full((h, w, 3), 0.6, np.float32)
    image[:, :24] *= 0.35  # the photo's shadow on the left half
    image[20:28, 6:14] = 0.01  # a black object inside it: dark material, not shade
    sky = np.zeros((h, w), bool)
    prob = photo_shadow_probability(image, sky)
    assert prob[24, 10] > 0.9 and prob[5, 5] > 0.9  # both found as "shadow" by darkness
    s_old = np.where(prob > 0.5, 0.0, 0.9).astype(np.float32)
    s_new = np.full((h, w), 0.9, np.float32)  # the new sun lights everything
    light = estimate_light(srgb_to_linear(image), s_old)
    guard = material_guard(image, prob, sky)
    assert guard[5, 5] > 0.8 and guard[24, 10] < 0.2
    timid = image.copy()
    on = guard_learned_relight(image, timid, s_old, s_new, sky, light, keep_sky=True,
                               lift=True, lift_guard=guard)
    physics = physics_relight(image, s_old, s_new, sky, light=light, snap=False)

    def y(x: np.ndarray, rows: slice, cols: slice) -> float:
        return float(luminance(srgb_to_linear(x))[rows, cols].mean())

    shade, black = (slice(2, 12), slice(2, 20)), (slice(22, 26), slice(8, 12))
    assert y(on, *shade) >= 0.95 * y(physics, *shade)  # shade lifted to physics
    assert y(physics, *black) > 5 * y(image, *black)  # physics would lift the black object
    assert y(on, *black) < 1.5 * y(image, *black)  # the guard keeps it black
    with pytest.raises(ValueError, match="lift guard of shape"):
        guard_learned_relight(image, timid, s_old, s_new, sky, light, keep_sky=True,
                              lift=True, lift_guard=guard[:10])


def test_lift_goes_no_higher_than_its_cap() -> None:
    from outcast_core.runtime.geometry.colour import luminance
    from outcast_core.runtime.pipeline.relight import physics_relight, shadow_contrast_floor

    h, w = 8, 8
    image = np.full((h, w, 3), 0.6, np.float32)
    image[:, :4] *= 0.3  # the photo's shadow on the left half
    s_old = np.full((h, w), 0.9, np.float32)
    s_old[:, :4] = 0.0
    s_new = np.full((h, w), 0.9, np.float32)  # the new sun lights everything
    light = estimate_light(srgb_to_linear(image), s_old)
    physics = physics_relight(image, s_old, s_new, None, light=light, snap=False)
    cap = np.full_like(image, 0.4)  # darker than physics' lift, brighter than the photo

    def y(x: np.ndarray) -> float:
        return float(luminance(srgb_to_linear(x))[:, :4].mean())

    full = shadow_contrast_floor(image, image, physics, s_old, s_new, lift=True)
    capped = shadow_contrast_floor(image, image, physics, s_old, s_new, lift=True,
                                   lift_cap_srgb=cap)
    assert y(full) == pytest.approx(y(physics), rel=1e-2)
    assert y(capped) == pytest.approx(y(cap), rel=1e-2)
    below = shadow_contrast_floor(image, image, physics, s_old, s_new, lift=True,
                                  lift_cap_srgb=image * 0.5)  # a cap below the relit image
    assert y(below) == pytest.approx(y(image), rel=1e-3)  # the lift never darkens
    with pytest.raises(ValueError, match="lift cap of shape"):
        shadow_contrast_floor(image, image, physics, s_old, s_new, lift=True,
                              lift_cap_srgb=cap[:4])


def test_lifted_old_shadow_takes_the_lit_surroundings_colour() -> None:
    """Where the lift acts, the relit surface takes the lit surroundings' a*b* (the shade's
    blue cast goes); where the guard says material, nothing moves."""
    from outcast_core.runtime.geometry.colour import linear_to_lab
    from outcast_core.runtime.pipeline.photo_shadows import (
        lit_surface_colour,
        photo_shadow_probability,
    )
    from outcast_core.runtime.pipeline.relight import guard_learned_relight

    h, w = 48, 48
    image = np.full((h, w, 3), [0.75, 0.6, 0.4], np.float32)  # warm sunlit sand
    image[:, :24] *= np.array([0.3, 0.35, 0.5], np.float32)  # blue-grey shade on the left
    sky = np.zeros((h, w), bool)
    prob = photo_shadow_probability(image, sky)
    s_old = np.where(prob > 0.5, 0.0, 0.9).astype(np.float32)
    s_new = np.full((h, w), 0.9, np.float32)  # the new sun lights everything
    light = estimate_light(srgb_to_linear(image), s_old)
    lit_ab = lit_surface_colour(image, prob, sky, 0.5)
    guard = np.ones((h, w), np.float32)
    guard[:, :8] = 0.0  # a strip the guard calls material

    def ab(x: np.ndarray, cols: slice) -> np.ndarray:
        return linear_to_lab(srgb_to_linear(x))[4:44, cols, 1:].reshape(-1, 2).mean(0)

    kwargs = dict(keep_sky=True, lift=True, lift_guard=guard)
    plain = guard_learned_relight(image, image, s_old, s_new, sky, light, **kwargs)
    coloured = guard_learned_relight(image, image, s_old, s_new, sky, light, lift_colour=lit_ab,
                                     **kwargs)
    sand, shade, material = ab(image, slice(30, 46)), slice(12, 20), slice(1, 6)
    assert np.hypot(*(ab(plain, shade) - sand)) > 10  # the shade's cast stays without it
    assert np.hypot(*(ab(coloured, shade) - sand)) < 3
    assert np.allclose(ab(coloured, material), ab(plain, material), atol=0.1)


def test_new_shade_takes_the_skys_colour_and_nothing_else_moves() -> None:
    """Where the new sun newly shadows a surface, the guarded relighting gives it the photo's
    colour turned by the clear-sky shade shift, at the relit brightness: bluer than the lit
    surface, whatever the relighting's own colour there (a neutral ``L`` gave the pool
    sample's white shelf brownish-violet new shade). Surfaces lit by both suns, the photo's
    own shade and the sky keep what the guards gave them before."""
    from outcast_core.runtime.geometry.colour import luminance
    from outcast_core.runtime.pipeline.photo_shadows import SKY_SHADE_SHIFT
    from outcast_core.runtime.pipeline.relight import guard_learned_relight, shade_weight

    h, w = 40, 60
    image = np.full((h, w, 3), [0.8, 0.7, 0.55], np.float32)  # warm sunlit paving
    image[:, :15] = [0.25, 0.24, 0.26]  # the photo's own shade
    sky = np.zeros((h, w), bool)
    sky[:6] = True
    image[sky] = [0.5, 0.7, 0.95]
    s_old = np.where(np.arange(w) < 15, 0.0, 0.9)[None].repeat(h, 0).astype(np.float32)
    s_new = s_old.copy()
    s_new[:, 40:] = 0.0  # the new sun's shadow on the right
    s_old[sky] = s_new[sky] = 0.0
    light = estimate_light(srgb_to_linear(image), s_old, sky)
    relit = image.copy()
    relit[:, 40:] = 0.3 * image[:, 40:]  # a relighting that darkens the new shade, no colour
    kwargs = dict(keep_sky=True, floor=False, anchor=False, detail=False)
    plain = guard_learned_relight(image, relit, s_old, s_new, sky, light, **kwargs)
    shaded = guard_learned_relight(image, relit, s_old, s_new, sky, light,
                                   shade_shift=SKY_SHADE_SHIFT, **kwargs)
    lin_p, lin_s = srgb_to_linear(plain), srgb_to_linear(shaded)
    new_shade = (slice(6, None), slice(44, None))
    log_br = lambda x: np.log(x[..., 2] / x[..., 0])[new_shade].mean()  # noqa: E731
    shift = SKY_SHADE_SHIFT[1] - SKY_SHADE_SHIFT[0]  # log B/R: 0.67
    photo = log_br(srgb_to_linear(image))
    assert abs(log_br(lin_p) - photo) < 0.2  # (0.3 x sRGB is not a pure change of intensity)
    assert log_br(lin_s) - photo == pytest.approx(shift, abs=0.01)
    np.testing.assert_allclose(luminance(lin_s)[new_shade], luminance(lin_p)[new_shade],
                               rtol=0.02)
    untouched = np.ones((h, w), bool)
    untouched[6:, 40:] = False
    np.testing.assert_allclose(shaded[untouched], plain[untouched], atol=1e-6)
    # The weight: full in new shade, none where both light it or the photo was in shade.
    weight = shade_weight(s_old, s_new)
    assert weight[20, 50] == 1.0 and weight[20, 30] == 0.0 and weight[20, 5] == 0.0
    # A soft new shadow's edge (S_n from 0.4 down to 0): the colour turns in step by step, with
    # no seam where the weight starts (a review: it once jumped to the photo's colour there).
    soft = s_old.copy()
    soft[:, 15:] = np.linspace(0.4, 0.0, w - 15, dtype=np.float32)
    violet = relit.copy()
    violet[:, 15:] = [0.3, 0.3, 0.45]  # a relighting's own tint in the new shade

    def steps(shift: tuple[float, float] | None) -> np.ndarray:  # log B/R along a row
        out = srgb_to_linear(guard_learned_relight(image, violet, s_old, soft, sky, light,
                                                   shade_shift=shift, **kwargs))
        return np.log(out[20, 15:, 2] / out[20, 15:, 0])

    turned = steps(SKY_SHADE_SHIFT)
    # The colour goes from the photo's to its shade's in small steps over the ramp (S_n 0.3
    # to 0.15) and never past them: until 2026-12-04 the two blends, one after the other,
    # gave a pixel half kept and half turned a quarter of L's violet (a step of 0.29 of the
    # turn, past the shade's own colour).
    turn = abs(turned[-1] - turned[0])
    assert np.abs(np.diff(turned)).max() <= 0.15 * turn
    assert turned.min() >= min(turned[0], turned[-1]) - 0.01 * turn
    assert turned.max() <= max(turned[0], turned[-1]) + 0.01 * turn
    assert turned[-1] == pytest.approx(photo + shift, abs=0.01)  # full shade: the shift


def test_the_sun_the_photo_showed_leaves_with_it() -> None:
    from outcast_core.runtime.pipeline.relight import remove_sun_glare

    h, w = 90, 120
    img = np.empty((h, w, 3), np.float32)
    img[:45] = (0.4, 0.55, 0.85)
    img[45:] = (0.5, 0.45, 0.4)
    sky = np.zeros((h, w), bool)
    sky[:45] = True
    yy, xx = np.mgrid[0:h, 0:w]
    r = np.hypot(xx + 0.5 - 60.0, yy + 0.5 - 20.0)
    glare = np.clip(np.where(r <= 5.0, 1.0, 0.9 - r / 40.0), 0.0, 1.0)[..., None]
    sunny = np.where(sky[..., None], img + (1.0 - img) * glare, img).astype(np.float32)
    out = remove_sun_glare(sunny, sky, 60.0, 20.0, 5.0)
    # The disc is the sky round it again (just outside the glare's reach, 4 core radii).
    assert np.abs(out[20, 60] - sunny[20, 60 + 23]).max() < 0.08
    assert np.abs(sunny[20, 60] - sunny[20, 60 + 23]).max() > 0.3
    assert np.array_equal(out[~sky], sunny[~sky])  # the ground is untouched
    assert np.array_equal(out[:, :10], sunny[:, :10])  # and so is the sky far from the sun
    moved = remove_sun_glare(sunny, sky, 60.0, 20.0, 5.0, to=(90.0, 25.0))
    assert moved[25, 90].min() > max(0.9, sunny[25, 90].min() + 0.2)
    assert moved[20, 60].min() < sunny[20, 60].min() - 0.2  # no longer white
    assert np.array_equal(moved[70:], sunny[70:])  # far from both suns, nothing changes
    pole = sky.copy()
    pole[15:35, 96:99] = False  # a pole in front of the new sun keeps its darkness
    in_front = remove_sun_glare(sunny, pole, 60.0, 20.0, 5.0, to=(90.0, 25.0))
    np.testing.assert_allclose(in_front[15:35, 96:99], sunny[15:35, 96:99], atol=1e-4)
    assert in_front[25, 90].min() > 0.9


def test_a_sun_brought_into_the_frame_is_drawn_on_the_sky_only() -> None:
    """``add_sun``: a clipped white core, glare in the sun's colour falling off beyond it, on
    the sky only (what stands in front of the sun keeps its darkness), faded by strength."""
    from outcast_core.runtime.pipeline.relight import SUN_CORE_DEG, add_sun

    h, w, focal = 90, 120, 100.0
    img = np.full((h, w, 3), 0.3, np.float32)
    sky = np.zeros((h, w), bool)
    sky[:45] = True
    sky[10:30, 58:62] = False  # a pole in front of the sun
    warm = np.array([1.0, 0.7, 0.4], np.float32)
    out = add_sun(img, sky, 40.0, 20.0, focal, warm)
    core = focal * math.tan(math.radians(SUN_CORE_DEG))
    assert out[20, 40].min() > 0.99  # the core clips white whatever the colour
    ring = out[20, 40 + int(core) + 3]  # the glare just beyond it: brighter, warm
    assert ring.mean() > 0.5 and ring[0] > ring[1] > ring[2]
    assert np.array_equal(out[~sky], img[~sky])  # the ground and the pole are untouched
    assert np.abs(out[5, 115] - img[5, 115]).max() < 0.02  # far from the sun, the sky stays
    assert np.array_equal(add_sun(img, sky, 40.0, 20.0, focal, strength=0.0), img)
    half = add_sun(img, sky, 40.0, 20.0, focal, strength=0.5)
    assert img[20, 40, 0] < half[20, 40, 0] < out[20, 40, 0]
    outside = add_sun(img, sky, -500.0, 20.0, focal)  # a sun far outside: nothing to draw
    assert np.array_equal(outside, img)


def test_the_old_suns_glare_leaves_no_halo_round_a_thin_bar_at_full_resolution() -> None:
    """A bar thinner than a working pixel against the photo's sun: the working size removes
    the glare but keeps the mixed pixels (no brighter than the sky round them), and their gain,
    upsampled, left the full-resolution sky beside the bar bright. ``glare_gone_full`` takes
    the excess off there too and keeps the bar dark."""
    from outcast_core.runtime.pipeline.relight import glare_gone_full, remove_sun_glare

    big, small = 400, 100
    yy, xx = np.mgrid[0:big, 0:big]
    glare = np.exp(-(np.hypot(xx - 200.0, yy - 150.0) / 40.0) ** 2)
    full = np.repeat((0.55 + 0.45 * glare)[..., None], 3, axis=-1).astype(np.float32)
    full[:, 229:232] = 0.08  # the bar: 3 px, under a working pixel
    work = cv2.resize(full, (small, small), interpolation=cv2.INTER_AREA)
    sky = np.ones((small, small), bool)
    sky[:, 57] = False  # the working column the bar darkens
    u, v, core = 50.0, 37.5, 4.0
    relit = remove_sun_glare(work, sky, u, v, core)
    out = transfer_to_full_resolution(full, work, relit)
    beside = np.s_[140:160, 233:236]  # sky just right of the bar, in the glare
    far = float(out[140:160, 300:330].mean())  # sky in the glare, away from the bar
    assert out[beside].mean() > far + 0.05  # the halo
    halo = float(out[beside].mean()) - far
    fixed = glare_gone_full(out.copy(), relit, sky, u, v, core)
    assert abs(float(fixed[beside].mean()) - far) < min(0.04, 0.5 * halo)
    assert fixed[140:160, 229:232].mean() < 0.2  # the bar keeps its darkness
    assert np.allclose(fixed[:, :150][360:], out[:, :150][360:])  # far from the sun: as it was
    as_u8 = glare_gone_full(np.rint(out * 255).astype(np.uint8), relit, sky, u, v, core)
    assert as_u8.dtype == np.uint8 and abs(as_u8[beside].mean() / 255 - far) < 0.04


def test_restore_detail_makes_the_photos_bands_once_per_cache() -> None:
    """The photo's (and the lifted photo's) bands do not depend on the sun: made once in the
    caller's cache, the same result for every sun; another size or no lifted photo remakes
    them."""
    from outcast_core.runtime.pipeline.relight import restore_detail

    photo, lifted = _textured(seed=7), _textured(seed=8)
    h, w = photo.shape[:2]
    sky = np.zeros((h, w), bool)
    s_o = np.full((h, w), 0.8, np.float32)
    cache: dict = {}
    made = []
    for k, s_n in enumerate((np.full((h, w), 0.8, np.float32), np.zeros((h, w), np.float32))):
        relit = cv2.GaussianBlur(photo, (0, 0), 1.0 + k)
        np.testing.assert_array_equal(
            restore_detail(photo, relit, s_o, s_n, sky, lifted, cache=cache),
            restore_detail(photo, relit, s_o, s_n, sky, lifted))
        made.append(cache["bands"])
    first = made[0]
    assert made[1] is first  # made once, for the first sun
    restore_detail(photo, photo, s_o, s_o, sky, None, cache=cache)
    assert cache["bands"] is not first and cache["bands"][2] is None


def test_meter_exposure_brings_the_frame_to_the_photos_level_and_keeps_the_pattern() -> None:
    """A scene the new sun leaves in shade is metered up as a camera would: one gain for the
    whole frame, so the light's pattern (a new shadow against lit ground, the sky) is kept."""
    from outcast_core.runtime.geometry.colour import linear_to_srgb, luminance, srgb_to_linear
    from outcast_core.runtime.pipeline.relight import METER_RANGE, meter_exposure

    rng = np.random.default_rng(3)
    lin = (0.2 + 0.1 * rng.random((40, 60, 3))).astype(np.float32)
    lin[:8] = 0.5  # a sky
    photo = linear_to_srgb(lin)
    relit_lin = lin * 0.2  # the whole frame put in shade ...
    relit_lin[20:, 30:] *= 0.5  # ... with a new shadow in it
    out = srgb_to_linear(meter_exposure(photo, linear_to_srgb(relit_lin)))
    assert np.mean(luminance(out)) == pytest.approx(np.mean(luminance(lin)), rel=1e-3)
    ratio = luminance(out) / luminance(relit_lin)
    assert np.ptp(ratio) < 1e-3 * ratio.mean()  # one gain: the pattern is kept
    # The gain is bounded: a black relighting is not blown up into noise.
    dark = srgb_to_linear(meter_exposure(photo, linear_to_srgb(lin * 1e-4)))
    assert np.mean(luminance(dark)) == pytest.approx(
        np.mean(luminance(lin)) * 1e-4 * METER_RANGE[1], rel=0.05)
    assert np.allclose(meter_exposure(photo, photo), photo, atol=1e-5)


def test_metered_up_highlights_roll_off_instead_of_clipping() -> None:
    from outcast_core.runtime.geometry.colour import linear_to_srgb, srgb_to_linear
    from outcast_core.runtime.pipeline.relight import METER_KNEE, meter_exposure

    lin = np.full((20, 30, 3), 0.1, np.float32)
    lin[:5] = np.linspace(0.5, 0.9, 30, dtype=np.float32)[None, :, None]  # a bright sky
    photo = linear_to_srgb(lin)
    relit = lin.copy()
    relit[5:] *= 0.2  # the ground put in shade: metered up about 2.5x
    out = srgb_to_linear(meter_exposure(photo, linear_to_srgb(relit)))
    sky = out[:5, :, 0]
    assert sky.max() < 0.999 and np.all(np.diff(sky[0]) > 0)  # kept apart, not clipped
    assert np.all(out[5:] < METER_KNEE)  # below the knee: the plain gain
    # At a gain of 1 nothing changes (the shoulder fades in with the gain).
    assert np.allclose(meter_exposure(photo, photo), photo, atol=1e-5)


def test_a_lit_surface_at_the_floor_keeps_its_colour_whole() -> None:
    """``S_o`` of a surface the photo shows lit is at least ``LIT_FLOOR`` (0.3, the pool
    sample's water, whose normals face away from the sun); the colour guards took 0.3 for half
    lit, so half its colour was ``L``'s, and at a grazing sun the lit water met its new shade
    in a blue-magenta arc (a user trial). Lit at the floor, the photo's colour is kept whole;
    at the overlay's threshold (0.15, the photo's found shadows) not at all."""
    from outcast_core.runtime.geometry.colour import linear_to_lab
    from outcast_core.runtime.pipeline.photo_shadows import LIT_FLOOR
    from outcast_core.runtime.pipeline.relight import (
        SHADE_LEVEL,
        guard_learned_relight,
        shade_weight,
    )

    h, w = 24, 32
    image = np.full((h, w, 3), [0.2, 0.75, 0.7], np.float32)  # cyan water
    sky = np.zeros((h, w), bool)
    s_old = np.full((h, w), LIT_FLOOR, np.float32)
    s_old[:, 16:] = SHADE_LEVEL
    s_new = np.full((h, w), 0.9, np.float32)
    light = estimate_light(srgb_to_linear(image), np.full((h, w), 0.9, np.float32), sky)
    relit = np.full((h, w, 3), [0.45, 0.7, 0.9], np.float32)  # L's own, bluer
    out = guard_learned_relight(image, relit, s_old, s_new, sky, light, keep_sky=True,
                                floor=False, anchor=False, detail=False)
    ab = lambda x: linear_to_lab(srgb_to_linear(x))[..., 1:]  # noqa: E731
    np.testing.assert_allclose(ab(out)[:, :16], ab(image)[:, :16], atol=0.5)
    np.testing.assert_allclose(ab(out)[:, 16:], ab(relit)[:, 16:], atol=0.5)
    # The new shade's weight and the colour guard's meet with no gap between them.
    from outcast_core.runtime.pipeline.relight import _both_lit

    # (The old ramps left up to half of it to L's colour; until 2026-12-04 the weight's
    # "fell" term still left a quarter where the photo's surface sat at the floor.)
    s_n = np.linspace(0.4, 0.0, 41, dtype=np.float32)[None]
    for lit_old in (1.0, 0.5, LIT_FLOOR):
        s_o = np.full_like(s_n, lit_old)
        np.testing.assert_allclose(_both_lit(s_o, s_n) + shade_weight(s_o, s_n), 1.0,
                                   atol=1e-6)


def test_a_penumbra_newly_shadowed_takes_its_share_of_the_shade_colour() -> None:
    """A pixel in the photo's own penumbra (``S_o`` 0.25: two thirds lit on the colour guard's
    scale) that the new sun puts in full shade takes two thirds of the shade's colour and keeps
    a third of the relighting's own (in linear light, at the relit luminance): the turn's share
    is the weight over what the colour guard does not keep, not all or nothing."""
    from outcast_core.runtime.geometry.colour import luminance
    from outcast_core.runtime.pipeline.photo_shadows import SKY_SHADE_SHIFT
    from outcast_core.runtime.pipeline.relight import guard_learned_relight, shade_weight

    h, w = 8, 8
    image = np.full((h, w, 3), [0.8, 0.7, 0.55], np.float32)
    sky = np.zeros((h, w), bool)
    s_old = np.full((h, w), 0.25, np.float32)
    s_new = np.zeros((h, w), np.float32)
    assert shade_weight(s_old, s_new)[0, 0] == pytest.approx(2.0 / 3.0, abs=1e-6)
    light = estimate_light(srgb_to_linear(image), np.full((h, w), 0.9, np.float32), sky)
    relit = np.full((h, w, 3), [0.3, 0.3, 0.45], np.float32)  # the relighting's own violet
    out = guard_learned_relight(image, relit, s_old, s_new, sky, light, keep_sky=True,
                                floor=False, anchor=False, detail=False,
                                shade_shift=SKY_SHADE_SHIFT)
    lin_r = srgb_to_linear(relit)[0, 0]
    turned = srgb_to_linear(image)[0, 0] * np.exp(
        np.array([SKY_SHADE_SHIFT[0], 0.0, SKY_SHADE_SHIFT[1]], np.float32))
    turned *= luminance(lin_r) / luminance(turned)
    expected = 2.0 / 3.0 * turned + 1.0 / 3.0 * lin_r
    np.testing.assert_allclose(srgb_to_linear(out)[0, 0], expected, rtol=1e-3, atol=1e-4)


def test_a_new_sun_lights_normals_the_photo_contradicts_no_more_than_their_surroundings(
        ) -> None:
    """The pool sample's glowing oval at a low sun: ``Z`` made the water by the swimmer a hump
    turned away from the photo's sun, which the photo shows lit like the water round it. Such
    pixels take at most the new shadow image of the trusted lit surface round them; a new
    shadow on them stays, the trusted surface and the photo's own shade are untouched, and
    with nothing trusted round them nothing is capped."""
    from outcast_core.runtime.pipeline.relight import NormalTrust

    h, w = 64, 64
    normals = np.zeros((h, w, 3), np.float32)
    normals[..., 1] = -1.0  # level ground (camera y points down)
    hump = np.zeros((h, w), bool)
    hump[24:40, 24:40] = True
    normals[hump] = (0.0, 0.3, -0.95)  # turned to the camera, away from an overhead sun
    sun = np.array([0.0, -1.0, 0.0], np.float32)
    sky = np.zeros((h, w), bool)
    sky[:, -4:] = True  # (sky beside it: neither lit, contradicted nor trusted)
    normals[sky] = 0.0
    s_o = np.full((h, w), 0.95, np.float32)  # the photo shows it all lit...
    s_o[:, :6] = 0.02  # ...but a strip of its own shade
    shade_hump = np.zeros((h, w), bool)
    shade_hump[2:5, 2:5] = True
    normals[shade_hump] = (0.0, 0.3, -0.95)
    grazed = np.zeros((h, w), bool)
    grazed[50:54, 50:54] = True
    normals[grazed] = (0.0, -0.3, -0.95)  # grazed by the photo's sun, not turned away
    s_o[grazed] = 0.3
    trust = NormalTrust(s_o, normals, sun, sky)
    assert trust.contradicted[hump].all() and not trust.contradicted[shade_hump].any()
    assert trust.contradicted.sum() == hump.sum() and not trust.contradicted[grazed].any()
    s_n = np.full((h, w), 0.2, np.float32)  # a low new sun: level ground at 0.2...
    s_n[:32] = 0.3  # ...0.3 on the far half
    s_n[hump] = 0.9  # the hump faces it
    s_n[30:34, 30:34] = 0.02  # a new shadow falling on the hump
    s_n[shade_hump] = 0.9
    s_n[sky] = 0.0
    capped = trust.cap(s_n)
    assert np.allclose(capped[25, 31], 0.3, atol=0.02) and np.allclose(capped[38, 31], 0.2,
                                                                        atol=0.02)
    assert np.allclose(capped[30:34, 30:34], 0.02)
    assert np.array_equal(capped[~hump], s_n[~hump])
    # A photo's sun low over level ground (2 degrees: a cosine of 0.035) does not make the
    # lit level ground contradicted.
    dusk = np.array([0.0, -0.035, 0.999], np.float32)
    level = NormalTrust(np.full((h, w), 0.3, np.float32), normals, dusk, sky)
    assert not level.contradicted[~hump & ~shade_hump & ~grazed].any()
    # No trusted lit surface round it: left as it is.
    alone = NormalTrust(s_o, np.broadcast_to(np.array([0.0, 0.3, -0.95], np.float32),
                                             (h, w, 3)), sun, sky)
    assert alone.contradicted[:, 6:-4].all()
    assert np.array_equal(alone.cap(s_n), s_n)
    with pytest.raises(ValueError, match="shape"):
        trust.cap(s_n[:10])
