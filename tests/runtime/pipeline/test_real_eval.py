"""The real-photo evaluation (``outcast eval real``) on tiny folders the tests make."""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from outcast_core.runtime.cli.main import main
from outcast_core.runtime.geometry.camera import normalize_sun, sun_vector
from outcast_core.runtime.io.imageio import write_image
from outcast_core.runtime.pipeline.real_eval import (
    SWEEP_SUNS,
    balanced_error_rate,
    evaluate_photo,
    find_items,
    lab_rmse,
    otsu_shadow_mask,
    shuffled_control,
    swept_shuffled_control,
)


def test_balanced_error_rate() -> None:
    t = np.zeros((4, 4), bool)
    t[:2] = True
    assert balanced_error_rate(t, t) == 0.0
    assert balanced_error_rate(~t, t) == 1.0
    assert balanced_error_rate(np.zeros_like(t), t) == 0.5  # all "lit": chance
    half = t.copy()
    half[0] = False  # half the shadow found, no false alarm
    assert balanced_error_rate(half, t) == pytest.approx(0.25)
    with pytest.raises(ValueError, match="one shape"):
        balanced_error_rate(t[:2], t)


def _photo_with_shadow(h: int = 48, w: int = 64, box: tuple[int, int, int, int] = (30, 44, 8, 30)):
    rng = np.random.default_rng(0)
    img = np.clip(0.7 + 0.03 * rng.standard_normal((h, w, 3)), 0, 1).astype(np.float32)
    r0, r1, c0, c1 = box
    mask = np.zeros((h, w), bool)
    mask[r0:r1, c0:c1] = True
    img[mask] *= np.array([0.3, 0.35, 0.45], np.float32)  # bluish shade
    return img, mask


def _write_item(folder: Path, name: str, img: np.ndarray, mask: np.ndarray) -> None:
    write_image(folder / f"{name}_image.png", img)
    cv2.imwrite(str(folder / f"{name}_mask.png"), mask.astype(np.uint8) * 255)


def test_find_items_pairs_images_with_masks(tmp_path: Path) -> None:
    img, mask = _photo_with_shadow()
    _write_item(tmp_path, "a", img, mask)
    _write_item(tmp_path, "b", img, mask)
    write_image(tmp_path / "b_free.png", img)
    write_image(tmp_path / "c_image.png", img)  # no mask: skipped
    items = find_items(tmp_path)
    assert [i.name for i in items] == ["a", "b"]
    assert items[0].free is None and items[1].free == tmp_path / "b_free.png"
    with pytest.raises(ValueError, match="found none"):
        find_items(_empty(tmp_path))


def _empty(tmp_path: Path) -> Path:
    d = tmp_path / "empty"
    d.mkdir()
    return d


def test_otsu_finds_a_dark_shadow() -> None:
    img, mask = _photo_with_shadow()
    assert balanced_error_rate(otsu_shadow_mask(img), mask) < 0.02


class _FakeSession:
    """A session whose overlay is the true mask for one sun and shifted sideways for the rest:
    the evaluation must find that sun, score it 0 and score the opposite azimuth worse."""

    def __init__(self, mask: np.ndarray, true_sun: tuple[float, float]) -> None:
        self.mask = mask
        self.true_w = sun_vector(*true_sun)
        self.sky = np.zeros(mask.shape, bool)

    def set_image(self, image: np.ndarray, **_: object) -> None:
        assert image.shape[:2] == self.mask.shape

    def shadow(self, w: np.ndarray) -> np.ndarray:
        angle = np.degrees(np.arccos(np.clip(normalize_sun(w) @ self.true_w, -1, 1)))
        shift = int(round(angle / 3))
        return np.where(np.roll(self.mask, shift, axis=1), 0.0, 1.0).astype(np.float32)

    def set_original_sun(self, w: np.ndarray) -> np.ndarray:
        return self.shadow(w)


def test_evaluate_photo_finds_the_aligned_sun(tmp_path: Path) -> None:
    img, mask = _photo_with_shadow()
    _write_item(tmp_path, "a", img, mask)
    item = find_items(tmp_path)[0]
    true_sun = SWEEP_SUNS[15]
    res = evaluate_photo(_FakeSession(mask, true_sun), item)
    assert res.best_sun == true_sun
    assert res.overlay_ber == 0.0 and res.refined_ber == 0.0
    assert res.opposite_ber > 0.25
    assert res.sky_claim == 0.0
    assert res.otsu_ber < 0.02


