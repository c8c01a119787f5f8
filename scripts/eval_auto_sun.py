"""Measure the automatic sun (``outcast_core.runtime.pipeline.auto_sun.find_sun``).

Real photos with human shadow masks (``NAME_image.*`` + ``NAME_mask.png``, as ``outcast eval
real``), per photo: the balanced error rate of the overlay at the best of the 24-sun sweep
(``real_eval.SWEEP_SUNS``, the ideal user), the overlay's BER at the found sun, the gap between
them, the confidence and the time of ``find_sun`` alone (depth excluded). Summary: the share of
photos whose gap is at most ``--within`` (issue 17: 0.03 for at least 70 %), mean and median.

Held-out synthetic views (``--synthetic DIR``, made by ``outcast data make``; the true sun is
known): the angle between the found and the true sun, with the depth the app would estimate
(``Z``) and with the renderer's exact depth (``--given-depth``), and the time per view; with the
sun model (``models/sun.onnx``) also the angle of ``D``'s own peak (``look_angle``). ``--set
LOOK_WEIGHT=0`` measures the search without ``D``.

The samples (``--samples``: ``samples/`` with ``suns.json``): the angle between the found sun and
the listed one, and the found elevation against astral's from the EXIF GPS and time, without the
EXIF prior (shadows only) and with it.

    python scripts/eval_auto_sun.py ../shared/realdev [--every 3] [--limit N] [--json OUT]
    python scripts/eval_auto_sun.py --samples samples
    python scripts/eval_auto_sun.py --synthetic DIR [--given-depth] [--limit N]

``--look-weights 0,0.01,...`` measures every photo (or pair) at each weight of the photo's look
(one session a photo), with one summary each.

Numbers only: nothing of a research data set is written anywhere but the optional JSON.
"""

from __future__ import annotations

import argparse
import ast
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from outcast_core.runtime.geometry.camera import sun_vector
from outcast_core.runtime.io.camera_pose import read_camera_pose
from outcast_core.runtime.io.imageio import read_image
from outcast_core.runtime.pipeline import auto_sun
from outcast_core.runtime.pipeline.auto_sun import MEASURE as DEFAULT_MEASURE
from outcast_core.runtime.pipeline.auto_sun import MEASURES, exif_sun_prior, find_sun
from outcast_core.runtime.pipeline.real_eval import (
    SWEEP_SUNS,
    balanced_error_rate,
    find_items,
    read_mask,
    shadow_mask,
)
from outcast_core.runtime.pipeline.session import RelightSession

#: What find_sun ranks by in this run (``--measure``).
MEASURE = [DEFAULT_MEASURE]
#: The weights of the photo's look (``auto_sun.LOOK_WEIGHT``) each photo is measured at
#: (``--look-weights``; None: the module's).
LOOK_WEIGHTS: list[float | None] = [None]
_DEFAULT_LOOK_WEIGHT = auto_sun.LOOK_WEIGHT


def _set_look_weight(weight: float | None) -> None:
    auto_sun.LOOK_WEIGHT = _DEFAULT_LOOK_WEIGHT if weight is None else weight


def _session(image: Any, preset: str) -> RelightSession:
    s = RelightSession(preset=preset)
    s.set_image(image.image_srgb, focal_35mm=image.exif.focal_35mm)
    return s


