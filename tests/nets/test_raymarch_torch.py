"""The torch volume builder must equal the numpy RaySampler (ratio, valid, rgb)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from outcast_core.nets.raymarch_torch import march_volume
from outcast_core.runtime.geometry.camera import Camera, sun_vector
from outcast_core.runtime.geometry.raymarch import MAX_RATIO, RaySampler

SUNS = {
    "front": (0.0, 35.0),
    "behind": (180.0, 35.0),
    "overhead": (0.0, 90.0),
    "grazing": (90.0, 2.0),
    "front_left_low": (-40.0, 8.0),
    "behind_right": (150.0, 60.0),
}


def _scene(seed: int, h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    depth = (1.0 + 5.0 * rng.random((h, w))).astype(np.float32)
    depth[: h // 4] = np.inf  # sky band
    depth[rng.random((h, w)) < 0.05] = 0.0  # holes
    image = rng.random((h, w, 3)).astype(np.float32)
    return depth, image


def _torch_volume(depth, image, cam, w, steps, step, scale=1.0):
    return march_volume(
        torch.from_numpy(image).permute(2, 0, 1)[None],
        torch.from_numpy(depth)[None, None],
        torch.tensor(np.asarray(w), dtype=torch.float32)[None],
        torch.tensor([[cam.focal]], dtype=torch.float32),
        steps, step, scale,
    )


@pytest.mark.parametrize("sun", sorted(SUNS))
@pytest.mark.parametrize("seed", [0, 1])
def test_volume_matches_numpy(sun: str, seed: int) -> None:
    depth, image = _scene(seed, 20, 28)
    cam = Camera.from_fov(20, 28, 55.0 + 10 * seed)
    w = sun_vector(*SUNS[sun])
    ref = RaySampler(depth, cam).volume(w, steps=10, step=1 / 20, image=image)
    got = _torch_volume(depth, image, cam, w, 10, 1 / 20)
    np.testing.assert_array_equal(got["valid"][0, 0].numpy(), ref["valid"])
    np.testing.assert_allclose(got["ratio"][0, 0].numpy(), ref["ratio"], atol=1e-4, rtol=0)
    rgb = got["rgb"][0].permute(1, 2, 3, 0).numpy()  # z x H x W x 3
    np.testing.assert_allclose(rgb, ref["rgb"], atol=1e-4, rtol=0)
    assert 0.05 < ref["valid"].mean() < 0.95  # the case exercises both branches


def test_half_resolution_volume_matches_numpy_on_pooled_depth() -> None:
    depth, image = _scene(3, 24, 32)
    cam = Camera.from_fov(24, 32, 60.0)
    ok = np.isfinite(depth) & (depth > 0)
    disp = np.where(ok, 1.0 / np.where(ok, depth, 1.0), 0.0)
    disp_lr = disp.reshape(12, 2, 16, 2).max(axis=(1, 3))
    depth_lr = np.where(disp_lr > 0, 1.0 / np.where(disp_lr > 0, disp_lr, 1.0), np.inf)
    image_lr = image.reshape(12, 2, 16, 2, 3).mean(axis=(1, 3))
    w = sun_vector(60.0, 30.0)
    ref = RaySampler(depth_lr.astype(np.float32), cam.resized(12, 16)).volume(
        w, steps=6, step=1 / 16, image=image_lr.astype(np.float32)
    )
    got = _torch_volume(depth, image, cam, w, 6, 1 / 16, scale=0.5)
    assert got["ratio"].shape == (1, 1, 6, 12, 16)
    np.testing.assert_array_equal(got["valid"][0, 0].numpy(), ref["valid"])
    np.testing.assert_allclose(got["ratio"][0, 0].numpy(), ref["ratio"], atol=1e-4, rtol=0)
    np.testing.assert_allclose(
        got["rgb"][0].permute(1, 2, 3, 0).numpy(), ref["rgb"], atol=1e-4, rtol=0
    )


def test_batch_with_different_suns_equals_single_runs() -> None:
    depth, image = _scene(4, 16, 16)
    cam = Camera.from_fov(16, 16)
    suns = [sun_vector(*SUNS[k]) for k in ("front", "behind")]
    img = torch.from_numpy(image).permute(2, 0, 1)[None].repeat(2, 1, 1, 1)
    dep = torch.from_numpy(depth)[None, None].repeat(2, 1, 1, 1)
    both = march_volume(
        img, dep, torch.tensor(np.stack(suns), dtype=torch.float32),
        torch.full((2, 1), cam.focal), 5, 1 / 8,
    )
    for b, w in enumerate(suns):
        one = _torch_volume(depth, image, cam, w, 5, 1 / 8)
        torch.testing.assert_close(both["ratio"][b], one["ratio"][0])


def test_invalid_samples_get_max_ratio_and_black_rgb() -> None:
    depth, image = _scene(5, 16, 16)
    out = _torch_volume(depth, image, Camera.from_fov(16, 16), sun_vector(0, 40), 8, 1 / 8)
    invalid = ~out["valid"]
    assert invalid.any()
    assert torch.all(out["ratio"][invalid] == MAX_RATIO)
    assert torch.all(out["rgb"][invalid.expand_as(out["rgb"])] == 0)


def test_bad_inputs_raise() -> None:
    img = torch.rand(1, 3, 8, 8)
    dep = torch.ones(1, 1, 8, 8)
    sun = torch.tensor([[0.0, -1.0, 0.0]])
    f = torch.tensor([[8.0]])
    with pytest.raises(ValueError, match="sun"):
        march_volume(img, dep, sun[:, :2], f, 4, 0.1)
    with pytest.raises(ValueError, match="focal"):
        march_volume(img, dep, sun, f[0], 4, 0.1)
    with pytest.raises(ValueError, match="steps"):
        march_volume(img, dep, sun, f, 0, 0.1)
    with pytest.raises(ValueError, match="volume_scale"):
        march_volume(img, dep, sun, f, 4, 0.1, volume_scale=0.3)
