"""Model cards come from manifests; evaluation metrics and the sweep table behave."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from outcast_core.eval.cli import render_depth, render_sweep, render_table
from outcast_core.eval.metrics import depth_errors, dssim, iou, mse
from outcast_core.eval.table import plot_speed_accuracy, save_sheet
from outcast_core.export.cards import render_cards, update_readme
from outcast_core.export.onnx_export import export_onnx, write_manifest
from outcast_core.nets import build


def test_metrics() -> None:
    rng = np.random.default_rng(0)
    a = rng.random((32, 32, 3)).astype(np.float32)
    assert mse(a, a) == 0.0 and abs(dssim(a, a)) < 1e-6
    b = np.clip(a + 0.1, 0, 1)
    assert mse(a, b) > 0 and 0 < dssim(a, b) < dssim(a, 1 - a) <= 1
    with pytest.raises(ValueError, match="one shape"):
        mse(a, a[:8])


def test_depth_errors_are_scale_free() -> None:
    rng = np.random.default_rng(1)
    gt = rng.uniform(1.0, 50.0, (16, 24))
    valid = np.ones_like(gt, bool)
    valid[:4] = False
    exact = depth_errors(3.7 * gt, gt, valid)  # any global scale is not an error
    assert exact["silog"] < 1e-9 and exact["abs_rel"] < 1e-9 and exact["delta1"] == 1.0
    noisy = gt * np.exp(rng.normal(0, 0.3, gt.shape))
    err = depth_errors(noisy, gt, valid)
    assert 0.25 < err["silog"] < 0.35 and 0.1 < err["abs_rel"] < 0.4 and err["delta1"] < 0.8
    bad = noisy.copy()
    bad[:4] = 1e9  # invalid pixels are not scored
    assert depth_errors(bad, gt, valid) == err
    assert np.isnan(depth_errors(gt, gt, np.zeros_like(valid))["silog"])
    a = np.zeros((4, 4), bool)
    b = a.copy()
    a[:2], b[1:3] = True, True
    assert iou(a, b) == pytest.approx(1 / 3) and iou(a & False, b & False) == 1.0
    text = render_depth({"Z": exact | {"sky_iou": 0.9, "time_s": 0.01}})
    assert "| Z | 0.0000 |" in text


def test_cards_render_from_manifests(tmp_path) -> None:
    torch.manual_seed(0)
    net = build("refine")
    path = tmp_path / "refine.onnx"
    export_onnx(net, "refine", path, [(16, 16)])
    write_manifest(net, "refine", path, {"config": {"stage": "relight", "run": "r", "batch": 4},
                                          "steps": 12, "wall_time_s": 3.5},
                   {"heldout_dssim": 0.1})
    text = render_cards(tmp_path, "preamble")
    assert "`refine.onnx`" in text and "12 steps" in text and "heldout_dssim" in text
    assert "preamble" in text
    (tmp_path / "README.md").write_text(text.replace("12 steps", "99 steps"))  # stale card
    fresh = update_readme(tmp_path).read_text()
    assert "12 steps" in fresh and "99 steps" not in fresh and fresh.count("preamble") == 1
    assert "Continues run" not in fresh
    write_manifest(net, "refine", path, {
        "config": {"stage": "relight", "run": "r2"}, "steps": 20, "wall_time_s": 7.0,
        "command": "outcast train r2.toml",
        "branched_from": {"run": "r", "step": 12, "wall_time_s": 3.5,
                          "command": "outcast train r.toml", "threads": 2},
    }, {})
    text = render_cards(tmp_path, "")
    assert "`outcast train r2.toml`" in text
    assert "Continues run `r` (`outcast train r.toml`) from its step 12" in text
    assert "trained with 2 thread(s)" in text
    assert "Extra data" not in text
    from outcast_core.export.checkpoint import _branch

    started = _branch({"init_onnx": "/m/depth.onnx", "sha256": "ab" * 32, "step": 9500,
                       "wall_time_s": 600.0, "command": "outcast train z4.toml"})
    write_manifest(net, "refine", path, {
        "config": {"stage": "relight", "run": "r3"}, "steps": 30, "wall_time_s": 60.0,
        "branched_from": started}, {})
    text = render_cards(tmp_path, "")
    assert ("Starts from the weights of `depth.onnx` (sha256 abababababab..., trained 9500 "
            "steps in 10 min by `outcast train z4.toml`)") in text
    assert "Continues run" not in text
    write_manifest(net, "refine", path, {
        "config": {"stage": "depth", "run": "z"}, "steps": 5, "wall_time_s": 1.0,
        "extra_data": [{"data_set": "/d/land", "views_loaded": 650,
                        "data_record": {"seed": 7, "views": 700, "suns": 1,
                                        "kind": "landscape"}}],
    }, {})
    assert ("- Extra data: `/d/land` (data seed 7, 700 views of 1 sun(s), scene kind landscape, "
            "650 of them loaded)") in render_cards(tmp_path, "")


def test_tables_and_pictures(tmp_path) -> None:
    res = {"rows": {"Ours": {"dssim": 0.1, "mse": 0.01, "shadow_mse": 0.02, "time_s": 0.5},
                    "Input": {"dssim": 0.2, "mse": 0.03, "time_s": 0.0}}}
    text = render_table(res)
    assert text.index("Input") < text.index("Ours") and "0.0200" in text
    sweep = [{"steps": z, "size": s, "shadow_mse": 0.01 * z / s, "latency_ms": z * s / 100}
             for z in (8, 16) for s in (96, 128)]
    assert render_sweep(sweep).count("\n") == 3
    png = plot_speed_accuracy(sweep, tmp_path / "p.png")
    sheet = save_sheet([{"a": np.zeros((8, 8, 3)), "b": np.ones((8, 8))}], tmp_path / "s.png")
    assert png.stat().st_size > 1000 and sheet.stat().st_size > 100


def test_shadow_contrast_measures_a_painted_new_shadow() -> None:
    """A relit photo whose new-shadow band is half as bright as the lit surface gives a
    contrast of 0.5 there; the band's share of the surface and the photo's own shadow contrast
    come out as painted."""
    from outcast_core.eval.samples import shadow_contrast

    h, w = 40, 50
    sky = np.zeros((h, w), bool)
    sky[:10] = True  # 30 surface rows
    s_o = np.full((h, w), 0.8, np.float32)
    s_o[:, :5] = 0.0  # an old shadow on the left
    s_n = np.full((h, w), 0.6, np.float32)
    s_n[20:26, 10:40] = 0.0  # a new shadow band, lit under the old sun
    image = np.full((h, w, 3), 0.6, np.float32)
    image[:, :5] = 0.24  # the photo's shadow: 0.4 of its lit surface
    relit = np.full((h, w, 3), 0.8, np.float32)
    relit[20:26, 10:40] = 0.4
    c = shadow_contrast(image, relit, s_o, s_n, sky)
    assert c["new_shadow_frac"] == pytest.approx(6 * 30 / (30 * 50), abs=1e-4)
    assert c["relit_contrast"] == pytest.approx(0.5, abs=1e-3)
    assert c["photo_contrast"] == pytest.approx(0.4, abs=1e-3)
    none = shadow_contrast(image, relit, s_o, np.full((h, w), 0.6, np.float32), sky)
    assert none["new_shadow_frac"] == 0.0 and none["relit_contrast"] is None
    assert shadow_contrast(image, relit, s_o, s_n, np.ones((h, w), bool))["relit_contrast"] \
        is None


def test_sample_photos_are_relit_into_a_sheet(tmp_path) -> None:
    import json

    from PIL import Image

    from outcast_core.eval.samples import relight_samples, save_samples_sheet

    rng = np.random.default_rng(0)
    Image.fromarray(rng.integers(0, 255, (48, 64, 3), dtype=np.uint8)).save(tmp_path / "a.jpg")
    spec = tmp_path / "suns.json"
    spec.write_text(json.dumps({"_about": "x", "a.jpg": {"from": [90, 40],
                                                         "to": [[270, 30], [0, 20]]}}))
    rows, records = relight_samples(spec)
    assert list(rows[0]) == ["Input", "Z depth", "S_o (refined)", "S_n 270,30", "Relit 270,30",
                             "S_n 0,20", "Relit 0,20"]
    assert records[0]["file"] == "a.jpg" and records[0]["relight"] == "learned"
    assert len(records[0]["contrast"]) == 2
    assert 0.0 <= records[0]["contrast"][0]["new_shadow_frac"] <= 1.0
    png = save_samples_sheet(rows, tmp_path / "s.png", tile=32)
    h, w = np.asarray(Image.open(png)).shape[:2]
    assert (h, w) == (18 + 24, 7 * 32)  # rows keep the photo's 4:3 aspect
    spec.write_text(json.dumps({"_about": "nothing"}))
    with pytest.raises(ValueError, match="at least one photo"):
        relight_samples(spec)


def test_evaluate_table_runs_every_method_on_a_tiny_test_set(tmp_path) -> None:
    """Table 1 end to end on a hand-made view with untrained exported networks: every row is
    measured, and a zero-head physics-base L (fed its light ratio and true normals, as there is
    no Z here) changes the photo where a zero-head Pix2Pix-like L returns it."""
    from outcast_core.data.dataset import save_view
    from outcast_core.eval.table import evaluate_table
    from outcast_core.runtime.geometry.camera import sun_angles
    from tests.train.conftest import make_view

    data = tmp_path / "test"
    v = make_view(0, size=128, suns=2)  # the evaluation works at 128 px
    v["sun_azel"] = np.array([sun_angles(s) for s in v["sun"]], np.float32)
    save_view(data / "view_000000", v, {})
    models = tmp_path / "models"
    torch.manual_seed(0)
    for kind, kw in (("shadow", {"steps": 8}), ("shadow_2d", {}), ("refine", {}),
                     ("relight", {"base": "physics"}), ("relight_pix2pix", {})):
        export_onnx(build(kind, **kw), kind, models / f"{kind}.onnx", [(16, 16)])
    res = evaluate_table(data, models, threads=1, sheet_pairs=1)
    assert res["missing"] == ["depth"] and res["views"] == 1 and res["pairs"] == 2
    rows = res["rows"]
    for method in ("Input", "Direct", "Ours", "2D", "Pix2Pix-like", "Physics (Ours shadows)",
                   "Physics (Direct shadows)"):
        assert method in rows and np.isfinite(rows[method]["dssim"]), method
    for method in ("Direct", "Ours", "2D"):
        assert np.isfinite(rows[method]["shadow_mse"]), method
    assert "Ours (Z depth)" not in rows and res["depth"] == {}
    assert rows["Pix2Pix-like"]["dssim"] == pytest.approx(rows["Input"]["dssim"], abs=1e-4)
    assert abs(rows["Ours"]["mse"] - rows["Input"]["mse"]) > 1e-5
    assert len(res["sheet"]) == 1 and "Ours" in res["sheet"][0]


def test_evaluate_table_with_z_adds_the_photo_pipeline_rows(tmp_path) -> None:
    """With ``depth.onnx`` installed, Table 1 also runs the photo-only pipeline: S and Direct on
    Z's post-processed depth, both fed to R and L, and Direct there differs from Direct on the
    true depth (an untrained Z's depth is not the ground truth)."""
    from outcast_core.data.dataset import save_view
    from outcast_core.eval.table import evaluate_table
    from outcast_core.runtime.geometry.camera import sun_angles
    from tests.train.conftest import make_view

    data = tmp_path / "test"
    v = make_view(0, size=128, suns=2)
    v["sun_azel"] = np.array([sun_angles(s) for s in v["sun"]], np.float32)
    save_view(data / "view_000000", v, {})
    models = tmp_path / "models"
    torch.manual_seed(0)
    for kind, kw in (("depth", {}), ("shadow", {"steps": 8}), ("refine", {}),
                     ("relight", {"base": "physics"})):
        export_onnx(build(kind, **kw), kind, models / f"{kind}.onnx", [(16, 16)])
    res = evaluate_table(data, models, threads=1, sheet_pairs=1)
    rows = res["rows"]
    for method in ("Ours (Z depth)", "Direct (Z depth)"):
        assert rows[method]["n"] == 2, method
        for key in ("dssim", "mse", "shadow_mse", "time_s"):
            assert np.isfinite(rows[method][key]), (method, key)
    assert rows["Direct (Z depth)"]["shadow_mse"] != pytest.approx(
        rows["Direct"]["shadow_mse"], abs=1e-6)
    assert "S_n Direct (Z depth)" in res["sheet"][0]


def test_evaluate_depth_scores_z_alone_on_one_sun_views(tmp_path) -> None:
    """The Z-only evaluation (``outcast eval --depth-data``) scores every photo of one-sun views
    (no relighting pairs there) and names the missing model file."""
    from outcast_core.data.dataset import save_view
    from outcast_core.eval.table import DEPTH_SCALES, evaluate_depth
    from outcast_core.runtime.geometry.camera import sun_angles
    from tests.train.conftest import make_view

    data = tmp_path / "land"
    for i in range(2):
        v = make_view(i, size=128, suns=1)
        v["sun_azel"] = np.array([sun_angles(s) for s in v["sun"]], np.float32)
        save_view(data / f"view_{i:06d}", v, {})
    models = tmp_path / "models"
    with pytest.raises(ValueError, match="depth.onnx"):
        evaluate_depth(data, models, threads=1)
    torch.manual_seed(0)
    export_onnx(build("depth"), "depth", models / "depth.onnx", [(32, 32)])
    res = evaluate_depth(data, models, threads=1)
    assert (res["views"], res["photos"]) == (2, 2)
    z = res["depth"]["Z"]
    assert z["n"] == 2 and np.isfinite(z["silog"]) and 0.0 <= z["sky_iou"] <= 1.0
    scaled = {f"Z, view shown {f:g}x larger" for f in DEPTH_SCALES}
    assert set(res["depth"]) == {"Z", "Z + post-processing (app)", "Ground-plane prior"} | scaled
    for row in scaled:  # scored on the view's own size, against the same ground truth
        assert res["depth"][row]["n"] == 2 and np.isfinite(res["depth"][row]["silog"])
    # An untrained Z's output depends on the scale it sees.
    assert res["depth"]["Z, view shown 3x larger"]["silog"] != pytest.approx(z["silog"])
