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
