"""Losses: SSIM / DSSIM, the structural loss that replaces E-LPIPS, LSGAN terms.

E-LPIPS needs pretrained backbone weights that cannot be downloaded here, so the paper's
perceptual loss is replaced by ``L1 + (1 - SSIM) / 2`` (a standard structural image loss that keeps
edges such as shadow boundaries sharp where plain L2 blurs them).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F  # noqa: N812  (the universal torch idiom)

_C1 = 0.01**2
_C2 = 0.03**2


def _gaussian_window(size: int, sigma: float, channels: int, like: torch.Tensor) -> torch.Tensor:
    x = torch.arange(size, dtype=like.dtype, device=like.device) - (size - 1) / 2
    g = torch.exp(-(x**2) / (2 * sigma**2))
    g = g / g.sum()
    win = g[:, None] * g[None, :]  # size x size
    return win.expand(channels, 1, size, size).contiguous()


def ssim_map(a: torch.Tensor, b: torch.Tensor, size: int = 11, sigma: float = 1.5) -> torch.Tensor:
    """Per-pixel SSIM (Wang et al. 2004, Gaussian 11x11, sigma 1.5) of images in [0, 1].

    Shape:
        ``(B, C, H, W)`` x 2 -> ``(B, C, H, W)`` (reflect-padded borders).
    """
    if a.shape != b.shape or a.dim() != 4:
        raise ValueError(
            f"expected two B x C x H x W tensors of one shape, got {a.shape}, {b.shape}"
        )
    c = a.shape[1]
    win = _gaussian_window(size, sigma, c, a)
    pad = size // 2

    def blur(x: torch.Tensor) -> torch.Tensor:
        return F.conv2d(F.pad(x, (pad,) * 4, mode="reflect"), win, groups=c)

    mu_a, mu_b = blur(a), blur(b)
    saa = blur(a * a) - mu_a**2
    sbb = blur(b * b) - mu_b**2
    sab = blur(a * b) - mu_a * mu_b
    num = (2 * mu_a * mu_b + _C1) * (2 * sab + _C2)
    den = (mu_a**2 + mu_b**2 + _C1) * (saa + sbb + _C2)
    return num / den


def dssim(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Structural dissimilarity ``(1 - SSIM) / 2`` per image (``B``), the paper's Table 1 metric."""
    return ((1.0 - ssim_map(a, b)) / 2.0).mean(dim=(1, 2, 3))


def structural_loss(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """``L1 + DSSIM``, averaged over the batch: our stand-in for E-LPIPS."""
    return (pred - target).abs().mean() + dssim(pred, target).mean()


def change_weight(vis_old: torch.Tensor, vis_new: torch.Tensor) -> torch.Tensor:
    """:func:`change_loss`'s per-pixel weight: ``|vis_old - vis_new|`` dilated by one pixel.

    Shape:
        ``(B, 1, H, W)`` x 2 -> ``(B, 1, H, W)``.
    """
    if vis_old.shape != vis_new.shape or vis_old.dim() != 4 or vis_old.shape[1] != 1:
        raise ValueError(
            f"expected two B x 1 x H x W visibility maps, got {vis_old.shape}, {vis_new.shape}"
        )
    return F.max_pool2d((vis_old - vis_new).abs(), 3, stride=1, padding=1)


def change_loss(
    pred: torch.Tensor, target: torch.Tensor, vis_old: torch.Tensor, vis_new: torch.Tensor,
    weight_sum: torch.Tensor | None = None,
) -> torch.Tensor:
    """L1 of ``pred`` against ``target`` on the pixels whose sun visibility changed.

    The weight is ``|vis_old - vis_new|`` dilated by one pixel (so shadow edges count), and the
    mean is over the weighted pixels of the whole batch: the term does not shrink when the moved
    shadows are small (within a batch, images with larger changes weigh more). Where no
    visibility changed the term is 0. Whole-image losses are dominated by the
    global change of light; this one is paid only where a shadow appears or disappears.

    ``weight_sum`` replaces the batch's weight sum as the normaliser (distributed training
    passes the sum over the whole global batch divided by the number of processes, so that the
    processes' mean is the one-process loss).

    Shape:
        pred, target ``(B, C, H, W)``; vis_old, vis_new ``(B, 1, H, W)`` -> scalar.
    """
    wgt = change_weight(vis_old, vis_new)
    err = ((pred - target).abs() * wgt).sum() / pred.shape[1]
    return err / (wgt.sum().clamp_min(1.0) if weight_sum is None else weight_sum)


def lsgan_d_loss(real: torch.Tensor, fake: torch.Tensor) -> torch.Tensor:
    """Least-squares critic loss: real -> 1, fake -> 0."""
    return 0.5 * (((real - 1.0) ** 2).mean() + (fake**2).mean())


def lsgan_g_loss(fake: torch.Tensor) -> torch.Tensor:
    """Least-squares generator loss: make the critic say 1."""
    return 0.5 * ((fake - 1.0) ** 2).mean()
