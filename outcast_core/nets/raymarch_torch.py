"""The epipolar volume builder of the S network: the torch twin of ``runtime.geometry.raymarch``.

The per-step coordinate maths is not re-derived here: it is
:func:`outcast_core.runtime.geometry.raymarch.march_coordinates`, called with ``torch`` as the array
namespace. Samples come from ``F.grid_sample(align_corners=False, padding_mode='border')``,
which is exactly ``runtime.geometry.raymarch.bilinear``. The sun direction and the focal length are
tensors,
so an exported graph takes them as inputs, and the pixel grid is built from the input's shape, so
height and width stay dynamic.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F  # noqa: N812  (the universal torch idiom)

from outcast_core.nets.geometry_torch import image_size, pixel_grid, valid_depth
from outcast_core.runtime.geometry.raymarch import EPS_FACTOR, MAX_RATIO, march_coordinates


def disparity(depth: torch.Tensor) -> torch.Tensor:
    """``1 / depth`` where there is a surface, else 0 (``B x 1 x H x W``)."""
    ok = valid_depth(depth)
    safe = torch.where(ok, depth, torch.ones_like(depth))
    return torch.where(ok, 1.0 / safe, torch.zeros_like(depth))


def downsample_inputs(
    image: torch.Tensor, disp: torch.Tensor, focal: torch.Tensor, factor: int
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Image (area average), disparity (max: the nearest surface) and focal at ``1 / factor``."""
    if factor == 1:
        return image, disp, focal
    return F.avg_pool2d(image, factor), F.max_pool2d(disp, factor), focal / factor


def march_volume(
    image: torch.Tensor,
    depth: torch.Tensor,
    sun: torch.Tensor,
    focal: torch.Tensor,
    steps: int,
    step: float,
    volume_scale: float = 1.0,
) -> dict[str, torch.Tensor]:
    """March ``steps`` steps toward the sun from every pixel and sample RGB and the depth ratio.

    Args:
        image: ``B x C x H x W`` (sRGB for the network; any channels).
        depth: ``B x 1 x H x W`` z depth; non-finite or ``<= 0`` = no surface.
        sun: ``B x 3`` camera-space unit sun direction.
        focal: ``B x 1`` focal length in pixels at the input resolution.
        steps: number of march steps ``z``.
        step: step length in normalised units (fraction of the longer image side).
        volume_scale: 1 (full resolution), 0.5 or 0.25: build the volume at that scale; ``H``
            and ``W`` must then be divisible by ``1 / volume_scale``.

    Returns:
        ``ratio`` (``B x 1 x z x h x w``, invalid = ``MAX_RATIO``), ``valid`` (same shape, bool)
        and ``rgb`` (``B x C x z x h x w``, zero where invalid), with ``h, w`` the volume's size.

    Shape:
        image ``(B, C, H, W)`` -> rgb ``(B, C, z, H * s, W * s)``.
    """
    if image.dim() != 4 or depth.dim() != 4 or depth.shape[1] != 1:
        raise ValueError(
            f"expected image B x C x H x W and depth B x 1 x H x W, got {tuple(image.shape)} "
            f"and {tuple(depth.shape)}"
        )
    if sun.dim() != 2 or sun.shape[1] != 3:
        raise ValueError(f"expected sun of shape B x 3, got {tuple(sun.shape)}")
    if focal.dim() != 2 or focal.shape[1] != 1:
        raise ValueError(f"expected focal of shape B x 1, got {tuple(focal.shape)}")
    if int(steps) != steps or steps < 1:
        raise ValueError(f"expected a positive integer number of steps, got {steps}")
    factor = round(1.0 / volume_scale)
    if volume_scale <= 0 or abs(factor * volume_scale - 1.0) > 1e-6 or factor not in (1, 2, 4):
        raise ValueError(f"expected volume_scale 1, 0.5 or 0.25, got {volume_scale}")
    image, disp, focal = downsample_inputs(image, disparity(depth), focal.to(image.dtype), factor)

    b, c = image.shape[:2]
    u, v = pixel_grid(disp)  # 1 x 1 x h x w
    width, height = image_size(disp)
    step_px = step * torch.maximum(width, height)
    sun = sun / torch.linalg.vector_norm(sun, dim=1, keepdim=True)
    w = tuple(sun[:, i].reshape(-1, 1, 1, 1) for i in range(3))  # each B x 1 x 1 x 1
    f = focal.reshape(-1, 1, 1, 1)
    k = torch.cumsum(torch.ones(int(steps), dtype=image.dtype, device=image.device), dim=0)
    s = (k * step_px).reshape(1, -1, 1, 1)  # 1 x z x 1 x 1
    qu, qv, fac, dir_ok = march_coordinates(torch, u, v, w, f, width / 2.0, height / 2.0, s)
    # qu, qv, fac: B x z x h x w; dir_ok: B x 1 x h x w
    inside = (qu >= 0) & (qu <= width) & (qv >= 0) & (qv <= height)
    valid = (disp > 0) & dir_ok & (fac > EPS_FACTOR) & inside  # B x z x h x w

    gx = 2.0 * qu / width - 1.0
    gy = 2.0 * qv / height - 1.0
    hh, ww = disp.shape[-2:]
    grid = torch.stack([gx, gy], dim=-1).reshape(b, -1, ww, 2)  # B x (z*h) x w x 2
    sampled = F.grid_sample(
        torch.cat([image, disp], dim=1), grid, mode="bilinear", padding_mode="border",
        align_corners=False,
    )  # B x (C+1) x (z*h) x w
    sampled = sampled.reshape(b, c + 1, -1, hh, ww)  # B x (C+1) x z x h x w
    rgb = sampled[:, :c]
    disp_q = sampled[:, c]  # B x z x h x w
    ok_q = disp_q > 0
    ratio = fac * disp / torch.where(ok_q, disp_q, torch.ones_like(disp_q))
    ratio = torch.where(ok_q, ratio, torch.full_like(ratio, MAX_RATIO)).clamp(0.0, MAX_RATIO)
    ratio = torch.where(valid, ratio, torch.full_like(ratio, MAX_RATIO))
    rgb = rgb * valid.unsqueeze(1).to(rgb.dtype)
    return {"ratio": ratio.unsqueeze(1), "valid": valid.unsqueeze(1), "rgb": rgb}
