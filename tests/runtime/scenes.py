"""Analytic test scenes with exact ray casting, independent of the code under test."""

from __future__ import annotations

import numpy as np


def box_scene_depth(
    height: int, width: int, focal: float, ground_z: float, boxes: list[tuple[float, ...]]
) -> np.ndarray:
    """Exact z depth of a ground plane ``z = ground_z`` (camera looking straight down) with
    axis-aligned boxes ``(x0, x1, y0, y1, h)`` standing on it (top at ``z = ground_z - h``).

    Rays are cast per pixel centre through the boxes with the slab method.
    """
    u = (np.arange(width) + 0.5 - width / 2) / focal
    v = (np.arange(height) + 0.5 - height / 2) / focal
    dx, dy = np.meshgrid(u, v)  # ray direction (dx, dy, 1): z = t
    depth = np.full((height, width), ground_z, dtype=np.float64)
    for x0, x1, y0, y1, h in boxes:
        z0, z1 = ground_z - h, ground_z
        t_near = np.full_like(dx, z0)
        t_far = np.full_like(dx, z1)
        for d, lo, hi in ((dx, x0, x1), (dy, y0, y1)):
            with np.errstate(divide="ignore", invalid="ignore"):
                ta = np.where(d != 0, lo / d, -np.inf)
                tb = np.where(d != 0, hi / d, np.inf)
            tmin = np.minimum(ta, tb)
            tmax = np.maximum(ta, tb)
            inside0 = (d == 0) & (lo <= 0) & (hi >= 0)
            tmin = np.where(d == 0, np.where(inside0, -np.inf, np.inf), tmin)
            tmax = np.where(d == 0, np.where(inside0, np.inf, -np.inf), tmax)
            t_near = np.maximum(t_near, tmin)
            t_far = np.minimum(t_far, tmax)
        hit = t_near <= t_far
        depth = np.where(hit & (t_near < depth), t_near, depth)
    return depth.astype(np.float32)


def box_scene_visibility(
    points: np.ndarray, w: np.ndarray, ground_z: float, boxes: list[tuple[float, ...]]
) -> np.ndarray:
    """Exact sun visibility of camera-space ``points`` (``H x W x 3``) toward direction ``w``."""
    eps = 1e-4
    o = points.reshape(-1, 3).astype(np.float64)
    o = o + eps * w  # leave the surface
    lit = np.ones(len(o), dtype=bool)
    for x0, x1, y0, y1, h in boxes:
        lo = np.array([x0, y0, ground_z - h])
        hi = np.array([x1, y1, ground_z])
        t_near = np.zeros(len(o))
        t_far = np.full(len(o), np.inf)
        for a in range(3):
            if abs(w[a]) < 1e-15:
                outside = (o[:, a] < lo[a]) | (o[:, a] > hi[a])
                t_far = np.where(outside, -np.inf, t_far)
                continue
            ta = (lo[a] - o[:, a]) / w[a]
            tb = (hi[a] - o[:, a]) / w[a]
            t_near = np.maximum(t_near, np.minimum(ta, tb))
            t_far = np.minimum(t_far, np.maximum(ta, tb))
        lit &= ~(t_near <= t_far)
    return lit.reshape(points.shape[:2])


def noisy_box_photo(seed: int, h: int = 60, w: int = 80) -> tuple[np.ndarray, np.ndarray]:
    """A grey photo with a little noise and the depth of one box on the ground seen by a 30 deg
    camera (the sessions' small test scene): ``(image, depth)``."""
    import math

    depth = box_scene_depth(h, w, w / (2 * math.tan(math.radians(15))), 60.0,
                            [(-4.0, 0.0, -3.0, 1.0, 4.0)])
    rng = np.random.default_rng(seed)
    image = np.clip(0.5 + 0.05 * rng.standard_normal((h, w, 3)), 0, 1).astype(np.float32)
    return image, depth
