"""Mitsuba's ``sunsky`` (Hosek-Wilkie sky + sun) baked into cheap emitters.

Path tracing with the ``sunsky`` emitter itself is slow on this CPU (``scalar_rgb``): every emitter
sample evaluates the analytic model (measured on a street scene: 2.5-3.0 s with ``sunsky`` vs 1.0 s
with a constant sky + directional sun; whole views 1.5-1.6x faster). So per sun we evaluate the
model once:

* the sky (``sun_scale = 0``) on a ``64 x 128`` latitude-longitude grid -> ``envmap`` emitter;
* the sun (``sky_scale = 0``) integrated over its disc -> the irradiance of a ``directional``
  emitter (hard shadows: the real disc is 0.54 deg wide, under a pixel at 128 px);
* the sun disc seen directly by the camera is added to the image afterwards, analytically.

World frame: z up. Mitsuba's ``envmap`` is y-up in its local frame, hence ``ENV_TO_WORLD``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

ENV_HEIGHT, ENV_WIDTH = 64, 128
SUN_APERTURE_DEG = 0.5358  # Mitsuba's default angular diameter of the sun
# local (x, y, z) of the envmap -> world (x, z-up): y -> z, z -> -y.
ENV_TO_WORLD = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def _env_directions() -> np.ndarray:
    """World directions of the envmap texel centres, ``H x W x 3`` (Mitsuba's envmap mapping)."""
    th = (np.arange(ENV_HEIGHT) + 0.5) / ENV_HEIGHT * math.pi
    ph = (np.arange(ENV_WIDTH) + 0.5) / ENV_WIDTH * 2 * math.pi
    T, P = np.meshgrid(th, ph, indexing="ij")
    local = np.stack([np.sin(T) * np.sin(P), np.cos(T), -np.sin(T) * np.cos(P)], axis=-1)
    return local @ ENV_TO_WORLD.T


def env_to_world_matrix() -> list[list[float]]:
    m = np.eye(4)
    m[:3, :3] = ENV_TO_WORLD
    return m.tolist()


def _basis(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    helper = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    a = np.cross(d, helper)
    a /= np.linalg.norm(a)
    return a, np.cross(d, a)


class SunSky:
    """Evaluates Mitsuba's ``sunsky`` model for one turbidity / ground albedo.

    Args:
        turbidity: atmospheric turbidity (1-10).
        albedo: ground albedo seen by the sky model.
    """

    def __init__(self, turbidity: float, albedo: float) -> None:
        import mitsuba as mi

        self._mi = mi
        base = {
            "type": "sunsky",
            "sun_direction": [0.0, 0.3, 0.95],
            "turbidity": float(turbidity),
            "albedo": float(albedo),
        }
        self._sky = mi.load_dict(dict(base, sun_scale=0.0))
        self._sun = mi.load_dict(dict(base, sky_scale=0.0))
        self._si = mi.SurfaceInteraction3f()

    def _set_sun(self, sun_world: np.ndarray) -> None:
        for e in (self._sky, self._sun):
            p = self._mi.traverse(e)
            p["sun_direction"] = self._mi.ScalarVector3f(*np.asarray(sun_world, float).tolist())
            p.update()

    def _eval(self, emitter: Any, d: np.ndarray) -> np.ndarray:
        self._si.wi = self._mi.Vector3f(*(-np.asarray(d, float)).tolist())
        return np.array(emitter.eval(self._si), dtype=np.float64)

    def bake(self, sun_world: np.ndarray) -> dict[str, Any]:
        """Sky envmap and sun of one sun direction (world, z up, unit).

        Returns:
            Dict with ``envmap`` (``64 x 128 x 3`` float32 radiance), ``sun_irradiance`` (RGB on a
            surface facing the sun), ``sun_radiance`` (mean RGB radiance of the disc) and
            ``sun_radius`` (radians).
        """
        w = np.asarray(sun_world, np.float64)
        w = w / np.linalg.norm(w)
        self._set_sun(w)
        dirs = _env_directions().reshape(-1, 3)
        env = np.array([self._eval(self._sky, d) for d in dirs], np.float32)
        env = np.nan_to_num(env.reshape(ENV_HEIGHT, ENV_WIDTH, 3), nan=0.0).clip(0.0, None)
        radius = math.radians(SUN_APERTURE_DEG) / 2
        a, b = _basis(w)
        samples = []
        for x in np.linspace(-0.9, 0.9, 7):
            for y in np.linspace(-0.9, 0.9, 7):
                if x * x + y * y <= 0.81:
                    d = w + math.tan(radius) * (x * a + y * b)
                    samples.append(self._eval(self._sun, d / np.linalg.norm(d)))
        radiance = np.nan_to_num(np.mean(samples, axis=0), nan=0.0).clip(0.0, None)
        solid = 2 * math.pi * (1 - math.cos(radius))
        return {
            "envmap": env,
            "sun_irradiance": radiance * solid,
            "sun_radiance": radiance,
            "sun_radius": radius,
        }


def sun_disc_coverage(rays_world: np.ndarray, sun_world: np.ndarray, radius: float) -> np.ndarray:
    """Fraction of each pixel covered by the sun disc.

    Args:
        rays_world: ``S x H x W x 3`` unit ray directions of ``S`` sub-pixel samples.
        sun_world: unit sun direction. radius: angular radius of the disc (radians).

    Returns:
        ``H x W`` float32 in [0, 1].
    """
    cos = rays_world @ np.asarray(sun_world, np.float64)
    return (cos >= math.cos(radius)).mean(axis=0).astype(np.float32)
