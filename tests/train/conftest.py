"""Tiny hand-made views in the data helper's format, for trainer tests."""

from __future__ import annotations

import numpy as np
import pytest

from outcast_core.runtime.geometry.camera import Camera, normals_from_depth, sun_vector


def make_view(seed: int, size: int = 32, suns: int = 3) -> dict:
    """A ground plane under a 60-degree camera with a box, lit by ``suns`` suns (format only:
    the shadow images are a crude stand-in, the geometry is exact)."""
    rng = np.random.default_rng(seed)
    cam = Camera.from_fov(size, size, 60.0)
    v = (np.arange(size) + 0.5 - size / 2) / cam.focal
    depth = np.full((size, size), np.inf, np.float32)
    below = v > 0.05
    depth[below] = (1.5 / v[below])[:, None]  # ground plane 1.5 below the camera
    c = int(rng.integers(size // 4, size // 2))
    depth[size // 3 : size // 2 + 4, c : c + 6] = 6.0  # a box face
    normals = normals_from_depth(depth, cam)
    sun = np.stack([sun_vector(float(rng.uniform(0, 360)), float(rng.uniform(15, 70)))
                    for _ in range(suns)]).astype(np.float32)
    cos = np.clip(np.einsum("hwc,kc->khw", normals, sun), 0, 1)
    cols = np.arange(size)[None, None, :]
    vis = np.broadcast_to(cols < rng.integers(size // 4, size, (suns, 1, 1)),
                          (suns, size, size)).astype(np.float32)
    shadow = (cos * vis).astype(np.float32)
    albedo = rng.uniform(0.1, 0.8, (size, size, 3)).astype(np.float32)
    rgb = albedo[None] * (0.2 + 3.0 * shadow[..., None])
    rgb[:, ~np.isfinite(depth)] = np.array([0.3, 0.5, 1.0], np.float32)
    return {"rgb": rgb.astype(np.float32), "shadow": shadow, "depth": depth, "normals": normals,
            "sky": ~np.isfinite(depth), "sun": sun, "fov_deg": 60.0}


@pytest.fixture
def fake_views() -> list[dict]:
    return [make_view(s) for s in range(3)]


@pytest.fixture(autouse=True)
def _home(tmp_path, monkeypatch):
    """Runs write checkpoints under a temporary HOME, never the real cache."""
    monkeypatch.setenv("HOME", str(tmp_path))
    return tmp_path
