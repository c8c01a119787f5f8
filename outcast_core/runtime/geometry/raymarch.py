"""Screen-space light-ray sampling: the heart of the S network and of Direct shadows.

For every pixel ``p`` with camera-space point ``P`` and the sun direction ``w``, the 3D ray
``P + t w`` projects to a 2D line in the image. We march ``z`` steps of a fixed length (in
normalised image units: a fraction of the image's longer side, so a network sees the same reach
at any resolution) along that line, and at each step ``q`` return

* the bilinear RGB sample at ``q``,
* the ratio ``depth_map(q) / depth_of_ray_point(q)`` (``< 1``: the ray passes behind the observed
  surface; ``= 1``: it touches it; ``> 1``: it is in front), clipped to ``[0, MAX_RATIO]``,
* a validity flag (inside the image, before the vanishing point, valid pixel, valid direction).

The maths, in closed form. With normalised coordinates ``(xn, yn) = ((u - cx) / f, (v - cy) / f)``
the image of the ray moves, at ``t = 0``, along ``d = (wx - xn wz, wy - yn wz)``. Inverse depth is
affine in image distance along a projected 3D line, and its slope follows from ``d``::

    1 / depth_ray(s) = (1 / P_z) * (1 - s * wz / (f * |d|))      (s: distance in pixels)

so the ratio is ``factor(s) * disp(p) / disp(q)`` with ``factor = 1 - s wz / (f |d|)`` and
``disp = 1 / depth``. This is exact (not a small-step approximation) and covers every case:

* sun in front of the camera (``wz > 0``): the 2D ray runs toward the sun's vanishing point
  ``c + f (wx, wy) / wz``; ``factor`` reaches 0 exactly there and steps beyond are invalid;
* sun behind the camera (``wz < 0``): the 2D ray runs away from the anti-vanishing point and the
  ray point approaches the camera plane only as ``s -> inf`` (``factor`` grows, never crosses 0);
* ``wz = 0``: parallel 2D rays, constant depth;
* sun on the pixel's viewing line (``|d| = 0``): the ray is seen end-on; nothing in a depth map
  can occlude it in screen space, so every step is invalid (the pixel is lit).

The per-step coordinate maths is written once (:func:`march_coordinates`) against a tiny array
namespace (arithmetic and ``where`` only) and shared with the torch twin used in training and ONNX
export (``outcast_core.nets.raymarch_torch``).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from outcast_core.runtime.geometry.camera import (
    Camera,
    normalize_sun,
    pixel_centres,
    relative_depth,
    valid_depth,
)

#: Ratio value given to invalid samples and the clip ceiling for valid ones ("far in front").
MAX_RATIO = 4.0
#: Below this 2D direction length (unit-free) the ray is seen end-on.
EPS_DIR = 1e-6
#: ``factor`` at or below this means the step is at or past the vanishing point.
EPS_FACTOR = 1e-6
#: Default step of the learned S network: 1/64 of the longer image side (z=32 reaches half).
DEFAULT_NET_STEP = 1.0 / 64.0
#: Default step of Direct shadows: 1/256 of the longer side (about 1 px at 256 px).
DEFAULT_DIRECT_STEP = 1.0 / 256.0


def march_coordinates(
    xp: Any,
    u: Any,
    v: Any,
    w: tuple[Any, Any, Any],
    focal: Any,
    cx: Any,
    cy: Any,
    s: Any,
) -> tuple[Any, Any, Any, Any]:
    """Image position and depth factor of the ray point ``s`` pixels along each pixel's 2D ray.

    Written for any array namespace ``xp`` with arithmetic and ``xp.where`` (numpy, torch), so
    the runtime and the exported network share these lines.

    Args:
        xp: array namespace (``numpy`` or ``torch``).
        u: pixel-centre column coordinates, any shape broadcastable with ``w``.
        v: pixel-centre row coordinates.
        w: sun direction components ``(wx, wy, wz)``, unit length, broadcastable.
        focal: focal length in pixels.
        cx: principal point u.
        cy: principal point v.
        s: distance along the 2D ray in pixels (scalar or broadcastable).

    Returns:
        ``(qu, qv, factor, dir_ok)``: the sample position, ``depth_ray(0) / depth_ray(s)`` and
        whether the pixel's 2D direction is defined.
    """
    wx, wy, wz = w
    xn = (u - cx) / focal
    yn = (v - cy) / focal
    dx = wx - xn * wz
    dy = wy - yn * wz
    n2 = (dx * dx + dy * dy) ** 0.5
    dir_ok = n2 > EPS_DIR
    n2s = xp.where(dir_ok, n2, EPS_DIR + 0.0 * n2)
    qu = u + s * dx / n2s
    qv = v + s * dy / n2s
    factor = 1.0 - s * wz / (focal * n2s)
    return qu, qv, factor, dir_ok


def disparity(depth: np.ndarray) -> np.ndarray:
    """Inverse of :func:`~outcast_core.runtime.geometry.camera.relative_depth`; 0 where there is no
    surface.

    Ratios are scale-invariant, so the normalisation changes nothing but keeps float32 sane for
    depth maps with a dynamic range of 1e6 or values near the float limits (the clamp of
    ``relative_depth`` keeps products of two disparities finite).
    """
    rel = relative_depth(depth)
    valid = np.isfinite(rel)
    out = np.zeros(rel.shape, dtype=np.float32)
    out[valid] = (1.0 / rel[valid]).astype(np.float32)
    return out


def bilinear(image: np.ndarray, qu: np.ndarray, qv: np.ndarray) -> np.ndarray:
    """Bilinear samples of ``image`` (``H x W`` or ``H x W x C``) at continuous ``(qu, qv)``.

    Coordinates follow the pixel-centre convention (centre of pixel 0 at 0.5); positions outside
    are clamped to the border, exactly like ``torch.grid_sample(align_corners=False,
    padding_mode='border')``.
    """
    h, w = image.shape[:2]
    x = np.clip(np.nan_to_num(qu - 0.5, nan=0.0), 0.0, w - 1.0)
    y = np.clip(np.nan_to_num(qv - 0.5, nan=0.0), 0.0, h - 1.0)
    x0 = np.floor(x).astype(np.int64)
    y0 = np.floor(y).astype(np.int64)
    x1 = np.minimum(x0 + 1, w - 1)
    y1 = np.minimum(y0 + 1, h - 1)
    ax = (x - x0).astype(np.float32)
    ay = (y - y0).astype(np.float32)
    if image.ndim == 3:
        ax = ax[..., None]
        ay = ay[..., None]
    top = image[y0, x0] * (1 - ax) + image[y0, x1] * ax
    bot = image[y1, x0] * (1 - ax) + image[y1, x1] * ax
    return top * (1 - ay) + bot * ay


@dataclass
class MarchStep:
    """One step of the march for every pixel (all ``H x W``)."""

    index: int
    qu: np.ndarray
    qv: np.ndarray
    ratio: np.ndarray
    valid: np.ndarray
    factor: np.ndarray


class RaySampler:
    """Set once per (depth map, camera); march for any sun direction.

    Args:
        depth: ``H x W`` z depth; non-finite or non-positive values mean "no surface".
        camera: intrinsics for the depth map's size.

    Example:
        >>> cam = Camera.from_fov(8, 8)
        >>> sampler = RaySampler(np.ones((8, 8), np.float32), cam)
        >>> vol = sampler.volume((0.0, -1.0, 0.0), steps=4, step=1 / 8)
        >>> vol["ratio"].shape
        (4, 8, 8)
    """

    def __init__(self, depth: np.ndarray, camera: Camera) -> None:
        depth = np.asarray(depth)
        if depth.ndim != 2:
            raise ValueError(f"expected depth of shape H x W, got shape {depth.shape}")
        if depth.shape != (camera.height, camera.width):
            raise ValueError(
                f"expected depth of shape {(camera.height, camera.width)}, got {depth.shape}"
            )
        self.camera = camera
        self.pixel_ok = valid_depth(depth)
        self.disp = disparity(depth)
        uu, vv = pixel_centres(camera.height, camera.width)
        self.u = uu.astype(np.float32)
        self.v = vv.astype(np.float32)

    def step_pixels(self, step: float) -> float:
        """A normalised step length in pixels at this resolution."""
        if not (np.isfinite(step) and step > 0):
            raise ValueError(f"expected a step > 0, got {step}")
        return float(step) * max(self.camera.height, self.camera.width)

    def sample(
        self, wt: tuple[float, float, float], s: float, index: np.ndarray | None = None
    ) -> MarchStep:
        """One march step at distance ``s`` pixels for all pixels, or for the flat ``index``."""
        cam = self.camera
        if index is None:
            u, v, disp_p, ok = self.u, self.v, self.disp, self.pixel_ok
        else:
            u, v = self.u.reshape(-1)[index], self.v.reshape(-1)[index]
            disp_p, ok = self.disp.reshape(-1)[index], self.pixel_ok.reshape(-1)[index]
        qu, qv, factor, dir_ok = march_coordinates(np, u, v, wt, cam.focal, cam.cx, cam.cy, s)
        inside = (qu >= 0) & (qu <= cam.width) & (qv >= 0) & (qv <= cam.height)
        valid = ok & dir_ok & (factor > EPS_FACTOR) & inside
        disp_q = bilinear(self.disp, qu, qv)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            ratio = np.where(disp_q > 0, factor * disp_p / disp_q, MAX_RATIO)
        ratio = np.clip(np.nan_to_num(ratio, nan=MAX_RATIO, posinf=MAX_RATIO), 0.0, MAX_RATIO)
        ratio = np.where(valid, ratio, MAX_RATIO).astype(np.float32)
        return MarchStep(0, qu, qv, ratio, valid, factor.astype(np.float32))

    def iter_steps(self, w: Any, steps: int, step: float) -> Iterator[MarchStep]:
        """Yield the march one step at a time (memory stays at a few ``H x W`` arrays).

        Args:
            w: camera-space sun direction (normalised here; ``ValueError`` if zero / non-finite).
            steps: number of steps ``z`` (>= 1).
            step: step length in normalised units (fraction of the longer image side).
        """
        check_steps(steps)
        wv = normalize_sun(w)
        step_px = self.step_pixels(step)
        wt = (float(wv[0]), float(wv[1]), float(wv[2]))
        for k in range(1, int(steps) + 1):
            st = self.sample(wt, k * step_px)
            st.index = k
            yield st

    def volume(
        self, w: Any, steps: int, step: float, image: np.ndarray | None = None
    ) -> dict[str, np.ndarray]:
        """The whole march as arrays: ``ratio`` and ``valid`` (``z x H x W``), and ``rgb``
        (``z x H x W x 3``, zero where invalid) when ``image`` is given."""
        if image is not None:
            image = np.asarray(image, dtype=np.float32)
            if image.shape[:2] != self.disp.shape or image.ndim != 3:
                raise ValueError(
                    f"expected an image of shape {self.disp.shape} x C, got {image.shape}"
                )
        ratios, valids, rgbs = [], [], []
        for st in self.iter_steps(w, steps, step):
            ratios.append(st.ratio)
            valids.append(st.valid)
            if image is not None:
                rgbs.append(bilinear(image, st.qu, st.qv) * st.valid[..., None])
        out = {"ratio": np.stack(ratios), "valid": np.stack(valids)}  # z x H x W
        if image is not None:
            out["rgb"] = np.stack(rgbs).astype(np.float32)  # z x H x W x C
        return out


def check_steps(steps: int) -> None:
    """``ValueError`` unless ``steps`` is a positive integer."""
    if isinstance(steps, bool) or int(steps) != steps or steps < 1:
        raise ValueError(f"expected a positive integer number of steps, got {steps}")


def steps_to_leave(camera: Camera, w: Any, step: float, max_steps: int) -> int:
    """The most steps any pixel's 2D ray stays inside the image and before the vanishing point.

    Marching further than this can never find a valid sample, so callers cap ``z`` here.
    """
    depth = np.ones((camera.height, camera.width), np.float32)
    sampler = RaySampler(depth, camera)
    wv = normalize_sun(w)
    step_px = sampler.step_pixels(step)
    qu, qv, factor, dir_ok = march_coordinates(
        np, sampler.u, sampler.v, tuple(float(x) for x in wv), camera.focal, camera.cx,
        camera.cy, 1.0,
    )
    # Per pixel: unit 2D direction (qu - u, qv - v) at s = 1; distance to leave the image box.
    du = qu - sampler.u
    dv = qv - sampler.v
    with np.errstate(divide="ignore", invalid="ignore"):
        tx = np.where(du > 0, (camera.width - sampler.u) / du,
                      np.where(du < 0, -sampler.u / du, np.inf))
        ty = np.where(dv > 0, (camera.height - sampler.v) / dv,
                      np.where(dv < 0, -sampler.v / dv, np.inf))
        s_max = np.minimum(tx, ty)
        # Vanishing point: factor(s) = 1 - s * a reaches 0 at s = 1 / a where a = 1 - factor(1).
        a = 1.0 - factor
        s_vp = np.where(a > 0, 1.0 / np.where(a > 0, a, 1.0), np.inf)
    s_max = np.where(dir_ok, np.minimum(s_max, s_vp), 0.0)
    n = int(np.ceil(np.max(s_max) / step_px)) if np.isfinite(np.max(s_max)) else max_steps
    return int(max(0, min(max_steps, n)))
