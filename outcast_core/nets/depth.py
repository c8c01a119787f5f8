"""``Z``: monocular depth (scale-free) and a sky mask, and its scale-invariant log loss."""

from __future__ import annotations

import torch
from torch import nn

from outcast_core.nets.blocks import UNet


class DepthNet(nn.Module):
    """``Z``: photo -> depth (scale-free, geometric mean over non-sky pixels = 1) and sky.

    Shape:
        image ``(B, 3, H, W)`` -> ``(depth (B, 1, H, W) > 0, sky (B, 1, H, W) in [0, 1])``.
    """

    def __init__(self, widths: tuple[int, ...] = (24, 40, 72, 96, 112)) -> None:
        super().__init__()
        self.unet = UNet(3, 2, widths)
        self.pad_multiple = 2 ** (len(widths) - 1)

    def forward(self, image: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        if image.dim() != 4 or image.shape[1] != 3:
            raise ValueError(f"expected image of shape B x 3 x H x W, got {tuple(image.shape)}")
        out = self.unet(image)
        log_depth = out[:, :1]
        sky = torch.sigmoid(out[:, 1:])
        ground = 1.0 - sky.detach()
        mean = (log_depth * ground).sum(dim=(2, 3), keepdim=True) / ground.sum(
            dim=(2, 3), keepdim=True
        ).clamp_min(1e-6)
        return torch.exp((log_depth - mean).clamp(-20.0, 20.0)), sky


def scale_invariant_log_loss(
    pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor
) -> torch.Tensor:
    """Eigen et al.'s scale-invariant log loss with ``lambda = 1`` (fully scale invariant).

    Args:
        pred: ``B x 1 x H x W`` predicted depth (> 0).
        target: ``B x 1 x H x W`` true depth.
        mask: ``B x 1 x H x W`` bool, pixels to use (finite, positive target).

    Returns:
        Scalar: mean over images of ``var(log pred - log target)`` on the mask.
    """
    m = mask.to(pred.dtype)
    safe_t = torch.where(mask, target, torch.ones_like(target))
    d = (torch.log(pred.clamp_min(1e-8)) - torch.log(safe_t)) * m
    n = m.sum(dim=(1, 2, 3)).clamp_min(1.0)
    mean = d.sum(dim=(1, 2, 3)) / n
    return ((d**2).sum(dim=(1, 2, 3)) / n - mean**2).mean()


def gradient_matching_loss(
    pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor, scales: int = 4
) -> torch.Tensor:
    """Multi-scale gradient matching on log depth (Li and Snavely's MegaDepth term).

    The log residual ``R = log pred - log target`` is free of the unknown scale; this is the mean
    absolute horizontal and vertical difference of ``R`` between neighbouring valid pixels, at
    ``scales`` resolutions (each half the last, by subsampling). A depth map whose log is a
    compressed copy of the truth's (the right ordering, too little relief) pays at every edge and
    slope, where the scale-invariant log loss only sees one variance over the whole image.

    Args:
        pred: ``B x 1 x H x W`` predicted depth (> 0).
        target: ``B x 1 x H x W`` true depth.
        mask: ``B x 1 x H x W`` bool, pixels to use (finite, positive target).
        scales: number of resolutions (>= 1).

    Returns:
        Scalar: the sum over scales of the mean absolute difference (over valid pixel pairs).
    """
    if scales < 1:
        raise ValueError(f"expected scales >= 1, got {scales}")
    safe_t = torch.where(mask, target, torch.ones_like(target))
    r = torch.log(pred.clamp_min(1e-8)) - torch.log(safe_t)
    m = mask.to(pred.dtype)
    total = pred.new_zeros(())
    for s in range(scales):
        step = 2**s
        rs, ms = r[..., ::step, ::step], m[..., ::step, ::step]
        gx = (rs[..., :, 1:] - rs[..., :, :-1]).abs() * ms[..., :, 1:] * ms[..., :, :-1]
        gy = (rs[..., 1:, :] - rs[..., :-1, :]).abs() * ms[..., 1:, :] * ms[..., :-1, :]
        n = (ms[..., :, 1:] * ms[..., :, :-1]).sum() + (ms[..., 1:, :] * ms[..., :-1, :]).sum()
        total = total + (gx.sum() + gy.sum()) / n.clamp_min(1.0)
    return total


def normal_loss(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Mean ``1 - cos`` of the angle between two unit normal maps on ``mask``.

    Args:
        pred, target: ``B x 3 x H x W`` unit normals (zero where undefined).
        mask: ``B x 1 x H x W`` bool, pixels to use.

    Returns:
        Scalar in ``[0, 2]``; 0 when the normals agree everywhere on the mask.
    """
    m = mask & (target.abs().sum(dim=1, keepdim=True) > 0)
    cos = (pred * target).sum(dim=1, keepdim=True)
    w = m.to(pred.dtype)
    return ((1.0 - cos) * w).sum() / w.sum().clamp_min(1.0)
