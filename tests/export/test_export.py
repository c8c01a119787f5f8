"""Export parity: every network kind in onnxruntime equals torch to 1e-4 at several sizes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import onnxruntime as ort
import pytest
import torch

from outcast_core.export.onnx_export import (
    PARITY_TOL,
    SPECS,
    check_parity,
    export_onnx,
    sample_inputs,
    spec_for,
    write_manifest,
)
from outcast_core.nets import build
from outcast_core.runtime.io.models import sha256_file


@pytest.mark.parametrize("kind", sorted(SPECS))
def test_export_parity_and_manifest(kind: str, tmp_path) -> None:
    torch.manual_seed(0)
    kw = {"steps": 8} if kind == "shadow" else {}
    net = build(kind, **kw)
    if kind in ("refine", "relight", "relight_pix2pix"):  # make the zero-init head non-trivial
        torch.nn.init.normal_(net.unet.head.weight, std=0.1)
    path = tmp_path / f"{kind}.onnx"
    m = net.pad_multiple
    worst = export_onnx(net, kind, path, [(2 * m, 2 * m), (3 * m, 5 * m), (5 * m, 2 * m)])
    assert worst <= PARITY_TOL
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    assert [i.name for i in sess.get_inputs()] == [n for n, _ in SPECS[kind].inputs]
    assert [o.name for o in sess.get_outputs()] == [n for n, _ in SPECS[kind].outputs]
    man = json.loads(write_manifest(net, kind, path, {"steps": 0}, {"x": 1.0}).read_text())
    assert man["sha256"] == sha256_file(path)
    assert man["file"] == path.name and man["colour_space"] == "srgb"
    assert man["pad_multiple"] == m
    if kind == "shadow":
        assert man["march_steps"] == 8 and man["volume_scale"] == 0.5
    # Only Z and D record the side they were trained at (the runtime shrinks photos to it).
    man = json.loads(write_manifest(net, kind, path, {"config": {"size": 96}}).read_text())
    assert man.get("input_side") == (96 if kind in ("depth", "sun") else None)
    if kind == "sun":  # what the runtime needs to read D's logits
        assert man["bins"] == net.bins.shape[0] and man["kappa"] > 0
        assert man["outputs"] == [{"name": "logits", "shape": ["B", man["bins"]]}]


def test_an_exported_sun_model_reads_in_the_runtime(tmp_path) -> None:
    """D exported with a few bins runs through the registry and read_sun on any photo size;
    the runtime's kernel mixture peaks at the bin the logits favour."""
    from outcast_core.nets.sun import SunNet
    from outcast_core.runtime.io.models import ModelRegistry
    from outcast_core.runtime.pipeline.sun_look import read_sun

    torch.manual_seed(0)
    net = SunNet(bins=48).eval()
    with torch.no_grad():  # logits that favour bin 7 whatever the photo
        net.fc[-1].weight.zero_()
        net.fc[-1].bias.zero_()
        net.fc[-1].bias[7] = 6.0
    export_onnx(net, "sun", tmp_path / "sun.onnx")
    write_manifest(net, "sun", tmp_path / "sun.onnx", {"config": {"size": 64}})
    model = ModelRegistry(tmp_path).load("sun")
    for shape in ((300, 400, 3), (20, 90, 3)):
        look = read_sun(model, np.random.default_rng(0).random(shape, np.float32),
                        mirrored=False)
        assert look.probabilities.shape == (48,)
        assert look.probabilities.sum() == pytest.approx(1.0)
        np.testing.assert_allclose(look.peak(), net.bins[7].numpy(), atol=1e-6)


def test_model_input_side_from_the_manifest_or_its_training_config() -> None:
    from outcast_core.runtime.io.models import Model

    def side(manifest: dict) -> int | None:
        return Model("depth", Path("depth.onnx"), manifest, None).input_side

    assert side({"input_side": 160, "training": {"config": {"size": 128}}}) == 160
    assert side({"training": {"config": {"size": 128}}}) == 128  # manifests before the key
    assert side({}) is None and side({"training": {}}) is None


