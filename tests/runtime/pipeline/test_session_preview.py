"""Step 2's drag preview: only what the new sun changes runs per sun, at the preview size; the
light-independent inputs are prepared once per photo, original sun and preset."""

from __future__ import annotations

import math
from collections import Counter

import numpy as np
import pytest

from outcast_core.runtime.pipeline import session as session_module
from outcast_core.runtime.pipeline.session import PRESETS, RelightSession, working_shape
from tests.runtime.scenes import box_scene_depth

SUNS = [(math.cos(a) * 0.5, -0.55, -0.67) for a in np.linspace(0.2, 2.5, 5)]
W_O = (0.3, -0.8, -0.5)


@pytest.fixture
def scene() -> tuple[np.ndarray, np.ndarray]:
    h, w = 150, 200
    depth = box_scene_depth(h, w, w / (2 * math.tan(math.radians(15))), 60.0,
                            [(-4.0, 0.0, -3.0, 1.0, 4.0), (2.0, 5.0, 1.0, 4.0, 2.0)])
    rng = np.random.default_rng(1)
    image = np.clip(0.5 + 0.1 * rng.standard_normal((h, w, 3)), 0, 1).astype(np.float32)
    return image, depth


def _count_runs(session: RelightSession, monkeypatch) -> tuple[Counter, dict]:
    """Count model runs by name and remember each model's last input size."""
    runs: Counter = Counter()
    sizes: dict = {}
    real_load = session.registry.load

    def load(name, **kwargs):
        model = real_load(name, **kwargs)

        class Counted:
            def __getattr__(self, attr):
                return getattr(model, attr)

            def run(self, feeds):
                runs[name] += 1
                sizes[name] = next(v.shape[2:] for v in feeds.values() if v.ndim == 4)
                return model.run(feeds)

        return Counted()

    monkeypatch.setattr(session.registry, "load", load)
    return runs, sizes


def test_learned_drag_runs_only_the_sun_dependent_networks_at_preview_size(
    scene, monkeypatch
) -> None:
    image, depth = scene
    s = RelightSession(preset="balanced", mode="learned")
    s.set_image(image, depth=depth)
    s.set_original_sun(W_O)
    normals_calls = Counter()
    real_normals = session_module.normals_from_depth

    def counted_normals(*a, **k):
        normals_calls["n"] += 1
        return real_normals(*a, **k)

    monkeypatch.setattr(session_module, "normals_from_depth", counted_normals)
    runs, sizes = _count_runs(s, monkeypatch)
    frames = [s.relight(w, preview=True) for w in SUNS]
    assert runs == Counter({"shadow": len(SUNS), "relight": len(SUNS)})  # nothing else per sun
    assert s.relight_preview_builds == 1 and normals_calls["n"] == 1
    small = working_shape(*s.image_srgb.shape[:2], PRESETS["balanced"].relight_preview_size)
    assert sizes["relight"] == small and sizes["shadow"] == small
    for f in frames:
        assert f.shape == s.image_srgb.shape and f.dtype == np.float32
        assert f.min() >= 0.0 and f.max() <= 1.0
    # Moving back to a sun already seen costs nothing.
    s.relight(SUNS[0], preview=True)
    assert runs["relight"] == len(SUNS)


def test_preview_cached_equals_uncached_and_is_rebuilt_when_the_inputs_change(scene) -> None:
    image, depth = scene
    s = RelightSession(preset="fast", mode="learned")
    s.set_image(image, depth=depth)
    s.set_original_sun(W_O)
    for w in SUNS[1:]:
        s.relight(w, preview=True)
    late = s.relight(SUNS[0], preview=True)
    fresh = RelightSession(preset="fast", mode="learned")
    fresh.set_image(image, depth=depth)
    fresh.set_original_sun(W_O)
    np.testing.assert_array_equal(late, fresh.relight(SUNS[0], preview=True))
    assert s.relight_preview_builds == 1
    s.set_original_sun((-0.3, -0.8, -0.5))  # S_o changes: the prepared inputs too
    s.relight(SUNS[0], preview=True)
    assert s.relight_preview_builds == 2
    s.set_preset("fast")  # same working size: caches cleared, inputs prepared again
    s.relight(SUNS[0], preview=True)
    assert s.relight_preview_builds == 3


def test_preview_follows_the_full_pass(scene) -> None:
    """At the preview's own resolution the drag preview is the full pass's picture, and nearer
    to it than to the next sun's. (Compared at full size, physics relighting of this all-noise
    photo differs by about 0.03: the photo's shadow stage calls its dark noise pixels shade and
    the full pass lifts them one by one, which a preview at a third of the size cannot.)"""
    import cv2

    image, depth = scene
    for mode in ("learned", "classic"):
        s = RelightSession(preset="balanced", mode=mode)
        s.set_image(image, depth=depth)
        s.set_original_sun(W_O)
        h, w_ = s.image_srgb.shape[:2]
        k = s.preset.relight_preview_size / max(h, w_)
        size = (round(w_ * k), round(h * k))

        def small(a: np.ndarray, size=size) -> np.ndarray:
            return cv2.resize(a, size, interpolation=cv2.INTER_AREA)

        for w, other in zip(SUNS[:2], SUNS[1:3], strict=True):
            prev = small(s.relight(w, preview=True))
            err = np.abs(small(s.relight(w)) - prev).mean()
            assert err < 0.03, mode
            assert err < np.abs(small(s.relight(other)) - prev).mean(), mode


