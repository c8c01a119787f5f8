"""Any ONNX depth model: tiny models with Depth Anything's and MiDaS's input/output conventions
(made with onnx.helper, no torch) give back the depth they were built from."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from outcast_core.runtime.geometry.camera import Camera
from outcast_core.runtime.io.depth_models import (
    ModelDepthSource,
    PhoneDepthSource,
    far_sky,
    fit_affine_ground,
    inverse_shift,
    inverse_to_depth,
    load_depth_model,
    read_sidecar,
    scale_to_ground,
)
from outcast_core.runtime.io.models import ModelError
from outcast_core.runtime.io.phone_depth import PhoneDepth
from outcast_core.runtime.pipeline.session import RelightSession
from tests.runtime.depth_fixtures import (
    encode_inverse_image,
    finite_corr,
    outdoor_scene,
    tiny_depth_model,
)

pytest.importorskip("onnx")


def _check_depth(depth: np.ndarray, sky: np.ndarray, truth: np.ndarray, *, scale: bool) -> None:
    true_sky = ~np.isfinite(truth)
    assert (sky == true_sky).mean() > 0.97
    surface = ~true_sky & ~sky
    assert finite_corr(1 / depth, 1 / truth, surface) >= 0.99
    near = surface & (truth < 30)  # the horizon's last rows are resampled across the sky
    assert finite_corr(depth, truth, near) >= 0.99
    if scale:  # the ground plane 1.6 m below the camera fixes the units
        assert np.median(np.abs(depth[near] / truth[near] - 1)) < 0.05


def test_depth_anything_convention(tmp_path: Path) -> None:
    truth, cam = outdoor_scene()
    image, top = encode_inverse_image(truth)
    # relative inverse depth with an unknown scale and shift, dynamic size, ViT patch 14
    path = tiny_depth_model(tmp_path / "da.onnx", input_name="pixel_values",
                            output_name="predicted_depth", size=None, block=14, gain=7.0,
                            offset=0.3)
    model = load_depth_model(path)
    assert model.spec.fixed_size is None and model.spec.output == "inverse-relative"
    depth, sky = model.estimate(image, cam)
    assert model.spec.multiple == 14  # found by running
    _check_depth(depth, sky, truth, scale=True)
    assert model.last_seconds > 0


def test_midas_convention_fixed_size(tmp_path: Path) -> None:
    truth, cam = outdoor_scene()
    image, _ = encode_inverse_image(truth)
    path = tiny_depth_model(tmp_path / "midas.onnx", input_name="0", output_name="1064",
                            size=(256, 256), block=32, gain=1500.0, offset=20.0)
    model = load_depth_model(path)
    assert model.spec.fixed_size == (256, 256) and model.spec.multiple == 32
    depth, sky = model.estimate(image, cam)
    _check_depth(depth, sky, truth, scale=True)


def test_dynamic_multiple_of_32_is_found(tmp_path: Path) -> None:
    truth, cam = outdoor_scene()
    image, _ = encode_inverse_image(truth)
    path = tiny_depth_model(tmp_path / "cnn.onnx", input_name="image", output_name="depth",
                            size=None, block=32, gain=2.0, offset=0.0, output_4d=True)
    model = load_depth_model(path)
    depth, sky = model.estimate(image, cam)
    assert model.spec.multiple == 32
    _check_depth(depth, sky, truth, scale=True)


def test_sidecar_declares_metric_depth_and_normalisation(tmp_path: Path) -> None:
    truth, cam = outdoor_scene()
    image, top = encode_inverse_image(truth)
    path = tiny_depth_model(tmp_path / "metric.onnx", input_name="x", output_name="y",
                            size=None, block=None, gain=top, offset=1e-4, mean=(0.5,) * 3,
                            std=(0.5,) * 3, reciprocal=True)
    (tmp_path / "metric.onnx.json").write_text(json.dumps(
        {"input_size": 64, "mean": [0.5] * 3, "std": [0.5] * 3, "output": "metric"}))
    model = load_depth_model(path)
    assert model.spec.output == "metric" and model.spec.side == 64
    depth, sky = model.estimate(image, cam)
    _check_depth(depth, sky, truth, scale=True)


def test_relative_depth_is_scaled_to_the_camera_height(tmp_path: Path) -> None:
    truth, cam = outdoor_scene()
    image, top = encode_inverse_image(truth)
    path = tiny_depth_model(tmp_path / "rel.onnx", input_name="x", output_name="y",
                            size=None, block=None, gain=top * 3, offset=3e-4, reciprocal=True)
    (tmp_path / "rel.onnx.json").write_text(json.dumps({"output": "depth-relative"}))
    depth, sky = load_depth_model(path).estimate(image, cam)
    _check_depth(depth, sky, truth, scale=True)


def test_no_sky_uses_the_level_grounds_horizon() -> None:
    truth, cam = outdoor_scene()
    truth = np.where(np.isfinite(truth), truth, 30.0)  # a far wall instead of the sky
    truth[: cam.height // 2] = 30.0
    r = 4.0 / truth + 0.7
    sky = np.zeros(truth.shape, bool)
    ground = fit_affine_ground(r, sky, cam)
    assert ground is not None and ground[1] > 0
    assert inverse_shift(r, sky, cam) == pytest.approx(0.7, abs=0.01)
    depth = inverse_to_depth(r, sky, cam)
    assert finite_corr(depth, truth, np.ones(truth.shape, bool)) >= 0.99
    assert np.median(np.abs(depth / truth - 1)) < 0.05


def test_affine_ground_finds_a_known_plane_among_outliers() -> None:
    cam = Camera.from_fov(240, 320, 60.0)  # 38 400 lower-half pixels: AFFINE_POINTS sampled
    xs = (np.arange(cam.width) + 0.5 - cam.cx) / cam.focal
    ys = (np.arange(cam.height) + 0.5 - cam.cy) / cam.focal
    xx, yy = np.meshgrid(xs, ys)
    rng = np.random.default_rng(5)
    plane = (0.15, 0.9, 0.35)
    r = plane[0] * xx + plane[1] * yy + plane[2] + rng.normal(0.0, 1e-3, xx.shape)
    outliers = rng.random(r.shape) < 0.35  # a third of the pixels anywhere in the range
    r[outliers] = rng.uniform(r.min(), r.max(), int(outliers.sum()))
    r[:5, :5] = np.nan  # not finite: left out
    sky = np.zeros(r.shape, bool)
    fit = fit_affine_ground(r, sky, cam, seed=3)
    assert fit is not None
    np.testing.assert_allclose(fit, plane, atol=2e-3)
    assert fit_affine_ground(r, sky, cam, seed=3) == fit  # deterministic for a seed
    assert fit_affine_ground(r.astype(np.float32), sky, cam, seed=3) == pytest.approx(fit,
                                                                                     abs=1e-5)
    assert fit_affine_ground(r, sky, cam, seed=4) == pytest.approx(fit, abs=1e-3)
    # A ceiling (nearer toward the top) is no ground; pure noise and too few pixels give none.
    assert fit_affine_ground(plane[0] * xx - plane[1] * yy + plane[2], sky, cam) is None
    assert fit_affine_ground(rng.uniform(0, 1, r.shape), sky, cam) is None
    assert fit_affine_ground(r, np.ones(r.shape, bool), cam) is None


def test_far_sky_needs_the_top_and_a_sky_colour() -> None:
    truth, cam = outdoor_scene()
    image, _ = encode_inverse_image(truth)
    inv = np.where(np.isfinite(truth), 1 / truth, 0.0)
    assert (far_sky(inv, image) == ~np.isfinite(truth)).mean() > 0.99
    assert (far_sky(inv) == ~np.isfinite(truth)).mean() > 0.98  # + the ground's farthest row
    grey = np.full_like(image, 0.3)  # the far region of a frame with no sky colour
    assert not far_sky(inv, grey).any()
    assert not far_sky(np.ones((8, 8))).any()


def test_scale_without_a_ground_plane_sets_the_median() -> None:
    cam = outdoor_scene()[1]
    d = scale_to_ground(np.full((cam.height, cam.width), 3.0), np.zeros((48, 64), bool), cam)
    assert np.median(d) == pytest.approx(10.0)
    with pytest.raises(ValueError, match="camera height"):
        scale_to_ground(d, np.zeros((48, 64), bool), cam, camera_height=0.0)


def test_the_photo_is_shrunk_before_it_is_made_float32(tmp_path: Path) -> None:
    """uint8, float32 and float64 photos (and a strided view) give the same model output."""
    big, _ = encode_inverse_image(outdoor_scene(96, 128)[0])
    path = tiny_depth_model(tmp_path / "da.onnx", input_name="pixel_values",
                            output_name="predicted_depth", size=None, block=14, gain=7.0,
                            offset=0.3)
    model = load_depth_model(path, threads=1)
    as_u8 = np.round(big * 255).astype(np.uint8)
    ref = model.run(as_u8 / np.float32(255.0), (48, 64))
    np.testing.assert_array_equal(model.run(as_u8, (48, 64)), ref)
    np.testing.assert_allclose(model.run((as_u8 / 255.0).astype(np.float64), (48, 64)), ref,
                               atol=1e-5)
    wide = np.zeros((96, 256, 3), np.float32)
    wide[:, ::2] = as_u8 / np.float32(255.0)
    np.testing.assert_array_equal(model.run(wide[:, ::2], (48, 64)), ref)
    with pytest.raises(ValueError, match="H x W x 3"):
        model.run(as_u8[..., :2])


def test_bad_models_and_sidecars_give_clear_errors(tmp_path: Path) -> None:
    with pytest.raises(ModelError, match="not found"):
        load_depth_model(tmp_path / "missing.onnx")
    junk = tmp_path / "junk.onnx"
    junk.write_bytes(b"not a model")
    with pytest.raises(ModelError, match="not a readable ONNX model"):
        load_depth_model(junk)
    import onnx
    from onnx import TensorProto, helper

    x = helper.make_tensor_value_info("x", TensorProto.FLOAT, [1, 1, 8, 8])  # grey input
    y = helper.make_tensor_value_info("y", TensorProto.FLOAT, [1, 1, 8, 8])
    model = helper.make_model(helper.make_graph([helper.make_node("Identity", ["x"], ["y"])],
                                                "g", [x], [y]),
                              opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    onnx.save(model, str(tmp_path / "grey.onnx"))
    with pytest.raises(ValueError, match="N x 3 x H x W"):
        load_depth_model(tmp_path / "grey.onnx")
    good = tiny_depth_model(tmp_path / "m.onnx", input_name="x", output_name="y", size=None,
                            block=None, gain=1.0, offset=0.0)
    for sidecar, message in [({"output": "disparity"}, "expected output"),
                             ({"inputsize": 5}, "unknown keys"),
                             ({"mean": [0.5, 0.5]}, "three numbers"),
                             ({"std": [0.0, 1.0, 1.0]}, "std > 0"),
                             ({"input_size": [0, 5]}, "input_size")]:
        (tmp_path / "m.onnx.json").write_text(json.dumps(sidecar))
        with pytest.raises(ValueError, match=message):
            load_depth_model(good)
    (tmp_path / "m.onnx.json").write_text("{")
    with pytest.raises(ValueError, match="cannot read depth model settings"):
        read_sidecar(tmp_path / "m.onnx.json")


def test_session_uses_the_depth_source_and_says_so(tmp_path: Path) -> None:
    truth, cam = outdoor_scene()
    image, _ = encode_inverse_image(truth)
    path = tiny_depth_model(tmp_path / "da.onnx", input_name="pixel_values",
                            output_name="predicted_depth", size=None, block=14, gain=7.0,
                            offset=0.3)
    s = RelightSession(mode="classic", preset="fast")
    s.depth_provider = ModelDepthSource(load_depth_model(path))
    s.set_image(image, fov_deg=60.0)
    assert s.depth_source.startswith("model da.onnx (") and s.depth_source.endswith(" s)")
    assert (s.sky == ~np.isfinite(truth)).mean() > 0.97
    phone = PhoneDepth(np.where(np.isfinite(truth), truth, 100.0).astype(np.float32),
                       "GDepth RangeLinear", True)
    s.depth_provider = PhoneDepthSource(phone)
    s.set_image(image, fov_deg=60.0)
    assert s.depth_source == "phone"
    assert (s.sky == ~np.isfinite(truth)).mean() > 0.97
    s.set_image(image, fov_deg=60.0, depth=np.ones((48, 64), np.float32))
    assert s.depth_source == "given"  # a depth file the user gives wins


def test_pick_depth_source_model_then_phone(tmp_path: Path) -> None:
    from outcast_core.runtime.io.depth_models import pick_depth_source
    from outcast_core.runtime.io.imageio import write_image

    truth, _ = outdoor_scene()
    image, _ = encode_inverse_image(truth)
    photo = tmp_path / "p.png"
    write_image(photo, image)
    assert pick_depth_source(photo) == (None, "")  # no model, no embedded map: Z
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"x")
    with pytest.raises(ModelError):
        pick_depth_source(photo, model_path=bad)
    provider, note = pick_depth_source(photo, model_path=bad, strict=False)
    assert provider is None and note.startswith("the depth model is not used: ")
    good = tiny_depth_model(tmp_path / "m.onnx", input_name="x", output_name="y", size=None,
                            block=None, gain=1.0, offset=0.0)
    provider, note = pick_depth_source(photo, model_path=good)
    assert isinstance(provider, ModelDepthSource) and note == ""


def test_the_model_sees_the_full_resolution_photo(tmp_path: Path) -> None:
    truth, cam = outdoor_scene()
    big, _ = encode_inverse_image(outdoor_scene(96, 128)[0])
    small = np.zeros((48, 64, 3), np.float32)  # a working image the model must not see
    small[..., 1:] = 0.5, 0.9  # (sky-coloured: the far region is the sky wherever it is)
    path = tiny_depth_model(tmp_path / "da.onnx", input_name="pixel_values",
                            output_name="predicted_depth", size=None, block=14, gain=7.0,
                            offset=0.3)
    source = ModelDepthSource(load_depth_model(path), photo_srgb=big)
    depth, sky = source(small, cam)
    _check_depth(depth, sky, truth, scale=True)
    with pytest.raises(ValueError, match="camera's size"):
        source(small[:10], cam)