def measure_real(folder: str, *, preset: str, every: int, limit: int | None,
                 within: float, sweep_cache: str = "") -> dict[str, Any]:
    """The real-photo figures (see the module docstring); ``sweep_cache``: a JSON file keeping
    each photo's sweep (it does not depend on the search) between runs."""
    cache: dict[str, list[float]] = {}
    if sweep_cache and Path(sweep_cache).is_file():
        cache = json.loads(Path(sweep_cache).read_text())
    items = find_items(folder)[::every]
    if limit:
        items = items[:limit]
    rows = []
    for item in items:
        loaded = read_image(item.image)
        truth = read_mask(item.mask)
        session = _session(loaded, preset)
        key = f"{item.name}:{preset}"
        sweep = cache.get(key) or [
            balanced_error_rate(shadow_mask(session.shadow(sun_vector(a, e)), session.sky,
                                            truth.shape), truth) for a, e in SWEEP_SUNS]
        cache[key] = sweep
        if sweep_cache:
            Path(sweep_cache).write_text(json.dumps(cache))
        for weight in LOOK_WEIGHTS:
            _set_look_weight(weight)
            t0 = time.perf_counter()
            fit = find_sun(session, measure=MEASURE[0])
            seconds = time.perf_counter() - t0
            found = balanced_error_rate(shadow_mask(session.shadow(fit.w), session.sky,
                                                    truth.shape), truth)
            best = float(min(sweep))
            row = {"name": item.name, "look_weight": auto_sun.LOOK_WEIGHT,
                   "best_sweep_ber": round(best, 4),
                   "best_sweep_sun": list(SWEEP_SUNS[int(np.argmin(sweep))]),
                   "found_ber": round(found, 4), "gap": round(found - best, 4),
                   "found_sun": [round(fit.azimuth, 1), round(fit.elevation, 1)],
                   "confidence": round(fit.confidence, 3), "found": fit.found,
                   "agreement": round(fit.agreement, 4), "seconds": round(seconds, 3)}
            rows.append(row)
            print(f"{item.name:10s} w {auto_sun.LOOK_WEIGHT:<6g} sweep {best:.3f}  found "
                  f"{found:.3f}  gap {found - best:+.3f}  sun {fit.azimuth:5.1f},"
                  f"{fit.elevation:4.1f}  conf {fit.confidence:.2f}  {seconds:.2f} s", flush=True)
    _set_look_weight(None)
    summaries = [_real_summary([r for r in rows if r["look_weight"] == w], within)
                 for w in dict.fromkeys(r["look_weight"] for r in rows)]
    return {"rows": rows, "summary": summaries[0] if len(summaries) == 1 else summaries}


def _real_summary(rows: list[dict[str, Any]], within: float) -> dict[str, Any]:
    gaps = np.array([r["gap"] for r in rows])
    secs = np.array([r["seconds"] for r in rows])
    summary = {
        "photos": len(rows), "within": within,
        "share_within": round(float((gaps <= within).mean()), 3),
        "mean_gap": round(float(gaps.mean()), 4), "median_gap": round(float(np.median(gaps)), 4),
        "mean_found_ber": round(float(np.mean([r["found_ber"] for r in rows])), 4),
        "mean_sweep_ber": round(float(np.mean([r["best_sweep_ber"] for r in rows])), 4),
        "found_better": int((gaps < 0).sum()),
        "confident": int(sum(r["found"] for r in rows)),
        "share_within_confident": round(float(np.mean([r["gap"] <= within for r in rows
                                                       if r["found"]] or [float("nan")])), 3),
        "share_within_not_confident": round(float(np.mean(
            [r["gap"] <= within for r in rows if not r["found"]] or [float("nan")])), 3),
        "median_seconds": round(float(np.median(secs)), 3),
        "max_seconds": round(float(secs.max()), 3),
        "look_weight": rows[0]["look_weight"],
    }
    print(json.dumps(summary))
    return summary


