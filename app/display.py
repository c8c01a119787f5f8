"""Qt-free conversions of session arrays into display images (uint8 numpy).

Everything here runs in the worker thread, so the GUI thread only wraps finished bytes in a
``QImage``.
"""

from __future__ import annotations

import numpy as np

#: Tint of predicted shadows over the photo (a cool blue that reads against warm and green scenes).
OVERLAY_RGB = (40, 110, 255)
#: Tint of the shadows found in the photo (step 2's "Shadows found" view): magenta, so it is not
#: taken for step 1's predicted shadows.
FOUND_RGB = (235, 50, 200)
#: Overlay strength on surfaces turned away from the sun (attached shadow), relative to cast ones.
ATTACHED_STRENGTH = 0.35
BUFFER_TITLES = {
    "input": "Input",
    "depth": "Depth",
    "normals": "Normals",
    "original_shadow": "Original shadow",
    "new_shadow": "New shadow",
    "output": "Output",
}


def to_uint8_rgb(image: np.ndarray) -> np.ndarray:
    """``H x W x 3`` float sRGB in [0, 1] (or uint8) to contiguous uint8."""
    a = np.asarray(image)
    if a.ndim != 3 or a.shape[2] < 3:
        raise ValueError(f"expected an image of shape H x W x 3, got {a.shape}")
    a = a[..., :3]
    if a.dtype == np.uint8:
        return np.ascontiguousarray(a)
    a = np.nan_to_num(a.astype(np.float32), nan=0.0, posinf=1.0, neginf=0.0)
    return np.ascontiguousarray((np.clip(a, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8))


def shadow_overlay_rgba(
    shadow: np.ndarray,
    sky: np.ndarray | None = None,
    cosine: np.ndarray | None = None,
    colour: tuple[int, int, int] = OVERLAY_RGB,
) -> np.ndarray:
    """Tinted overlay of predicted shadows.

    The shadow image is cosine-weighted (a lit ground under a low sun is only ``sin(el)`` bright),
    so when the cosine term is given the overlay shows ``1 - visibility`` with
    ``visibility = shadow / cos``: lit surfaces stay clear whatever their angle, cast shadows are
    tinted fully and surfaces turned away from the sun at :data:`ATTACHED_STRENGTH`.

    Args:
        shadow: ``H x W`` float in [0, 1].
        sky: ``H x W`` bool, never tinted.
        cosine: ``H x W`` ``max(0, N.w)`` for the same sun, or None.
        colour: tint RGB.

    Returns:
        ``H x W x 4`` uint8 RGBA (straight alpha).
    """
    s = np.asarray(shadow, dtype=np.float32)
    if s.ndim != 2:
        raise ValueError(f"expected a shadow of shape H x W, got {s.shape}")
    s = np.clip(np.nan_to_num(s, nan=1.0), 0.0, 1.0)
    if cosine is not None:
        c = np.asarray(cosine, dtype=np.float32)
        if c.shape != s.shape:
            raise ValueError(f"expected a cosine map of shape {s.shape}, got {c.shape}")
        lit_side = c > 0.05
        vis = np.where(lit_side, s / np.maximum(c, 0.05), 0.0)
        # Cast shadows (what the user aligns) at full strength; surfaces turned away from the
        # sun only lightly, so a wall at grazing light does not hide the photo.
        dark = np.where(lit_side, 1.0 - np.clip(vis, 0.0, 1.0), ATTACHED_STRENGTH)
    else:
        dark = 1.0 - s
    if sky is not None:
        if sky.shape != s.shape:
            raise ValueError(f"expected a sky mask of shape {s.shape}, got {sky.shape}")
        dark = np.where(sky, 0.0, dark)
    out = np.empty(s.shape + (4,), np.uint8)  # H x W x 4
    out[..., 0], out[..., 1], out[..., 2] = colour
    out[..., 3] = (np.clip(dark, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
    return out


def found_shadow_overlay_rgba(
    probability: np.ndarray,
    sky: np.ndarray | None = None,
    colour: tuple[int, int, int] = FOUND_RGB,
) -> np.ndarray:
    """Tinted overlay of the shadows found in the photo (what de-shadowing lifts).

    Args:
        probability: ``H x W`` float in [0, 1], the session's ``lifted_shadows()``.
        sky: ``H x W`` bool, never tinted.
        colour: tint RGB.

    Returns:
        ``H x W x 4`` uint8 RGBA (straight alpha): alpha is the probability.

    Example:
        >>> found_shadow_overlay_rgba(np.array([[0.0, 1.0]]))[..., 3].tolist()
        [[0, 255]]
    """
    p = np.asarray(probability, dtype=np.float32)
    return shadow_overlay_rgba(1.0 - np.clip(np.nan_to_num(p, nan=0.0), 0.0, 1.0), sky,
                               colour=colour)


def depth_to_rgb(depth_display: np.ndarray, sky: np.ndarray | None = None) -> np.ndarray:
    """Display-ready depth (``H x W`` in [0, 1], near = 1) as a colour map; sky black."""
    import cv2

    d = np.asarray(depth_display, dtype=np.float32)
    if d.ndim == 3 and d.shape[2] >= 3:  # already an image
        return to_uint8_rgb(d)
    if d.ndim != 2:
        raise ValueError(f"expected depth of shape H x W, got {d.shape}")
    grey = (np.clip(np.nan_to_num(d, nan=0.0), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
    rgb = cv2.applyColorMap(grey, cv2.COLORMAP_TURBO)[..., ::-1]  # BGR -> RGB
    if sky is not None:
        if sky.shape != d.shape:
            raise ValueError(f"expected a sky mask of shape {d.shape}, got {sky.shape}")
        rgb = np.where(sky[..., None], 0, rgb)
    return np.ascontiguousarray(rgb.astype(np.uint8))


def normals_to_rgb(normals: np.ndarray) -> np.ndarray:
    """Camera-space unit normals as the usual ``(n + 1) / 2`` colours (x red, -y green, -z blue)."""
    n = np.asarray(normals, dtype=np.float32)
    if n.ndim != 3 or n.shape[2] != 3:
        raise ValueError(f"expected normals of shape H x W x 3, got {n.shape}")
    if n.min() >= 0.0:  # already display-ready
        return to_uint8_rgb(n)
    # Flip y and z so that up-facing is green and camera-facing is blue, as in most papers.
    vis = np.stack([n[..., 0], -n[..., 1], -n[..., 2]], axis=-1)  # H x W x 3
    zero = np.linalg.norm(n, axis=-1) < 1e-6
    out = to_uint8_rgb((vis + 1.0) / 2.0)
    out[zero] = 0
    return out


def grey_to_rgb(image: np.ndarray) -> np.ndarray:
    g = np.asarray(image, dtype=np.float32)
    if g.ndim == 3:
        return to_uint8_rgb(g)
    if g.ndim != 2:
        raise ValueError(f"expected an H x W image, got {g.shape}")
    return to_uint8_rgb(np.repeat(g[..., None], 3, axis=-1))


def buffer_to_rgb(name: str, array: np.ndarray, sky: np.ndarray | None = None) -> np.ndarray:
    """One of the session's buffers as uint8 RGB for display."""
    if name == "depth":
        return depth_to_rgb(array, sky)
    if name == "normals":
        return normals_to_rgb(array)
    if name in ("original_shadow", "new_shadow"):
        return grey_to_rgb(array)
    return to_uint8_rgb(array)
