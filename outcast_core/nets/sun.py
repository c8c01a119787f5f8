"""``D``: the sun's direction read from a photo's appearance, as a distribution over the sphere.

:func:`~outcast_core.runtime.pipeline.auto_sun.find_sun` ranks suns by how well their predicted
shadows agree with the photo's found shadows. Those predictions rest on the estimated depth, and
on held-out synthetic views even the *true* shadow mask with ``Z``'s depth puts the
best-agreeing sun about 49 degrees off (``models/EVAL.md``): the estimated normals are 22
degrees off the renderer's. ``D`` reads the sun from what the photo shows directly (which faces
are bright, where the shade falls, the sky's gradient) without going through a depth map; its
distribution can be a second term of the search's ranking (``auto_sun.LOOK_WEIGHT``, 0 by
default: the first ``D`` made the real dev photos' suns worse, ``models/EVAL.md``).

Architecture: ``Z``'s encoder (:class:`~outcast_core.nets.depth.DepthNet`'s five levels, same
parameter names, so a run may start it from the shipped ``models/depth.onnx``), then a 3x3
convolution, global mean and max pooling and two linear layers to ``K`` logits, one per
direction of :func:`direction_bins` (a Fibonacci lattice over the whole sphere of camera-space
directions: a tilted camera sees suns below its own horizontal). The target is a von
Mises-Fisher kernel about the true sun over those directions (:func:`soft_target`); the
distribution at any direction is the same kernel's mixture of the bins
(:meth:`~outcast_core.runtime.pipeline.sun_look.SunLook.likelihood`).

Shape:
    image ``(B, 3, H, W)`` (sRGB in [0, 1], ``H, W`` multiples of 16) -> ``(B, K)`` logits.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F  # noqa: N812  (the universal torch idiom)
from torch import nn

from outcast_core.nets.blocks import conv_block
from outcast_core.runtime.pipeline.sun_look import DEFAULT_BINS, DEFAULT_KAPPA, direction_bins

#: Number of direction bins (mean spacing about 11 degrees): the runtime reader's.
BINS = DEFAULT_BINS
#: Concentration of the von Mises-Fisher kernel of the targets and of the runtime's mixture
#: (``1 / sigma^2`` with ``sigma`` 8 degrees): the runtime reader's.
KAPPA = DEFAULT_KAPPA


def soft_target(sun: torch.Tensor, bins: torch.Tensor, kappa: float = KAPPA) -> torch.Tensor:
    """``B x K`` target distribution: a von Mises-Fisher kernel about each (unit) ``sun``
    (``B x 3``) evaluated at the ``K x 3`` ``bins``, normalised over the bins."""
    sun = F.normalize(sun, dim=1)
    return torch.softmax(kappa * (sun @ bins.T), dim=1)


class _Encoder(nn.Module):
    """``Z``'s encoder: the strided conv blocks of :class:`~outcast_core.nets.blocks.UNet`,
    under the same names (``enc.I.J``)."""

    def __init__(self, widths: tuple[int, ...]) -> None:
        super().__init__()
        self.enc = nn.ModuleList()
        prev = 3
        for i, c in enumerate(widths):
            self.enc.append(conv_block(prev, c, stride=1 if i == 0 else 2))
            prev = c

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        for blk in self.enc:
            x = blk(x)
        return x


class SunNet(nn.Module):
    """``D``: photo -> logits over :func:`direction_bins` (see the module docstring).

    Args:
        widths: the encoder's channels per level (``Z``'s by default).
        bins: number of direction bins.
        hidden: width of the head.
        dropout: dropout before the last layer (training only).
        freeze: how many of the encoder's first (finest) levels are not trained: started from
            ``Z``'s, they keep its low-level features, and a training step skips their
            backward pass, the costliest part at full resolution.
    """

    def __init__(self, widths: tuple[int, ...] = (24, 40, 72, 96, 112), bins: int = BINS,
                 hidden: int = 256, dropout: float = 0.2, freeze: int = 0) -> None:
        super().__init__()
        if not 0 <= freeze <= len(widths):
            raise ValueError(f"expected 0 <= freeze <= {len(widths)}, got {freeze}")
        self.unet = _Encoder(tuple(widths))  # "unet.enc.*": Z's parameter names
        for blk in list(self.unet.enc)[:freeze]:
            blk.requires_grad_(False)
        c = widths[-1]
        self.mix = nn.Sequential(nn.Conv2d(c, hidden // 2, 3, padding=1),
                                 nn.LeakyReLU(0.1, inplace=True))
        self.fc = nn.Sequential(nn.Linear(hidden, hidden), nn.LeakyReLU(0.1, inplace=True),
                                nn.Dropout(dropout), nn.Linear(hidden, bins))
        self.register_buffer("bins", torch.from_numpy(direction_bins(bins)), persistent=False)
        self.pad_multiple = 2 ** (len(widths) - 1)

    def forward(self, image: torch.Tensor) -> torch.Tensor:
        if image.dim() != 4 or image.shape[1] != 3:
            raise ValueError(f"expected image of shape B x 3 x H x W, got {tuple(image.shape)}")
        x = self.mix(self.unet(image))
        pooled = torch.cat([x.mean(dim=(2, 3)), x.amax(dim=(2, 3))], dim=1)
        return self.fc(pooled)


def sun_loss(logits: torch.Tensor, sun: torch.Tensor, bins: torch.Tensor,
             kappa: float = KAPPA) -> torch.Tensor:
    """Cross-entropy of the logits against :func:`soft_target` (mean over the batch)."""
    target = soft_target(sun, bins, kappa)
    return -(target * torch.log_softmax(logits, dim=1)).sum(dim=1).mean()


def expected_angle_deg(logits: torch.Tensor, sun: torch.Tensor, bins: torch.Tensor) -> torch.Tensor:
    """``B`` angles (degrees) between each true ``sun`` and the most likely bin (a coarse
    figure for the training log; the runtime takes the kernel mixture's peak)."""
    best = bins[logits.argmax(dim=1)]
    cos = (F.normalize(sun, dim=1) * best).sum(dim=1).clamp(-1.0, 1.0)
    return torch.rad2deg(torch.acos(cos))


__all__ = ["BINS", "KAPPA", "SunNet", "direction_bins", "expected_angle_deg", "soft_target",
           "sun_loss"]