def measure_synthetic(folder: str, *, preset: str, limit: int | None,
                      given_depth: bool) -> dict[str, Any]:
    """The synthetic figures: angle to the true sun per (view, sun) pair."""
    from outcast_core.data.dataset import iter_views
    from outcast_core.runtime.geometry.colour import tonemap_aces

    rows = []
    pairs = 0
    for view in iter_views(folder):
        for k in range(len(view["sun"])):
            if limit and pairs >= limit:
                break
            # The training views' tone curve (train.data.tonemap: ACES, then sRGB), as Z and
            # S saw them; a plain sRGB encoding clips the highlights they never saw clipped.
            img = tonemap_aces(view["rgb"][k], view["exposure"])
            s = RelightSession(preset=preset)
            depth = np.where(view["sky"], np.inf, view["depth"]) if given_depth else None
            s.set_image(img.astype(np.float32), fov_deg=view["fov_deg"], depth=depth)
            true = np.asarray(view["sun"][k], np.float64)
            true = true / np.linalg.norm(true)
            look = s.sun_look()  # D's own peak, when the sun model is there and used
            look_ang = None if look is None else round(math.degrees(math.acos(float(
                np.clip(look.peak() @ true, -1.0, 1.0)))), 2)
            for weight in LOOK_WEIGHTS:
                _set_look_weight(weight)
                t0 = time.perf_counter()
                fit = find_sun(s, measure=MEASURE[0])
                sec = time.perf_counter() - t0
                ang = math.degrees(math.acos(float(np.clip(fit.w @ true, -1.0, 1.0))))
                rows.append({"view": view["meta"].get("seed", len(rows)), "sun": k,
                             "look_weight": auto_sun.LOOK_WEIGHT,
                             "true": [round(float(x), 1) for x in view["sun_azel"][k]],
                             "found": [round(fit.azimuth, 1), round(fit.elevation, 1)],
                             "angle": round(ang, 2), "look_angle": look_ang,
                             "confidence": round(fit.confidence, 3),
                             "seconds": round(sec, 3)})
                print(json.dumps(rows[-1]), flush=True)
            pairs += 1
    _set_look_weight(None)
    summaries = [_synthetic_summary([r for r in rows if r["look_weight"] == w], given_depth)
                 for w in dict.fromkeys(r["look_weight"] for r in rows)]
    return {"rows": rows, "summary": summaries[0] if len(summaries) == 1 else summaries}


def _synthetic_summary(rows: list[dict[str, Any]], given_depth: bool) -> dict[str, Any]:
    angles = np.array([r["angle"] for r in rows])
    conf = np.array([r["confidence"] for r in rows])
    summary = {"pairs": len(rows), "depth": "given" if given_depth else "estimated",
               "median_angle": round(float(np.median(angles)), 2),
               "share_within_15": round(float((angles <= 15).mean()), 3),
               "median_angle_confident": round(float(np.median(angles[conf >= 0.3])), 2)
               if (conf >= 0.3).any() else None,
               "confident": int((conf >= 0.3).sum()),
               "median_seconds": round(float(np.median([r["seconds"] for r in rows])), 3)}
    looks = [r["look_angle"] for r in rows if r["look_angle"] is not None]
    if looks:  # D alone: the peak of its distribution
        summary["look_median_angle"] = round(float(np.median(looks)), 2)
    summary["look_weight"] = rows[0]["look_weight"]
    print(json.dumps(summary))
    return summary


def _angle(a: tuple[float, float], b: tuple[float, float]) -> float:
    return math.degrees(math.acos(float(np.clip(sun_vector(*a) @ sun_vector(*b), -1.0, 1.0))))


