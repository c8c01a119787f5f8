"""``R`` (shadow refinement), ``L`` (relighting), the Pix2Pix-like ablation and ``A`` (critic).

All image tensors are sRGB-encoded ``[0, 1]``. ``R`` and ``L`` are residual: their last
convolution starts at zero, so an untrained ``R`` returns its input shadow and an untrained ``L``
returns its base image, and training only has to learn the change. ``L``'s base is the photo
(``base="photo"``, the paper's form) or the physics relighting of the photo by shading ratios
(``base="physics"``): ``C_o (1 + r S_n) / (1 + r S_o)`` in linear RGB with the per-channel
sun/ambient ratio ``r`` as an extra input (``light_ratio``, estimated from the photo by
:func:`outcast_core.runtime.pipeline.relight.estimate_light`), so new shadows are already cast and
old ones
already lifted before the network corrects what the ratio model misses. The shipped ``L`` uses
the photo base: the physics base was tried (``train/configs/relight_v4.toml``) and scored worse on
held-out views, as the base paints the shadow networks' errors at full strength.
"""

from __future__ import annotations

import torch
from torch import nn

from outcast_core.nets.blocks import UNet, broadcast_vector

_EPS = 1e-3


def _logit(x: torch.Tensor) -> torch.Tensor:
    x = x.clamp(_EPS, 1.0 - _EPS)
    return torch.log(x / (1.0 - x))


def srgb_to_linear(x: torch.Tensor) -> torch.Tensor:
    """Torch twin of :func:`outcast_core.runtime.geometry.colour.srgb_to_linear` (values clipped
    first)."""
    x = x.clamp(0.0, 1.0)
    return torch.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(x: torch.Tensor) -> torch.Tensor:
    """Torch twin of :func:`outcast_core.runtime.geometry.colour.linear_to_srgb` (values clipped
    first)."""
    x = x.clamp(0.0, 1.0)
    # The clamp keeps pow's base >= 1e-8 so its gradient stays finite in the unused branch.
    return torch.where(x <= 0.0031308, x * 12.92, 1.055 * x.clamp_min(1e-8) ** (1 / 2.4) - 0.055)


def physics_base(
    image: torch.Tensor, shadow_old: torch.Tensor, shadow_new: torch.Tensor,
    normals: torch.Tensor, light_ratio: torch.Tensor,
) -> torch.Tensor:
    """The shading-ratio relighting of
    :func:`outcast_core.runtime.pipeline.relight.physics_relight`.

    Pixels without a surface (zero normals: sky, or depth the network had none for) keep the
    photo. ``B x 3 x H x W`` sRGB in, sRGB out; ``light_ratio`` is ``B x 3``.
    """
    r = light_ratio[:, :, None, None]
    gain = (1.0 + r * shadow_new.clamp(0.0, 1.0)) / (1.0 + r * shadow_old.clamp(0.0, 1.0))
    surface = (normals * normals).sum(dim=1, keepdim=True) > 0.25
    gain = torch.where(surface, gain, torch.ones_like(gain))
    return linear_to_srgb(srgb_to_linear(image) * gain)


def _check_image(name: str, t: torch.Tensor, channels: int, like: torch.Tensor | None) -> None:
    if t.dim() != 4 or t.shape[1] != channels:
        raise ValueError(f"expected {name} of shape B x {channels} x H x W, got {tuple(t.shape)}")
    if like is not None and (t.shape[0] != like.shape[0] or t.shape[2:] != like.shape[2:]):
        raise ValueError(
            f"expected {name} with batch and size {(like.shape[0], *like.shape[2:])}, "
            f"got {tuple(t.shape)}"
        )


def _check_sun(name: str, t: torch.Tensor, batch: int) -> None:
    if tuple(t.shape) != (batch, 3):
        raise ValueError(f"expected {name} of shape ({batch}, 3), got {tuple(t.shape)}")


class RefineNet(nn.Module):
    """``R``: ``S_o = R(S(C, w_o), C, w_o)`` sharpens the original shadow using the photo.

    Shape:
        shadow ``(B, 1, H, W)``, image ``(B, 3, H, W)``, sun ``(B, 3)`` -> ``(B, 1, H, W)``.
    """

    def __init__(self, widths: tuple[int, ...] = (16, 32, 48, 64)) -> None:
        super().__init__()
        self.unet = UNet(7, 1, widths, zero_head=True)
        self.pad_multiple = 2 ** (len(widths) - 1)

    def forward(self, shadow: torch.Tensor, image: torch.Tensor, sun: torch.Tensor) -> torch.Tensor:
        _check_image("image", image, 3, None)
        _check_image("shadow", shadow, 1, image)
        _check_sun("sun", sun, image.shape[0])
        x = torch.cat([shadow, image, broadcast_vector(sun, image)], dim=1)  # B x 7 x H x W
        return torch.sigmoid(_logit(shadow) + self.unet(x))