def test_export_of_relight_with_the_physics_base_takes_the_light_ratio(tmp_path) -> None:
    torch.manual_seed(0)
    net = build("relight", base="physics")
    torch.nn.init.normal_(net.unet.head.weight, std=0.1)
    path = tmp_path / "relight.onnx"
    assert export_onnx(net, "relight", path, [(16, 16), (24, 40)]) <= PARITY_TOL
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    names = [i.name for i in sess.get_inputs()]
    assert names == [n for n, _ in SPECS["relight"].inputs] + ["light_ratio"]
    feeds = sample_inputs("relight", 16, 16, spec=spec_for("relight", net))
    a = sess.run(None, feeds)[0]
    b = sess.run(None, feeds | {"light_ratio": feeds["light_ratio"] * 4.0})[0]
    assert np.abs(a - b).max() > 1e-3  # the ratio reaches the graph
    man = json.loads(write_manifest(net, "relight", path, {"steps": 0}).read_text())
    assert man["base"] == "physics"
    assert man["inputs"][-1] == {"name": "light_ratio", "shape": ["B", 3]}


def test_session_relights_with_a_physics_base_l_as_the_physics_mode_does(tmp_path) -> None:
    """An untrained physics-base L (zero head) is the shading-ratio relighting: the session must
    feed it its own light estimate, shadows and sky exactly as its physics mode uses them."""
    from outcast_core.runtime.io.models import ModelRegistry
    from outcast_core.runtime.pipeline.relight import physics_relight
    from outcast_core.runtime.pipeline.session import RelightSession
    from tests.runtime.scenes import box_scene_depth

    net = build("relight", base="physics")
    path = tmp_path / "relight.onnx"
    write_manifest(net, "relight", path, {"steps": 0},
                   parity=export_onnx(net, "relight", path, [(16, 16)]))
    h, w = 48, 64
    depth = box_scene_depth(h, w, 150.0, 60.0, [(-4.0, 0.0, -3.0, 1.0, 4.0)])
    depth[:8] = np.inf  # a sky band
    rng = np.random.default_rng(2)
    image = np.clip(0.5 + 0.15 * rng.standard_normal((h, w, 3)), 0, 1).astype(np.float32)
    s = RelightSession(registry=ModelRegistry(tmp_path), mode="classic", relight_mode="learned",
                       preset="fast")
    assert s.relight_mode == "learned"
    # Compare L's own output (the colour guard, the shade floor, which colours new shadows as
    # physics on the smoothed new shadow, the lift and the photo's detail are tested in
    # test_relight).
    s.colour_guard = s.lift_new_light = s.contrast_floor = s.keep_detail = False
    s.daylight = False  # (the new sun's daylight, the same for both: tested in test_daylight)
    s.set_image(image, depth=depth, fov_deg=30.0)
    # Shade the photo by its own shadows so the session measures its light ratio.
    from outcast_core.runtime.geometry.colour import linear_to_srgb, srgb_to_linear

    shade = 1.0 + np.array([4.0, 3.0, 2.0], np.float32) * s.shadow((-0.5, -0.3, -0.8))[..., None]
    s.set_image(linear_to_srgb(0.15 * srgb_to_linear(s.image_srgb) * shade), depth=depth,
                fov_deg=30.0)
    s.set_original_sun((-0.5, -0.3, -0.8))
    assert s.light_estimate.measured
    w_n = (0.6, -0.2, -0.8)
    got = s.relight(w_n)
    want = physics_relight(s.image_srgb, s.original_shadow, s.shadow(w_n), s.sky,
                           light=s.light_estimate, snap=False)
    np.testing.assert_allclose(got, np.clip(want, 1e-3, 1 - 1e-3), atol=2e-5)
    assert np.abs(got - s.image_srgb).max() > 0.05  # the shadows moved


def test_batch_of_two_runs_in_onnxruntime(tmp_path) -> None:
    net = build("shadow", steps=8).eval()
    path = tmp_path / "s.onnx"
    export_onnx(net, "shadow", path, [(32, 32)])
    one = sample_inputs("shadow", 32, 48, seed=1)
    two = {k: np.concatenate([v, v]) for k, v in one.items()}
    out = ort.InferenceSession(str(path)).run(None, two)[0]
    with torch.no_grad():
        ref = net(*[torch.from_numpy(v) for v in two.values()]).numpy()
    assert np.abs(out - ref).max() <= PARITY_TOL


def test_parity_check_catches_a_different_network(tmp_path) -> None:
    torch.manual_seed(0)
    net = build("refine")
    torch.nn.init.normal_(net.unet.head.weight, std=0.5)
    path = tmp_path / "r.onnx"
    export_onnx(net, "refine", path, [(16, 16)])
    torch.nn.init.normal_(net.unet.head.weight, std=0.5)  # the torch net changes after export
    with pytest.raises(RuntimeError, match="differs"):
        check_parity(net, "refine", path, [(16, 16)])