def measure_samples(folder: str, *, preset: str) -> dict[str, Any]:
    """The samples' figures (see the module docstring)."""
    listed = json.loads((Path(folder) / "suns.json").read_text())
    rows = []
    for name, entry in listed.items():
        if name.startswith("_"):
            continue
        loaded = read_image(Path(folder) / name)
        session = _session(loaded, preset)
        prior = exif_sun_prior(loaded.exif)
        row: dict[str, Any] = {"name": name, "listed": entry["from"],
                               "astral_elevation": None if prior is None
                               else round(prior.elevation, 2)}
        for label, p in (("shadows", None), ("exif_elevation", prior and
                                              type(prior)(prior.elevation,
                                                          description=prior.description)),
                         ("exif_full", prior)):
            if label != "shadows" and p is None:
                continue
            t0 = time.perf_counter()
            fit = find_sun(session, prior=p, measure=MEASURE[0],
                           pitch_roll=read_camera_pose(Path(folder) / name))
            sec = time.perf_counter() - t0
            row[label] = {
                "sun": [round(fit.azimuth, 1), round(fit.elevation, 1)],
                "true_elevation": round(fit.true_elevation, 1),
                "angle_to_listed": round(_angle((fit.azimuth, fit.elevation),
                                                tuple(entry["from"])), 1),
                "elevation_minus_astral": None if prior is None
                else round(fit.true_elevation - prior.elevation, 1),
                "confidence": round(fit.confidence, 3), "found": fit.found,
                "source": fit.source, "pitch_roll": [round(fit.pitch, 1), round(fit.roll, 1)],
                "pose_source": fit.pose_source,
                "seconds": round(sec, 2),
            }
        rows.append(row)
        print(json.dumps(row), flush=True)
    return {"samples": rows}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", nargs="?", default="", help="folder of NAME_image.* + NAME_mask.png")
    ap.add_argument("--samples", default="", help="the samples folder (with suns.json)")
    ap.add_argument("--synthetic", default="", help="a synthetic data set (outcast data make)")
    ap.add_argument("--given-depth", action="store_true",
                    help="synthetic: use the renderer's depth instead of the estimated one")
    ap.add_argument("--preset", default="balanced", choices=["fast", "balanced", "accurate"])
    ap.add_argument("--every", type=int, default=1, help="take every N-th photo")
    ap.add_argument("--limit", type=int, default=None, help="at most N photos")
    ap.add_argument("--within", type=float, default=0.03, help="BER gap counted as a match")
    ap.add_argument("--json", default="", help="write the figures to this JSON file")
    ap.add_argument("--measure", default=DEFAULT_MEASURE, choices=MEASURES,
                    help="what the search ranks suns by (auto_sun.MEASURES)")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="override an auto_sun constant for this run (a Python literal), e.g. "
                         "FINE_PATTERNS='((3, 0.5), (2, 0.25))'")
    ap.add_argument("--sweep-cache", default="", help="JSON file keeping the sweeps between runs")
    ap.add_argument("--look-weights", default="", metavar="W1,W2,...",
                    help="measure every photo at each of these weights of the photo's look "
                         "(auto_sun.LOOK_WEIGHT; 0: the shadows alone), one summary each")
    args = ap.parse_args(argv)
    if not args.folder and not args.samples and not args.synthetic:
        ap.error("give a folder of photos with masks, --samples or --synthetic")
    MEASURE[0] = args.measure
    for item in args.set:
        name, _, value = item.partition("=")
        if not hasattr(auto_sun, name):
            ap.error(f"--set: auto_sun has no {name!r}")
        setattr(auto_sun, name, ast.literal_eval(value))
    global _DEFAULT_LOOK_WEIGHT
    _DEFAULT_LOOK_WEIGHT = auto_sun.LOOK_WEIGHT  # after --set
    if args.look_weights:
        LOOK_WEIGHTS[:] = [float(w) for w in args.look_weights.split(",")]
        if min(LOOK_WEIGHTS) < 0:  # type: ignore[type-var]
            ap.error("--look-weights: expected weights >= 0")
        if args.samples:
            ap.error("--look-weights: not with --samples (set LOOK_WEIGHT with --set)")
    out: dict[str, Any] = {"preset": args.preset, "measure": args.measure, "set": args.set}
    if args.folder:
        out["real"] = measure_real(args.folder, preset=args.preset, every=max(1, args.every),
                                   limit=args.limit, within=args.within,
                                   sweep_cache=args.sweep_cache)
    if args.samples:
        out["samples"] = measure_samples(args.samples, preset=args.preset)
    if args.synthetic:
        out["synthetic"] = measure_synthetic(args.synthetic, preset=args.preset,
                                             limit=args.limit, given_depth=args.given_depth)
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