class RelightNet(nn.Module):
    """``L``: ``C_n = L(C_o, S_o, S_n, N, w_o, w_n, Psi)`` (depth is not an input).

    Args:
        widths: U-Net widths.
        base: what the network's residual is added to: ``"photo"`` (``C_o``) or ``"physics"``
            (:func:`physics_base`, which needs ``light_ratio``). The choice adds no parameters,
            so a checkpoint of either base loads into the other.

    Shape:
        image ``(B, 3, H, W)``, shadow_old / shadow_new ``(B, 1, H, W)``, normals and view_dirs
        ``(B, 3, H, W)``, sun_old / sun_new ``(B, 3)``, light_ratio ``(B, 3)`` (physics base
        only) -> image ``(B, 3, H, W)``.
    """

    BASES = ("photo", "physics")

    def __init__(self, widths: tuple[int, ...] = (24, 48, 72, 112), base: str = "photo") -> None:
        super().__init__()
        if base not in self.BASES:
            raise ValueError(f"expected base in {self.BASES}, got {base!r}")
        self.base = base
        self.unet = UNet(17, 3, widths, zero_head=True)
        self.pad_multiple = 2 ** (len(widths) - 1)

    def forward(
        self, image: torch.Tensor, shadow_old: torch.Tensor, shadow_new: torch.Tensor,
        normals: torch.Tensor, sun_old: torch.Tensor, sun_new: torch.Tensor,
        view_dirs: torch.Tensor, light_ratio: torch.Tensor | None = None,
    ) -> torch.Tensor:
        _check_image("image", image, 3, None)
        for name, t, c in (("shadow_old", shadow_old, 1), ("shadow_new", shadow_new, 1),
                           ("normals", normals, 3), ("view_dirs", view_dirs, 3)):
            _check_image(name, t, c, image)
        _check_sun("sun_old", sun_old, image.shape[0])
        _check_sun("sun_new", sun_new, image.shape[0])
        x = torch.cat([
            image, shadow_old, shadow_new, normals, broadcast_vector(sun_old, image),
            broadcast_vector(sun_new, image), view_dirs,
        ], dim=1)  # B x 17 x H x W
        start = image
        if self.base == "physics":
            if light_ratio is None:
                raise ValueError("expected light_ratio of shape (B, 3) for the physics base")
            _check_sun("light_ratio", light_ratio, image.shape[0])
            start = physics_base(image, shadow_old, shadow_new, normals, light_ratio)
        return torch.sigmoid(_logit(start) + self.unet(x))


class Pix2PixRelightNet(nn.Module):
    """The Pix2Pix-like ablation: ``L`` without shadow inputs.

    Shape:
        image, normals, view_dirs ``(B, 3, H, W)``, sun_old / sun_new ``(B, 3)`` -> image.
    """

    def __init__(self, widths: tuple[int, ...] = (24, 48, 72, 112)) -> None:
        super().__init__()
        self.unet = UNet(15, 3, widths, zero_head=True)
        self.pad_multiple = 2 ** (len(widths) - 1)

    def forward(
        self, image: torch.Tensor, normals: torch.Tensor, sun_old: torch.Tensor,
        sun_new: torch.Tensor, view_dirs: torch.Tensor,
    ) -> torch.Tensor:
        _check_image("image", image, 3, None)
        _check_image("normals", normals, 3, image)
        _check_image("view_dirs", view_dirs, 3, image)
        _check_sun("sun_old", sun_old, image.shape[0])
        _check_sun("sun_new", sun_new, image.shape[0])
        x = torch.cat([
            image, normals, broadcast_vector(sun_old, image), broadcast_vector(sun_new, image),
            view_dirs,
        ], dim=1)  # B x 15 x H x W
        return torch.sigmoid(_logit(image) + self.unet(x))


class PatchDiscriminator(nn.Module):
    """``A``: a patch LSGAN critic with a 70 px receptive field, conditioned on ``C_o``, ``S_n``.

    Shape:
        candidate ``(B, 3, H, W)``, image ``(B, 3, H, W)`` (``C_o``), shadow_new ``(B, 1, H, W)``
        -> scores ``(B, 1, H / 8 - 2, W / 8 - 2)`` (unbounded; LSGAN targets 1 real, 0 fake).
    """

    receptive_field = 70

    def __init__(self, width: int = 32) -> None:
        super().__init__()
        act = nn.LeakyReLU(0.2, inplace=True)
        self.net = nn.Sequential(
            nn.Conv2d(7, width, 4, 2, 1), act,
            nn.Conv2d(width, width * 2, 4, 2, 1), act,
            nn.Conv2d(width * 2, width * 4, 4, 2, 1), act,
            nn.Conv2d(width * 4, width * 4, 4, 1, 1), act,
            nn.Conv2d(width * 4, 1, 4, 1, 1),
        )

    def forward(
        self, candidate: torch.Tensor, image: torch.Tensor, shadow_new: torch.Tensor
    ) -> torch.Tensor:
        _check_image("candidate", candidate, 3, None)
        _check_image("image", image, 3, candidate)
        _check_image("shadow_new", shadow_new, 1, candidate)
        return self.net(torch.cat([candidate, image, shadow_new], dim=1))
