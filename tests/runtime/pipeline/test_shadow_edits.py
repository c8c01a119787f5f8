"""The user's corrections of the found shadows (``ShadowEdit``: "a shadow" / "not a shadow").

The scene is the ski-slope sample's failure in small: bright snow, a wide shadow on it, and a
large dark material (pines). One threshold calls the pines shadow and the shaded snow lit.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from outcast_core.runtime.pipeline.photo_shadows import (
    MAX_SHADOW_EDITS,
    PICK_RADIUS,
    ShadowEdit,
    apply_edit_masks,
    deshadow,
    photo_shadow_probability,
    shadow_edit_masks,
    shadow_edit_region,
    shadow_edits_from_json,
    shadow_edits_to_json,
)
from outcast_core.runtime.pipeline.session import RelightSession

H, W = 96, 128
SNOW = np.array([0.85, 0.86, 0.9], np.float32)


def _slope(seed: int = 0) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Snow, its shadow (2.2x darker, bluer), pines (near black, green) and a sky strip."""
    rng = np.random.default_rng(seed)
    img = np.clip(SNOW * (1 + 0.03 * rng.standard_normal((H, W, 1))), 0, 1).astype(np.float32)
    parts = {k: np.zeros((H, W), bool) for k in ("sky", "shadow", "pines")}
    parts["sky"][:12] = True
    parts["pines"][12:40, :] = True  # a tree line across the frame
    parts["pines"][40:60, 10:22] = True  # a trunk down to the snow
    parts["shadow"][55:90, 40:100] = True
    img[parts["sky"]] = [0.55, 0.7, 0.95]
    img[parts["pines"]] = [0.05, 0.09, 0.05]
    img[parts["shadow"]] *= np.array([0.42, 0.45, 0.52], np.float32)
    return img, parts


def apply_shadow_edits(p, img, sky, edits):
    """The edits' regions made and applied at one size (as the session does at its own)."""
    return apply_edit_masks(p, sky, *shadow_edit_masks(p, img, sky, edits))


def _centre(mask: np.ndarray) -> tuple[float, float]:
    ys, xs = np.nonzero(mask)
    return (xs.mean() + 0.5) / mask.shape[1], (ys.mean() + 0.5) / mask.shape[0]


def test_the_automatic_split_fails_here_as_on_the_ski_slope() -> None:
    img, parts = _slope()
    p = photo_shadow_probability(img, parts["sky"])
    assert p[parts["pines"]].mean() > 0.9  # the pines are called shadow
    assert p[parts["shadow"]].mean() < 0.1  # the shaded snow is called lit


def test_not_a_shadow_drops_the_found_region_under_or_near_the_click() -> None:
    img, parts = _slope()
    sky = parts["sky"]
    p = photo_shadow_probability(img, sky)
    on = shadow_edit_region(p, img, sky, ShadowEdit(0.5, 20 / H, shadow=False))
    assert (on == ((p > 0.5) & parts["pines"])).mean() > 0.99
    # A click just beside the trunk (within PICK_RADIUS) still means it.
    beside = ShadowEdit((22 + 0.5 * PICK_RADIUS * W) / W, 50 / H, shadow=False)
    assert (shadow_edit_region(p, img, sky, beside) == on).all()
    # Far from every found shadow: nothing.
    assert not shadow_edit_region(p, img, sky, ShadowEdit(0.9, 0.95, shadow=False)).any()


def test_a_shadow_fills_the_even_region_round_the_click_and_never_the_sky() -> None:
    img, parts = _slope()
    sky = parts["sky"]
    p = photo_shadow_probability(img, sky)
    x, y = _centre(parts["shadow"])
    region = shadow_edit_region(p, img, sky, ShadowEdit(x, y, shadow=True))
    inside = (region & parts["shadow"]).sum() / parts["shadow"].sum()
    outside = (region & ~parts["shadow"]).sum() / parts["shadow"].sum()
    assert inside > 0.97 and outside < 0.05  # the shadow, not the lit snow or the pines
    assert not shadow_edit_region(p, img, sky, ShadowEdit(0.5, 0.02, shadow=True)).any()