def test_prepare_relight_preview_builds_before_the_first_drag(scene) -> None:
    image, depth = scene
    s = RelightSession(preset="fast", mode="learned")
    s.set_image(image, depth=depth)
    with pytest.raises(RuntimeError, match="set_original_sun"):
        s.prepare_relight_preview()
    s.set_original_sun(W_O)
    s.prepare_relight_preview()
    assert s.relight_preview_builds == 1
    s.relight(SUNS[0], preview=True)
    assert s.relight_preview_builds == 1



def test_lift_runs_at_working_and_preview_sizes_and_only_brightens(scene) -> None:
    image, depth = scene
    s = RelightSession(preset="balanced", mode="learned")
    assert s.lift_new_light  # the app's default
    s.lift_new_light = False
    s.set_image(image, depth=depth)
    s_o = s.shadow(W_O)
    photo = (image * (0.3 + 0.7 * (s_o[..., None] > 0.2))).astype(np.float32)
    s.set_image(photo, depth=depth)
    s.set_original_sun(W_O)
    off = s.relight(SUNS[0])
    off_preview = s.relight(SUNS[0], preview=True)
    s.lift_new_light = True
    s._relight_cache.clear()
    s._relight_preview = None
    on = s.relight(SUNS[0])
    on_preview = s.relight(SUNS[0], preview=True)
    assert on.shape == off.shape and on_preview.shape == off_preview.shape
    # The lift only raises luminance (never darkens), and it acts somewhere; where it acts the
    # surface takes its lit surroundings' colour, which may move single channels either way,
    # and then the new daylight's colour (a per-channel gain of luminance 1, which moves a
    # coloured pixel's luminance a little: one pixel 0.4 % since the anchor runs before the
    # floor).
    from outcast_core.runtime.geometry.colour import luminance, srgb_to_linear

    y_on, y_off = luminance(srgb_to_linear(on)), luminance(srgb_to_linear(off))
    assert (y_on >= y_off * (1 - 5e-3) - 1e-4).all()
    assert (y_on > y_off * 1.1 + 0.01).any()
    # "Confirm sun" makes the drag preview's lift inputs, so the first drag frame does not,
    # and they are kept for the next sun.
    s.set_original_sun(W_O)
    s.prepare_relight_preview()
    h, w = s._relight_preview_state()["shadow_old"].shape
    assert ("base", (h, w)) in s._lift_guards and (h, w) in s._lift_guards
    keys = set(s._lift_guards)
    s.relight(SUNS[1], preview=True)
    assert set(s._lift_guards) == keys


def _turned(w: tuple[float, float, float], deg: float) -> np.ndarray:
    """``w`` (made unit) turned by ``deg`` degrees, away from the camera's x axis."""
    u = np.asarray(w, float) / np.linalg.norm(w)
    p = np.cross(u, (1.0, 0.0, 0.0))
    p /= np.linalg.norm(p)
    return math.cos(math.radians(deg)) * u + math.sin(math.radians(deg)) * p


@pytest.mark.parametrize("mode", ["learned", "classic"])
def test_relit_to_its_own_sun_the_photo_comes_back(scene, mode) -> None:
    """The new sun starts at the original one (and a time-lapse passes through it): the relit
    photo is then the photo, at every size, and it leaves it smoothly as the sun moves away."""
    image, depth = scene
    s = RelightSession(preset="balanced", mode=mode)
    s.set_image(image, depth=depth)
    s.set_original_sun(W_O)
    assert np.array_equal(s.relight(W_O), s.image_srgb)
    assert np.abs(s.relight(W_O, preview=True) - s.image_srgb).max() <= 1.0 / 255 + 1e-6
    assert np.abs(s.relight_full(W_O) - image).max() < 1e-5
    far = s.relight(_turned(W_O, 90.0))
    changes = [np.abs(s.relight(_turned(W_O, d)) - s.image_srgb).mean() for d in (0, 4, 8, 16)]
    assert changes[0] == 0.0 and np.all(np.diff(changes) >= -1e-6)
    assert np.abs(far - s.image_srgb).mean() > changes[1]


