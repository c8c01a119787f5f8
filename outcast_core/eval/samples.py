"""Relight the sample photographs with the shipped models: a side-by-side PNG sheet.

The samples have no ground truth, so this is for looking at: is the old shadow removed, and is
the new one cast in the new sun's direction? Each row is one photo: the input, ``Z``'s depth,
the refined old shadow ``S_o`` and, per new sun, ``S_n`` and the relit photo. The original suns
come from a JSON file (``samples/suns.json``): ``{"file.jpg": {"from": [az, el], "to":
[[az, el], ...]}}``, angles relative to the camera as in ``outcast relight``.

Beside the sheet, :func:`shadow_contrast` puts two numbers on "is the new shadow in the relit
photo": how much of the surface ``S_n`` moves into shadow, and how dark the relit photo is
there against the surface lit under both suns, next to the same ratio for the photo's own
shadows (a real shadow's darkness, on the same surfaces and camera).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from outcast_core.eval.table import save_sheet
from outcast_core.runtime.geometry.camera import sun_vector

#: Shadow masks of :func:`shadow_contrast`, as fractions of a shadow image's 90th percentile on
#: the surface (its "fully lit" level, which includes the cosine term): below ``DARK`` is in
#: shadow, above ``LIT`` is lit (and above ``LIT_OLD`` for the original sun, where lit only
#: has to mean "not in shadow").
DARK, LIT, LIT_OLD = 0.2, 0.7, 0.5


def _mean_ratio(image: np.ndarray, a: np.ndarray, b: np.ndarray) -> float | None:
    """Mean sRGB value of ``image`` over mask ``a`` divided by that over mask ``b`` (None when
    either mask is empty or ``b`` is black)."""
    if not a.any() or not b.any():
        return None
    den = float(image[b].mean())
    return round(float(image[a].mean()) / den, 3) if den > 0 else None


def shadow_contrast(
    image: np.ndarray, relit: np.ndarray, s_o: np.ndarray, s_n: np.ndarray, sky: np.ndarray
) -> dict[str, float | None]:
    """How much new shadow the relit photo shows.

    Args:
        image, relit: ``H x W x 3`` sRGB input and relit photo.
        s_o, s_n: ``H x W`` shadow images of the original and the new sun.
        sky: ``H x W`` bool, no surface.

    Returns:
        ``new_shadow_frac``: fraction of the surface lit under the original sun and in shadow
        under the new one; ``relit_contrast``: the relit photo's mean there over its mean where
        both suns light the surface; ``photo_contrast``: the input's mean in the original sun's
        shadow over its mean where that sun lights the surface. Ratios are None where a mask is
        empty; a ratio near ``photo_contrast`` means new shadows as dark as the photo's own.
    """
    surface = ~np.asarray(sky, bool)
    if not surface.any():
        return {"new_shadow_frac": 0.0, "relit_contrast": None, "photo_contrast": None}
    top_o = float(np.percentile(s_o[surface], 90))
    top_n = float(np.percentile(s_n[surface], 90))
    lit_o = surface & (s_o > LIT_OLD * top_o)
    new = lit_o & (s_n < DARK * top_n)
    both = lit_o & (s_n > LIT * top_n)
    old = surface & (s_o < DARK * top_o)
    return {
        "new_shadow_frac": round(float(new.sum()) / float(surface.sum()), 4),
        "relit_contrast": _mean_ratio(relit, new, both),
        "photo_contrast": _mean_ratio(image, old, surface & (s_o > LIT * top_o)),
    }


def relight_samples(
    spec: str | Path, models: str | Path = "models", preset: str = "balanced"
) -> tuple[list[dict[str, np.ndarray]], list[dict[str, Any]]]:
    """Run the app's photo-only pipeline (learned mode) on every photo named in ``spec``.

    Returns:
        ``(sheet rows, records)``: one row of labelled images and one record (file, suns,
        depth source, shadow and relight modes, seconds) per photo.
    """
    from outcast_core.runtime.io.imageio import read_image
    from outcast_core.runtime.io.models import ModelRegistry
    from outcast_core.runtime.pipeline.session import RelightSession, depth_for_display

    spec = Path(spec)
    entries = {k: v for k, v in json.loads(spec.read_text()).items() if not k.startswith("_")}
    if not entries:
        raise ValueError(f"expected at least one photo in {spec}, got none")
    rows, records = [], []
    for name, entry in entries.items():
        loaded = read_image(spec.parent / name, max_pixels=4_000_000)
        session = RelightSession(ModelRegistry(models), preset=preset, mode="learned")
        # With the photo's file, as the app and the CLI set it: its metadata give the camera's
        # tilt, the horizon of the new sun's daylight (without it the ski slope's relit
        # photos came out blue-white, unlike the CLI's).
        session.set_image(loaded.image_srgb, focal_35mm=loaded.exif.focal_35mm,
                          photo_path=spec.parent / name)
        s_o = session.set_original_sun(sun_vector(*entry["from"]))
        row: dict[str, np.ndarray] = {
            "Input": session.image_srgb,
            "Z depth": depth_for_display(session.depth, session.sky),
            "S_o (refined)": s_o,
        }
        contrast = []
        for az, el in entry["to"]:
            w = sun_vector(az, el)
            s_n, relit = session.relit_shadow(w), session.relight(w)
            row[f"S_n {az:g},{el:g}"] = s_n
            row[f"Relit {az:g},{el:g}"] = relit
            contrast.append(shadow_contrast(session.image_srgb, relit, s_o, s_n, session.sky))
        rows.append(row)
        records.append({"file": name, "from": entry["from"], "to": entry["to"],
                        "depth_source": session.depth_source, "shadows": session.shadow_mode,
                        "relight": session.relight_mode,
                        "seconds": round(sum(session.timings.values()), 2),
                        "contrast": contrast})
    return rows, records


def save_samples_sheet(rows: list[dict[str, np.ndarray]], path: str | Path,
                       tile: int = 192) -> Path:
    """One photo per row; the suns differ per photo, so new-sun columns are numbered (``sun 1``
    is the first ``to`` sun of each photo)."""
    renamed = [dict(zip(_numbered(list(r)), r.values(), strict=True)) for r in rows]
    return save_sheet(renamed, path, tile=tile)


def _numbered(labels: list[str]) -> list[str]:
    """``S_n 90,30`` -> ``S_n sun 1``, ``Relit 90,30`` -> ``Relit sun 1``, ..."""
    out, suns = [], []
    for lab in labels:
        if lab.startswith(("S_n ", "Relit ")):
            kind, sun = lab.split(" ", 1)
            if sun not in suns:
                suns.append(sun)
            out.append(f"{kind} sun {suns.index(sun) + 1}")
        else:
            out.append(lab)
    return out
