"""Contact sheets of a data set: RGB under two suns, depth, normals and shadow images."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from outcast_core.data.dataset import list_views, load_view
from outcast_core.runtime.geometry.colour import tonemap_aces

COLUMNS = ("rgb sun 0", "rgb sun 1", "depth", "normals", "shadow 0", "shadow 1")


def depth_image(depth: np.ndarray) -> np.ndarray:
    """Inverse depth scaled to [0, 1] per image as ``H x W x 3`` (sky black)."""
    valid = np.isfinite(depth) & (depth > 0)
    inv = np.zeros_like(depth, dtype=np.float32)
    inv[valid] = 1.0 / depth[valid]
    if valid.any():
        inv /= max(float(np.percentile(inv[valid], 99)), 1e-6)
    return np.repeat(np.clip(inv, 0, 1)[..., None], 3, axis=-1)


def view_row(view: dict) -> list[np.ndarray]:
    """The sheet's tiles of one view, each ``H x W x 3`` float in [0, 1] (sRGB-encoded)."""
    k = len(view["rgb"])
    s0, s1 = 0, min(1, k - 1)
    e = view["exposure"]
    normals = np.where(view["sky"][..., None], 0.0, view["normals"] * 0.5 + 0.5)
    return [
        tonemap_aces(view["rgb"][s0], e),
        tonemap_aces(view["rgb"][s1], e),
        depth_image(view["depth"]),
        normals,
        np.repeat(view["shadow"][s0][..., None], 3, -1),
        np.repeat(view["shadow"][s1][..., None], 3, -1),
    ]


def contact_sheet(root: str | Path, out: str | Path, max_views: int = 8, tile: int = 160) -> Path:
    """Write a PNG contact sheet of the first ``max_views`` views of a data set.

    Args:
        root: data set folder. out: PNG path. max_views: rows. tile: tile size in pixels.

    Returns:
        The written path.
    """
    from PIL import Image, ImageDraw

    views = list_views(root)
    if not views:
        raise ValueError(f"expected finished views in {str(root)!r}, got none")
    if max_views < 1:
        raise ValueError(f"expected max_views >= 1, got {max_views}")
    step = max(1, len(views) // max_views)
    chosen = views[::step][:max_views]
    head = 16
    sheet = Image.new("RGB", (tile * len(COLUMNS), head + tile * len(chosen)), (30, 30, 30))
    draw = ImageDraw.Draw(sheet)
    for c, name in enumerate(COLUMNS):
        draw.text((c * tile + 4, 2), name, fill=(230, 230, 230))
    for r, path in enumerate(chosen):
        view = load_view(path)
        for c, img in enumerate(view_row(view)):
            im = Image.fromarray((np.clip(img, 0, 1) * 255 + 0.5).astype(np.uint8))
            im = im.resize((tile, tile * img.shape[0] // img.shape[1]), Image.NEAREST)
            sheet.paste(im, (c * tile, head + r * tile))
        m = view["meta"]
        az, el = view["sun_azel"][0]
        draw.text(
            (4, head + r * tile + 2),
            f"{path.name} {m.get('kind', '')} az{az:.0f} el{el:.0f}",
            fill=(255, 255, 0),
        )
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(out)
    return out
