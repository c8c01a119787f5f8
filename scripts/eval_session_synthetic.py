"""The app's relighting pipelines on held-out synthetic views with true depth.

``outcast eval`` (Table 1) scores the networks one by one; this scores what the app's session
does end to end, for each choice the session offers, on views made by ``outcast data make``:
the photo's original sun and true depth are given, the original shadow ``S_o`` is found by the
session (``refine``), and the photo is relit to every other sun of the view.

Per configuration it prints the relit image's MSE and DSSIM against the render under the new
sun (both tone-mapped with the view's exposure), and how much the relit photo brightens the
surface that the new sun newly lights and darkens the surface it newly shadows (mean sRGB there
over the input's), next to the truth's own factors. Run::

    python3 scripts/eval_session_synthetic.py ~/.cache/outcast/data/test --max-views 20 [--only 0,2]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from outcast_core.data.dataset import list_views, load_view  # noqa: E402
from outcast_core.eval.metrics import dssim  # noqa: E402
from outcast_core.runtime.pipeline.session import RelightSession  # noqa: E402
from outcast_core.train.data import auto_exposure, tonemap  # noqa: E402

#: (label, session keyword arguments): the app's default first.
CONFIGS: list[tuple[str, dict]] = [
    ("learned L, S_o from the photo, photo's detail, colour guard, shade floor and guarded lift "
     "(app default)", {}),
    ("the default without the photo's detail", {"keep_detail": False}),
    ("the default without the exposure anchor", {"exposure_anchor": False}),
    ("learned L, S_o from the photo, colour guard, shade floor, no lift",
     {"lift_new_light": False}),
    ("learned L, S_o from the photo, colour guard, no floor", {"contrast_floor": False}),
    ("learned L, S_o from the photo, no guard, no floor",
     {"colour_guard": False, "contrast_floor": False}),
    ("learned L, S_o from R", {"refine": "learned"}),
    ("physics, S_o from the photo", {"relight_mode": "physics"}),
    ("physics, S_o from R", {"relight_mode": "physics", "refine": "learned"}),
    ("the default without the new sun's daylight", {"daylight": False}),
    ("physics, S_o from the photo, without the new sun's daylight",
     {"relight_mode": "physics", "daylight": False}),
]
#: Ground-truth shadow levels that make a pixel dark (in shadow) or lit.
DARK, LIT = 0.05, 0.3


def factor(img: np.ndarray, base: np.ndarray, m: np.ndarray) -> float:
    """Mean sRGB of ``img`` over the mask ``m``, over the input's (``base``, grey) there."""
    return float(img.mean(axis=-1)[m].mean() / max(base[m].mean(), 1e-4))


def _session(kwargs: dict) -> RelightSession:
    guard = kwargs.pop("colour_guard", True)
    floor = kwargs.pop("contrast_floor", True)
    lift = kwargs.pop("lift_new_light", True)
    detail = kwargs.pop("keep_detail", True)
    anchor = kwargs.pop("exposure_anchor", True)
    daylight = kwargs.pop("daylight", True)
    s = RelightSession(preset="fast", shadow_mode="learned", **kwargs)
    s.daylight = daylight
    s.colour_guard, s.contrast_floor, s.lift_new_light = guard, floor, lift
    s.keep_detail, s.exposure_anchor = detail, anchor
    return s


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("data", help="held-out data folder (outcast data make)")
    p.add_argument("--max-views", type=int, default=20)
    p.add_argument("--only", default="", help="configurations to run, by number in CONFIGS "
                   "(0: the app's default), separated by commas; default all")
    args = p.parse_args(argv)
    configs = CONFIGS
    if args.only:
        configs = [CONFIGS[int(i)] for i in args.only.split(",")]
    views = list_views(Path(args.data).expanduser())[: args.max_views]
    if not views:
        raise SystemExit(f"no views in {args.data}")
    rows = {label: {"mse": [], "dssim": [], "lit": [], "shd": []} for label, _ in configs}
    truth_lit: list[float] = []
    truth_shd: list[float] = []
    t0 = time.perf_counter()
    sessions = [(label, _session(dict(kw))) for label, kw in configs]
    for vpath in views:
        v = load_view(vpath)
        e = v["exposure"] if v["exposure"] > 0 else auto_exposure(v["rgb"][0])
        imgs = [tonemap(v["rgb"][k], e) for k in range(v["rgb"].shape[0])]
        depth = np.where(v["sky"], np.inf, v["depth"]).astype(np.float32)
        k_suns = len(imgs)
        for i in range(k_suns):
            for _, s in sessions:
                s.set_image(imgs[i], fov_deg=v["fov_deg"], depth=depth)
                s.set_original_sun(v["sun"][i])
            for j in range(k_suns):
                if j == i:
                    continue
                so, sn = v["shadow"][i], v["shadow"][j]
                newly_lit = (so < DARK) & (sn > LIT) & ~v["sky"]
                newly_shd = (so > LIT) & (sn < DARK) & ~v["sky"]
                base = imgs[i].mean(axis=-1)

                if newly_lit.sum() >= 20:
                    truth_lit.append(factor(imgs[j], base, newly_lit))
                if newly_shd.sum() >= 20:
                    truth_shd.append(factor(imgs[j], base, newly_shd))
                for label, s in sessions:
                    out = s.relight(v["sun"][j])
                    r = rows[label]
                    r["mse"].append(float(np.mean((out - imgs[j]) ** 2)))
                    r["dssim"].append(float(dssim(out, imgs[j])))
                    if newly_lit.sum() >= 20:
                        r["lit"].append(factor(out, base, newly_lit))
                    if newly_shd.sum() >= 20:
                        r["shd"].append(factor(out, base, newly_shd))
    n_pairs = len(rows[configs[0][0]]["mse"])
    print(f"{len(views)} views, {n_pairs} pairs, {time.perf_counter() - t0:.0f} s; truth: newly "
          f"lit x{np.mean(truth_lit):.2f}, newly shadowed x{np.mean(truth_shd):.2f}\n")
    print(f"| Pipeline | MSE | DSSIM | Newly lit (truth x{np.mean(truth_lit):.2f}) | "
          f"Newly shadowed (truth x{np.mean(truth_shd):.2f}) |")
    print("|---|---|---|---|---|")
    for label, _ in configs:
        r = rows[label]
        print(f"| {label} | {np.mean(r['mse']):.4f} | {np.mean(r['dssim']):.4f} | "
              f"x{np.mean(r['lit']):.3f} | x{np.mean(r['shd']):.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
