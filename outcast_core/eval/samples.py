"""Relight the sample photographs with the shipped models: a side-by-side PNG sheet.

The samples have no ground truth, so this is for looking at: is the old shadow removed, and is
the new one cast in the new sun's direction? Each row is one photo: the input, ``Z``'s depth,
the refined old shadow ``S_o`` and, per new sun, ``S_n`` and the relit photo. The original suns
come from a JSON file (``samples/suns.json``): ``{"file.jpg": {"from": [az, el], "to":
[[az, el], ...]}}``, angles relative to the camera as in ``outcast relight``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from outcast_core.eval.table import save_sheet
from outcast_core.runtime.geometry import sun_vector


def relight_samples(
    spec: str | Path, models: str | Path = "models", preset: str = "balanced"
) -> tuple[list[dict[str, np.ndarray]], list[dict[str, Any]]]:
    """Run the app's photo-only pipeline (learned mode) on every photo named in ``spec``.

    Returns:
        ``(sheet rows, records)``: one row of labelled images and one record (file, suns,
        depth source, shadow and relight modes, seconds) per photo.
    """
    from outcast_core.runtime.imageio import read_image
    from outcast_core.runtime.models import ModelRegistry
    from outcast_core.runtime.session import RelightSession, depth_for_display

    spec = Path(spec)
    entries = {k: v for k, v in json.loads(spec.read_text()).items() if not k.startswith("_")}
    if not entries:
        raise ValueError(f"expected at least one photo in {spec}, got none")
    rows, records = [], []
    for name, entry in entries.items():
        loaded = read_image(spec.parent / name, max_pixels=4_000_000)
        session = RelightSession(ModelRegistry(models), preset=preset, mode="learned")
        session.set_image(loaded.image_srgb, focal_35mm=loaded.exif.focal_35mm)
        s_o = session.set_original_sun(sun_vector(*entry["from"]))
        row: dict[str, np.ndarray] = {
            "Input": session.image_srgb,
            "Z depth": depth_for_display(session.depth, session.sky),
            "S_o (refined)": s_o,
        }
        for az, el in entry["to"]:
            w = sun_vector(az, el)
            row[f"S_n {az:g},{el:g}"] = session.shadow(w)
            row[f"Relit {az:g},{el:g}"] = session.relight(w)
        rows.append(row)
        records.append({"file": name, "from": entry["from"], "to": entry["to"],
                        "depth_source": session.depth_source, "shadows": session.shadow_mode,
                        "relight": session.relight_mode,
                        "seconds": round(sum(session.timings.values()), 2)})
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