def test_a_drop_never_takes_an_added_shadow_with_it_in_either_order() -> None:
    img, parts = _slope()
    sky = parts["sky"]
    p = photo_shadow_probability(img, sky)
    add = ShadowEdit(*_centre(parts["shadow"]), shadow=True)
    drop = ShadowEdit(0.5, 20 / H, shadow=False)
    out, not_shadow = apply_shadow_edits(p, img, sky, [add, drop])
    assert out[parts["shadow"]].mean() > 0.95 and out[parts["pines"]].mean() < 0.05
    assert not_shadow[parts["pines"]].mean() > 0.95 and not not_shadow[parts["shadow"]].any()
    assert not out[sky].any()
    same, _ = apply_shadow_edits(p, img, sky, [drop, add])
    assert np.abs(same - out).max() < 1e-6
    # "Not a shadow" clicked in a region the user added takes that addition back.
    back, _ = apply_shadow_edits(p, img, sky, [add, drop, ShadowEdit(add.x, add.y, False)])
    assert back[parts["shadow"]].mean() < 0.1
    none, nothing = apply_shadow_edits(p, img, sky, [])
    assert np.abs(none - np.where(sky, 0, p)).max() < 1e-6 and not nothing.any()


def test_a_point_must_lie_in_the_photo() -> None:
    with pytest.raises(ValueError, match="inside the photo"):
        ShadowEdit(1.2, 0.5, shadow=True)


def test_the_lift_leaves_what_is_not_a_shadow_out_of_its_statistics() -> None:
    """Dropped pines are no lit surface: counted as lit (their probability 0), they made the
    shadow look brighter than its "lit" surroundings and it was not lifted at all."""
    img, parts = _slope()
    sky = parts["sky"]
    p = photo_shadow_probability(img, sky)
    edits = [ShadowEdit(*_centre(parts["shadow"]), shadow=True), ShadowEdit(0.5, 0.2, False)]
    edited, not_shadow = apply_shadow_edits(p, img, sky, edits)
    core = np.zeros((H, W), bool)
    core[62:84, 50:90] = True
    lit = ~parts["shadow"] & ~parts["pines"] & ~sky
    naive = deshadow(img, edited, sky)
    lifted = deshadow(img, edited, sky | not_shadow)
    assert naive[core].mean() < 1.2 * img[core].mean()  # the pines as lit: hardly lifted
    assert abs(lifted[core].mean() - img[lit].mean()) < 0.1 * img[lit].mean()
    assert np.abs(lifted[parts["pines"]] - img[parts["pines"]]).max() < 0.02


def test_session_edits_redo_the_found_shadows_at_every_size_and_stay_with_the_photo() -> None:
    img, parts = _slope()
    big = np.repeat(np.repeat(img, 3, axis=0), 3, axis=1)  # larger than the working size
    depth = np.full(big.shape[:2], 10.0, np.float32)
    depth[:36] = np.inf  # the sky strip
    s = RelightSession(mode="classic", preset="fast")
    s.set_image(big, depth=depth)
    s.set_original_sun((0.3, -0.5, 0.8))
    found = s.shadow_probability.copy()
    plain = s.deshadow_full()
    shadow = np.repeat(np.repeat(parts["shadow"], 3, axis=0), 3, axis=1)
    pines = np.repeat(np.repeat(parts["pines"], 3, axis=0), 3, axis=1)
    edits = (ShadowEdit(*_centre(parts["shadow"]), shadow=True), ShadowEdit(0.5, 0.2, False))
    s.set_shadow_edits(edits)
    assert s.shadow_edits == edits and s.shadow_edits_used == (True, True)
    s.set_shadow_edits((*edits, ShadowEdit(0.5, 0.05, shadow=True)))  # on the sky
    assert s.shadow_edits_used == (True, True, False)
    s.set_shadow_edits(edits)
    detail = s.found_shadows_detail()
    assert detail["probability"].shape == big.shape[:2]  # found again at the detail size
    assert detail["probability"][shadow].mean() > 0.9
    assert detail["probability"][pines].mean() < 0.1 and detail["excluded"][pines].mean() > 0.95
    fixed = s.deshadow_full()
    assert fixed[shadow].mean() > 1.6 * plain[shadow].mean()
    assert np.abs(fixed[pines] - big[pines]).mean() < np.abs(plain[pines] - big[pines]).mean()
    # S_o follows: the shaded snow is shadow now, the pines lit (their cosine term).
    s_o = s.original_shadow
    on_working = {k: cv2.resize(m.astype(np.uint8), s_o.shape[::-1],
                                interpolation=cv2.INTER_NEAREST) > 0 for k, m in parts.items()}
    assert s_o[on_working["shadow"]].mean() < 0.15 < s_o[on_working["pines"]].mean()
    # Kept across a preset with another working size and a new original sun.
    s.set_preset("balanced")
    s.set_original_sun((0.2, -0.6, 0.77))
    assert s.shadow_edits == edits and s.shadow_probability.max() > 0.9
    # () gives back exactly the found shadows; a new photo starts without edits.
    s.set_preset("fast")
    s.set_original_sun((0.3, -0.5, 0.8))
    s.set_shadow_edits(())
    assert np.array_equal(s.shadow_probability, found)
    s.set_shadow_edits(edits)
    s.set_image(big, depth=depth)
    assert s.shadow_edits == ()
    with pytest.raises(ValueError, match="ShadowEdit"):
        s.set_shadow_edits([(0.5, 0.5, True)])


