"""Small building blocks shared by the networks: conv blocks and a plain 2D U-Net."""

from __future__ import annotations

import torch
import torch.nn.functional as F  # noqa: N812  (the universal torch idiom)
from torch import nn


def conv_block(cin: int, cout: int, stride: int = 1) -> nn.Sequential:
    """3x3 conv (optionally strided) + GroupNorm-free LeakyReLU, then a 3x3 conv + LeakyReLU."""
    return nn.Sequential(
        nn.Conv2d(cin, cout, 3, stride=stride, padding=1),
        nn.LeakyReLU(0.1, inplace=True),
        nn.Conv2d(cout, cout, 3, padding=1),
        nn.LeakyReLU(0.1, inplace=True),
    )


def up2(x: torch.Tensor) -> torch.Tensor:
    """Bilinear x2 upsampling (exports as an ONNX Resize with constant scales)."""
    return F.interpolate(x, scale_factor=2.0, mode="bilinear", align_corners=False)


def broadcast_vector(vec: torch.Tensor, like: torch.Tensor) -> torch.Tensor:
    """``B x K`` -> ``B x K x H x W`` constant maps the size of ``like``."""
    if vec.dim() != 2:
        raise ValueError(f"expected a B x K vector, got shape {tuple(vec.shape)}")
    ones = torch.ones_like(like[:, :1])  # B x 1 x H x W
    return vec.reshape(vec.shape[0], -1, 1, 1) * ones


class UNet(nn.Module):
    """A plain 2D U-Net: ``levels`` strided encoder blocks, a decoder with skip concatenation.

    Args:
        cin: input channels.
        cout: output channels (raw, no activation).
        widths: channels per level, finest first; ``len(widths) - 1`` downsamplings, so inputs
            must be divisible by ``2 ** (len(widths) - 1)``.
        zero_head: start the output convolution at zero (the wrapper's residual is identity).

    Shape:
        ``(B, cin, H, W) -> (B, cout, H, W)``.
    """

    def __init__(
        self, cin: int, cout: int, widths: tuple[int, ...] = (16, 32, 64, 96),
        zero_head: bool = False,
    ) -> None:
        super().__init__()
        self.enc = nn.ModuleList()
        prev = cin
        for i, c in enumerate(widths):
            self.enc.append(conv_block(prev, c, stride=1 if i == 0 else 2))
            prev = c
        self.dec = nn.ModuleList()
        for i in range(len(widths) - 1, 0, -1):
            self.dec.append(conv_block(widths[i] + widths[i - 1], widths[i - 1]))
        self.head = nn.Conv2d(widths[0], cout, 1)
        if zero_head:
            nn.init.zeros_(self.head.weight)
            nn.init.zeros_(self.head.bias)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        skips = []
        for blk in self.enc:
            x = blk(x)
            skips.append(x)
        x = skips.pop()
        for blk in self.dec:
            x = blk(torch.cat([up2(x), skips.pop()], dim=1))
        return self.head(x)


def count_parameters(module: nn.Module) -> int:
    """Number of trainable parameters."""
    return sum(p.numel() for p in module.parameters() if p.requires_grad)
