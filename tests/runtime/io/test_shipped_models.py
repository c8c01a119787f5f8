"""The shipped ONNX models load with their checksums and run through the session (no torch)."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from outcast_core.runtime.io.models import DEFAULT_MODEL_DIR, ModelError, ModelRegistry
from outcast_core.runtime.pipeline.session import RelightSession
from tests.runtime.scenes import box_scene_depth

SHIPPED = sorted(p.stem for p in DEFAULT_MODEL_DIR.glob("*.json"))


def test_the_shadow_model_ships() -> None:
    assert "shadow" in SHIPPED


@pytest.mark.parametrize("name", SHIPPED)
def test_each_model_loads_and_matches_its_manifest(name: str) -> None:
    model = ModelRegistry().load(name)
    assert [i["name"] for i in model.manifest["inputs"]] == model.input_names
    assert model.manifest.get("metrics"), f"{name} ships without measured metrics"
    assert model.manifest.get("training"), f"{name} ships without its training record"


def test_learned_session_end_to_end() -> None:
    h, w = 60, 80  # not a multiple of the pad size on purpose
    depth = box_scene_depth(h, w, 150.0, 60.0, [(-4.0, 0.0, -3.0, 1.0, 4.0)])
    rng = np.random.default_rng(0)
    image = np.clip(0.5 + 0.1 * rng.standard_normal((h, w, 3)), 0, 1).astype(np.float32)
    s = RelightSession(mode="learned", preset="fast")
    assert s.shadow_mode == "learned"
    s.set_image(image, depth=depth, fov_deg=30.0)
    shadow = s.shadow((-0.5, -0.3, -0.8))
    assert shadow.shape == (h, w) and np.isfinite(shadow).all()
    assert shadow.min() >= 0 and shadow.max() <= 1
    s.set_original_sun((-0.5, -0.3, -0.8))
    out = s.relight((0.5, 0.3, -0.8))
    assert out.shape == (h, w, 3) and np.isfinite(out).all()
    assert out.min() >= 0 and out.max() <= 1


@pytest.mark.skipif("depth" not in SHIPPED, reason="no depth model shipped")
def test_session_depth_from_z_is_post_processed() -> None:
    """The session runs Z at its training scale (a 192 x 256 photo shrunk to 96 x 128, as its
    manifest says) and post-processes at the working size."""
    from outcast_core.runtime.pipeline.depth_post import postprocess_z, run_depth_model

    rng = np.random.default_rng(3)
    image = np.empty((192, 256, 3), np.float32)
    image[:80] = (0.4, 0.6, 0.95)  # clear sky over textured ground
    image[80:] = 0.3 + 0.2 * rng.random((112, 256, 1))
    s = RelightSession(mode="learned", preset="fast")
    s.set_image(image, fov_deg=60.0)
    assert s.depth_source == "model" and s.image_srgb.shape == (192, 256, 3)
    model = ModelRegistry().load("depth")
    assert model.input_side == model.manifest["training"]["config"]["size"] == 128
    raw, sky_prob = run_depth_model(model, s.image_srgb)
    depth, sky = postprocess_z(raw, sky_prob, s.image_srgb, s.camera)
    np.testing.assert_array_equal(s.sky, sky)
    np.testing.assert_allclose(s.depth, depth, rtol=1e-6)
    full = model.run({"image": s.image_srgb.transpose(2, 0, 1)[None]})["depth"][0, 0]
    assert not np.allclose(raw, full, rtol=1e-3)  # not Z at the working size
    assert not s.sky[120:].any()  # the textured ground is never sky


def test_corrupt_model_file_is_named(tmp_path: Path) -> None:
    for f in DEFAULT_MODEL_DIR.glob("shadow.*"):
        shutil.copy(f, tmp_path / f.name)
    data = bytearray((tmp_path / "shadow.onnx").read_bytes())
    data[len(data) // 2] ^= 0xFF
    (tmp_path / "shadow.onnx").write_bytes(bytes(data))
    with pytest.raises(ModelError, match=r"shadow\.onnx.*corrupt"):
        ModelRegistry(tmp_path).load("shadow")
    (tmp_path / "shadow.onnx").unlink()
    with pytest.raises(ModelError, match=r"shadow\.onnx.*missing"):
        ModelRegistry(tmp_path).load("shadow")


def test_learned_shadows_do_not_depend_on_depth_units() -> None:
    """Depth in any unit gives the same shadows, down to values whose inverse overflows float32."""
    h, w = 48, 64
    depth = box_scene_depth(h, w, 120.0, 60.0, [(-4.0, 0.0, -3.0, 1.0, 4.0)])
    image = np.full((h, w, 3), 0.5, np.float32)
    sun = (-0.5, -0.3, -0.8)
    out = []
    for scale in (1.0, 1e-40):  # 1e-40 m: denormal in float32, 1 / depth is inf
        s = RelightSession(mode="learned", preset="fast")
        s.set_image(image, depth=(depth * scale).astype(np.float32), fov_deg=50.0)
        out.append(s.shadow(sun))
    assert np.all(np.isfinite(out[1]))
    np.testing.assert_allclose(out[0], out[1], atol=1e-4)

