"""The user's corrections of the found shadows (``ShadowEdit``: "a shadow" / "not a shadow").

The scene is the ski-slope sample's failure in small: bright snow, a wide shadow on it, and a
large dark material (pines). One threshold calls the pines shadow and the shaded snow lit.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from outcast_core.runtime.pipeline.photo_shadows import (
    LIFT_ABOVE_LIT,
    MAX_BRUSH_RADIUS,
    MAX_SHADOW_CLICKS,
    MAX_SHADOW_EDITS,
    NOT_SHADOW_LEVEL,
    PICK_RADIUS,
    SHADE_SHIFT,
    ShadowEdit,
    apply_edit_masks,
    deshadow,
    photo_shadow_probability,
    shadow_edit_masks,
    shadow_edit_region,
    shadow_edit_strokes,
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


def _slope_depth(parts: dict[str, np.ndarray]) -> np.ndarray:
    depth = np.full((H, W), 10.0, np.float32)
    depth[parts["sky"]] = np.inf
    return depth


def _slope_session(image: np.ndarray | None = None
                   ) -> tuple[RelightSession, dict[str, np.ndarray]]:
    """A classic-mode session on the slope (or on ``image``, the slope at another size) with
    its sun confirmed, and the slope's parts."""
    img, parts = _slope()
    s = RelightSession(mode="classic", preset="fast")
    s.set_image(img if image is None else image, depth=_slope_depth(parts))
    s.set_original_sun((0.3, -0.5, 0.8))
    return s, parts


def _slope_files(tmp_path: Path) -> tuple[Path, Path, dict[str, np.ndarray]]:
    """The slope and its depth map written for the command line, and its parts."""
    from outcast_core.runtime.io import imageio

    img, parts = _slope()
    photo, dpath = tmp_path / "slope.png", tmp_path / "d.npy"
    imageio.write_image(photo, img)
    imageio.write_depth(dpath, _slope_depth(parts))
    return photo, dpath, parts


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

    photo, dpath, parts = _slope_files(tmp_path)
    x, y = _centre(parts["shadow"])
    base = ["deshadow", str(photo), "--from", "20,30", "--depth", str(dpath), "-q", "--force"]
    assert main([*base, "-o", str(tmp_path / "a.png"), "--mask", str(tmp_path / "a_m.png")]) == 0
    assert main([*base, "-o", str(tmp_path / "b.png"), "--mask", str(tmp_path / "b_m.png"),
                 "--not-shadow", "0.5,0.2", "--shadow", f"{x},{y}"]) == 0
    plain, fixed = (imageio.read_shadow_png(tmp_path / f"{k}_m.png") for k in "ab")
    # The mask is what the de-shadow lifts: the pines, found as shadow, are near black and
    # green beside the snow, so lifted only in part (about 0.2), and not at all once dropped.
    assert plain[parts["pines"]].mean() > 0.1 and fixed[parts["pines"]].max() < 0.01
    assert plain[parts["shadow"]].mean() < 0.1 and fixed[parts["shadow"]].mean() > 0.9
    lifted = imageio.read_image(tmp_path / "b.png").image_srgb
    assert lifted[parts["shadow"]].mean() > 1.6 * _slope()[0][parts["shadow"]].mean()
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

    # A geometry that predicts no shadow anywhere near.
    monkeypatch.setattr(session_module, "near_predicted_shadow",
                        lambda prior, sky, radius: np.zeros(np.shape(sky), np.float32))
    s, parts = _slope_session()
    shape = s.image_srgb.shape[:2]
    work = cv2.resize(parts["shadow"].astype(np.uint8), shape[::-1],
                      interpolation=cv2.INTER_NEAREST) > 0
    before = s._lift_guard(shape)
    s.set_shadow_edits([ShadowEdit(*_centre(parts["shadow"]), shadow=True)])
    after = s._lift_guard(shape)
    assert before is not None and after is not None
    assert before[work].max() == 0.0 and after[work].mean() > 0.95