def test_the_original_share_fades_out_at_the_fade_angle() -> None:
    """Past ``ORIGINAL_FADE_DEG`` nothing of the photo's own state is mixed in."""
    from outcast_core.runtime.pipeline.relight import ORIGINAL_FADE_DEG, original_share

    assert original_share(np.array(W_O), _turned(W_O, ORIGINAL_FADE_DEG + 1.0)) == 0.0
    assert 0.0 < original_share(np.array(W_O), _turned(W_O, ORIGINAL_FADE_DEG / 2)) < 1.0


@pytest.mark.parametrize("mode", ["classic", "learned"])
def test_metered_exposure_in_every_relighting_cached_per_exposure(scene, mode) -> None:
    from outcast_core.runtime.geometry.colour import luminance, srgb_to_linear

    image, depth = scene
    s = RelightSession(preset="fast", mode=mode)
    s.set_image(image, depth=depth)
    s.set_original_sun(W_O)
    w = SUNS[2]
    fixed = s.relight(w)
    assert s.exposure == "photo"
    with pytest.raises(ValueError, match="exposure"):
        s.exposure = "auto"
    s.exposure = "metered"
    metered = s.relight(w)
    assert metered is not fixed  # the cached fixed-exposure image is not returned

    def level(img: np.ndarray) -> float:
        return float(np.mean(np.minimum(luminance(srgb_to_linear(img)), 1.0)))

    assert level(metered) == pytest.approx(level(s.image_srgb), rel=0.02)
    stream = list(s.relight_stream([w]))[0]
    assert np.allclose(stream, metered, atol=2e-3)
    preview = s.relight(w, preview=True)
    assert level(preview) == pytest.approx(level(s.image_srgb), rel=0.05)
    full = s.relight_full(w)
    assert full.shape == metered.shape and np.allclose(full, metered, atol=2e-3)
    s.exposure = "photo"
    assert np.allclose(s.relight(w), fixed)


def test_the_normals_trust_caps_the_full_pass_and_the_preview_alike(scene, monkeypatch) -> None:
    """Both the working-size relighting and the drag preview take the new shadow image as the
    photo's contradiction of the normals caps it (:class:`~outcast_core.runtime.pipeline.
    relight.NormalTrust`; here a cap that blacks it all out, to see that its result is used),
    the working size's made once per found shadow and made again for a new one; off, neither
    takes it."""
    from outcast_core.runtime.pipeline.relight import NormalTrust

    image, depth = scene

    def relit(trust: bool, blackout: bool) -> tuple[np.ndarray, np.ndarray, RelightSession]:
        with monkeypatch.context() as m:
            if blackout:
                m.setattr(NormalTrust, "cap", lambda self, s_new: np.zeros_like(s_new))
            s = RelightSession(preset="balanced", mode="classic")
            s.trust_normals = trust
            s.set_image(image, depth=depth)
            s.set_original_sun(W_O)
            return s.relight(SUNS[0]), s.relight(SUNS[1], preview=True), s

    work, prev, s = relit(True, False)
    black_work, black_prev, _ = relit(True, True)
    assert np.abs(black_work - work).max() > 0.05 and np.abs(black_prev - prev).max() > 0.05
    off_work, off_prev, off = relit(False, False)
    off_black_work, off_black_prev, _ = relit(False, True)
    assert np.array_equal(off_black_work, off_work) and np.array_equal(off_black_prev, off_prev)
    assert off._normal_trust() is None
    trust = s._normal_trust()
    s.relight(SUNS[2])
    assert s._normal_trust() is trust  # (made once for this found shadow)
    s.set_original_sun(SUNS[3])
    assert s._normal_trust() is not trust


def test_the_new_shadow_view_shows_the_shadow_the_relighting_uses(scene, monkeypatch) -> None:
    """The "New shadow" view (:meth:`RelightSession.buffers`) and :meth:`RelightSession.
    relit_shadow` give the new shadow the relighting takes: the photo's found shadows at its
    own sun, the geometry's far from it, and the normals' cap applied (a cap that blacks it all
    out here, to see it used); the plain :meth:`RelightSession.shadow` stays the geometry's."""
    from outcast_core.runtime.pipeline.relight import NormalTrust

    image, depth = scene
    s = RelightSession(preset="fast", mode="classic")
    s.set_image(image, depth=depth)
    with pytest.raises(RuntimeError, match="set_original_sun"):
        s.relit_shadow(SUNS[0])
    s.set_original_sun(W_O)
    assert np.allclose(s.relit_shadow(W_O), s.original_shadow, atol=1e-6)
    far = SUNS[4]
    assert np.array_equal(s.relit_shadow(far), s._normal_trust().cap(s.shadow(far)))
    with monkeypatch.context() as m:
        m.setattr(NormalTrust, "cap", lambda self, s_new: np.zeros_like(s_new))
        s.set_original_sun(W_O)  # (found again: a trust made with the patched cap)
        assert s.relit_shadow(far).max() == 0.0 and s.shadow(far).max() > 0.5
        assert s.buffers(far)["new_shadow"].max() == 0.0
