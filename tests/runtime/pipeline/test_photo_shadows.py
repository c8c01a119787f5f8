"""The photo's own shadows: found (with the geometry as the prior), turned into S_o, lifted."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from outcast_core.runtime.cli.main import main
from outcast_core.runtime.geometry.colour import linear_to_srgb
from outcast_core.runtime.io.imageio import read_image, read_shadow_png, write_depth, write_image
from outcast_core.runtime.pipeline import photo_shadows as ps
from outcast_core.runtime.pipeline.photo_shadows import (
    LIT_FLOOR,
    deshadow,
    original_shadow_from_photo,
    photo_shadow_probability,
)
from outcast_core.runtime.pipeline.session import RelightSession
from tests.runtime.scenes import box_scene_depth

H, W = 64, 96
SHADE = np.array([0.45, 0.5, 0.6], np.float32)  # darker and bluer, as sky-lit shade is


def _ground(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    base = np.array([0.75, 0.65, 0.5], np.float32)  # warm sunlit gravel
    return np.clip(base * (1 + 0.05 * rng.standard_normal((H, W, 1))), 0, 1).astype(np.float32)


def _shadowed(box=(30, 50, 20, 60)) -> tuple[np.ndarray, np.ndarray]:
    img = _ground()
    mask = np.zeros((H, W), bool)
    r0, r1, c0, c1 = box
    mask[r0:r1, c0:c1] = True
    img[mask] *= SHADE
    return img, mask


def test_probability_finds_the_shadow_and_never_the_sky() -> None:
    img, mask = _shadowed()
    sky = np.zeros((H, W), bool)
    sky[:8] = True
    img[:8] = [0.2, 0.3, 0.6]  # a dark blue sky would pass a luminance threshold
    p = photo_shadow_probability(img, sky)
    assert p[mask].mean() > 0.9
    assert p[~mask & ~sky].mean() < 0.05
    assert np.all(p[sky] == 0)


def test_prior_gates_dark_regions_far_from_any_predicted_shadow() -> None:
    img, mask = _shadowed(box=(40, 60, 5, 25))
    prior = np.ones((H, W), np.float32)  # S predicts no shadow here...
    prior[40:60, 70:90] = 0.0  # ...only far to the right
    p = photo_shadow_probability(img, np.zeros((H, W), bool), prior)
    assert p[mask].mean() < 0.1
    prior[40:60, 20:40] = 0.0  # a predicted shadow overlapping it: it is kept
    p = photo_shadow_probability(img, np.zeros((H, W), bool), prior)
    assert p[mask].mean() > 0.7
    with pytest.raises(ValueError, match="prior"):
        photo_shadow_probability(img, np.zeros((H, W), bool), prior[1:])


def test_original_shadow_is_dark_in_shadow_and_lit_elsewhere() -> None:
    img, mask = _shadowed()
    sky = np.zeros((H, W), bool)
    p = photo_shadow_probability(img, sky)
    cos = np.full((H, W), 0.05, np.float32)  # rough normals call the ground "facing away"
    s_o = original_shadow_from_photo(p, cos, sky)
    inner = np.zeros_like(mask)
    inner[32:48, 22:58] = True  # the soft edge follows the photo's: look inside it
    assert np.all(s_o[inner] < 0.15)
    assert np.all(s_o[~mask] >= LIT_FLOOR - 1e-6)  # the photo says lit: not an attached shadow


@pytest.mark.parametrize("cos", [0.0, 0.3, 0.7, 1.0])
def test_original_shadow_marks_exactly_the_found_shadows_whatever_the_cosine(cos: float) -> None:
    p = np.linspace(0.0, 1.0, 1001, dtype=np.float32)[None]
    s_o = original_shadow_from_photo(p, np.full_like(p, cos), np.zeros(p.shape, bool))
    assert np.all(s_o[p > 0.5] < 0.15)  # every found shadow, also on a surface facing the sun
    assert np.all(s_o[p < 0.45] >= 0.15)  # and nothing the photo calls clearly lit
    assert np.all(np.diff(s_o[0]) <= 1e-7)  # darker with more evidence of shadow
    assert s_o[0, 0] == pytest.approx(max(cos, LIT_FLOOR))


def test_deshadow_lifts_the_shadow_and_keeps_the_lit_surface() -> None:
    img, mask = _shadowed()
    sky = np.zeros((H, W), bool)
    out = deshadow(img, photo_shadow_probability(img, sky), sky)
    free = _ground()
    inner = np.zeros_like(mask)
    inner[33:47, 23:57] = True
    err_before = np.abs(img[inner] - free[inner]).mean()
    err_after = np.abs(out[inner] - free[inner]).mean()
    assert err_after < 0.2 * err_before
    # The shade's blue cast goes with it: the lifted colour matches the lit ground's balance.
    lifted = out[inner].mean(axis=0)
    lit = free[~mask].mean(axis=0)
    np.testing.assert_allclose(lifted / lifted.sum(), lit / lit.sum(), atol=0.02)
    far = np.zeros_like(mask)
    far[:, :8] = True
    assert np.abs(out[far] - img[far]).max() < 0.01


def test_a_lifted_shadow_beside_cyan_water_is_not_turned_teal() -> None:
    """Grey paving half in shade beside a sunlit cyan pool: the lit surroundings are mostly
    water, whose colour the local lit/shade ratio takes for the lift's (teal paving, a user
    trial). The lift may warm the paving, never cool or green it."""
    img = np.full((H, W, 3), 0.55, np.float32)  # grey paving in the sun
    img[:, W // 2:] = [0.1, 0.6, 0.7]  # the pool
    shade = np.zeros((H, W), bool)
    shade[8:56, 6:W // 2] = True
    img[shade] = 0.55 * np.array([0.3, 0.32, 0.36], np.float32)  # its shade: bluish
    p = shade.astype(np.float32)
    sky = np.zeros((H, W), bool)
    out = deshadow(img, p, sky, marked=shade)  # the user marked it ("Mark shadow")
    lifted = out[20:44, 14:26].mean(axis=(0, 1))
    assert lifted.mean() > 2.0 * img[20:44, 14:26].mean()  # it is lifted
    before = img[30, 20]
    assert lifted[0] / lifted[1] >= 0.99 * before[0] / before[1]  # no less red
    assert lifted[2] / lifted[1] <= 1.01 * before[2] / before[1]  # no more blue
    assert np.allclose(ps.warm_lift(np.array([0.2, 0.5, 0.9])), 0.5)


def test_a_bright_fleck_inside_a_shadow_is_not_lifted_into_glare() -> None:
    """A sun fleck a "Mark shadow" fill took in: lifted by the shade's ratio it would clip to
    white; it ends no brighter than the lit surface around it plus LIFT_ABOVE_LIT."""
    from outcast_core.runtime.geometry.colour import luminance, srgb_to_linear

    img, mask = _shadowed()
    img *= 0.6  # a duller day: nothing clips
    fleck = np.zeros((H, W), bool)
    fleck[38:42, 36:44] = True
    img[fleck] = _ground()[fleck] * 0.6  # as bright as the lit gravel
    sky = np.zeros((H, W), bool)

    def fleck_over_lit(**bound) -> float:  # the fleck's linear luminance over the lit gravel's
        out = luminance(srgb_to_linear(deshadow(img, mask.astype(np.float32), sky, **bound)))
        return float(out[fleck].mean() / out[~mask].mean())

    assert fleck_over_lit() <= np.exp(ps.LIFT_ABOVE_LIT) * 1.05
    assert fleck_over_lit(above_lit=None) > 2.5  # unbounded: lifted far past the lit gravel


def test_deshadow_leaves_a_dark_material_alone() -> None:
    """A dark blue object beside warm gravel is not a shadow the sun can lift."""
    img = _ground()
    obj = np.zeros((H, W), bool)
    obj[20:44, 30:60] = True
    img[obj] = [0.05, 0.08, 0.3]
    sky = np.zeros((H, W), bool)
    out = deshadow(img, photo_shadow_probability(img, sky), sky)
    assert np.abs(out[obj] - img[obj]).mean() < 0.05


def _session_inputs(tmp_path: Path) -> tuple[np.ndarray, np.ndarray]:
    focal = W / (2 * math.tan(math.radians(30)))
    depth = box_scene_depth(H, W, focal, 60.0, [(-4.0, 0.0, -3.0, 1.0, 4.0)])
    img, _ = _shadowed()
    return img, depth


def test_session_refines_from_the_photo_and_deshadows(tmp_path: Path) -> None:
    img, depth = _session_inputs(tmp_path)
    s = RelightSession(mode="classic", preset="fast")
    s.set_image(img, depth=depth)
    with pytest.raises(RuntimeError, match="set_original_sun"):
        s.deshadow()
    assert s.refinement == "photo"
    s_o = s.set_original_sun((0.5, -0.6, 0.6))
    assert s.shadow_probability is not None and s.shadow_probability.shape == s_o.shape
    full = s.deshadow_full()
    assert full.shape == img.shape
    assert full[35:45, 25:55].mean() > 1.5 * img[35:45, 25:55].mean()
    assert s.deshadow() is s.deshadow()  # computed once per original sun
    learned = RelightSession(mode="classic", preset="fast", refine="learned")
    assert learned.refinement == "guided filter"
    with pytest.raises(ValueError, match="refine"):
        RelightSession(refine="magic")


def test_the_lift_probability_is_made_once_per_size(tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """What the app shows as the found shadows and what the de-shadow lifts are one
    computation: at the working size and at the full-size de-shadow's, each is made once for
    both (they were made twice), and the de-shadow is the same as with its own."""
    img, depth = _session_inputs(tmp_path)
    big = cv2.resize(img, (4 * W, 4 * H), interpolation=cv2.INTER_LINEAR)
    big_depth = cv2.resize(depth, (4 * W, 4 * H), interpolation=cv2.INTER_NEAREST)
    s = RelightSession(mode="classic", preset="fast")
    s.set_image(big, depth=big_depth)
    s.set_original_sun((0.5, -0.6, 0.6))
    made: list[tuple[int, int]] = []
    real = ps.lift_probability

    def counted(image, *args, **kwargs):
        made.append(np.asarray(image).shape[:2])
        return real(image, *args, **kwargs)

    monkeypatch.setattr(ps, "lift_probability", counted)
    monkeypatch.setattr("outcast_core.runtime.pipeline.session.lift_probability", counted)
    shown, out = s.lifted_shadows(), s.deshadow()
    mask, full = s.lifted_shadows_full(), s.deshadow_full()
    detail = s.found_shadows_detail()["image"].shape[:2]
    assert detail != s.image_srgb.shape[:2]  # the full-size de-shadow is found apart
    assert sorted(made) == sorted([s.image_srgb.shape[:2], detail])
    monkeypatch.setattr(ps, "lift_probability", real)
    found = ps.found_shade_marks(s.image_srgb, s.shadow_probability, s.sky)
    marks = found.astype(np.float32) if found.any() else None
    np.testing.assert_array_equal(out, deshadow(s.image_srgb, s.shadow_probability, s.sky,
                                                marked=marks))
    assert shown.shape == out.shape[:2] and mask.shape == full.shape[:2] == big.shape[:2]
    with pytest.raises(ValueError, match="lift probability"):
        deshadow(s.image_srgb, s.shadow_probability, s.sky, lifted=mask)

    # Found shadows another S_o replaced meanwhile (a correction while an export runs): their
    # lift is their own, and it is not kept for the new S_o.
    old = s.found_shadows_detail()
    s.set_shadow_edits([ps.ShadowEdit(0.5, 0.6, shadow=False)])
    assert s.found_shadows_detail() is not old
    np.testing.assert_array_equal(
        s._detail_lifted(old),
        real(old["image"], old["probability"], old["excluded"], marked=old["marked"]))
    assert s._detail_lift is None


def test_cli_deshadow(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    img, depth = _session_inputs(tmp_path)
    photo, dpath = tmp_path / "p.png", tmp_path / "d.npy"
    write_image(photo, img)
    write_depth(dpath, depth)
    out, mask = tmp_path / "out.png", tmp_path / "mask.png"
    args = ["deshadow", str(photo), "--from", "45,35", "--depth", str(dpath), "-o", str(out),
            "--mask", str(mask), "-q"]
    assert main(args) == 0
    res = read_image(out).image_srgb
    assert res.shape == img.shape and res[35:45, 25:55].mean() > 1.5 * img[35:45, 25:55].mean()
    assert read_shadow_png(mask)[35:45, 25:55].mean() > 0.8
    assert main(args) == 2  # nothing overwritten without --force
    assert "exists" in capsys.readouterr().err
    assert main([a for a in args if a != "-q"] + ["--force"]) == 0
    said = capsys.readouterr().err
    assert f"wrote {out} (" in said and f"wrote {mask} (the shadows lifted" in said


def _furrows(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An ``n x n`` photo of warm ground with thin dark furrows (texture, which the lift leaves
    alone though the photometric stage finds them as shadow) and a wide cast shadow; the
    furrows' and the shadow's masks."""
    img = np.full((n, n, 3), 0.6, np.float32) * np.array([1.0, 0.95, 0.85], np.float32)
    furrows, wide = np.zeros((n, n), bool), np.zeros((n, n), bool)
    for x0 in range(0, 2 * n // 5, 10):
        furrows[: n // 2, x0:x0 + 2] = True
    wide[3 * n // 5:, 3 * n // 5:] = True
    img[furrows | wide] *= 0.35
    return img, furrows, wide


@pytest.mark.parametrize("n, detail_side", [(200, 1024), (400, 1024), (400, 200)])
def test_cli_deshadow_mask_is_what_the_de_shadow_lifts(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, n: int, detail_side: int
) -> None:
    """``deshadow --mask`` writes what the de-shadow lifts (the session's
    ``lifted_shadows_full``: ``lift_probability``, the app's "Shadows found" tint), not the bare
    found probability, which also holds the furrows the lift leaves dark: the session's own
    ``lifted_shadows`` for a photo found at the working size (200 px, fast),
    ``lift_probability`` at ``found_shadows_detail``'s size otherwise, upsampled bilinearly to
    the photo's size (``DETAIL_SIDE`` 200 for a 400 px photo)."""
    from outcast_core.runtime.geometry.camera import sun_vector
    from outcast_core.runtime.pipeline import session as session_module

    monkeypatch.setattr(session_module, "DETAIL_SIDE", detail_side)
    img, furrows, wide = _furrows(n)
    depth = np.full((n, n), 10.0, np.float32)
    photo, dpath, out, mask = (tmp_path / k for k in ("p.png", "d.npy", "o.png", "m.png"))
    write_image(photo, img)
    write_depth(dpath, depth)
    assert main(["deshadow", str(photo), "--from", "45,35", "--depth", str(dpath), "--preset",
                 "fast", "-o", str(out), "--mask", str(mask), "-q"]) == 0
    written = read_shadow_png(mask)
    assert written.shape == (n, n)
    s = RelightSession(mode="classic", preset="fast")
    s.set_image(read_image(photo).image_srgb, depth=depth)
    s.set_original_sun(sun_vector(45.0, 35.0))
    d = s.found_shadows_detail()
    if n == 200:  # found and lifted at the working size: exactly what the app tints
        assert d["image"] is s.image_srgb
        expected = s.lifted_shadows()
    else:
        assert d["image"].shape[:2] == (detail_side * n // max(n, detail_side),) * 2
        expected = ps.lift_probability(d["image"], d["probability"], d["excluded"],
                                       marked=d["marked"])
        expected = cv2.resize(expected, (n, n), interpolation=cv2.INTER_LINEAR)
    np.testing.assert_allclose(written, expected, atol=1e-4)  # 16-bit quantisation
    np.testing.assert_allclose(s.lifted_shadows_full(), expected, atol=1e-5)
    found = cv2.resize(d["probability"], (n, n), interpolation=cv2.INTER_LINEAR)
    assert written[furrows].mean() < 0.75 * found[furrows].mean()  # the furrows: not lifted
    assert written[wide].mean() > 0.9  # the wide shadow: lifted


def test_deshadow_keeps_black_things_in_the_shade_black() -> None:
    """Black railings in a shadow are far darker than shade is here: they are not lifted to
    grey with the shade around them."""
    img, mask = _shadowed()
    rails = np.zeros_like(mask)
    rails[30:50, 30:32] = rails[30:50, 44:46] = True
    img[rails] = 0.03
    sky = np.zeros((H, W), bool)
    out = deshadow(img, photo_shadow_probability(img, sky), sky)
    shade = mask & ~rails
    assert out[shade].mean() > 1.3 * img[shade].mean()  # the shade is lifted
    assert out[rails].mean() < 0.08  # the rails stay black


def test_a_small_bright_class_is_highlights_not_the_lit_surface():
    """A white object in a dim, half-shaded scene: Otsu alone splits white from everything
    else and calls the lit ground shade; the shade threshold splits again inside the dark class."""
    lin = np.full((60, 60), math.exp(-3.2), np.float32)  # lit ground, dim
    lin[:, :18] = math.exp(-4.5)  # shade: 30 %
    lin[:6, 30:] = 1.0  # a white object: 5 %
    img = np.repeat(linear_to_srgb(lin)[..., None], 3, axis=-1)
    sky = np.zeros((60, 60), bool)
    log_y = np.log(lin.ravel() + 1e-3)
    assert ps._otsu_threshold(log_y) > -3.0  # Otsu alone takes the lit ground for shade
    p = ps.photo_shadow_probability(img, sky)
    assert p[30, 5] > 0.9
    assert p[30, 45] < 0.1


@pytest.mark.parametrize("sigma", [3.0, 20.0, 60.0])
def test_wide_blur_matches_a_direct_gaussian(sigma: float) -> None:
    import cv2

    from outcast_core.runtime.pipeline.photo_shadows import wide_blur

    rng = np.random.default_rng(3)
    x = cv2.GaussianBlur(rng.random((120, 200, 3)).astype(np.float32), (0, 0), 2.0)
    x[40:80, 60:140] += 1.0  # a sharp-edged region: the weight maps it blurs are like this
    want = cv2.GaussianBlur(x, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
    got = wide_blur(x, sigma)
    assert got.shape == x.shape and got.dtype == np.float32
    np.testing.assert_allclose(got, want, atol=0.01 if sigma > 16 else 1e-6)
    one = wide_blur(x[..., 0], sigma)  # 2-D in, 2-D out
    assert one.shape == x.shape[:2]


def test_shadows_for_full_resolution_outputs_are_found_at_the_detail_size(tmp_path: Path) -> None:
    """A photo larger than the working size: its shadows are found at up to DETAIL_SIDE, so
    their edges follow the photo's, and the exported mask has the photo's size."""
    from outcast_core.runtime.pipeline import session as session_module

    rng = np.random.default_rng(5)
    h, w = 300, 400
    img = np.clip(0.7 + 0.02 * rng.standard_normal((h, w, 3)), 0, 1).astype(np.float32)
    img[:, 201:] *= 0.3  # a straight shadow edge between working-size pixels
    depth = np.full((h, w), 10.0, np.float32)
    s = RelightSession(mode="classic", preset="fast")
    s.set_image(img, depth=depth)
    with pytest.raises(RuntimeError, match="set_original_sun"):
        s.found_shadows_detail()
    s.set_original_sun((0.5, -0.6, 0.6))
    assert s.image_srgb.shape[1] < w  # the working size is smaller than the photo
    d = s.found_shadows_detail()
    assert d["probability"].shape == d["original_shadow"].shape == d["sky"].shape == (h, w)
    assert s.found_shadows_detail() is d  # once per original sun
    found = d["probability"] > 0.5
    truth = np.zeros((h, w), bool)
    truth[:, 201:] = True
    working = cv2.resize(s.shadow_probability, (w, h), interpolation=cv2.INTER_LINEAR) > 0.5
    assert (found != truth).mean() < 0.002
    assert (found != truth).mean() <= (working != truth).mean()
    # The de-shadowed photo is made there too, and the exported mask has the photo's size.
    full = s.deshadow_full()
    assert full.shape == img.shape and full[:, 210:].mean() > 2.0 * img[:, 210:].mean()
    monkey_side = session_module.DETAIL_SIDE
    try:  # a photo larger than DETAIL_SIDE: found at DETAIL_SIDE, mask still at full size
        session_module.DETAIL_SIDE = 200
        s.set_original_sun((0.5, -0.6, 0.6))
        assert s.found_shadows_detail()["probability"].shape == (150, 200)
    finally:
        session_module.DETAIL_SIDE = monkey_side
    photo, dpath = tmp_path / "big.png", tmp_path / "d.npy"
    write_image(photo, img)
    write_depth(dpath, depth)
    out, mask = tmp_path / "out.png", tmp_path / "mask.png"
    assert main(["deshadow", str(photo), "--from", "45,35", "--depth", str(dpath), "-o",
                 str(out), "--mask", str(mask), "-q"]) == 0
    assert read_shadow_png(mask).shape == (h, w)
    before = out.read_bytes()  # the mask may not be the de-shadowed photo's own file
    for force in ([], ["--force"]):
        assert main(["deshadow", str(photo), "--from", "45,35", "--depth", str(dpath), "-o",
                     str(out), "--mask", str(out), "-q", *force]) == 2
        assert out.read_bytes() == before


def test_deshadow_keeps_fine_dark_texture_and_lifts_wide_shadows() -> None:
    """Furrow-like dark stripes (2 px wide in a 400 px photo) are the surface's texture, not a
    shadow to lift; a wide shadow beside them is lifted."""
    h, w = 400, 400
    img = np.full((h, w, 3), 0.6, np.float32)
    furrows = np.zeros((h, w), bool)
    for x0 in range(0, 160, 10):
        furrows[:200, x0:x0 + 2] = True
    img[furrows] *= 0.35
    img[240:, 240:] *= 0.35  # a wide cast shadow
    sky = np.zeros((h, w), bool)
    p = photo_shadow_probability(img, sky)
    thin = ps.without_texture(p)
    assert thin[furrows].mean() < 0.6 * p[furrows].mean()  # the furrows' shade, mostly gone
    assert thin[300:380, 300:380].min() > 0.9  # the wide shadow's, kept
    out = deshadow(img, p, sky)
    assert out[furrows].mean() < 1.15 * img[furrows].mean()  # texture kept (1.25 unopened)
    assert out[280:380, 280:380].mean() > 1.5 * img[280:380, 280:380].mean()  # shadow lifted


def test_sky_shade_shift_takes_blue_shade_for_shade_and_a_dark_material_still_not() -> None:
    """Shade under a clear sky is much bluer than the lit ground (``SKY_SHADE_SHIFT``); the
    de-shadow's nearly neutral ``SHADE_SHIFT`` half rejects it, the sky shift takes it, and a
    dark material of another hue (red-brown) stays rejected under both."""
    from outcast_core.runtime.geometry.colour import srgb_to_linear

    lin = srgb_to_linear(_ground())
    lin[20:44, 10:40] *= np.exp(np.array([-1.75, -1.5, -1.08], np.float32))  # (-.25, +.42)
    lin[20:44, 56:86] *= np.array([0.3, 0.08, 0.03], np.float32)  # dark red-brown material
    img = linear_to_srgb(lin).astype(np.float32)
    sky = np.zeros((H, W), bool)
    p = photo_shadow_probability(img, sky)
    assert p[32, 25] > 0.9 and p[32, 70] > 0.9  # both dark
    neutral = ps.same_material(img, p, ~sky)
    clear_sky = ps.same_material(img, p, ~sky, ps.SKY_SHADE_SHIFT)
    assert neutral[26:38, 16:34].mean() < 0.9 < clear_sky[26:38, 16:34].mean()
    assert clear_sky[26:38, 62:80].mean() < 0.2 and neutral[26:38, 62:80].mean() < 0.2
    lifted = deshadow(img, p, sky, ps.SKY_SHADE_SHIFT)[26:38, 16:34].mean()
    assert lifted > 1.05 * deshadow(img, p, sky)[26:38, 16:34].mean()


def test_session_lift_expects_the_clear_sky_shade_colour(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """The relighting's lift (guard and ceiling) expects clear-sky shade
    (``relight.LIFT_SHADE_SHIFT`` = ``SKY_SHADE_SHIFT``); the de-shadow export keeps
    ``SHADE_SHIFT``."""
    from outcast_core.runtime.pipeline import relight, session

    shifts: list[tuple[str, tuple[float, float]]] = []
    real_guard, real_deshadow = session.material_guard, session.deshadow

    def guard(img, p, sky, shift=ps.SHADE_SHIFT):
        shifts.append(("guard", shift))
        return real_guard(img, p, sky, shift)

    def lift(img, p, sky, shift=ps.SHADE_SHIFT, marked=None, above_lit=ps.LIFT_ABOVE_LIT,
             lifted=None):
        shifts.append(("deshadow", shift))
        return real_deshadow(img, p, sky, shift, marked, above_lit, lifted)

    monkeypatch.setattr(session, "material_guard", guard)
    monkeypatch.setattr(session, "deshadow", lift)
    img, depth = _session_inputs(tmp_path)
    s = RelightSession(preset="fast")
    s.set_image(img, depth=depth)
    assert s.relight_mode == "learned" and s.lift_new_light
    s.set_original_sun((0.5, -0.6, 0.6))
    s.relight((-0.5, -0.6, 0.6))
    assert relight.LIFT_SHADE_SHIFT == ps.SKY_SHADE_SHIFT != ps.SHADE_SHIFT
    assert ("guard", ps.SKY_SHADE_SHIFT) in shifts
    assert ("deshadow", ps.SKY_SHADE_SHIFT) in shifts
    shifts.clear()
    s.deshadow()
    assert shifts == [("deshadow", ps.SHADE_SHIFT)]


def test_the_photos_own_shade_shift_is_measured_at_its_shadows_edges() -> None:
    """New shade takes the colour shift of the photo's own shade (the relighting's
    ``shaded_colour``): measured between its found shadows and the lit ring round them, along
    clear-sky shade's direction, within its range; the clear sky's shift without enough of
    either; a warmer "shade" (a dark material) counts as none."""
    from outcast_core.runtime.geometry.colour import linear_to_srgb
    from outcast_core.runtime.pipeline.photo_shadows import (
        SHIFT_RANGE,
        SKY_SHADE_SHIFT,
        photo_shade_shift,
    )

    sky_dir = np.asarray(SKY_SHADE_SHIFT)

    def photo(t: float) -> tuple[np.ndarray, np.ndarray]:
        lit = np.array([0.6, 0.45, 0.3], np.float32)  # linear, a warm paving
        shade = 0.1 * lit * np.exp(np.array([t * sky_dir[0], 0.0, t * sky_dir[1]]))
        lin = np.tile(lit, (60, 80, 1))
        found = np.zeros((60, 80), bool)
        found[15:45, 20:60] = True
        lin[found] = shade
        return linear_to_srgb(lin.astype(np.float32)), found

    surface = np.ones((60, 80), bool)
    for t in (0.0, 0.5, 1.0, 1.4):
        image, found = photo(t)
        got = np.asarray(photo_shade_shift(image, found, surface))
        assert np.allclose(got, t * sky_dir, atol=0.02), (t, got)
    image, found = photo(3.0)  # bluer than the range allows
    assert np.allclose(photo_shade_shift(image, found, surface), SHIFT_RANGE[1] * sky_dir)
    image, found = photo(-1.0)  # warmer than the lit surface: not the sky's shade
    assert np.allclose(photo_shade_shift(image, found, surface), (0.0, 0.0))
    image, found = photo(1.0)
    assert photo_shade_shift(image, np.zeros_like(found), surface) == SKY_SHADE_SHIFT


@pytest.mark.parametrize("dtype", [np.float32, np.uint8])
def test_keep_fills_in_boxes_and_bands_is_the_whole_frame_blend(monkeypatch, dtype) -> None:
    """``keep_fills`` upsamples only boxes round the filled pixels, in bands of rows and
    columns (a review: one box round two marks in opposite corners was the whole frame, and a
    100-megapixel photo got several GB of temporaries): the same pixels as blending the whole
    frame at once, at a scale that is not a whole number, in 8 bits and in float."""
    import cv2

    from outcast_core.runtime.pipeline import photo_shadows as ps

    monkeypatch.setattr(ps, "FILL_BAND", 7)
    monkeypatch.setattr(ps, "FILL_BAND_COLUMNS", 11)
    rng = np.random.default_rng(2)
    h, w, big_h, big_w = 30, 40, 77, 101
    before = rng.uniform(0.3, 0.8, (h, w, 3)).astype(np.float32)
    before[2:8, 3:9] = 0.002  # two crushed marks, far apart
    before[20:28, 30:38] = 0.002
    after = rng.uniform(0.3, 0.8, (h, w, 3)).astype(np.float32)
    full = rng.uniform(0.0, 1.0, (big_h, big_w, 3)).astype(np.float32)
    if dtype == np.uint8:
        full = np.rint(full * 255).astype(np.uint8)
    share = ps.filled_share(before, after)
    assert len(ps._fill_boxes(share > 0)) == 2
    share = cv2.dilate(share, np.ones((3, 3), np.uint8))  # (a working pixel's reach)
    ys = ((np.arange(big_h) + 0.5) * h / big_h - 0.5).astype(np.float32)
    xs = ((np.arange(big_w) + 0.5) * w / big_w - 0.5).astype(np.float32)
    mx, my = np.meshgrid(xs, ys)
    k = cv2.remap(share, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)[..., None]
    k = np.clip(4.0 * k, 0.0, 1.0)  # a black photo: darker than every fill
    up = cv2.remap(after, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    base = full.astype(np.float32) / (255.0 if dtype == np.uint8 else 1.0)
    want = base + k * (up - base)
    photo = np.zeros((big_h, big_w, 3), dtype)
    got = ps.keep_fills(full.copy(), before, after, None, photo)
    if dtype == np.uint8:
        want = np.clip(np.rint(want * 255.0), 0, 255).astype(np.uint8)
        assert np.abs(got.astype(int) - want.astype(int)).max() <= 1
    else:
        np.testing.assert_allclose(got, want, atol=1e-5)
    assert (got[k[..., 0] == 0] == full[k[..., 0] == 0]).all()  # nothing else touched


def _deep_blue_scene() -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Warm gravel with a cast shadow in deep blue shade (its chromaticity moved twice the
    clear sky's shift, as the dev photos' SBU shade often is), beside a navy object (bluer
    only, red against green unchanged: 31 degrees off the sky's direction) and a dark
    sea-blue one (moved mostly in red: 36 degrees off)."""
    from outcast_core.runtime.geometry.colour import srgb_to_linear

    lin = srgb_to_linear(_ground())
    regions = {name: np.zeros((H, W), bool) for name in ("shadow", "navy", "sea")}
    regions["shadow"][34:56, 8:38] = True
    regions["navy"][6:24, 52:68] = True
    regions["sea"][38:58, 60:90] = True
    gains = {"shadow": (-2.3, -1.8, -0.96), "navy": (-2.0, -2.0, -0.8),
             "sea": (-3.1, -1.2, -0.4)}  # natural log, R, G, B
    for name, g in gains.items():
        lin[regions[name]] *= np.exp(np.array(g, np.float32))
    return linear_to_srgb(lin).astype(np.float32), regions


def _log_contrast(img: np.ndarray, inside: np.ndarray, lit: np.ndarray) -> float:
    from outcast_core.runtime.geometry.colour import luminance, srgb_to_linear

    y = np.log(luminance(srgb_to_linear(np.clip(img, 0, 1))) + 1e-3)
    return float(y[lit].mean() - y[inside].mean())


def test_found_shade_marks_take_deep_blue_shade_and_leave_blue_materials() -> None:
    """A found shadow whose own lit ring says it is its shade (darker, moved along the clear
    sky's direction) is marked; dark blue materials that moved elsewhere are not, nor what the
    user marked "not a shadow" (passed as ``sky``)."""
    img, regions = _deep_blue_scene()
    sky = np.zeros((H, W), bool)
    p = photo_shadow_probability(img, sky)
    assert all(p[r].mean() > 0.8 for r in regions.values())  # all three found dark
    marks = ps.found_shade_marks(img, p, sky)
    core = cv2.erode(regions["shadow"].astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    assert marks[core].all()
    assert not marks[regions["navy"]].any() and not marks[regions["sea"]].any()
    assert not marks[~cv2.dilate(regions["shadow"].astype(np.uint8),
                                 np.ones((9, 9), np.uint8)).astype(bool)].any()
    assert not ps.found_shade_marks(img, p, regions["shadow"]).any()  # "not a shadow"
    assert not ps.found_shade_marks(img, np.zeros_like(p), sky).any()  # nothing found


def test_deep_blue_shade_is_lifted_to_its_lit_ring_when_found_as_shade() -> None:
    """The photo-wide lift's material guard, expecting shade nearly neutral, keeps most of
    deep blue shade (a blue-grey ghost in "Shadows removed"); lifted as the found marks say,
    from the lit ring round it, the shadow nearly goes, and the blue materials stay."""
    img, regions = _deep_blue_scene()
    sky = np.zeros((H, W), bool)
    p = photo_shadow_probability(img, sky)
    marks = ps.found_shade_marks(img, p, sky).astype(np.float32)
    plain = deshadow(img, p, sky)
    marked = deshadow(img, p, sky, marked=marks)
    core = cv2.erode(regions["shadow"].astype(np.uint8), np.ones((7, 7), np.uint8)) > 0
    lit = ~cv2.dilate((p > 0.1).astype(np.uint8), np.ones((7, 7), np.uint8)).astype(bool)
    before = _log_contrast(img, core, lit)
    assert _log_contrast(plain, core, lit) > 0.5 * before  # the ghost
    assert abs(_log_contrast(marked, core, lit)) < 0.15 * before
    for name in ("navy", "sea"):  # (the photo-wide statistics count the shadow as shade now)
        assert np.abs(marked[regions[name]] - plain[regions[name]]).mean() < 0.01


def test_a_mark_inside_a_wide_shadow_is_lifted_to_the_lit_ground_beyond_it() -> None:
    """A "Mark shadow" stroke painted inside a wide shadow the photo's probability missed was
    tinted and not lifted: the ring round the stroke is that shadow too (a user trial on the
    ski slope). It is measured against the lit ground round the shadow it lies in, as a click
    there is; only the marked pixels are lifted. A mark on a lit patch gets nothing either
    way, and a mark covering the whole shadow is lifted as before."""
    img, mask = _shadowed(box=(16, 48, 20, 76))  # a wide shadow
    sky = np.zeros((H, W), bool)
    p = np.where(mask, 0.3, 0.0).astype(np.float32)  # missed: found at 0.3 only
    stroke = np.zeros((H, W), bool)
    stroke[30:36, 40:56] = True  # painted well inside it
    plain = deshadow(img, p, sky)
    p, _ = ps.apply_edit_masks(p, sky, stroke, np.zeros((H, W), bool))  # as the session does
    out = deshadow(img, p, sky, marked=stroke.astype(np.float32))
    from outcast_core.runtime.geometry.colour import luminance, srgb_to_linear

    def y(a: np.ndarray, where: np.ndarray) -> float:
        return float(luminance(srgb_to_linear(a))[where].mean())

    lit = ~cv2.dilate(mask.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    assert y(out, stroke) > 0.85 * y(img, lit)  # lifted to the lit ground
    rest = mask & ~cv2.dilate(stroke.astype(np.uint8), np.ones((9, 9), np.uint8)).astype(bool)
    assert y(plain, stroke) < 0.5 * y(img, lit)  # (unmarked, it stays a shadow)
    np.testing.assert_allclose(out[rest], plain[rest], atol=0.02)  # the rest is not marked
    p_whole, _ = ps.apply_edit_masks(np.where(mask, 0.3, 0.0).astype(np.float32), sky, mask,
                                     np.zeros((H, W), bool))
    whole = deshadow(img, p_whole, sky, marked=mask.astype(np.float32))
    assert y(whole, stroke) > 0.85 * y(img, lit)
    patch = np.zeros((H, W), bool)
    patch[2:8, 2:10] = True  # on the lit ground
    np.testing.assert_allclose(deshadow(img, p, sky, marked=patch.astype(np.float32))[patch],
                               plain[patch], atol=0.05)


def test_a_marked_shadow_beside_its_white_occluder_is_lifted_to_the_ground_not_the_box(
) -> None:
    """A box's shadow on brown carpet, marked: the lit ring round it holds the carpet and the
    white box itself, which Otsu's bright class picked: the shadow was lifted to the box's
    cream, three times the carpet (a dev photo). The ring's class that turns from the shadow
    as lit shade does (the carpet) is taken; the same shadow without the box is lifted to the
    carpet as before."""
    from outcast_core.runtime.geometry.colour import luminance, srgb_to_linear

    rng = np.random.default_rng(4)
    carpet = np.array([0.45, 0.35, 0.25], np.float32)
    img = np.clip(carpet * (1 + 0.04 * rng.standard_normal((H, W, 1))), 0, 1).astype(np.float32)
    shadow = np.zeros((H, W), bool)
    shadow[30:50, 20:60] = True
    box = np.zeros((H, W), bool)
    box[20:50, 60:80] = True
    img[shadow] *= SHADE  # darker and bluer
    img[box] = [0.92, 0.93, 0.95]  # white
    sky = np.zeros((H, W), bool)
    p = shadow.astype(np.float32)
    out = deshadow(img, p, sky, marked=p)

    def y(a: np.ndarray, where: np.ndarray) -> float:
        return float(np.median(luminance(srgb_to_linear(a))[where]))

    core = cv2.erode(shadow.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    ground = ~cv2.dilate((shadow | box).astype(np.uint8), np.ones((9, 9), np.uint8)).astype(bool)
    assert 0.8 < y(out, core) / y(img, ground) < 1.25
    assert y(out, core) < 0.5 * y(img, box)
    bare = img.copy()
    bare[box] = img[ground][: int(box.sum())]  # carpet where the box stood
    alone = deshadow(bare, p, sky, marked=p)
    assert 0.8 < y(alone, core) / y(img, ground) < 1.25


def test_a_marked_shadow_is_lifted_no_brighter_than_its_lit_ring_even_unbounded() -> None:
    """The relighting's ceiling is the de-shadow without its bound (``above_lit=None``); a
    marked shadow's pixels still end no brighter than the lit surface's bright end round it
    (``marked_lift``'s ``top``): a penumbra lifted by the core's gain made a light rim."""
    img, mask = _shadowed()
    img *= 0.6
    rim = mask & ~(cv2.erode(mask.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0)
    img[rim] = np.sqrt(img[rim] * _ground()[rim] * 0.6)  # a penumbra: half way in log
    sky = np.zeros((H, W), bool)
    out = deshadow(img, mask.astype(np.float32), sky, marked=mask.astype(np.float32),
                   above_lit=None)
    from outcast_core.runtime.geometry.colour import luminance, srgb_to_linear

    y = luminance(srgb_to_linear(out))
    ring = cv2.dilate(mask.astype(np.uint8), np.ones((9, 9), np.uint8)).astype(bool) & ~mask
    assert y[rim].mean() <= 1.02 * np.percentile(y[ring], ps.MARKED_TOP)
    assert y[mask & ~rim].mean() > 0.8 * y[ring].mean()  # the core is lifted


def test_the_session_lifts_found_deep_blue_shade_in_both_the_export_and_the_relighting(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The session hands the found marks to the de-shadow (the export, the found shadows the
    app shows) and to the relighting's lift, whose ceiling it raises and lets the lift reach,
    on surfaces that face up (``relight.LIFT_MARK_FACING``); without them deep blue shade
    stays a ghost in both. The box scene's camera looks straight down, its horizon's up the
    camera's vertical, so its ground counts as a wall for the relighting's lift until
    ``facing_up`` is made to say otherwise."""
    from outcast_core.runtime.pipeline import session as session_module

    img, regions = _deep_blue_scene()
    _, depth = _session_inputs(tmp_path)
    core = cv2.erode(regions["shadow"].astype(np.uint8), np.ones((7, 7), np.uint8)) > 0

    def lifted(found: bool = True) -> tuple[float, float, np.ndarray]:
        if not found:
            monkeypatch.setattr(session_module, "found_shade_marks",
                                lambda image, p, sky: np.zeros(p.shape, bool))
        s = RelightSession(preset="fast")
        s.set_image(img, depth=depth)
        s.set_original_sun((0.5, -0.6, 0.6))
        lit = ~cv2.dilate((s.shadow_probability > 0.1).astype(np.uint8),
                          np.ones((7, 7), np.uint8)).astype(bool)
        relit = s.relight((-0.5, -0.6, -0.6))  # a sun that lights the shadow's ground
        return (_log_contrast(s.deshadow(), core, lit), _log_contrast(relit, core, lit),
                s.lifted_shadows())

    export, on_a_wall, shown = lifted()
    monkeypatch.setattr(session_module, "facing_up",
                        lambda normals, up: np.ones(np.shape(normals)[:2], np.float32))
    _, relit, _ = lifted()
    ghost_export, ghost_relit, _ = lifted(found=False)
    before = _log_contrast(img, core, ~cv2.dilate(regions["shadow"].astype(np.uint8),
                                                   np.ones((7, 7), np.uint8)).astype(bool))
    assert ghost_export > 0.5 * before and abs(export) < 0.2 * before
    assert relit < 0.5 * ghost_relit
    assert on_a_wall == pytest.approx(ghost_relit, abs=1e-6)
    assert shown[core].mean() > 0.9  # what the app shows as found: all of it


def _deep_blue_session(tmp_path: Path, crushed: bool = False
                       ) -> tuple[RelightSession, dict[str, np.ndarray]]:
    """The deep blue scene in a session at its sun; ``crushed``: its shadow 22x darker than
    the gravel (past the largest lift, so the lift's ceiling fills it)."""
    from outcast_core.runtime.geometry.colour import srgb_to_linear

    img, regions = _deep_blue_scene()
    if crushed:
        lin = srgb_to_linear(img)
        lin[regions["shadow"]] *= np.float32(np.exp(-1.3))
        img = linear_to_srgb(lin).astype(np.float32)
    _, depth = _session_inputs(tmp_path)
    s = RelightSession(preset="fast")
    s.set_image(img, depth=depth)
    s.set_original_sun((0.5, -0.6, 0.6))
    return s, regions


def test_the_relightings_found_marks_face_up_and_follow_the_cameras_tilt(tmp_path: Path) -> None:
    """The box scene's camera looks straight down: with the camera's vertical as the horizon's
    up its ground is a wall, and the relighting's lift takes no found marks there (nor does
    a full-size relighting fill them); told the camera's pitch, the ground faces up and they
    count (they went stale with the old up: a review)."""
    s, regions = _deep_blue_session(tmp_path)
    core = cv2.erode(regions["shadow"].astype(np.uint8), np.ones((7, 7), np.uint8)) > 0
    assert s._working_marks()[core].all()  # the de-shadow's, whatever faces where
    assert s.relight_fills() is None
    s.set_camera_tilt(-90.0, 0.0)
    fills = s.relight_fills()
    assert fills is not None and fills[core].min() == 1.0
    assert s.relight_fills(np.zeros((32, 48), bool)).shape == (32, 48)
    s.set_camera_tilt(None)
    assert s.relight_fills() is None


def test_found_marks_are_read_before_the_users_and_physics_fills_only_the_users(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Found marks are read before the user's marks (a stroke neither splits a found shadow
    nor becomes one), and physics mode fills only what the user marked: the lift's ceiling
    fills a crushed found shadow, which physics followed once the user had marked anything
    anywhere (a review)."""
    from outcast_core.runtime.pipeline import session as session_module
    from outcast_core.runtime.pipeline.photo_shadows import ShadowEdit

    monkeypatch.setattr(session_module, "facing_up",  # the box scene's ground faces the camera
                        lambda normals, up: np.ones(np.shape(normals)[:2], np.float32))
    s, regions = _deep_blue_session(tmp_path, crushed=True)
    core = cv2.erode(regions["shadow"].astype(np.uint8), np.ones((7, 7), np.uint8)) > 0
    shape = s.image_srgb.shape[:2]
    assert s._lift_inputs(shape)["lift_fill"][core].mean() > 0.9  # the ceiling's trust
    navy = regions["navy"]
    ys, xs = np.nonzero(navy)
    s.set_shadow_edits([ShadowEdit(float(xs.mean() + 0.5) / W, float(ys.mean() + 0.5) / H,
                                   shadow=True)])
    user = s._marked(s.sky)
    assert user is not None and user[navy].mean() > 0.9
    inputs = s._lift_inputs(shape)
    assert inputs["lift_fill"][core].mean() > 0.9
    physics = inputs["physics_fill"]
    assert physics is None or not physics[~(user > 0)].any()
    # The user brushes over part of the found shadow: it stays marked whole (read before the
    # user's marks: leaving the mark out of it split a shadow, a GUI trial), and beyond it the
    # marks are the user's own (found again from the marked probability, a stroke became a
    # hard 1 with a penumbra grown round it: a review).
    found = ps.found_shade_marks(s.image_srgb, s._found[1], s.sky)
    assert found[core].all()
    s.set_shadow_edits([ShadowEdit((20.0 + 2 * k) / W, 45.0 / H, shadow=True, radius=0.06,
                                   start=k == 0) for k in range(16)])
    user = s._marked(s.sky)
    assert user is not None and (user[core] > 0).mean() > 0.3 and (user[core] == 0).any()
    marks = s._working_marks()
    assert marks[found].min() == 1.0
    np.testing.assert_array_equal(marks[~found], user[~found])


def test_a_marked_shadows_penumbra_is_lifted_to_the_lit_surface_not_past_it() -> None:
    """A penumbra (a smooth ramp from the shadow to the lit gravel) inside a mark takes the
    share of the gain that brings it to the lit surface: the whole gain lifted it to the
    lit gravel's bright end, a light rim round the shadow (a user trial: cream, 3 px)."""
    from outcast_core.runtime.geometry.colour import luminance, srgb_to_linear

    rng = np.random.default_rng(3)
    base = np.array([0.45, 0.4, 0.3], np.float32)  # gravel: its bright end 1.17x its median
    img = np.clip(base * np.exp(0.1 * rng.standard_normal((H, W, 1))), 0, 1).astype(np.float32)
    mask = np.zeros((H, W), bool)
    mask[24:40, 30:66] = True
    dist = cv2.distanceTransform(mask.astype(np.uint8), cv2.DIST_L2, 3)
    depth = np.clip(dist / 4.0, 0.0, 1.0)[..., None]  # 0 at the edge, 1 from 4 px in
    img = (img * np.exp(np.log(SHADE) * depth)).astype(np.float32)
    rim = mask & (dist <= 2.5)
    sky = np.zeros((H, W), bool)
    out = deshadow(img, mask.astype(np.float32), sky, marked=mask.astype(np.float32))
    y = luminance(srgb_to_linear(out))
    ring = cv2.dilate(mask.astype(np.uint8), np.ones((11, 11), np.uint8)).astype(bool) & ~mask
    assert np.median(y[rim]) <= 1.05 * np.median(y[ring])
    core = mask & (dist > 5)
    assert np.median(y[core]) > 0.6 * np.median(y[ring])  # the shadow itself is lifted (0.21)


def test_found_shade_marks_are_made_once_per_sun_and_size_across_shadow_marks(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A "Mark shadow" edit does not change the shadows as found, so their found marks are
    not made again (0.13 s per edit at the export's size before); "Not a shadow" does."""
    from outcast_core.runtime.pipeline import session as session_module
    from outcast_core.runtime.pipeline.photo_shadows import ShadowEdit

    made: list[tuple[int, int]] = []
    real = session_module.found_shade_marks

    def counted(image, p, sky):
        made.append(np.shape(p))
        return real(image, p, sky)

    monkeypatch.setattr(session_module, "found_shade_marks", counted)
    s, regions = _deep_blue_session(tmp_path)
    assert len(made) == 1
    ys, xs = np.nonzero(regions["navy"])
    s.set_shadow_edits([ShadowEdit(float(xs.mean() + 0.5) / W, float(ys.mean() + 0.5) / H,
                                   shadow=True)])
    assert s._marked(s.sky) is not None and len(made) == 1
    s.set_shadow_edits([ShadowEdit(float(xs.mean() + 0.5) / W, float(ys.mean() + 0.5) / H,
                                   shadow=False)])
    assert len(made) == 2  # what is surface changed
    s.set_original_sun((0.5, -0.6, 0.6))
    assert len(made) == 3