def test_every_de_shadow_takes_the_marked_shadow_at_its_own_size(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The export's de-shadow (working and detail size) and the relighting's lift base are
    told what the user marked as shadow, at their size and off the sky, so that neither
    weakens it as another material than the lit surface round it."""
    from outcast_core.runtime.pipeline import session as session_module

    seen: list[tuple[tuple[int, int], np.ndarray | None]] = []
    bounds: list[float | None] = []
    real = session_module.deshadow

    def spy(img, p, sky, shift=SHADE_SHIFT, marked=None, above_lit=LIFT_ABOVE_LIT,
            lifted=None):
        seen.append((p.shape, marked))
        bounds.append(above_lit)
        return real(img, p, sky, shift, marked, above_lit, lifted)

    monkeypatch.setattr(session_module, "deshadow", spy)
    monkeypatch.setattr(session_module, "DETAIL_SIDE", 4 * max(H, W))
    s, parts = _slope_session(cv2.resize(_slope()[0], (4 * W, 4 * H),
                                         interpolation=cv2.INTER_NEAREST))
    s.deshadow()
    assert seen[-1][1] is None  # nothing marked
    s.set_shadow_edits([ShadowEdit(*_centre(parts["shadow"]), shadow=True)])
    s.deshadow()
    s.deshadow_full()
    s._lift_inputs(s.image_srgb.shape[:2])
    sizes = set()
    for shape, marked in seen[1:]:
        assert marked is not None and marked.shape == shape
        truth = cv2.resize(parts["shadow"].astype(np.uint8), shape[::-1],
                           interpolation=cv2.INTER_NEAREST) > 0
        on = marked > 0.5  # a clicked region's cover: 1, its edge smooth at other sizes
        assert (on & truth).sum() > 0.8 * truth.sum()
        assert not (on & ~cv2.dilate(truth.astype(np.uint8), np.ones((5, 5)))).any()
        sizes.add(shape)
    assert len(sizes) == 2  # the working size and the detail size
    # The exports' lifts are bounded (sun flecks), the relighting's base is not (its texture).
    assert bounds[-1] is None and set(bounds[:-1]) == {LIFT_ABOVE_LIT}


def test_marked_share_is_the_surface_the_user_s_marks_cover() -> None:
    """:meth:`RelightSession.marked_share`: the share of the photo the "Mark shadow" regions
    cover at the working size; "not a shadow" adds nothing to it."""
    s, parts = _slope_session()
    assert s.marked_share() == 0.0
    s.set_shadow_edits((ShadowEdit(0.5, 0.2, False),))  # the pines: dropped, not marked
    assert s.marked_share() == 0.0
    mark = (ShadowEdit(*_centre(parts["shadow"]), shadow=True),)
    measured = s.marked_share(mark)  # other corrections, measured without applying them
    assert s.shadow_edits == (ShadowEdit(0.5, 0.2, False),)
    s.set_shadow_edits(mark)
    assert s.marked_share() == measured and s.marked_share(()) == 0.0
    sky = s.sky
    shadow = cv2.resize(parts["shadow"].astype(np.uint8), sky.shape[::-1],
                        interpolation=cv2.INTER_NEAREST) > 0
    expected = float(shadow.mean())
    assert 0.8 * expected < s.marked_share() < 1.3 * expected
    s.set_shadow_edits(())
    assert s.marked_share() == 0.0


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
    s, parts = _slope_session()
    useful = (ShadowEdit(*_centre(parts["shadow"]), shadow=True),)
    s.set_shadow_edits((*useful, ShadowEdit(0.5, 0.05, shadow=True)))  # the second: the sky
    assert s.shadow_edits_used == (True, False)
    kept = s.deshadow()
    s.set_shadow_edits(useful)
    assert s.shadow_edits == useful and s.shadow_edits_used == (True,)
    assert s.deshadow() is kept  # not made again


# ---------------------------------------------------------------- the brush (radius > 0)


def _disc(shape: tuple[int, int], x: float, y: float, radius: float) -> np.ndarray:
    """The pixels whose centres lie within ``radius`` (fraction of the longer side) of the
    point, give or take the rasterizer's half pixel."""
    h, w = shape
    rows, cols = np.mgrid[0:h, 0:w]
    return np.hypot(cols + 0.5 - x * w, rows + 0.5 - y * h) <= radius * max(h, w)


def test_a_not_a_shadow_dab_drops_the_found_shadow_inside_its_disc_only() -> None:
    """The tree line is one found region across the frame: a click drops it whole, a dab only
    what lies under it (a shadow joined to a dark object keeps the rest)."""
    img, parts = _slope()
    sky = parts["sky"]
    p = photo_shadow_probability(img, sky)
    dab = ShadowEdit(0.5, 26 / H, shadow=False, radius=0.05)
    used: list[bool] = []
    added, dropped = shadow_edit_masks(p, img, sky, [dab], used)
    assert used == [True] and not added.any()
    inside = _disc((H, W), dab.x, dab.y, dab.radius - 1 / W)
    near = _disc((H, W), dab.x, dab.y, dab.radius + 1 / W)
    found = (p > 0.5) & ~sky
    assert dropped[inside & found].all() and not dropped[~near].any()
    out, not_shadow = apply_edit_masks(p, sky, added, dropped)
    assert out[inside].max() < 0.01 and not_shadow[inside & found].all()
    # The tree line beyond the disc (and its soft edge) is still found.
    beyond = parts["pines"] & ~_disc((H, W), dab.x, dab.y, dab.radius + 4 / W)
    assert out[beyond].mean() > 0.9 and not not_shadow[beyond].any()
    click, _ = apply_shadow_edits(p, img, sky, [ShadowEdit(dab.x, dab.y, shadow=False)])
    assert click[beyond].mean() < 0.05  # what a click does: the whole region
    # On lit snow, far from any found shadow: nothing, and said so.
    used = []
    none = shadow_edit_masks(p, img, sky, [ShadowEdit(0.9, 0.95, False, radius=0.03)], used)
    assert used == [False] and not none[0].any() and not none[1].any()


def _line(x0: float, x1: float, y: float, shadow: bool, radius: float) -> list[ShadowEdit]:
    """A straight stroke from ``x0`` to ``x1`` at height ``y``, a dab every half radius (as
    the app lays them)."""
    n = max(2, round(abs(x1 - x0) * W / (0.5 * radius * W)) + 1)
    return [ShadowEdit(float(x), y, shadow, radius) for x in np.linspace(x0, x1, n)]


def test_a_shadow_stroke_adds_only_the_shadow_under_it() -> None:
    """The slope's shadow is missed (the pines set the threshold). A "Mark shadow" stroke
    across its edge adds the shadow under it, not the lit snow it crossed (which the lift
    brightened into hard-edged discs of glare: a user trial); one inside the shadow adds its
    whole area; one on lit snow alone adds nothing and says so, as a click there."""
    img, parts = _slope()
    sky, shadow = parts["sky"], parts["shadow"]
    p = photo_shadow_probability(img, sky)
    assert p[shadow].mean() < 0.2  # missed
    across = _line(25 / W, 60 / W, 72 / H, True, 0.05)  # lit snow, then the shadow's edge
    under = np.zeros((H, W), bool)
    for dab in across:
        under |= _disc((H, W), dab.x, dab.y, dab.radius - 1 / W)
    used: list[bool] = []
    added, dropped = shadow_edit_masks(p, img, sky, across, used)
    assert used == [True] * len(across) and not dropped.any()
    assert added[under & shadow].all()
    assert not added[~shadow].any()  # not one pixel of lit snow
    out, _ = apply_edit_masks(p, sky, added, dropped)
    lit = under & ~shadow
    lit[:, 36:] = False  # (beyond the soft edge)
    core, rim = np.zeros((H, W), bool), under.copy()
    for dab in across:  # full strength within half a radius of the stroke's line
        core |= _disc((H, W), dab.x, dab.y, 0.4 * dab.radius)
        rim &= ~_disc((H, W), dab.x, dab.y, 0.7 * dab.radius)
    assert out[core & shadow].min() > 0.99 and out[lit].max() < 0.05
    # A soft brush: where the stroke ends inside the shadow, it fades out.
    assert out[rim & shadow].min() < 0.5 and added[rim & shadow].max() < 0.6
    # Inside the shadow: one even surface, darker than the snow round it: all of it.
    inside = _line(55 / W, 85 / W, 72 / H, True, 0.04)
    added, _ = shadow_edit_masks(p, img, sky, inside)
    assert added[_disc((H, W), 70 / W, 72 / H, 0.03)].all() and not added[~shadow].any()
    # On lit snow alone (beside the shadow, and far from it): nothing, every dab unused.
    for lit in (_line(104 / W, 124 / W, 72 / H, True, 0.04),
                _line(20 / W, 100 / W, 93 / H, True, 0.02),
                [ShadowEdit(0.85, 0.7, shadow=True, radius=0.04)]):
        used = []
        added, dropped = shadow_edit_masks(p, img, sky, lit, used)
        assert used == [False] * len(lit) and not added.any() and not dropped.any()
    # Across the sky's edge (the pines under it: one dark surface): never the sky; on the
    # sky alone: nothing.
    edge = ShadowEdit(0.5, 12 / H, shadow=True, radius=0.05)
    added, _ = shadow_edit_masks(p, img, sky, [edge])
    assert added.any() and not added[sky].any()
    used = []
    added, _ = shadow_edit_masks(p, img, sky, [ShadowEdit(0.5, 0.03, True, radius=0.02)], used)
    assert used == [False] and not added.any()


def test_a_stroke_is_decided_as_a_whole() -> None:
    """The shadow under a stroke is found for the stroke as a whole (its dabs alone may each
    lie on one side of the edge): every dab of it changed something, or none did."""
    img, parts = _slope()
    sky, shadow = parts["sky"], parts["shadow"]
    p = photo_shadow_probability(img, sky)
    across = _line(20 / W, 60 / W, 72 / H, True, 0.03)
    used: list[bool] = []
    added, _ = shadow_edit_masks(p, img, sky, across, used)
    assert used == [True] * len(across) and not added[~shadow].any()
    # Alone, its first dab lies on lit snow: refused.
    used = []
    alone = shadow_edit_masks(p, img, sky, across[:1], used)
    assert used == [False] and not alone[0].any() and not alone[1].any()
    # Painted again over what is painted: changes nothing (and is said so). (Begun where the
    # first ended, it would be one stroke with it: shadow_edit_strokes.)
    used = []
    again = shadow_edit_masks(p, img, sky, [*across, *across], used)
    assert used == [True] * len(across) + [False] * len(across)
    assert (again[0] == added).all()


def test_not_a_shadow_paints_the_probability_to_zero_in_the_whole_disc() -> None:
    """A dab drops all of its disc, weak probability too (0.1-0.45 stayed: a pink tint on the
    overlay and some lift in the export, a user trial on a lattice facade); one whose disc
    holds nothing above NOT_SHADOW_LEVEL changes nothing."""
    img, parts = _slope()
    sky = parts["sky"]
    p = np.zeros((H, W), np.float32)
    p[50:70, 20:60] = 0.3  # a weakly found, fragmented facade
    p[55:60, 25:30] = 0.9
    p[80:90, 100:120] = NOT_SHADOW_LEVEL  # a faint haze, not seen on the overlay
    dab = ShadowEdit(40 / W, 60 / H, shadow=False, radius=0.1)
    used: list[bool] = []
    added, dropped = shadow_edit_masks(p, img, sky, [dab], used)
    inside = _disc((H, W), dab.x, dab.y, dab.radius - 1 / W)
    assert used == [True] and dropped[inside].all() and not added.any()
    out, not_shadow = apply_edit_masks(p, sky, added, dropped)
    assert out[inside].max() == 0.0 and not_shadow[inside].all()
    # Beyond the disc and its soft edge: as found.
    beyond = ~_disc((H, W), dab.x, dab.y, dab.radius + 4 / W)
    assert np.allclose(out[beyond], p[beyond])
    # On the faint haze (and on lit snow): nothing; the next dab of a stroke over dropped
    # ground changes nothing either.
    used = []
    faint = ShadowEdit(110 / W, 85 / H, shadow=False, radius=0.03)
    again = ShadowEdit(41 / W, 60 / H, shadow=False, radius=0.03)
    masks = shadow_edit_masks(p, img, sky, [dab, faint, again], used)
    assert used == [True, False, False] and (masks[1] == dropped).all()


def test_dabs_paint_into_the_masks_in_order() -> None:
    """A "not a shadow" dab clears what was added under it and drops the found shadow there;
    a "Mark shadow" stroke adds the shadow under it (here its whole disc: the pines are one
    dark surface) and takes back what was dropped there; a "not a shadow" click on a painted
    area takes that painted area back."""
    img, parts = _slope()
    sky = parts["sky"]
    p = photo_shadow_probability(img, sky)
    x, y = _centre(parts["shadow"])
    fill = ShadowEdit(x, y, shadow=True)  # a click: the whole shadow
    rub = ShadowEdit(x, y, shadow=False, radius=0.05)
    disc = _disc((H, W), x, y, 0.05 - 1 / W)
    used: list[bool] = []
    added, _ = shadow_edit_masks(p, img, sky, [fill, rub], used)
    assert used == [True, True]
    outside = parts["shadow"] & ~_disc((H, W), x, y, 0.07)
    assert not added[disc].any() and added[outside].mean() > 0.95
    # The other way round the dab comes first and the click adds the whole shadow.
    added, _ = shadow_edit_masks(p, img, sky, [rub, fill])
    assert added[parts["shadow"]].mean() > 0.97
    # Dropped pines painted back as shadow: no longer dropped there, added instead.
    pine = ShadowEdit(0.3, 26 / H, shadow=False, radius=0.05)
    back = ShadowEdit(0.3, 26 / H, shadow=True, radius=0.03)
    inner = _disc((H, W), 0.3, 26 / H, 0.03 - 1 / W)
    added, dropped = shadow_edit_masks(p, img, sky, [pine, back])
    core = _disc((H, W), 0.3, 26 / H, 0.4 * 0.03)  # where the soft dab works at full strength
    assert added[inner].all() and not dropped[core].any()
    # Under its faint rim the drop stays and the cover fades in over it: no hard edge at full
    # strength out to the footprint's edge (a review).
    rim = inner & ~_disc((H, W), 0.3, 26 / H, 0.7 * 0.03)
    assert dropped[rim].all() and added[rim].max() < 0.5
    out, _ = apply_edit_masks(p, sky, added, dropped)
    assert out[core].min() > 0.99 and out[rim].min() < 0.9
    assert dropped[_disc((H, W), 0.3, 26 / H, 0.05 - 1 / W) & ~_disc((H, W), 0.3, 26 / H, 0.04)
                   ].all()
    # Two strokes painted in the shadow; a "not a shadow" click on one takes that one back.
    left = _line(45 / W, 52 / W, 72 / H, True, 0.02)
    right = _line(85 / W, 92 / W, 72 / H, True, 0.02)
    used = []
    added, _ = shadow_edit_masks(p, img, sky, [*left, *right, ShadowEdit(48 / W, 72 / H, False)],
                                 used)
    assert all(used) and added[:, 80:].any() and not added[:, :60].any()


def test_leaving_out_the_dabs_that_changed_nothing_gives_the_same_masks() -> None:
    """What the session counts on when the app takes back a stroke that changed nothing (a
    "not a shadow" dab is decided alone, after the ones before it; a "Mark shadow" stroke as
    a whole: all its dabs changed something or none did)."""
    rng = np.random.default_rng(3)
    img, parts = _slope()
    sky = parts["sky"]
    p = photo_shadow_probability(img, sky)
    for _ in range(6):
        edits = []
        for _ in range(40):  # clicks, and strokes of 1-8 dabs half a radius apart
            x, y = rng.random(2)
            radius = 0.0 if rng.random() < 0.15 else float(rng.choice([0.01, 0.03, 0.08]))
            shadow, angle = bool(rng.random() < 0.5), rng.random() * 2 * np.pi
            for k in range(1 if radius == 0 else int(rng.integers(1, 9))):
                step = 0.5 * radius * k
                at = np.clip([x + step * np.cos(angle), y + step * np.sin(angle) * W / H], 0, 1)
                edits.append(ShadowEdit(float(at[0]), float(at[1]), shadow, radius))
        used: list[bool] = []
        masks = shadow_edit_masks(p, img, sky, edits, used)
        assert len(used) == len(edits) and 0 < sum(used) < len(edits)
        for start, stop in shadow_edit_strokes(edits, (H, W)):
            if edits[start].shadow:
                assert len(set(used[start:stop])) == 1
        kept = [e for e, u in zip(edits, used, strict=True) if u]
        again = shadow_edit_masks(p, img, sky, kept)
        assert all(np.array_equal(a, b) for a, b in zip(masks, again, strict=True))


def test_thousands_of_dabs_each_paint_their_disc() -> None:
    """A stroke is hundreds of dabs and a project may hold thousands, each run of them drawn
    into one window of the photo (the time: ``benchmarks/bench_runtime.py --only brush``):
    2000 "not a shadow" dabs in ten strokes over a photo found all shadow drop their discs,
    each something new, and nothing beyond them."""
    h, w = 384, 512  # dabs 2.3 px apart, less than half their radius (5.1 px), as the app's
    p, sky = np.ones((h, w), np.float32), np.zeros((h, w), bool)
    img = np.full((h, w, 3), 0.5, np.float32)
    edits = [ShadowEdit(0.05 + 0.9 * (i % 200) / 199, 0.05 + 0.1 * (i // 200), False,
                        radius=0.01, start=i % 200 == 0) for i in range(2000)]
    used: list[bool] = []
    added, dropped = shadow_edit_masks(p, img, sky, edits, used)
    assert len(used) == 2000 and all(used) and not added.any()
    # Each stroke's discs: within a radius of its line (give or take a pixel).
    rows, cols = np.mgrid[0:h, 0:w] + 0.5
    near = np.full((h, w), np.inf)
    for k in range(10):
        x0, x1, y = 0.05 * w, 0.95 * w, (0.05 + 0.1 * k) * h
        near = np.minimum(near, np.hypot(np.maximum(np.maximum(x0 - cols, cols - x1), 0),
                                         rows - y))
    assert dropped[near <= 0.01 * w - 1].all() and not dropped[near > 0.01 * w + 1].any()
    assert shadow_edit_strokes(edits, (h, w)) == [(k, k + 200) for k in range(0, 2000, 200)]


def test_strokes_are_counted_as_the_user_made_them() -> None:
    stroke = [ShadowEdit(0.1 + 0.01 * i, 0.5, False, radius=0.02) for i in range(30)]
    other = [ShadowEdit(0.1 + 0.01 * i, 0.8, False, radius=0.02) for i in range(30)]
    click = ShadowEdit(0.5, 0.5, True)
    edits = [*stroke, click, click, *stroke, *other]
    assert shadow_edit_strokes(edits, (H, W)) == [(0, 30), (30, 31), (31, 32), (32, 62),
                                                  (62, 92)]
    # Another kind or size starts another stroke, wherever it starts.
    marked = [ShadowEdit(e.x, e.y, True, e.radius) for e in stroke]
    assert len(shadow_edit_strokes([*stroke, *marked], (H, W))) == 2
    assert shadow_edit_strokes([], (H, W)) == []


def _started(dabs: list[ShadowEdit]) -> list[ShadowEdit]:
    """A stroke as the app makes it: its first dab marked as its start."""
    return [replace(e, start=k == 0) for k, e in enumerate(dabs)]


def test_a_stroke_retraced_from_where_the_last_ended_is_another() -> None:
    """Unmarked, a stroke begun where the one before of its kind and size ended counted with
    it: a stroke painted back over the last one was never taken back as changing nothing,
    the panel said "1 correction" for two undo steps, and the two were decided as one. The
    app marks each stroke's first dab; a marked stroke holds its dabs wherever they lie (one
    that leaves the photo and comes back)."""
    img, parts = _slope()
    sky = parts["sky"]
    p = photo_shadow_probability(img, sky)
    there = _started(_line(55 / W, 85 / W, 72 / H, True, 0.04))  # inside the missed shadow
    back = _started(there[::-1])
    assert shadow_edit_strokes([*there, *back], (H, W)) == [(0, len(there)),
                                                            (len(there), 2 * len(there))]
    unmarked = [replace(e, start=False) for e in [*there, *back]]
    assert shadow_edit_strokes(unmarked, (H, W)) == [(0, 2 * len(there))]  # (as before)
    used: list[bool] = []
    masks = shadow_edit_masks(p, img, sky, [*there, *back], used)
    assert used == [True] * len(there) + [False] * len(back)  # the second: taken back
    again = shadow_edit_masks(p, img, sky, there)
    assert all(np.array_equal(a, b) for a, b in zip(masks, again, strict=True))
    # One stroke that left the photo (no dabs there) and came back further on.
    gap = _started([*_line(45 / W, 55 / W, 72 / H, True, 0.02),
                    *_line(80 / W, 90 / W, 72 / H, True, 0.02)])
    assert shadow_edit_strokes(gap, (H, W)) == [(0, len(gap))]
    # Read back from a project as written (the points rounded to 5 decimals).
    read = shadow_edits_from_json(shadow_edits_to_json([*there, *back]))
    assert shadow_edit_strokes(read, (H, W)) == shadow_edit_strokes([*there, *back], (H, W))


def test_a_mark_shadow_stroke_inside_a_clicked_region_changes_nothing() -> None:
    """A "Mark shadow" click adds the missed shadow; a stroke inside it afterwards adds
    nothing new (the masks are the same), so the app takes it back and says so; it was
    counted as used (only painted areas were taken for added)."""
    img, parts = _slope()
    sky = parts["sky"]
    p = photo_shadow_probability(img, sky)
    click = ShadowEdit(*_centre(parts["shadow"]), shadow=True)
    stroke = _started(_line(55 / W, 85 / W, 72 / H, True, 0.04))
    used: list[bool] = []
    masks = shadow_edit_masks(p, img, sky, [click, *stroke], used)
    assert used == [True] + [False] * len(stroke)
    alone = shadow_edit_masks(p, img, sky, [click])
    assert all(np.array_equal(a, b) for a, b in zip(masks, alone, strict=True))
    # Left out or not, a "not a shadow" click in it later takes back the same.
    take = ShadowEdit(70 / W, 72 / H, shadow=False)
    with_it = shadow_edit_masks(p, img, sky, [click, *stroke, take])
    without = shadow_edit_masks(p, img, sky, [click, take])
    assert all(np.array_equal(a, b) for a, b in zip(with_it, without, strict=True))


def test_shadow_edit_region_is_for_clicks_only() -> None:
    """A dab's effect depends on its stroke and the edits before it: shadow_edit_masks
    paints dabs (shadow_edit_region's own answer for one differed from it)."""
    img, parts = _slope()
    p = photo_shadow_probability(img, parts["sky"])
    with pytest.raises(ValueError, match="expected a click"):
        shadow_edit_region(p, img, parts["sky"], ShadowEdit(0.5, 0.3, False, radius=0.02))


def test_a_dab_s_radius_is_checked_and_round_trips_through_a_project() -> None:
    dabs = (ShadowEdit(0.25, 0.5, False, radius=0.02), ShadowEdit(0.3, 0.5, True, 0.123456789),
            ShadowEdit(0.5, 0.5, True), ShadowEdit(0.1, 0.1, False, radius=MAX_BRUSH_RADIUS))
    data = shadow_edits_to_json(dabs)
    assert data[0] == {"x": 0.25, "y": 0.5, "shadow": False, "r": 0.02}
    assert "r" not in data[2]  # a click is written as before brushes existed
    back = shadow_edits_from_json(data)
    assert back[0] == dabs[0] and back[2] == dabs[2] and back[3] == dabs[3]
    assert back[1].radius == pytest.approx(dabs[1].radius, rel=1e-4)
    tiny = shadow_edits_from_json(shadow_edits_to_json([ShadowEdit(0.5, 0.5, False, 1e-9)]))
    assert tiny[0].radius > 0  # never rounded to a click
    # An older file (no "r") reads as clicks.
    assert shadow_edits_from_json([{"x": 0.2, "y": 0.4, "shadow": True}]) == (
        ShadowEdit(0.2, 0.4, True, 0.0),)
    for radius in (-0.01, MAX_BRUSH_RADIUS + 0.01, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="brush radius"):
            ShadowEdit(0.5, 0.5, False, radius)
    for bad, words in [([{"x": 0.1, "y": 0.2, "shadow": True, "r": 0.5}], "brush radius"),
                       ([{"x": 0.1, "y": 0.2, "shadow": True, "r": -1}], "brush radius"),
                       ([{"x": 0.1, "y": 0.2, "shadow": True, "r": "0.1"}], "numbers"),
                       ([{"x": 0.1, "y": 0.2, "shadow": True, "r": True}], "numbers"),
                       ([{"x": 0.1, "y": 0.2, "shadow": True, "r": None}], "numbers"),
                       ([{"x": 0.1, "y": 0.2, "shadow": True, "r": 10**400}], "too large")]:
        with pytest.raises(ValueError, match=words):
            shadow_edits_from_json(bad)
    # A stroke's start round-trips; "start" is written for it only, and checked on reading.
    stroke = (ShadowEdit(0.2, 0.5, True, 0.02, start=True), ShadowEdit(0.21, 0.5, True, 0.02))
    data = shadow_edits_to_json(stroke)
    assert data[0]["start"] is True and "start" not in data[1]
    assert shadow_edits_from_json(data) == stroke
    assert repr(stroke[0]).endswith("radius=0.02, start=True)")
    assert repr(ShadowEdit(0.5, 0.5, True)) == "ShadowEdit(x=0.5, y=0.5, shadow=True)"
    for bad, words in [([{"x": 0.1, "y": 0.2, "shadow": True, "r": 0.1, "start": 1}],
                        "true/false"),
                       ([{"x": 0.1, "y": 0.2, "shadow": True, "r": 0.1, "start": "yes"}],
                        "true/false"),
                       ([{"x": 0.1, "y": 0.2, "shadow": True, "r": 0.1, "start": None}],
                        "true/false"),
                       ([{"x": 0.1, "y": 0.2, "shadow": True, "start": True}], "for a click")]:
        with pytest.raises(ValueError, match=words):
            shadow_edits_from_json(bad)
    with pytest.raises(ValueError, match="for a click"):
        ShadowEdit(0.5, 0.5, True, start=True)


def test_a_project_holds_at_most_so_many_clicks_and_edits() -> None:
    """Strokes need many edits, clicks few, and a click costs far more (20000 of them took
    30-47 s to apply, again at every later edit): two limits, each said by name."""
    dab = {"x": 0.1, "y": 0.2, "shadow": True, "r": 0.01}
    click = {"x": 0.1, "y": 0.2, "shadow": True}
    fine = [click] * MAX_SHADOW_CLICKS + [dab] * (MAX_SHADOW_EDITS - MAX_SHADOW_CLICKS)
    assert len(shadow_edits_from_json(fine)) == MAX_SHADOW_EDITS
    with pytest.raises(ValueError, match=f"at most {MAX_SHADOW_CLICKS} clicks"):
        shadow_edits_from_json([click] * (MAX_SHADOW_CLICKS + 1))
    with pytest.raises(ValueError, match=f"at most {MAX_SHADOW_EDITS} shadow edits"):
        shadow_edits_from_json([dab] * (MAX_SHADOW_EDITS + 1))


def test_session_takes_strokes_and_drops_one_that_changed_nothing_without_redoing() -> None:
    s, parts = _slope_session()
    found = s.shadow_probability.copy()
    h, w = found.shape
    stroke = tuple(ShadowEdit(0.3 + 0.01 * i, 26 / H, False, radius=0.03) for i in range(20))
    s.set_shadow_edits(stroke)
    assert s.shadow_edits_used == (True,) * 20
    row = round(26 / H * h)
    assert s.shadow_probability[row, round(0.4 * w)] < 0.01  # under the stroke: dropped
    assert s.shadow_probability[row, round(0.9 * w)] > 0.9  # the tree line beyond it: kept
    idle = tuple(ShadowEdit(0.2 + 0.01 * i, 0.04, True, radius=0.02) for i in range(10))  # sky
    kept, detail = s.deshadow(), s.found_shadows_detail()
    s.set_shadow_edits((*stroke, *idle))
    assert s.shadow_edits_used == (True,) * 20 + (False,) * 10
    # A stroke that changed nothing redoes nothing either (in "Shadows removed" the
    # full-resolution de-shadow was made again for it).
    assert s.deshadow() is kept and s.found_shadows_detail() is detail
    s.set_shadow_edits(stroke)  # the app takes the idle stroke back: nothing to redo
    assert s.shadow_edits == stroke and s.shadow_edits_used == (True,) * 20
    assert s.deshadow() is kept


def test_cli_takes_a_brush_dab_as_x_y_r(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    from outcast_core.runtime.cli.main import main, parse_shadow_edit
    from outcast_core.runtime.io import imageio

    assert parse_shadow_edit("0.5,0.2,0.05", shadow=False) == ShadowEdit(0.5, 0.2, False, 0.05)
    assert parse_shadow_edit("0.5,0.2", shadow=True) == ShadowEdit(0.5, 0.2, True)
    photo, dpath, parts = _slope_files(tmp_path)
    base = ["deshadow", str(photo), "--from", "20,30", "--depth", str(dpath), "-q", "--force"]
    assert main([*base, "-o", str(tmp_path / "a.png"), "--mask", str(tmp_path / "a_m.png")]) == 0
    assert main([*base, "-o", str(tmp_path / "b.png"), "--mask", str(tmp_path / "b_m.png"),
                 "--not-shadow", f"0.5,{26 / H},0.05"]) == 0
    plain, mask = (imageio.read_shadow_png(tmp_path / f"{k}_m.png") for k in "ab")
    dab = _disc((H, W), 0.5, 26 / H, 0.04)
    beyond = parts["pines"] & ~_disc((H, W), 0.5, 26 / H, 0.09)
    # What is lifted (the pines: in part) is gone under the dab and as it was beyond it.
    assert plain[dab].min() > 0.1 and mask[dab].max() < 0.05
    assert plain[beyond].mean() > 0.1
    assert np.abs(mask[beyond] - plain[beyond]).mean() < 0.02
    capsys.readouterr()
    assert main([*base[:-2], "--force", "-o", str(tmp_path / "e.png"),
                 "--not-shadow", "0.9,0.95,0.02"]) == 0
    assert "note: --not-shadow 0.9,0.95,0.02 changed nothing (no found shadow within R" in (
        capsys.readouterr().err)
    # Noted and counted per stroke, as the app counts them (it was per dab).
    on_pines = [f"{0.3 + 0.02 * k},{26 / H},0.03" for k in range(3)]
    on_snow = [f"{0.85 + 0.01 * k:g},0.95,0.02" for k in range(3)]
    assert main([*base[:-2], "--force", "-o", str(tmp_path / "f.png"),
                 *(a for dab in [*on_pines, *on_snow] for a in ("--not-shadow", dab))]) == 0
    err = capsys.readouterr().err
    assert err.count("note:") == 1 and (
        "note: --not-shadow 0.85,0.95,0.02 and the 2 dabs after it (a stroke) changed nothing "
        "(no found shadow within R") in err
    assert "(128x96; 1 shadow correction; " in err
    for bad, words in [("0.5,0.5,0.3", "brush radius R"), ("0.5,0.5,-0.1", "brush radius R"),
                       ("0.5,0.5,nan", "brush radius R"), ("0.5,0.5,big", "brush radius R"),
                       (f"0.5,0.5,{MAX_BRUSH_RADIUS + 0.01}", "brush radius R a fraction"),
                       ("0.5,0.5,0", "omit R for a click"), ("0.5,0.5,-0", "omit R"),
                       ("1.5,0.5,0.1", "X,Y,R with X,Y fractions 0-1"),
                       ("0.5,0.5,0.1,2", "or X,Y,R (a brush dab)"),
                       ("0.5", "or X,Y,R (a brush dab)")]:
        with pytest.raises(SystemExit) as info:
            main([*base, "-o", str(tmp_path / "d.png"), "--not-shadow", bad])
        assert info.value.code == 2
        err = capsys.readouterr().err
        assert "--not-shadow" in err and words in err and len(err.strip().splitlines()) == 1
        assert f"got {bad!r}" in err  # the whole value, R too
    # At most so many clicks (a click costs far more than a dab), with both flags together.
    with pytest.raises(SystemExit) as info:
        main([*base, "-o", str(tmp_path / "d.png"),
              *["--shadow", "0.5,0.5", "--not-shadow", "0.5,0.5"] * (MAX_SHADOW_CLICKS // 2),
              "--shadow", "0.5,0.5,0.02", "--shadow", "0.5,0.5"])
    assert info.value.code == 2
    assert f"at most {MAX_SHADOW_CLICKS} clicks" in capsys.readouterr().err


def test_timelapse_says_which_corrections_changed_nothing_and_counts_the_rest(
        tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """As ``relight`` and ``deshadow`` do."""
    from outcast_core.runtime.cli.main import main

    photo, dpath, parts = _slope_files(tmp_path)
    capsys.readouterr()
    assert main(["timelapse", str(photo), "--from", "20,30", "--depth", str(dpath), "--sweep",
                 "10,20:40,50", "--frames", "2", "--size", "working", "-o",
                 str(tmp_path / "t.gif"), "--shadow", "0.5,0.05", "--not-shadow", "0.5,0.2",
                 "--not-shadow", "0.9,0.95,0.02"]) == 0
    err = capsys.readouterr().err
    assert "note: --shadow 0.5,0.05 changed nothing (the sky" in err
    assert "note: --not-shadow 0.9,0.95,0.02 changed nothing (no found shadow within R" in err
    assert "note: --not-shadow 0.5,0.2 " not in err
    assert f"wrote 2 frames to {tmp_path / 't.gif'} (1 shadow correction)" in err


def test_the_learned_relighting_is_physics_where_the_user_marked_a_material(monkeypatch) -> None:
    """"Not a shadow" on the tree line (a dark material): the learned relighting takes
    physics' there (``guard_learned_relight``'s ``physics_at``), which follows the correction;
    ``L`` alone bleached the ski-slope sample's pines whatever the correction said (a user
    trial). Without the correction nothing is held."""
    import outcast_core.runtime.pipeline.session as session_module

    img, parts = _slope()
    s = RelightSession(preset="fast")
    s.set_image(img, depth=_slope_depth(parts))
    s.set_original_sun((0.3, -0.5, 0.8))
    assert s.relight_mode == "learned"
    seen = []
    real = session_module.guard_learned_relight

    def spy(*args, **kwargs):
        seen.append(kwargs.get("physics_at"))
        return real(*args, **kwargs)

    monkeypatch.setattr(session_module, "guard_learned_relight", spy)
    w_new = (-0.5, -0.4, 0.75)
    s.relight(w_new)
    assert seen and seen[-1] is None
    s.set_shadow_edits([ShadowEdit(0.5, 20 / H, shadow=False)])
    s.relight(w_new)
    held = seen[-1]
    assert held is not None and held.shape == s.image_srgb.shape[:2]
    inner = cv2.erode(parts["pines"].astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    size = held.shape[::-1]
    inner = cv2.resize(inner.astype(np.uint8), size, interpolation=cv2.INTER_NEAREST) > 0
    shadow = cv2.resize(parts["shadow"].astype(np.uint8), size,
                        interpolation=cv2.INTER_NEAREST) > 0
    assert held[inner & (np.arange(held.shape[1]) > 30)[None, :]].min() > 0.9
    assert held[shadow].max() < 0.05


def test_the_found_shadows_shown_are_what_the_de_shadow_lifts() -> None:
    """``lift_probability``: a thin dark stripe (a trunk's shadow the photometric stage finds
    at 0.4-0.5) is texture to the lift and is not lifted, so it is not shown as found either
    (the app tinted it and the lift left it dark: a user trial); a wide shadow is both; marked
    by the user, the stripe is both. The session's ``lifted_shadows`` is that of its own
    probability, and follows the corrections."""
    from outcast_core.runtime.pipeline.photo_shadows import lift_probability

    img, parts = _slope()
    sky = parts["sky"]
    img[70:90, 110:112] *= np.array([0.42, 0.45, 0.52], np.float32)  # a 2 px trunk's shadow
    p = photo_shadow_probability(img, sky)
    stripe = np.zeros((H, W), bool)
    stripe[72:88, 110:112] = True
    p[parts["shadow"] | stripe] = 0.9  # as if found (the pines set the threshold)
    lifted = lift_probability(img, p, sky)
    assert lifted[stripe].max() < 0.2
    inner = cv2.erode(parts["shadow"].astype(np.uint8), np.ones((9, 9), np.uint8)) > 0
    assert lifted[inner].min() > 0.5
    marked = np.zeros((H, W), np.float32)
    marked[70:90, 108:114] = 1.0
    assert lift_probability(img, p, sky, marked=marked)[stripe].min() > 0.5
    s, parts = _slope_session()
    before = s.lifted_shadows()
    np.testing.assert_array_equal(
        before, lift_probability(s.image_srgb, s.shadow_probability, s.sky))
    s.set_shadow_edits([ShadowEdit(*_centre(parts["shadow"]), shadow=True)])
    after = s.lifted_shadows()
    assert after[inner].mean() > before[inner].mean() + 0.3


def test_a_mark_counts_whole_where_the_soft_brush_works_at_full_strength() -> None:
    """The user's mark (what the de-shadow, the "Shadows found" tint and the lift's guard take
    at the user's word) counts as the probability does: whole within about half the brush's
    radius of the stroke's line (the dashed ring), fading beyond; the raw cover weighed it at
    half there (a review)."""
    s, parts = _slope_session()
    stroke = _line(55 / W, 85 / W, 72 / H, True, 0.04)
    s.set_shadow_edits(stroke)
    marked = s._marked(s.sky)
    core = np.zeros((H, W), bool)
    for dab in stroke:
        core |= _disc((H, W), dab.x, dab.y, 0.4 * dab.radius)
    cover = s._edit_masks[0]
    assert cover[core].min() < 0.99  # the raw cover is not whole there ...
    assert marked is not None and marked[core].min() > 0.99  # ... the mark is
    rim = (cover > 0) & (cover < 0.25)
    assert rim.any() and marked[rim].max() < 0.5  # and fades with the brush
    np.testing.assert_allclose(marked, np.clip(2 * cover, 0, 1), atol=1e-6)


# ---------------------------------------------------------------- the ski-slope trial (round 2)


def _trunk_and_its_shadow() -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """Snow, a tree line, a black trunk standing on the snow and its thin shadow running down
    from the trunk's base (missed: the trunk and the pines set the threshold), as the left
    tree on the ski slope; the image, the sky and the parts."""
    img, parts = _slope()
    img[12:40] = SNOW  # no tree line: the trunk alone
    parts["pines"][:] = False
    trunk = np.zeros((H, W), bool)
    trunk[20:60, 60:68] = True
    shadow = np.zeros((H, W), bool)
    shadow[60:96, 60:68] = True
    img[parts["shadow"]] = SNOW  # (the slope's own wide shadow is not here)
    img[trunk] = [0.03, 0.025, 0.02]
    img[shadow] *= np.array([0.42, 0.45, 0.52], np.float32)
    return img, parts["sky"], {"trunk": trunk, "shadow": shadow}


def test_a_stroke_down_a_shadow_from_its_trunk_adds_the_shadow_not_the_trunk() -> None:
    """A "Mark shadow" stroke begun on the black base of a trunk and drawn down its shadow
    on the snow: the stroke's darkest pixels are the trunk (found already), and taken for
    the shadow under the stroke, the trunk alone was added (160 pixels of the 1656 under
    the stroke on the ski slope, "1 correction" and nothing seen: a user trial). What is
    found already is left out of the stroke's split: it adds the shadow, whole along its
    line, and not the trunk."""
    img, sky, parts = _trunk_and_its_shadow()
    p = photo_shadow_probability(img, sky)
    assert p[24:56, 62:66].min() > 0.9 and p[parts["shadow"]].mean() < 0.1
    stroke = _started([ShadowEdit(64 / W, float(y) / H, True, 0.06)
                       for y in np.arange(54, 93, 3.8)])
    used: list[bool] = []
    added, dropped = shadow_edit_masks(p, img, sky, stroke, used)
    assert used == [True] * len(stroke) and not dropped.any()
    weight = np.clip(2 * added, 0, 1)
    line = parts["shadow"].copy()
    line[:, :62] = line[:, 66:] = False  # the middle of the shadow, along the stroke
    line[:62] = line[90:] = False
    assert weight[line].min() > 0.99
    assert weight[parts["trunk"] & (p > 0.5)].max() == 0.0  # a dark object found: not marked
    assert not added[~parts["shadow"] & ~parts["trunk"]].any()  # nor the lit snow


def test_a_stroke_over_a_shadow_shown_already_changes_nothing() -> None:
    """A "Mark shadow" stroke over a shadow that is found and lifted already (what "Shadows
    found" shows) changes (almost) nothing: it is said so and the app takes it back, not
    counted as a correction nobody can see."""
    rng = np.random.default_rng(5)
    img = np.clip(SNOW * (1 + 0.03 * rng.standard_normal((H, W, 1))), 0, 1).astype(np.float32)
    img[40:90, 30:100] *= np.array([0.42, 0.45, 0.52], np.float32)  # a wide shadow, found
    sky = np.zeros((H, W), bool)
    p = photo_shadow_probability(img, sky)
    from outcast_core.runtime.pipeline.photo_shadows import lift_probability

    inner = np.zeros((H, W), bool)
    inner[50:80, 40:90] = True
    assert lift_probability(img, p, sky)[inner].min() > 0.9
    inside = _started(_line(50 / W, 80 / W, 65 / H, True, 0.04))
    used: list[bool] = []
    added, _ = shadow_edit_masks(p, img, sky, inside, used)
    assert used == [False] * len(inside) and not added.any()


def _pylon_before_the_pines() -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """The slope with a black lift pylon standing before the tree line (joined to it, one
    found region with it and the trunk), darker than the pines."""
    img, parts = _slope()
    pylon = np.zeros((H, W), bool)
    pylon[16:88, 100:106] = True
    pylon[60:64, 94:112] = True  # its crossarm
    img[pylon] = [0.008, 0.008, 0.009]
    return img, parts["sky"], {**parts, "pylon": pylon}


def test_not_a_shadow_on_a_pylon_takes_the_pylon_not_the_pines_it_stands_before() -> None:
    """One found region joins a black pylon to the pines across the frame: a click on the
    pylon dropped them all (a user trial). It takes the part of the brightness clicked:
    the pylon, its rim with it; a click on the pines takes the pines and their trunk (of
    their brightness), not the pylon."""
    img, sky, parts = _pylon_before_the_pines()
    p = photo_shadow_probability(img, sky)
    found = (p > 0.5) & ~sky
    n, labels = cv2.connectedComponents(found.astype(np.uint8), connectivity=8)
    assert labels[70, 103] == labels[25, 30] == labels[50, 15]  # one region
    pylon = shadow_edit_region(p, img, sky, ShadowEdit(103 / W, 75 / H, shadow=False))
    assert (pylon & parts["pylon"]).sum() > 0.95 * (parts["pylon"] & found).sum()
    assert (pylon & parts["pines"] & ~parts["pylon"]).sum() < 0.05 * parts["pines"].sum()
    rim = cv2.dilate(parts["pylon"].astype(np.uint8), np.ones((7, 7), np.uint8)) > 0
    left = found & rim & ~pylon & ~parts["pines"]
    left[:42] = False  # (the pines' own soft edge)
    assert left.sum() < 0.02 * (parts["pylon"] & found).sum()  # its soft rim goes with it
    pines = shadow_edit_region(p, img, sky, ShadowEdit(0.3, 25 / H, shadow=False))
    assert (pines & parts["pines"] & found).sum() > 0.95 * (parts["pines"] & found).sum()
    assert (pines & parts["pylon"]).sum() < 0.3 * parts["pylon"].sum()
    # Through the corrections: the pylon dropped, the pines still found.
    out, not_shadow = apply_shadow_edits(p, img, sky, [ShadowEdit(103 / W, 75 / H, False)])
    lower = parts["pylon"].copy()
    lower[:44] = False  # (below the tree line)
    assert out[lower].max() < 0.05 and not_shadow[lower & found].all()
    inner = cv2.erode(parts["pines"].astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    assert out[inner & ~rim].mean() > 0.9


def test_a_marked_shadow_is_lifted_to_the_lit_surface_round_it() -> None:
    """A "Mark shadow" click on a snow shadow whose surroundings hold other shadows the found
    probability missed (counted as lit) and dark pines found as shade: the photo-wide
    statistics lifted it short of the snow and bluish (a lavender-grey area with its outline
    left, on the ski slope: a user trial). Lifted from the lit snow just round it, it ends at
    the snow's level and colour; the unmarked shadows and the pines are lifted as before."""
    from outcast_core.runtime.geometry.colour import linear_to_lab, srgb_to_linear
    from outcast_core.runtime.pipeline.photo_shadows import (
        deshadow_log_gain,
        lift_probability,
        marked_weight,
    )

    img, parts = _slope()
    sky = parts["sky"]
    others = np.zeros((H, W), bool)  # more snow shadows round it, lighter, missed
    others[44:96, 0:8] = others[44:96, 110:128] = others[92:96, :] = True
    img[others & ~parts["pines"]] *= np.array([0.55, 0.58, 0.64], np.float32)
    p = photo_shadow_probability(img, sky)
    assert p[parts["shadow"]].mean() < 0.2 and p[others & ~parts["pines"]].mean() < 0.2
    masks = shadow_edit_masks(p, img, sky, [ShadowEdit(*_centre(parts["shadow"]), True)])
    edited, not_shadow = apply_edit_masks(p, sky, *masks)
    marked = marked_weight(masks[0])
    out = deshadow(img, edited, sky | not_shadow, marked=marked)
    plain = deshadow(img, edited, sky | not_shadow)
    lab = linear_to_lab(srgb_to_linear(out))
    inner = cv2.erode(parts["shadow"].astype(np.uint8), np.ones((7, 7), np.uint8)) > 0
    lit = ~parts["shadow"] & ~others & ~parts["pines"] & ~sky
    snow = linear_to_lab(srgb_to_linear(img))[lit].mean(axis=0)
    shadow = lab[inner].mean(axis=0)
    assert abs(shadow[0] - snow[0]) < 2.0  # L*
    assert np.hypot(*(shadow[1:] - snow[1:])) < 1.5  # a*b*
    short = linear_to_lab(srgb_to_linear(plain))[inner].mean(axis=0)
    assert short[0] < snow[0] - 4.0  # (the photo-wide statistics: short)
    # Where nothing is marked, the gain is the unmarked one.
    lift = lift_probability(img, edited, sky | not_shadow, marked=marked)
    gain = deshadow_log_gain(img, lift, sky | not_shadow, marked=marked)
    unmarked = deshadow_log_gain(img, lift, sky | not_shadow)
    np.testing.assert_array_equal(gain[marked == 0], unmarked[marked == 0])
    assert (gain[inner] > unmarked[inner] + 0.1).all()


def test_a_marked_deep_blue_shadow_is_lifted_to_the_lit_colour_not_cyan() -> None:
    """A marked shadow whose red lies further below the lit surface than the largest lift
    (16x; deep blue shade on pavement: red 25x down, green 7x, blue 3x, as two dev photos'
    are): all channels come down by red's shortfall, so it ends in the pavement's colour, a
    little darker. Red clipped alone fell short and the shadow came out cyan (a*b* 12 away)."""
    from outcast_core.runtime.geometry.colour import linear_to_lab, linear_to_srgb, srgb_to_linear
    from outcast_core.runtime.pipeline.photo_shadows import marked_weight

    rng = np.random.default_rng(3)
    lin = np.full((H, W, 3), [0.5, 0.42, 0.33], np.float32)
    shadow = np.zeros((H, W), bool)
    shadow[40:80, 30:100] = True
    lin[shadow] /= np.array([25.0, 7.0, 3.0], np.float32)
    lin *= 1.0 + 0.03 * rng.standard_normal((H, W, 1)).astype(np.float32)
    img = linear_to_srgb(np.clip(lin, 0.0, 1.0))
    sky = np.zeros((H, W), bool)
    p = photo_shadow_probability(img, sky)
    masks = shadow_edit_masks(p, img, sky, [ShadowEdit(*_centre(shadow), True)])
    edited, not_shadow = apply_edit_masks(p, sky, *masks)
    marked = marked_weight(masks[0])
    assert marked[shadow].mean() > 0.9
    out = linear_to_lab(srgb_to_linear(deshadow(img, edited, sky | not_shadow, marked=marked)))
    inner = cv2.erode(shadow.astype(np.uint8), np.ones((7, 7), np.uint8)) > 0
    ring = (cv2.dilate(shadow.astype(np.uint8), np.ones((15, 15), np.uint8)) > 0) & ~shadow
    lit = linear_to_lab(srgb_to_linear(img))[ring].mean(axis=0)
    got = out[inner].mean(axis=0)
    assert np.hypot(*(got[1:] - lit[1:])) < 3.0  # the pavement's colour
    assert lit[0] - 15.0 < got[0] < lit[0] + 1.0  # its level, a little darker


def _reference_marked_lift(log_c, p, usable, marked):
    """``marked_lift`` as first written (ab58bda): two elliptical dilations per region (each
    mark with the shadow it lies in and the ring's lit class chosen as ``marked_lift`` does
    since 2026-12-04: what is compared here is the bands)."""
    from outcast_core.runtime.pipeline import photo_shadows as ps

    m = np.clip(np.asarray(marked, np.float32), 0.0, 1.0)
    h, w = m.shape
    side = max(h, w)
    y = log_c @ ps.LUMA_709
    grown = ps._marks_with_their_shadows(m > 0, log_c, usable)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(grown.astype(np.uint8),
                                                           connectivity=8)
    gap = max(1, round(ps.MARKED_GAP * side))
    reach = gap + max(2, round(ps.MARKED_RING * side))
    candidates = usable & (p <= 0.5) & ~grown
    lit = np.zeros(log_c.shape, np.float32)
    top = np.zeros((h, w), np.float32)
    weight = np.zeros((h, w), np.float32)
    for k in range(1, n):
        x0, y0, bw, bh = stats[k, :4]
        t, le = max(0, y0 - reach), max(0, x0 - reach)
        b, r = min(h, y0 + bh + reach), min(w, x0 + bw + reach)
        region = (labels[t:b, le:r] == k).astype(np.uint8)
        near = cv2.dilate(region, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * gap + 1,) * 2))
        far = cv2.dilate(region, cv2.getStructuringElement(cv2.MORPH_ELLIPSE,
                                                           (2 * reach + 1,) * 2))
        ring = (far > 0) & (near == 0) & candidates[t:b, le:r]
        if ring.sum() < 16:
            continue
        inside = (region > 0) & (m[t:b, le:r] > 0)
        values = y[t:b, le:r][ring]
        split = ps._otsu_threshold(values)
        bright = values >= split
        if (ps.STROKE_MIN_SHARE * values.size <= bright.sum() < values.size
                and np.median(values[bright]) - np.median(values[~bright]) > ps.STROKE_SPLIT):
            ring = ps._lit_class(log_c[t:b, le:r], ring, bright, inside)
        lit[t:b, le:r][inside] = log_c[t:b, le:r][ring].mean(axis=0)
        top[t:b, le:r][inside] = np.percentile(y[t:b, le:r][ring], ps.MARKED_TOP)
        weight[t:b, le:r][inside] = m[t:b, le:r][inside]
    if not weight.any():
        return None
    on = (weight > 0) & usable
    sigma = max(1.0, ps.RATIO_SIGMA * ps.SHADE_SIGMA * side)
    n_m = ps.wide_blur((weight * on).astype(np.float32), sigma)
    mu = (ps.wide_blur(log_c * (weight * on)[..., None], sigma)
          / np.maximum(n_m, 1e-6)[..., None])
    mu = np.where((n_m > 1e-4)[..., None], mu, log_c)
    gain = ps.warm_lift(np.clip(lit - mu, 0.0, ps.MAX_LIFT_LOG))
    # (since 2026-12-03) a penumbra takes the share of the gain that brings it to the lit level
    smooth = cv2.GaussianBlur(y, (0, 0), max(1.0, side * ps.PENUMBRA_SMOOTH))
    share = np.clip((lit @ ps.LUMA_709 - smooth) / np.maximum(gain @ ps.LUMA_709, 1e-3), 0, 1)
    gain = gain * np.where(weight > 0, share, 1.0)[..., None]
    excess = (mu - log_c) @ ps.LUMA_709 - ps.DARKER_MARGIN
    keep = np.exp(-0.5 * (np.maximum(excess, 0.0) / ps.DARKER_WIDTH) ** 2)
    return (np.where((weight > 0)[..., None], gain, 0.0).astype(np.float32), top,
            keep.astype(np.float32), weight)


def _lift_scene(rng: np.random.Generator, h: int, w: int
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Log colour (two surfaces on the left, so Otsu's split is taken in the bands there, one
    on the right), a shadow probability and a usable mask."""
    log_c = rng.normal(-1.5, 0.3, (h, w, 3)).astype(np.float32)
    dark = rng.random((h, w)) < 0.3
    dark[:, w // 2:] = False
    log_c[dark] -= 1.2
    p = cv2.GaussianBlur(rng.random((h, w)).astype(np.float32), (0, 0), 3) * 2 - 0.5
    usable = rng.random((h, w)) > 0.1
    return log_c, np.clip(p, 0, 1), usable


def _assert_same_lift(got, want) -> None:
    assert (got is None) == (want is None)
    if want is not None:
        for a, b in zip(got, want, strict=True):
            np.testing.assert_array_equal(a, b)


def test_the_ellipse_dilation_by_rows_is_opencv_s() -> None:
    from outcast_core.runtime.pipeline.photo_shadows import _dilated_ellipse

    rng = np.random.default_rng(3)
    for radius in (1, 2, 5, 14, 36):
        for shape in ((9, 13), (80, 60), (40, 150)):
            mask = (rng.random(shape) < 0.01).astype(np.uint8)
            mask[rng.integers(shape[0]), :rng.integers(1, shape[1])] = 1
            want = cv2.dilate(mask, cv2.getStructuringElement(cv2.MORPH_ELLIPSE,
                                                              (2 * radius + 1,) * 2))
            np.testing.assert_array_equal(_dilated_ellipse(mask, radius), want)


def test_marked_lift_reads_each_region_s_own_band_as_the_reference_does() -> None:
    """Regions of one pixel, a few and many, touching the border and each other's bands (each
    region reads its whole band, however it overlaps another's), at two sizes (bands 6 and 14
    pixels out): the same as the loop of two dilations per region, bit for bit."""
    from outcast_core.runtime.pipeline.photo_shadows import marked_lift

    rng = np.random.default_rng(7)
    for seed, (h, w) in enumerate([(120, 160), (300, 400), (120, 160), (300, 400)]):
        log_c, p, usable = _lift_scene(rng, h, w)
        m = np.zeros((h, w), np.float32)
        for _ in range(6):
            cx, cy = int(rng.integers(-5, w + 5)), int(rng.integers(-5, h + 5))
            axes = (int(rng.integers(1, w // 6)), int(rng.integers(1, h // 6)))
            cv2.ellipse(m, (cx, cy), axes, float(rng.integers(180)), 0, 360,
                        float(rng.uniform(0.2, 1.0)), -1)
        m[rng.random((h, w)) < 0.002] = 1.0  # lone pixels
        m[0, :5] = m[-3:, -1] = 0.5  # on the border
        m[h // 2, w // 2:w // 2 + 4] = m[h // 2 + 1, w // 2 + 4] = 1.0  # a few, diagonal
        if seed >= 2:
            m[:, w // 3] = 0.7  # one long region crossing everything
        _assert_same_lift(marked_lift(log_c, p, usable, m),
                          _reference_marked_lift(log_c, p, usable, m))


def test_marked_lift_takes_a_speckled_mark_of_many_regions() -> None:
    from outcast_core.runtime.pipeline.photo_shadows import marked_lift

    rng = np.random.default_rng(11)
    h, w = 150, 200
    log_c, p, usable = _lift_scene(rng, h, w)
    m = (rng.random((h, w)) < 0.01).astype(np.float32)
    n = cv2.connectedComponents((m > 0).astype(np.uint8), connectivity=8)[0] - 1
    assert n > 250
    got = marked_lift(log_c, p, usable, m)
    _assert_same_lift(got, _reference_marked_lift(log_c, p, usable, m))
    assert got is not None and (got[3][m > 0] > 0).mean() > 0.9


def test_a_marked_crushed_shadow_is_taken_whole_and_filled_at_every_size() -> None:
    """A shadow the camera crushed to noise (a toddler's shadow on sunlit pavement at 1/400 of
    it, a dev photo): one "Mark shadow" click took a few pixels round the point (the noise
    spread its log luminance past the fill's range) and the lift, capped at 16x, turned them
    saturated blue. Now the click takes the shadow and its penumbra, and the de-shadow fills
    it with the pavement's colour, at the working size and at full resolution, where the
    photo's noise is not multiplied back in; relit, the same."""
    from outcast_core.runtime.geometry.colour import linear_to_lab, srgb_to_linear

    rng = np.random.default_rng(3)
    big_h, big_w = 1200, 1600
    pave = np.array([0.72, 0.66, 0.6], np.float32)
    img = np.clip(pave * (1 + 0.04 * rng.standard_normal((big_h, big_w, 1))), 0, 1)
    yy, xx = np.mgrid[0:big_h, 0:big_w]
    core = ((yy - 800) / 120.0) ** 2 + ((xx - 700) / 420.0) ** 2 <= 1.0
    edge = ((yy - 800) / 128.0) ** 2 + ((xx - 700) / 428.0) ** 2 <= 1.0
    img[edge & ~core] *= 0.3  # the penumbra
    noise = rng.integers(0, 4, (big_h, big_w, 3)) / 255.0  # JPEG's crushed shade: 0-3 / 255
    img[core] = noise[core]
    img = img.astype(np.float32)
    depth = np.full((big_h, big_w), 10.0, np.float32)  # a wall facing the camera
    s = RelightSession(preset="fast")
    s.set_image(img, depth=depth)
    s.set_original_sun((0.3, -0.5, -0.8))  # behind the camera: the wall is lit
    s.set_shadow_edits([ShadowEdit(700 / big_w, 800 / big_h, True)])
    work = s.image_srgb.shape[:2]
    small = cv2.resize(edge.astype(np.uint8), (work[1], work[0]),
                       interpolation=cv2.INTER_NEAREST) > 0
    assert s._marked(s.sky)[small].mean() > 0.95  # the click took it whole

    def gap(out: np.ndarray, inside: np.ndarray, lit: np.ndarray) -> tuple[float, float, float]:
        lab = linear_to_lab(srgb_to_linear(np.clip(out, 0, 1)))
        d = lab[inside].mean(axis=0) - lab[lit].mean(axis=0)
        return float(abs(d[0])), float(np.hypot(d[1], d[2])), float(lab[inside][:, 0].std())

    inner = cv2.erode(small.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    light = ~(cv2.dilate(small.astype(np.uint8), np.ones((9, 9), np.uint8)) > 0)
    d_l, d_ab, _ = gap(s.deshadow(), inner, light)
    assert d_l < 6.0 and d_ab < 2.0  # the pavement's level and colour
    full = s.deshadow_full()
    assert full.shape == img.shape
    # 8 bits for an 8-bit file (no full-size float buffer): the same picture, rounded.
    full8 = s.deshadow_full(dtype=np.uint8)
    assert full8.dtype == np.uint8 and np.abs(full8 / 255.0 - full).max() <= 1.0 / 255 + 1e-4
    inner_full = cv2.erode(core.astype(np.uint8), np.ones((31, 31), np.uint8)) > 0
    light_full = ~(cv2.dilate(edge.astype(np.uint8), np.ones((41, 41), np.uint8)) > 0)
    d_l, d_ab, spread = gap(full, inner_full, light_full)
    lit_spread = float(linear_to_lab(srgb_to_linear(img))[light_full][:, 0].std())
    assert d_l < 6.0 and d_ab < 2.0
    assert spread < lit_spread + 1.0  # no noise multiplied back in
    # Relit to a sun that lights the wall too: the marked shadow is gone there as well (the
    # lift's ceiling is the filled photo, and physics, which has no data there, does not
    # bound it), and its full-size pixels are not the photo's noise multiplied.
    relit = s.relight_full((-0.3, -0.6, -0.7))
    d_l, d_ab, spread = gap(relit, inner_full, light_full)
    assert d_l < 6.0 and d_ab < 3.0 and spread < lit_spread + 1.0
    preview = s.relight((-0.3, -0.6, -0.7), preview=True)  # dragging: the same
    d_l, d_ab, spread = gap(preview, inner, light)
    assert d_l < 8.0 and d_ab < 3.0 and spread < lit_spread + 1.5
    # Physics relighting too (it multiplied the noise: L* 11.7 against the wall's 68).
    p = RelightSession(mode="classic", preset="fast")
    p.set_image(img, depth=depth)
    p.set_original_sun((0.3, -0.5, -0.8))
    p.set_shadow_edits([ShadowEdit(700 / big_w, 800 / big_h, True)])
    d_l, d_ab, spread = gap(p.relight_full((-0.3, -0.6, -0.7)), inner_full, light_full)
    assert d_l < 6.0 and d_ab < 3.0 and spread < lit_spread + 1.0


def test_a_black_object_in_a_marked_shadow_that_is_not_crushed_stays_black() -> None:
    """The fill is for a shadow the camera crushed, decided on the shadow's own level: a black
    bin inside a marked shadow 6x darker than the ground is more than 16x darker than the
    ground itself, and was painted the ground's colour (a review); it stays dark while the
    shadow round it is lifted."""
    from outcast_core.runtime.geometry.colour import linear_to_srgb, srgb_to_linear
    from outcast_core.runtime.pipeline.photo_shadows import marked_weight

    rng = np.random.default_rng(5)
    ground = np.full((H, W, 3), 0.6, np.float32) * (1 + 0.02 * rng.standard_normal((H, W, 1)))
    lin = srgb_to_linear(np.clip(ground, 0, 1).astype(np.float32))
    shadow = np.zeros((H, W), bool)
    shadow[30:80, 30:110] = True
    bin_ = np.zeros((H, W), bool)
    bin_[45:65, 60:75] = True
    lin[shadow] /= 6.0
    lin[bin_] = srgb_to_linear(np.float32(0.03))
    img = linear_to_srgb(lin)
    sky = np.zeros((H, W), bool)
    p = photo_shadow_probability(img, sky)
    added = shadow.astype(np.float32)  # the whole shadow, the bin in it (as a brush paints)
    edited, not_shadow = apply_edit_masks(p, sky, added, np.zeros((H, W), bool))
    out = deshadow(img, edited, sky | not_shadow, marked=marked_weight(added))
    inner = shadow & ~(cv2.dilate(bin_.astype(np.uint8), np.ones((9, 9), np.uint8)) > 0)
    inner = cv2.erode(inner.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    assert abs(float(out[inner].mean()) - 0.6) < 0.06  # the shadow lifted to the ground
    core = cv2.erode(bin_.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    assert float(out[core].mean()) < 0.2  # the bin still dark
