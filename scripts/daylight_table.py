"""Make ``outcast_core/runtime/pipeline/daylight_table.py``: the renderer's clear sky and sun per
sun elevation, the table :mod:`outcast_core.runtime.pipeline.daylight` carries a relit photo's
light with (Python constants: text in git, re-made by this script).

Mitsuba's ``sunsky`` (the Hosek-Wilkie sky and its sun, as ``outcast_core.data.sky`` bakes it
for the training renders) at turbidity 3 and ground albedo 0.3, for sun elevations
``SUN_ELEVATIONS``: the sun's irradiance on a surface facing it, the sky's irradiance on level
ground, and the sky's radiance seen at ``VIEW_ELEVATIONS`` above the horizon, averaged over
the view's azimuth from the sun's (``VIEW_AZIMUTHS``, trapezoid weights), linear RGB. Needs the
training extras (Mitsuba); a few seconds. Run::

    python3 scripts/daylight_table.py
"""

from __future__ import annotations

import math
import sys
import textwrap
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

TURBIDITY, ALBEDO = 3.0, 0.3
SUN_ELEVATIONS = (2, 3, 4, 5, 7, 10, 13, 16, 20, 25, 30, 35, 40, 50, 60, 70, 80, 90)
VIEW_ELEVATIONS = (0, 3, 7, 12, 20, 30, 45, 60, 90)
VIEW_AZIMUTHS = (0, 10, 20, 35, 50, 70, 90, 120, 150, 180)
OUT = ROOT / "outcast_core" / "runtime" / "pipeline" / "daylight_table.py"


def main() -> int:
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    from outcast_core.data.sky import ENV_HEIGHT, ENV_WIDTH, SunSky, _env_directions

    sky = SunSky(TURBIDITY, ALBEDO)
    dirs = _env_directions()  # world, z up
    th = (np.arange(ENV_HEIGHT) + 0.5) / ENV_HEIGHT * math.pi
    solid = (math.pi / ENV_HEIGHT) * (2 * math.pi / ENV_WIDTH) * np.sin(th)[:, None]
    cos_z = np.clip(dirs[..., 2], 0.0, None)
    sun_irr, sky_irr, seen = [], [], []
    for el in SUN_ELEVATIONS:
        e = math.radians(el)
        w = np.array([0.0, math.cos(e), math.sin(e)])
        baked = sky.bake(w)
        env = baked["envmap"].astype(np.float64)
        sun_irr.append(baked["sun_irradiance"])
        sky_irr.append((env * (cos_z * solid)[..., None]).sum((0, 1)))
        grid = np.zeros((len(VIEW_ELEVATIONS), len(VIEW_AZIMUTHS), 3))
        for i, v in enumerate(VIEW_ELEVATIONS):
            for j, a in enumerate(VIEW_AZIMUTHS):
                vr, ar = math.radians(max(v, 0.5)), math.radians(a)
                d = np.array([math.sin(ar) * math.cos(vr), math.cos(ar) * math.cos(vr),
                              math.sin(vr)])
                grid[i, j] = sky._eval(sky._sky, d)
        seen.append(np.nan_to_num(grid, nan=0.0).clip(0.0, None))
        print(f"elevation {el:>2}: sun {np.round(sun_irr[-1], 3)}, sky {np.round(sky_irr[-1], 3)}")
    az = np.asarray(VIEW_AZIMUTHS, np.float64)
    wts = np.diff(az, prepend=az[0]) / 2 + np.diff(az, append=az[-1]) / 2  # trapezoid
    seen_mean = [(g * wts[None, :, None]).sum(1) / wts.sum() for g in seen]

    def triple(v) -> str:
        return "(" + ", ".join(f"{x:.5g}" for x in np.ravel(v)) + ")"

    def rows(values) -> str:
        return "".join(f"    {triple(v)},\n" for v in values)

    def nested(values) -> str:  # per sun elevation, a triple per view elevation
        return "".join("    (\n" + "".join(f"        {triple(t)},\n" for t in v) + "    ),\n"
                       for v in values)

    def angles(name: str, values) -> str:
        body = ", ".join(f"{float(e):g}" for e in values)
        return "\n".join(textwrap.wrap(f"{name} = ({body})", 99,
                                        subsequent_indent="    ")) + "\n"

    OUT.write_text(
        '"""The renderer\'s clear sky and sun per sun elevation (linear RGB), made by\n'
        f"``python3 scripts/daylight_table.py`` (Mitsuba ``sunsky``, turbidity {TURBIDITY:g},\n"
        f'ground albedo {ALBEDO:g}); do not edit by hand."""\n\n'
        + angles("SUN_ELEVATIONS", SUN_ELEVATIONS) + angles("VIEW_ELEVATIONS", VIEW_ELEVATIONS)
        + "#: The sun's irradiance on a surface facing it, per sun elevation.\n"
        f"SUN = (\n{rows(sun_irr)})\n"
        "#: The sky's irradiance on level ground, per sun elevation.\n"
        f"SKY = (\n{rows(sky_irr)})\n"
        "#: The sky's radiance seen at each of VIEW_ELEVATIONS (averaged round the horizon),\n"
        "#: per sun elevation.\n"
        f"SKY_SEEN = (\n{nested(seen_mean)})\n")
    print(f"wrote {OUT} ({OUT.stat().st_size} bytes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