def test_edits_round_trip_through_a_project_and_bad_ones_are_refused() -> None:
    edits = (ShadowEdit(0.25, 0.5, shadow=False), ShadowEdit(1.0, 0.0, shadow=True))
    assert shadow_edits_from_json(shadow_edits_to_json(edits)) == edits
    assert shadow_edits_from_json(None) == ()
    for bad, words in [({"x": 0.1}, "list"), ([{"x": 0.1, "y": 0.2}], "x, y, shadow"),
                       ([{"x": "0.1", "y": 0.2, "shadow": True}], "numbers"),
                       ([{"x": 0.1, "y": 0.2, "shadow": 1}], "true/false"),
                       ([{"x": 1.5, "y": 0.2, "shadow": True}], "inside the photo"),
                       ([{"x": float("nan"), "y": 0.2, "shadow": True}], "inside the photo"),
                       ([{"x": 0.1, "y": 0.2, "shadow": True}] * (MAX_SHADOW_EDITS + 1),
                        "at most"),
                       ([{"x": 10**400, "y": 0.2, "shadow": True}], "too large")]:
        with pytest.raises(ValueError, match=words):
            shadow_edits_from_json(bad)


def test_cli_takes_the_corrections_in_their_order(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture) -> None:
    from outcast_core.runtime.cli.main import main
    from outcast_core.runtime.io import imageio

    img, parts = _slope()
    depth = np.full((H, W), 10.0, np.float32)
    depth[parts["sky"]] = np.inf
    photo, dpath = tmp_path / "slope.png", tmp_path / "d.npy"
    imageio.write_image(photo, img)
    imageio.write_depth(dpath, depth)
    x, y = _centre(parts["shadow"])
    base = ["deshadow", str(photo), "--from", "20,30", "--depth", str(dpath), "-q", "--force"]
    assert main([*base, "-o", str(tmp_path / "a.png"), "--mask", str(tmp_path / "a_m.png")]) == 0
    assert main([*base, "-o", str(tmp_path / "b.png"), "--mask", str(tmp_path / "b_m.png"),
                 "--not-shadow", "0.5,0.2", "--shadow", f"{x},{y}"]) == 0
    plain, fixed = (imageio.read_shadow_png(tmp_path / f"{k}_m.png") for k in "ab")
    assert plain[parts["pines"]].mean() > 0.9 and fixed[parts["pines"]].mean() < 0.1
    assert plain[parts["shadow"]].mean() < 0.1 and fixed[parts["shadow"]].mean() > 0.9
    lifted = imageio.read_image(tmp_path / "b.png").image_srgb
    assert lifted[parts["shadow"]].mean() > 1.6 * img[parts["shadow"]].mean()
    # Order matters: "not a shadow" clicked in the added shadow takes it back.
    assert main([*base, "-o", str(tmp_path / "c.png"), "--mask", str(tmp_path / "c_m.png"),
                 "--shadow", f"{x},{y}", "--not-shadow", f"{x},{y}"]) == 0
    assert imageio.read_shadow_png(tmp_path / "c_m.png")[parts["shadow"]].mean() < 0.1
    capsys.readouterr()
    # A click that changes nothing is said (the sky), and the "wrote" line counts the rest.
    assert main([*base[:-2], "--force", "-o", str(tmp_path / "e.png"), "--shadow", "0.5,0.05",
                 "--not-shadow", "0.5,0.2"]) == 0
    err = capsys.readouterr().err
    assert "note: --shadow 0.5,0.05 changed nothing (the sky" in err
    assert "(128x96; 1 shadow correction; " in err
    with pytest.raises(SystemExit) as info:
        main([*base, "-o", str(tmp_path / "d.png"), "--shadow", "0.5"])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "--shadow" in err and "fractions 0-1" in err and len(err.strip().splitlines()) == 1


