"""The cast-shadow networks: ``S`` (learned ray marching, the paper's key idea) and ``S2D``.

``S`` (:class:`ShadowNet`) follows the paper: 2D features ``[RGB, max(0, N.w)]`` go through a
2D encoder; the epipolar volume ``B x 4 x z x h x w`` (RGB + depth ratio, built by
:func:`outcast_core.nets.raymarch_torch.march_volume`) goes through a 3D encoder that halves every
axis per level and doubles the features, each level collapsed over the march axis with a max (so
any ``z`` works); a decoder runs on the element-wise max of both, with skip connections (3D skips
bilinearly upsampled where their resolution is coarser). The output is
``S = max(0, N.w) * sigmoid(logit)``: a cosine-weighted visibility in [0, 1], 0 on sky.

``S2D`` (:class:`Shadow2DNet`) is the paper's "2D" ablation: the same inputs, no ray marching, a
plain U-Net on RGB, cosine, sun direction and normalised disparity.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod

import torch
import torch.nn.functional as F  # noqa: N812  (the universal torch idiom)
from torch import nn

from outcast_core.nets.blocks import UNet, broadcast_vector, conv_block, up2
from outcast_core.nets.geometry_torch import cosine_term, image_size
from outcast_core.nets.raymarch_torch import disparity, march_volume
from outcast_core.runtime.geometry.raymarch import DEFAULT_NET_STEP


def _check_inputs(
    image: torch.Tensor, depth: torch.Tensor, normals: torch.Tensor, sun: torch.Tensor,
    focal: torch.Tensor, multiple: int,
) -> None:
    if image.dim() != 4 or image.shape[1] != 3:
        raise ValueError(f"expected image of shape B x 3 x H x W, got {tuple(image.shape)}")
    b, _, h, w = image.shape
    for name, t, c in (("depth", depth, 1), ("normals", normals, 3)):
        if tuple(t.shape) != (b, c, h, w):
            raise ValueError(f"expected {name} of shape {(b, c, h, w)}, got {tuple(t.shape)}")
    if tuple(sun.shape) != (b, 3) or tuple(focal.shape) != (b, 1):
        raise ValueError(
            f"expected sun {(b, 3)} and focal {(b, 1)}, "
            f"got {tuple(sun.shape)} and {tuple(focal.shape)}"
        )
    if not torch.jit.is_tracing() and (h % multiple or w % multiple):
        raise ValueError(f"expected H and W divisible by {multiple}, got {h} x {w}")


class _CastShadowNet(nn.Module, ABC):
    """Shared front and back of the shadow networks: input checks, the cosine term, and
    ``S = sigmoid(logit) * cos``. Subclasses implement :meth:`visibility_logit`."""

    pad_multiple = 8

    def forward(
        self, image: torch.Tensor, depth: torch.Tensor, normals: torch.Tensor,
        sun: torch.Tensor, focal: torch.Tensor,
    ) -> torch.Tensor:
        logit, cos = self.logits(image, depth, normals, sun, focal)
        return torch.sigmoid(logit) * cos

    def logits(
        self, image: torch.Tensor, depth: torch.Tensor, normals: torch.Tensor,
        sun: torch.Tensor, focal: torch.Tensor,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Visibility logits and the cosine term (``S = sigmoid(logit) * cos``), for training."""
        _check_inputs(image, depth, normals, sun, focal, self.pad_multiple)
        sun = sun / torch.linalg.vector_norm(sun, dim=1, keepdim=True)
        cos = cosine_term(normals, sun)  # B x 1 x H x W
        return self.visibility_logit(image, depth, sun, focal, cos), cos

    @abstractmethod
    def visibility_logit(
        self, image: torch.Tensor, depth: torch.Tensor, sun: torch.Tensor, focal: torch.Tensor,
        cos: torch.Tensor,
    ) -> torch.Tensor:
        """``B x 1 x H x W`` visibility logits (``sun`` already unit length)."""


