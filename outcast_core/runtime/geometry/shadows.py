"""Direct shadows: the paper's non-learned screen-space baseline, and the fallback mode.

``shadow = max(0, N . w) * visibility``, where a march sample occludes when the light ray passes
*behind* the observed surface at that sample, by more than a small bias and by less than the
occluder thickness. Thickness is relative to depth: a sample with ray depth ``D_r`` behind a
surface at ``D_m`` occludes when ``D_m (1 + bias) < D_r < D_m (1 + thickness)``; ``inf`` means
everything behind an observed surface is solid. In ratio terms (``r = D_m / D_r``):
``1 / (1 + thickness) < r < 1 / (1 + bias)``.

The march stops as soon as no pixel can change any more ("march no further than a scene needs"):
every still-lit pixel's ray has left the image, passed the vanishing point, or come so close to the
camera (sun behind it) that it lies in front of every surface of the depth map.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from outcast_core.runtime.geometry.camera import (
    Camera,
    cosine_term,
    normalize_sun,
    normals_from_depth,
)
from outcast_core.runtime.geometry.raymarch import DEFAULT_DIRECT_STEP, RaySampler, check_steps

#: Relative depth tolerance below which a sample counts as touching, not occluding.
DEFAULT_BIAS = 0.005
#: Default march length of Direct mode in steps of ``DEFAULT_DIRECT_STEP`` (reach: one image side).
DEFAULT_DIRECT_STEPS = 256
#: How many steps are marched between checks for an early exit.
_CHUNK = 8


@dataclass
class DirectStats:
    """What a Direct run did: steps asked for, steps marched, and why it stopped."""

    steps_requested: int
    steps_marched: int
    stop_reason: str


def parse_thickness(value: str | float) -> float:
    """Parse a thickness argument: a float > 0 or ``inf``."""
    if isinstance(value, str):
        if value.strip().lower() in {"inf", "infinity"}:
            return math.inf
        try:
            value = float(value)
        except ValueError as exc:
            raise ValueError(f"expected a thickness > 0 or 'inf', got {value!r}") from exc
    if math.isnan(value) or value <= 0:
        raise ValueError(f"expected a thickness > 0 or 'inf', got {value}")
    return float(value)


def direct_visibility(
    depth: np.ndarray,
    camera: Camera,
    w: Any,
    *,
    steps: int = DEFAULT_DIRECT_STEPS,
    step: float = DEFAULT_DIRECT_STEP,
    thickness: float = math.inf,
    bias: float = DEFAULT_BIAS,
    sampler: RaySampler | None = None,
    stats: DirectStats | None = None,
) -> np.ndarray:
    """Binary sun visibility by screen-space ray marching (1 = lit, 0 = occluded).

    Args:
        depth: ``H x W`` z depth (non-finite or <= 0: no surface; such pixels get 1).
        camera: intrinsics for the depth map.
        w: camera-space sun direction.
        steps: maximum number of march steps.
        step: step length in normalised units (fraction of the longer image side).
        thickness: occluder thickness relative to depth (``inf``: solid).
        bias: relative depth tolerance for self-intersection.
        sampler: a :class:`RaySampler` already built for this depth map (reused across suns).
        stats: filled with the number of steps marched and the stop reason.

    Returns:
        ``H x W`` float32 in {0, 1}.
    """
    thickness = parse_thickness(thickness)
    if not (math.isfinite(bias) and bias >= 0):
        raise ValueError(f"expected a bias >= 0, got {bias}")
    if sampler is None:
        sampler = RaySampler(depth, camera)
    check_steps(steps)
    wv = normalize_sun(w)
    wt = (float(wv[0]), float(wv[1]), float(wv[2]))
    step_px = sampler.step_pixels(step)
    r_hi = 1.0 / (1.0 + bias)
    r_lo = 0.0 if math.isinf(thickness) else 1.0 / (1.0 + thickness)
    disp = sampler.disp
    disp_max = float(disp.max()) if disp.size else 0.0
    disp_min_pos = float(disp[disp > 0].min()) if (disp > 0).any() else 0.0
    lit = np.ones(disp.size, dtype=bool)
    # March only the pixels that can still change: their flat indices shrink as rays finish.
    index = np.flatnonzero(sampler.pixel_ok)
    marched, reason = 0, "all steps marched"
    for k in range(1, int(steps) + 1):
        if index.size == 0:
            reason = "no pixel can change"
            break
        marched = k
        st = sampler.sample(wt, k * step_px, index)
        occl = st.valid & (st.ratio < r_hi) & (st.ratio > r_lo)
        lit[index[occl]] = False
        # A pixel stays active while its ray can still find a valid sample further on.
        still = ~occl & (st.qu >= 0) & (st.qu <= camera.width) & (st.qv >= 0) \
            & (st.qv <= camera.height) & (st.factor > 0)
        ray_disp = disp.reshape(-1)[index] * st.factor
        if wv[2] < 0 and disp_max > 0:
            # Sun behind the camera: the ray's disparity only grows. Once it exceeds every
            # surface's (times the bias), the ray is in front of everything for good.
            still &= ray_disp < disp_max * (1.0 + bias) * 1.0001
        if wv[2] > 0 and not math.isinf(thickness) and disp_min_pos > 0:
            # Sun in front, finite thickness: once the ray is further behind every surface than
            # the thickness allows, nothing can occlude it any more.
            still &= ray_disp * (1.0 + thickness) > disp_min_pos * 0.9999
        if k % _CHUNK == 0 or not still.all():
            index = index[still]
    if stats is not None:
        stats.steps_requested = int(steps)
        stats.steps_marched = int(marched)
        stats.stop_reason = reason
    return lit.reshape(disp.shape).astype(np.float32)


def direct_shadow(
    depth: np.ndarray,
    camera: Camera,
    w: Any,
    *,
    normals: np.ndarray | None = None,
    sky: np.ndarray | None = None,
    steps: int = DEFAULT_DIRECT_STEPS,
    step: float = DEFAULT_DIRECT_STEP,
    thickness: float = math.inf,
    bias: float = DEFAULT_BIAS,
    sampler: RaySampler | None = None,
    stats: DirectStats | None = None,
) -> np.ndarray:
    """The Direct shadow image: ``max(0, N . w) * visibility``, 0 on sky.

    Args:
        depth: ``H x W`` z depth.
        camera: intrinsics for the depth map.
        w: camera-space sun direction.
        normals: ``H x W x 3`` normals; computed from depth when omitted.
        sky: optional ``H x W`` bool sky mask (sky pixels get 0 and never occlude).
        steps, step, thickness, bias, sampler, stats: see :func:`direct_visibility`.

    Returns:
        ``H x W`` float32 in [0, 1].

    Example:
        >>> cam = Camera.from_fov(16, 16)
        >>> s = direct_shadow(np.full((16, 16), 5.0, np.float32), cam, (0.0, 0.0, -1.0))
        >>> float(s.max()) <= 1.0
        True
    """
    depth = np.asarray(depth, dtype=np.float32)
    if depth.ndim != 2:
        raise ValueError(f"expected depth of shape H x W, got shape {depth.shape}")
    if sky is not None:
        sky = np.asarray(sky, dtype=bool)
        if sky.shape != depth.shape:
            raise ValueError(f"expected a sky mask of shape {depth.shape}, got {sky.shape}")
        depth = np.where(sky, np.inf, depth).astype(np.float32)
    if normals is None:
        normals = normals_from_depth(depth, camera)
    cos = cosine_term(normals, w)
    vis = direct_visibility(
        depth, camera, w, steps=steps, step=step, thickness=thickness, bias=bias,
        sampler=sampler, stats=stats,
    )
    out = cos * vis
    if sky is not None:
        out[sky] = 0.0
    return np.clip(out, 0.0, 1.0).astype(np.float32)