def test_shuffled_control_uses_other_photos_only() -> None:
    a = np.zeros((8, 8), bool)
    a[:4] = True
    b = ~a
    out = shuffled_control({"a": a, "b": b}, {"a": a, "b": b})
    assert out == {"a": 1.0, "b": 1.0}


def test_swept_control_gives_the_other_photos_their_best_sun_and_this_photos_sky() -> None:
    top = np.zeros((8, 8), bool)
    top[:4] = True
    none = np.zeros((8, 8), bool)
    # b's sweep holds one sun that shadows a's shadow exactly: the control finds it, where
    # one mask per photo (b's best for b) would not.
    sweeps = {
        "a": {"masks": np.stack([none, top]), "sky": none, "truth": top},
        "b": {"masks": np.stack([~top, top]), "sky": none, "truth": ~top},
    }
    out = swept_shuffled_control(sweeps)
    assert out["a"] == (0.0, 0.0)  # b's second sun on a's mask; a's own second sun
    assert out["b"][0] == pytest.approx(0.5)  # a's suns: none (chance) or the inverse (1.0)
    assert out["b"][1] == 0.0  # b's own first sun
    # This photo's sky is never shadow: b's exact match falls to chance under a's sky.
    sweeps["a"]["sky"] = top
    assert swept_shuffled_control(sweeps)["a"] == (pytest.approx(0.5), pytest.approx(0.5))
    lone = swept_shuffled_control({"a": sweeps["a"]})["a"]
    assert np.isnan(lone[0]) and lone[1] == pytest.approx(0.5)


def test_lab_rmse_zero_for_equal_images() -> None:
    img, mask = _photo_with_shadow()
    assert lab_rmse(img, img, mask) == 0.0
    assert lab_rmse(img, np.clip(img + 0.1, 0, 1), mask) > 1.0


