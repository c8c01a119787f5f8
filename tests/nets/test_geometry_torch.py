"""The torch geometry twins must equal the numpy originals."""

from __future__ import annotations

import numpy as np
import torch

from outcast_core.nets import geometry_torch as gt
from outcast_core.runtime.geometry import camera as g


def _bumpy_depth(h: int, w: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w]
    d = 3.0 + 0.5 * np.sin(xx / 3.0) + 0.3 * np.cos(yy / 4.0) + 0.05 * rng.random((h, w))
    return d.astype(np.float32)


def test_view_directions_match_numpy() -> None:
    cam = g.Camera.from_fov(12, 20, 70.0)
    got = gt.view_directions(torch.zeros(2, 1, 12, 20), torch.full((2, 1), cam.focal))
    ref = g.view_directions(cam)
    for b in range(2):
        np.testing.assert_allclose(got[b].permute(1, 2, 0).numpy(), ref, atol=1e-6)


def test_normals_match_numpy_on_valid_depth() -> None:
    for seed in range(3):
        cam = g.Camera.from_fov(16, 24, 60.0)
        depth = _bumpy_depth(16, 24, seed)
        ref = g.normals_from_depth(depth, cam)
        got = gt.normals_from_depth(
            torch.from_numpy(depth)[None, None], torch.tensor([[cam.focal]])
        )[0].permute(1, 2, 0).numpy()
        np.testing.assert_allclose(got, ref, atol=1e-5)


def test_normals_match_numpy_away_from_sky() -> None:
    cam = g.Camera.from_fov(16, 16, 60.0)
    depth = _bumpy_depth(16, 16, 7)
    depth[:5] = np.inf
    ref = g.normals_from_depth(depth, cam)
    got = gt.normals_from_depth(torch.from_numpy(depth)[None, None], torch.tensor([[cam.focal]]))
    got = got[0].permute(1, 2, 0).numpy()
    np.testing.assert_array_equal(got[:5], 0.0)
    # Identical wherever the 3x3 Sobel stencil sees only valid pixels (rows 6 and below).
    np.testing.assert_allclose(got[6:], ref[6:], atol=1e-5)


def test_cosine_term_matches_numpy() -> None:
    cam = g.Camera.from_fov(8, 8)
    n = g.normals_from_depth(_bumpy_depth(8, 8, 1), cam)
    w = g.sun_vector(30.0, 40.0)
    got = gt.cosine_term(torch.from_numpy(n).permute(2, 0, 1)[None],
                         torch.tensor(w, dtype=torch.float32)[None])
    np.testing.assert_allclose(got[0, 0].numpy(), g.cosine_term(n, w), atol=1e-6)