def test_a_second_not_a_shadow_click_on_the_same_spot_changes_nothing() -> None:
    """A double click near a dark object's edge must not reach for the real shadow beside it
    (the nearest found shadow within PICK_RADIUS, once the object is dropped)."""
    rng = np.random.default_rng(1)
    img = np.clip(0.8 + 0.01 * rng.standard_normal((256, 256, 3)), 0, 1).astype(np.float32)
    img[80:160, 40:110] = 0.15  # a dark car
    img[80:160, 113:190] = 0.3  # its shadow, three pixels away
    sky = np.zeros((256, 256), bool)
    p = photo_shadow_probability(img, sky)
    assert p[120, 150] > 0.9 and p[120, 70] > 0.9
    assert PICK_RADIUS * 256 > 113 - 108  # the shadow is within reach of the click
    click = ShadowEdit(108.5 / 256, 120 / 256, shadow=False)
    once, _ = apply_shadow_edits(p, img, sky, [click])
    twice, _ = apply_shadow_edits(p, img, sky, [click, click])
    assert once[120, 70] < 0.01 and once[120, 150] > 0.9
    assert np.abs(twice - once).max() < 1e-6


def test_a_marked_shadow_may_be_lifted_wherever_it_is(monkeypatch: pytest.MonkeyPatch) -> None:
    """The relighting's lift acts only near a shadow the geometry predicts and on what looks
    like shade, not material; a shadow the user marked is one, wherever it is."""
    from outcast_core.runtime.pipeline import session as session_module

    img, parts = _slope()
    depth = np.full((H, W), 10.0, np.float32)
    depth[parts["sky"]] = np.inf
    # A geometry that predicts no shadow anywhere near.
    monkeypatch.setattr(session_module, "near_predicted_shadow",
                        lambda prior, sky, radius: np.zeros(np.shape(sky), np.float32))
    s = RelightSession(mode="classic", preset="fast")
    s.set_image(img, depth=depth)
    s.set_original_sun((0.3, -0.5, 0.8))
    shape = s.image_srgb.shape[:2]
    work = cv2.resize(parts["shadow"].astype(np.uint8), shape[::-1],
                      interpolation=cv2.INTER_NEAREST) > 0
    before = s._lift_guard(shape)
    s.set_shadow_edits([ShadowEdit(*_centre(parts["shadow"]), shadow=True)])
    after = s._lift_guard(shape)
    assert before is not None and after is not None
    assert before[work].max() == 0.0 and after[work].mean() > 0.95


def test_a_shadow_click_on_lit_ground_is_refused() -> None:
    """A sunlit fleck inside a shadow (or lit snow beside a trunk's shadow) is not darker than
    what is round it: "a shadow" there would be lifted to glare, so it adds nothing."""
    img, parts = _slope()
    img[65:75, 60:72] = SNOW  # a sun fleck in the snow's shadow
    sky = parts["sky"]
    p = photo_shadow_probability(img, sky)
    fleck = ShadowEdit(66 / W, 70 / H, shadow=True)
    assert not shadow_edit_region(p, img, sky, fleck).any()
    inside = ShadowEdit(45 / W, 85 / H, shadow=True)  # the shadow itself, fleck excluded
    region = shadow_edit_region(p, img, sky, inside)
    assert region[parts["shadow"]].mean() > 0.8 and region[65:75, 60:72].mean() < 0.1


def test_dropping_edits_that_changed_nothing_redoes_nothing() -> None:
    img, parts = _slope()
    depth = np.full((H, W), 10.0, np.float32)
    depth[parts["sky"]] = np.inf
    s = RelightSession(mode="classic", preset="fast")
    s.set_image(img, depth=depth)
    s.set_original_sun((0.3, -0.5, 0.8))
    useful = (ShadowEdit(*_centre(parts["shadow"]), shadow=True),)
    s.set_shadow_edits((*useful, ShadowEdit(0.5, 0.05, shadow=True)))  # the second: the sky
    assert s.shadow_edits_used == (True, False)
    kept = s.deshadow()
    s.set_shadow_edits(useful)
    assert s.shadow_edits == useful and s.shadow_edits_used == (True,)
    assert s.deshadow() is kept  # not made again
