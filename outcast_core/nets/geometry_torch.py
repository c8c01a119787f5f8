"""Torch twins of :mod:`outcast_core.runtime.geometry.camera` (pixel grids, Psi, normals from
depth).

Every function takes batched ``B x C x H x W`` tensors and builds its pixel grid from the input's
shape with tensor ops only, so a traced (ONNX) graph keeps a dynamic height and width.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F  # noqa: N812  (the universal torch idiom)

_EPS = 1e-12


def pixel_grid(x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Pixel-centre coordinates ``(u, v)`` for the spatial size of ``x``.

    Built with ``cumsum`` over ones (not ``arange`` of a Python int) so that tracing keeps the
    size symbolic.

    Args:
        x: any tensor of shape ``B x C x H x W``.

    Returns:
        ``(u, v)``, each ``1 x 1 x H x W``: ``u = column + 0.5``, ``v = row + 0.5``.
    """
    if x.dim() != 4:
        raise ValueError(f"expected a B x C x H x W tensor, got shape {tuple(x.shape)}")
    ones = torch.ones_like(x[:1, :1])  # 1 x 1 x H x W
    u = torch.cumsum(ones, dim=3) - 0.5  # 1 x 1 x H x W
    v = torch.cumsum(ones, dim=2) - 0.5  # 1 x 1 x H x W
    return u, v


def image_size(x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """``(width, height)`` of ``x`` as 0-d float tensors (symbolic under tracing)."""
    ones = torch.ones_like(x[0, 0])  # H x W
    return ones[0].sum(), ones[:, 0].sum()


def view_directions(x: torch.Tensor, focal: torch.Tensor) -> torch.Tensor:
    """Per-pixel unit view directions ``Psi`` (twin of ``geometry.view_directions``).

    Args:
        x: any ``B x C x H x W`` tensor giving the size.
        focal: ``B x 1`` focal lengths in pixels at this resolution.

    Returns:
        ``B x 3 x H x W`` unit vectors.
    """
    focal = _check_focal(focal, x)
    u, v = pixel_grid(x)
    width, height = image_size(x)
    f = focal.reshape(-1, 1, 1, 1)  # B x 1 x 1 x 1
    xn = (u - width / 2.0) / f  # B x 1 x H x W
    yn = (v - height / 2.0) / f
    rays = torch.cat([xn, yn, torch.ones_like(xn)], dim=1)  # B x 3 x H x W
    return rays / torch.linalg.vector_norm(rays, dim=1, keepdim=True)


def valid_depth(depth: torch.Tensor) -> torch.Tensor:
    """Mask of pixels with a surface: finite and strictly positive depth."""
    return torch.isfinite(depth) & (depth > 0)


def _check_focal(focal: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    if focal.dim() != 2 or focal.shape[1] != 1:
        raise ValueError(f"expected focal of shape B x 1, got {tuple(focal.shape)}")
    return focal.to(x.dtype)


def _fill_invalid(d: torch.Tensor, valid: torch.Tensor, iterations: int = 8) -> torch.Tensor:
    """Give invalid pixels the mean of their valid neighbours, grown ``iterations`` times.

    The numpy original uses the exact nearest valid pixel (OpenCV distance transform); this
    approximation only changes normals of pixels whose 3x3 stencil touches an invalid pixel.
    """
    known = valid.to(d.dtype)
    val = torch.where(valid, d, torch.zeros_like(d))
    for _ in range(iterations):
        s = F.avg_pool2d(val * known, 3, stride=1, padding=1, count_include_pad=False)
        c = F.avg_pool2d(known, 3, stride=1, padding=1, count_include_pad=False)
        grown = c > 0
        val = torch.where(known > 0, val, torch.where(grown, s / c.clamp_min(1e-12), val))
        known = torch.maximum(known, grown.to(d.dtype))
    return torch.where(known > 0, val, torch.ones_like(val))


def _sobel_xy(p: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Sobel derivatives along u and v of ``B x C x H x W`` with edge replication."""
    pad = F.pad(p, (1, 1, 1, 1), mode="replicate")  # B x C x (H+2) x (W+2)
    h, w = p.shape[-2:]

    def s(dy: int, dx: int) -> torch.Tensor:
        return pad[..., 1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w]

    du = (s(-1, 1) + 2 * s(0, 1) + s(1, 1)) - (s(-1, -1) + 2 * s(0, -1) + s(1, -1))
    dv = (s(1, -1) + 2 * s(1, 0) + s(1, 1)) - (s(-1, -1) + 2 * s(-1, 0) + s(-1, 1))
    return du / 8.0, dv / 8.0


def normals_from_depth(depth: torch.Tensor, focal: torch.Tensor) -> torch.Tensor:
    """Unit camera-facing normals from z depth (twin of ``geometry.normals_from_depth``).

    Args:
        depth: ``B x 1 x H x W`` z depth; non-finite or ``<= 0`` means no surface.
        focal: ``B x 1`` focal length in pixels.

    Returns:
        ``B x 3 x H x W``; unit where valid, zero elsewhere. Identical to the numpy version
        wherever a pixel's 3x3 neighbourhood is all valid (see :func:`_fill_invalid`).
    """
    if depth.dim() != 4 or depth.shape[1] != 1:
        raise ValueError(f"expected depth of shape B x 1 x H x W, got {tuple(depth.shape)}")
    focal = _check_focal(focal, depth)
    work = depth.to(torch.float64)
    valid = valid_depth(work)
    out = []
    for b in range(work.shape[0]):
        vb = valid[b : b + 1]
        scale = work[b : b + 1][vb].median() if bool(vb.any()) else work.new_tensor(1.0)
        d = torch.where(vb, work[b : b + 1] / scale, torch.zeros_like(work[b : b + 1]))
        d = _fill_invalid(d, vb)  # 1 x 1 x H x W
        u, v = pixel_grid(d)
        width, height = image_size(d)
        f = focal[b].to(torch.float64)
        pts = torch.cat([(u - width / 2) / f * d, (v - height / 2) / f * d, d], dim=1)
        du, dv = _sobel_xy(pts)
        n = torch.linalg.cross(du, dv, dim=1)  # 1 x 3 x H x W
        norm = torch.linalg.vector_norm(n, dim=1, keepdim=True)
        good = (norm > _EPS) & vb & torch.isfinite(norm)
        n = torch.where(good, n / torch.where(norm > _EPS, norm, torch.ones_like(norm)), 0.0)
        facing = (n * pts).sum(dim=1, keepdim=True)
        out.append(torch.where(facing > 0, -n, n))
    return torch.cat(out).to(depth.dtype)


def cosine_term(normals: torch.Tensor, sun: torch.Tensor) -> torch.Tensor:
    """``max(0, N . w)``: ``B x 3 x H x W`` normals, ``B x 3`` sun -> ``B x 1 x H x W``."""
    if sun.dim() != 2 or sun.shape[1] != 3:
        raise ValueError(f"expected sun of shape B x 3, got {tuple(sun.shape)}")
    c = (normals * sun.reshape(-1, 3, 1, 1)).sum(dim=1, keepdim=True)
    return c.clamp(0.0, 1.0)
