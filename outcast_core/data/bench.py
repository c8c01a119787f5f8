"""Rendering throughput: ``python -m outcast_core.data.bench [--views N --suns K --res R --spp S]``.

Renders views in memory (nothing written) and prints views per minute and image pairs per minute.
"""

from __future__ import annotations

import argparse
import os
import time


def run_bench(
    views: int = 3, suns: int = 4, res: int = 128, spp: int = 32, seed: int = 900_000
) -> float:
    """Render ``views`` views and print the throughput.

    Returns:
        Views per minute.
    """
    from outcast_core.data.dataset import render_one

    render_one(seed, 1, 16, 1, 0)  # warm-up: Mitsuba plugin loading
    t0 = time.perf_counter()
    for i in range(views):
        render_one(i, suns, res, spp, seed)
    dt = time.perf_counter() - t0
    vpm = 60.0 * views / dt
    print(
        f"{views} views, K={suns}, {res} px, {spp} spp: {dt:.1f} s, {vpm:.2f} views/min, "
        f"{vpm * suns:.1f} images/min (cpu count {os.cpu_count()}, load {os.getloadavg()[0]:.1f})"
    )
    return vpm


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--views", type=int, default=3)
    p.add_argument("--suns", type=int, default=4)
    p.add_argument("--res", type=int, default=128)
    p.add_argument("--spp", type=int, default=32)
    p.add_argument("--seed", type=int, default=900_000)
    a = p.parse_args(argv)
    run_bench(a.views, a.suns, a.res, a.spp, a.seed)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