@pytest.mark.slow
def test_cli_eval_real_on_a_tiny_folder(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    data = tmp_path / "data"
    data.mkdir()
    for i, box in enumerate([(30, 44, 8, 30), (20, 40, 30, 60)]):
        img, mask = _photo_with_shadow(box=box)
        _write_item(data, f"p{i}", img, mask)
        if i == 1:
            write_image(data / "p1_free.png", np.clip(img / 0.4, 0, 1) * mask[..., None]
                        + img * ~mask[..., None])
    out_json, sheet = tmp_path / "r.json", tmp_path / "sheet.png"
    rc = main(["eval", "real", str(data), "--mode", "classic", "--preset", "fast,balanced",
               "--json", str(out_json), "--sheet", str(sheet), "-q"])
    assert rc == 0
    text = capsys.readouterr().out
    assert "Speed / accuracy" in text and "| fast |" in text
    rep = json.loads(out_json.read_text())
    assert set(rep) == {"fast", "balanced"}
    photos = rep["fast"]["photos"]
    assert [p["name"] for p in photos] == ["p0", "p1"]
    for p in photos:
        for key in ("overlay_ber", "opposite_ber", "refined_ber", "otsu_ber", "shuffled_ber",
                    "swept_shuffled_ber", "swept_own_ber", "sky_claim"):
            assert 0.0 <= p[key] <= 1.0, key
        assert p["otsu_ber"] < 0.05
        assert p["relit_chroma"] is not None and 0.0 <= p["relit_chroma"] < 50.0
    assert photos[1]["deshadow_in"] is not None and photos[0]["deshadow_in"] is None
    assert (tmp_path / "sheet_fast.png").is_file() and (tmp_path / "sheet_balanced.png").is_file()
    # Nothing overwritten silently.
    assert main(["eval", "real", str(data), "--mode", "classic", "--json", str(out_json),
                 "-q"]) == 2
    assert "exists" in capsys.readouterr().err


def test_cli_eval_real_rejects_a_folder_without_masks(tmp_path: Path,
                                                       capsys: pytest.CaptureFixture) -> None:
    assert main(["eval", "real", str(tmp_path)]) == 2
    assert "NAME_mask.png" in capsys.readouterr().err


def test_report_section_is_replaced_and_the_rest_kept(tmp_path: Path) -> None:
    from outcast_core.runtime.pipeline.real_eval import real_section, update_report

    report = tmp_path / "EVAL.md"
    report.write_text("# Synthetic\n\nTable 1\n")
    update_report(report, "## Real photographs\n\nBER 0.3")
    update_report(report, "## Real photographs\n\nBER 0.2")
    text = report.read_text()
    assert text.startswith("# Synthetic\n\nTable 1\n")
    assert "BER 0.2" in text and "BER 0.3" not in text
    assert text.count("## Real photographs") == 1
    assert "BER 0.2" in real_section(text)


def test_cli_eval_real_with_a_depth_model(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    pytest.importorskip("onnx")
    from tests.runtime.depth_fixtures import tiny_depth_model

    data = tmp_path / "data"
    data.mkdir()
    img, mask = _photo_with_shadow()
    _write_item(data, "p0", img, mask)
    model = tiny_depth_model(tmp_path / "da.onnx", input_name="pixel_values",
                             output_name="predicted_depth", size=None, block=14, gain=7.0,
                             offset=0.3)
    out_json = tmp_path / "r.json"
    assert main(["eval", "real", str(data), "--mode", "classic", "--preset", "fast",
                 "--depth-model", str(model), "--json", str(out_json), "-q"]) == 0
    rep = json.loads(out_json.read_text())
    assert rep["photos"][0]["depth_source"].startswith("model da.onnx")
    assert main(["eval", "real", str(data), "--depth-model", str(tmp_path / "none.onnx"),
                 "-q"]) == 2
    assert "none.onnx" in capsys.readouterr().err


def test_new_shade_ratio_compares_new_shadows_with_the_photos_own() -> None:
    from outcast_core.runtime.pipeline.real_eval import new_shade_ratio

    img = np.full((20, 40, 3), 0.8, np.float32)
    img[:, :10] = 0.3  # the photo's own shadow
    so = np.ones((20, 40), np.float32)
    so[:, :10] = 0.0
    sn = np.ones((20, 40), np.float32)
    sn[:, 30:] = 0.0  # the new sun's shadow
    prob = 1.0 - so
    sky = np.zeros((20, 40), bool)
    same = img.copy()
    same[:, 30:] = 0.3
    half = img.copy()
    half[:, 30:] = 0.52
    assert new_shade_ratio(img, same, so, sn, prob, sky) == pytest.approx(1.0, abs=1e-3)
    assert 0.3 < new_shade_ratio(img, half, so, sn, prob, sky) < 0.7
    assert new_shade_ratio(img, img, so, sn, prob, sky) == pytest.approx(0.0, abs=1e-6)
    assert new_shade_ratio(img, same, so, sn, None, sky) is None
    assert new_shade_ratio(img, same, so, np.ones_like(sn), prob, sky) is None  # no new shadow


def test_shade_colour_gap_compares_the_new_shades_colour_with_the_photos_own() -> None:
    """0 when the new shade turns as the photo's own shade does against its lit ring; the
    distance of the two chromaticity shifts otherwise; None without a new shadow, a marked
    one, or its lit ring (the sky is neither)."""
    from outcast_core.runtime.geometry.colour import log_chromaticity, srgb_to_linear
    from outcast_core.runtime.pipeline.real_eval import shade_colour_gap

    lit_colour, shade_colour = (0.8, 0.7, 0.55), (0.25, 0.25, 0.3)
    img = np.full((60, 80, 3), lit_colour, np.float32)
    img[10:30, 10:30] = shade_colour  # the photo's own (marked) shadow
    marked = np.zeros((60, 80), bool)
    marked[10:30, 10:30] = True
    so = np.where(marked, 0.0, 0.9).astype(np.float32)
    sn = so.copy()
    sn[40:, 40:] = 0.0  # the new sun's shadow
    sky = np.zeros((60, 80), bool)
    same = img.copy()
    same[40:, 40:] = shade_colour
    assert shade_colour_gap(img, same, marked, so, sn, sky) == pytest.approx(0.0, abs=1e-4)
    grey = img.copy()
    grey[40:, 40:] = 0.25
    want = np.hypot(*(log_chromaticity(srgb_to_linear(np.float32(shade_colour)), 1e-3)
                      - log_chromaticity(srgb_to_linear(np.full(3, 0.25, np.float32)), 1e-3)))
    assert shade_colour_gap(img, grey, marked, so, sn, sky) == pytest.approx(want, rel=1e-3)
    assert shade_colour_gap(img, same, marked, so, so, sky) is None  # no new shadow
    assert shade_colour_gap(img, same, np.zeros_like(marked), so, sn, sky) is None
    all_sky = np.ones_like(sky)
    all_sky[40:, 40:] = False  # only the new shadow is surface: no marked edge to compare
    assert shade_colour_gap(img, same, marked, so, sn, all_sky) is None


def test_old_shade_ratio_measures_the_old_shadow_left_where_the_new_sun_lights_it() -> None:
    from outcast_core.runtime.pipeline.real_eval import old_shade_ratio

    img = np.full((60, 60, 3), 0.8, np.float32)
    img[20:40, 20:40] = 0.2  # the photo's own (marked) shadow
    marked = np.zeros((60, 60), bool)
    marked[20:40, 20:40] = True
    lit, sky = np.ones((60, 60), np.float32), np.zeros((60, 60), bool)
    from outcast_core.runtime.geometry.colour import linear_to_srgb, srgb_to_linear

    halfway = img.copy()  # the geometric mean of lit and shade in linear light: half the log
    halfway[20:40, 20:40] = linear_to_srgb(np.sqrt(srgb_to_linear(np.float32(0.8))
                                                   * srgb_to_linear(np.float32(0.2))))
    assert old_shade_ratio(img, img, marked, lit, sky) == pytest.approx(1.0)
    assert old_shade_ratio(img, halfway, marked, lit, sky) == pytest.approx(0.5, abs=0.01)
    gone = np.full_like(img, 0.8)
    assert old_shade_ratio(img, gone, marked, lit, sky) == pytest.approx(0.0, abs=1e-6)
    # Where the new sun does not light the old shadow, there is nothing to measure.
    assert old_shade_ratio(img, img, marked, np.zeros_like(lit), sky) is None
    # A marked region no darker than its surroundings says nothing about a relighting.
    assert old_shade_ratio(np.full_like(img, 0.8), img, marked, lit, sky) is None


def test_false_lift_measures_what_the_relighting_does_to_wrongly_found_shadows() -> None:
    """The mean log gain where the found shadow lies away from every marked one and the new
    sun lights it: 0 unchanged, ln 4 for four times the light; what lies near a marked shadow,
    on the sky, stays shadowed or is no found shadow is left out."""
    from outcast_core.runtime.geometry.colour import linear_to_srgb, srgb_to_linear
    from outcast_core.runtime.pipeline.real_eval import false_lift

    img = np.full((60, 60, 3), 0.7, np.float32)
    img[:, 40:] = 0.15  # a dark material the photo's shadows take in
    img[5:15, 5:15] = 0.15  # a real (marked) shadow
    s_o = np.ones((60, 60), np.float32)
    s_o[:, 40:] = 0.0
    s_o[5:15, 5:15] = 0.0
    marked = np.zeros((60, 60), bool)
    marked[5:15, 5:15] = True
    lit, sky = np.ones((60, 60), np.float32), np.zeros((60, 60), bool)
    relit = img.copy()
    relit[:, 40:] = linear_to_srgb(4.0 * srgb_to_linear(np.float32(0.15)))
    relit[5:15, 5:15] = 0.9  # the real shadow lifted: not counted
    assert false_lift(img, img, marked, s_o, lit, sky) == pytest.approx(0.0, abs=1e-6)
    assert false_lift(img, relit, marked, s_o, lit, sky) == pytest.approx(math.log(4.0), abs=0.01)
    # Where the new sun does not light it, or only a sky is left, nothing is measured.
    assert false_lift(img, relit, marked, s_o, np.zeros_like(lit), sky) is None
    assert false_lift(img, relit, marked, s_o, lit, np.ones_like(sky)) is None
    # A found strip just beside a marked shadow (within the ring) is that shadow's edge, not a
    # material: left out (about ln 11 if it counted).
    s_o = np.ones((60, 60), np.float32)
    s_o[:, 40:42] = 0.0
    beside = np.zeros((60, 60), bool)
    beside[:, 37:40] = True
    lifted = img.copy()
    lifted[:, 40:42] = 0.5
    assert false_lift(img, lifted, beside, s_o, lit, sky) is None
    assert false_lift(img, lifted, np.zeros_like(beside), s_o, lit, sky) > 2.0


def test_detail_ratio_measures_the_fine_texture_a_relighting_keeps() -> None:
    """1 for the photo's own texture whatever the exposure (a gain is no loss of detail),
    below 1 for a blurred relighting, None with too few pixels or no texture."""
    from outcast_core.runtime.pipeline.real_eval import detail_ratio

    rng = np.random.default_rng(4)
    img = np.clip(0.4 + 0.08 * rng.standard_normal((128, 160, 3)), 0.05, 1).astype(np.float32)
    where = np.zeros((128, 160), bool)
    where[20:100, 20:140] = True
    from outcast_core.runtime.geometry.colour import linear_to_srgb, srgb_to_linear

    brighter = linear_to_srgb(srgb_to_linear(img) * 1.5)
    assert detail_ratio(img, brighter, where) == pytest.approx(1.0, abs=0.02)
    blurred = cv2.GaussianBlur(img, (0, 0), 1.5)
    assert detail_ratio(img, blurred, where) < 0.5
    assert detail_ratio(img, img, np.zeros_like(where)) is None
    flat = np.full_like(img, 0.5)
    assert detail_ratio(flat, img, where) is None


def test_the_relit_check_turns_the_sun_about_the_horizon() -> None:
    """The relighting checks' new sun stands at the photo's sun's elevation above the horizon,
    120 degrees round it, also for a camera pitched down (its vertical is not the horizon's)."""
    from outcast_core.runtime.geometry.camera import camera_rotation
    from outcast_core.runtime.pipeline.daylight import elevation_above
    from outcast_core.runtime.pipeline.real_eval import RELIGHT_TURN, relit_check_sun

    class Pitched:
        def horizon_tilt(self) -> tuple[float, float]:
            return -25.0, 0.0

    up = camera_rotation(-25.0, 0.0) @ np.array([0.0, -1.0, 0.0])
    w_o = sun_vector(30.0, 20.0)
    w_n = relit_check_sun(Pitched(), 30.0, 20.0)
    assert elevation_above(w_n, up) == pytest.approx(elevation_above(w_o, up), abs=1e-9)
    flat = [w - (w @ up) * up for w in (w_o, w_n)]
    cos_turn = flat[0] @ flat[1] / (np.linalg.norm(flat[0]) * np.linalg.norm(flat[1]))
    assert math.degrees(math.acos(cos_turn)) == pytest.approx(RELIGHT_TURN, abs=1e-6)
    # About the camera's vertical the elevation would differ by tens of degrees here.
    w_cam = sun_vector(30.0 + RELIGHT_TURN, 20.0)
    assert abs(elevation_above(w_cam, up) - elevation_above(w_o, up)) > 10.0
    # Without a horizon (an object with no horizon_tilt): the camera's vertical.
    np.testing.assert_allclose(relit_check_sun(object(), 30.0, 20.0), w_cam, atol=1e-9)


def test_cli_eval_real_skips_a_photo_it_cannot_evaluate(tmp_path: Path,
                                                       capsys: pytest.CaptureFixture) -> None:
    """One mask of the wrong size stopped a whole run (a user trial): that photo is skipped
    with its reason (on stderr, in the table and the JSON) and the others are evaluated; with
    none left it is an error."""
    data = tmp_path / "data"
    data.mkdir()
    img, mask = _photo_with_shadow(box=(30, 44, 8, 30))
    _write_item(data, "a", img, mask)
    _write_item(data, "b", img, mask)
    write_image(data / "b_mask.png", np.zeros((10, 10), np.float32), force=True)
    out_json = tmp_path / "r.json"
    assert main(["eval", "real", str(data), "--mode", "classic", "--preset", "fast,balanced",
                 "--json", str(out_json)]) == 0
    out, err = capsys.readouterr()
    said = "outcast eval real: warning: b skipped: expected a mask of the image's size"
    assert err.count(said) == 1  # (once, not once a preset)
    assert "Skipped b: expected a mask" in out and "**mean (1)**" in out
    rep = json.loads(out_json.read_text())["fast"]
    assert [p["name"] for p in rep["photos"]] == ["a"] and rep["skipped"][0]["name"] == "b"
    write_image(data / "a_mask.png", np.zeros((10, 10), np.float32), force=True)
    assert main(["eval", "real", str(data), "--mode", "classic", "--preset", "fast"]) == 2
    assert "no photo could be evaluated" in capsys.readouterr().err