class ShadowNet(_CastShadowNet):
    """``S``: cast shadows from one image, its depth and normals, for any sun direction.

    Args:
        steps: march steps ``z``.
        step: step length (fraction of the longer image side).
        volume_scale: 1 or 0.5: resolution of the epipolar volume relative to the input.
        widths2d: 2D encoder channels per level (4 levels, finest first).
        widths3d: 3D encoder channels per level (level 0 mixes along the ray only, at the
            volume's resolution; levels 1-3 halve every axis, levels 2-3 add a second conv).

    Shape:
        image ``(B, 3, H, W)``, depth ``(B, 1, H, W)``, normals ``(B, 3, H, W)``, sun ``(B, 3)``,
        focal ``(B, 1)`` -> shadow ``(B, 1, H, W)``; ``H, W`` multiples of :attr:`pad_multiple`.
    """

    def __init__(
        self, steps: int = 32, step: float = DEFAULT_NET_STEP, volume_scale: float = 0.5,
        widths2d: tuple[int, ...] = (16, 24, 40, 56), widths3d: tuple[int, ...] = (8, 16, 24, 32),
    ) -> None:
        super().__init__()
        if volume_scale not in (1.0, 0.5):
            raise ValueError(f"expected volume_scale 1 or 0.5, got {volume_scale}")
        if len(widths2d) != 4 or len(widths3d) != 4:
            raise ValueError(f"expected 4 widths per encoder, got {widths2d}, {widths3d}")
        self.steps = int(steps)
        self.step = float(step)
        self.volume_scale = float(volume_scale)
        self.shift = round(math.log2(1.0 / volume_scale))  # 2D level of 3D level 0
        self.pad_multiple = 8 * (2**self.shift)
        self.enc2d = nn.ModuleList()
        prev = 4
        for i, c in enumerate(widths2d):
            self.enc2d.append(conv_block(prev, c, stride=1 if i == 0 else 2))
            prev = c
        act = nn.LeakyReLU(0.1, inplace=True)
        self.enc3d = nn.ModuleList([nn.Sequential(
            nn.Conv3d(4, widths3d[0], (3, 1, 1), padding=(1, 0, 0)), act,
        )])
        for k in range(1, 4):
            layers: list[nn.Module] = [
                nn.Conv3d(widths3d[k - 1], widths3d[k], 3, stride=2, padding=1), act,
            ]
            if k >= 2:  # a second conv where the volume is small (level 1 is the costly one)
                layers += [nn.Conv3d(widths3d[k], widths3d[k], 3, padding=1), act]
            self.enc3d.append(nn.Sequential(*layers))
        # 3D level k lands on 2D level min(k + shift, 3), upsampled by 2 ** (excess).
        self.target = [min(k + self.shift, 3) for k in range(4)]
        self.upscale = [2 ** (k + self.shift - t) for k, t in enumerate(self.target)]
        self.proj = nn.ModuleList(
            nn.Conv2d(widths3d[k], widths2d[t], 1) for k, t in enumerate(self.target)
        )
        self.dec = nn.ModuleList(
            conv_block(widths2d[i] + widths2d[i - 1], widths2d[i - 1]) for i in range(3, 0, -1)
        )
        self.head = nn.Conv2d(widths2d[0], 1, 1)

    def visibility_logit(
        self, image: torch.Tensor, depth: torch.Tensor, sun: torch.Tensor, focal: torch.Tensor,
        cos: torch.Tensor,
    ) -> torch.Tensor:
        feats = []
        x = torch.cat([image, cos], dim=1)  # B x 4 x H x W
        for blk in self.enc2d:
            x = blk(x)
            feats.append(x)
        vol = march_volume(image, depth, sun, focal, self.steps, self.step, self.volume_scale)
        v = torch.cat([vol["rgb"], vol["ratio"] - 1.0], dim=1)  # B x 4 x z x h x w
        for k, blk in enumerate(self.enc3d):
            v = blk(v)
            g = self.proj[k](v.amax(dim=2))  # B x C x h_k x w_k (march axis collapsed)
            if self.upscale[k] > 1:
                g = F.interpolate(
                    g, scale_factor=float(self.upscale[k]), mode="bilinear", align_corners=False
                )
            t = self.target[k]
            feats[t] = torch.maximum(feats[t], g)
        x = feats[3]
        for i, blk in zip(range(2, -1, -1), self.dec, strict=True):
            x = blk(torch.cat([up2(x), feats[i]], dim=1))
        return self.head(x)


class Shadow2DNet(_CastShadowNet):
    """``S2D``: the paper's 2D ablation (a U-Net; no ray marching). Same inputs as ``S``.

    Channels: RGB, ``max(0, N.w)``, the sun direction (3 constant maps), the disparity
    normalised by its mean over surface pixels (0 on sky) and the focal length relative to the
    image width (a constant map: the field of view).
    """

    pad_multiple = 8

    def __init__(self, widths: tuple[int, ...] = (16, 32, 48, 72)) -> None:
        super().__init__()
        self.unet = UNet(9, 1, widths)
        self.pad_multiple = 2 ** (len(widths) - 1)

    def visibility_logit(
        self, image: torch.Tensor, depth: torch.Tensor, sun: torch.Tensor, focal: torch.Tensor,
        cos: torch.Tensor,
    ) -> torch.Tensor:
        disp = disparity(depth)
        ok = (disp > 0).to(disp.dtype)
        count = ok.sum(dim=(2, 3), keepdim=True).clamp_min(1)
        mean = (disp * ok).sum(dim=(2, 3), keepdim=True) / count
        disp = disp / mean.clamp_min(1e-12)
        rel_focal = broadcast_vector(focal, image) / image_size(image)[0]
        x = torch.cat([image, cos, broadcast_vector(sun, image), disp, rel_focal], dim=1)
        # x: B x 9 x H x W
        return self.unet(x)
