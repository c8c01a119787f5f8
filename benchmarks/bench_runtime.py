"""Runtime benchmark: Direct shadows' speed/accuracy trade, what "set once, query many" saves,
and issue 19's speed goals (full-resolution relight at 12 / 24 / 108 MP with peak memory, the
step-2 drag preview, a 120-frame 1080p time-lapse: ``benchmarks/speed.py``).

Run: ``python benchmarks/bench_runtime.py`` (several minutes on 2 cores), or
``python benchmarks/bench_runtime.py --quick`` (about two minutes), or one part:
``--only speed`` (or ``brush``: the shadow corrections' brush dabs against a click).

Everything is measured in this run and printed as ratios against a baseline measured in the same
run, so the figures compare across machines. Accuracy is measured against an exact ray cast of an
analytic scene (blocks on the ground seen from above), the same oracle the tests use.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from outcast_core.runtime.geometry.camera import Camera, backproject  # noqa: E402
from outcast_core.runtime.geometry.shadows import DirectStats, direct_visibility  # noqa: E402
from outcast_core.runtime.pipeline.session import PRESETS, RelightSession  # noqa: E402
from tests.runtime.scenes import box_scene_depth, box_scene_visibility  # noqa: E402

GROUND_Z = 60.0
BOXES = [
    (-9.0, -4.0, -7.0, -2.0, 3.0), (3.0, 7.0, 2.0, 6.0, 5.0), (-2.0, 1.0, 5.0, 8.0, 1.5),
    (5.0, 9.0, -9.0, -5.0, 4.0), (-1.0, 0.0, -1.0, 0.0, 6.0),
]
SUNS = [(30, 70), (120, 40), (200, 25), (90, 15)]


def best_of(fn, repeats: int) -> tuple[float, object]:
    best, out = math.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def sun(az: float, el: float) -> np.ndarray:
    a, e = math.radians(az), math.radians(el)
    return np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), -math.sin(e)])


def direct_trade(size: int, repeats: int) -> None:
    cam = Camera.from_fov(size, size, 30.0)
    depth = box_scene_depth(size, size, cam.focal, GROUND_Z, BOXES)
    pts = backproject(depth, cam)
    gts = [~box_scene_visibility(pts, sun(*s), GROUND_Z, BOXES) for s in SUNS]
    print(f"\nDirect shadows at {size}x{size}: step (fraction of the image side) vs. error")
    print(f"{'step':>8} {'time/sun s':>11} {'x baseline':>11} {'mask error %':>13} "
          f"{'steps marched (mean)':>21}")
    rows = []
    for denom in (64, 128, 256, 512):
        step = 1.0 / denom
        times, errs, marched = [], [], []
        for s, gt in zip(SUNS, gts, strict=True):
            st = DirectStats(0, 0, "")
            t, vis = best_of(lambda s=s, st=st, n=denom, h=step: direct_visibility(
                depth, cam, sun(*s), steps=n, step=h, stats=st), repeats)
            times.append(t)
            errs.append(float(((vis < 0.5) != gt).mean() * 100))
            marched.append(st.steps_marched)
        rows.append((denom, float(np.mean(times)), float(np.mean(errs)), float(np.mean(marched))))
    base = rows[-1][1]
    for denom, t, e, m in rows:
        print(f"{'1/' + str(denom):>8} {t:11.4f} {t / base:11.2f} {e:13.2f} {m:21.1f}")


def early_exit(size: int, repeats: int) -> None:
    cam = Camera.from_fov(size, size, 30.0)
    depth = box_scene_depth(size, size, cam.focal, GROUND_Z, BOXES)
    print(f"\nEarly exit ('march no further than a scene needs') at {size}x{size}, step 1/256:")
    print(f"{'sun az,el':>10} {'steps':>6} {'time s':>8} {'no-exit time s':>15} {'ratio':>6}")
    for s in SUNS:
        st = DirectStats(0, 0, "")
        t_exit, _ = best_of(lambda s=s, st=st: direct_visibility(
            depth, cam, sun(*s), steps=256, step=1 / 256, stats=st), repeats)
        # Baseline: the same march forced to every step (a bias of -inf keeps all rays active).
        t_full, _ = best_of(lambda s=s: _full_march(depth, cam, sun(*s)), repeats)
        print(f"{str(s):>10} {st.steps_marched:6d} {t_exit:8.4f} {t_full:15.4f} "
              f"{t_exit / t_full:6.2f}")


def _full_march(depth: np.ndarray, cam: Camera, w: np.ndarray) -> np.ndarray:
    from outcast_core.runtime.geometry.raymarch import RaySampler

    sampler = RaySampler(depth, cam)
    lit = np.ones(depth.shape, bool)
    for st in sampler.iter_steps(w, 256, 1 / 256):
        lit &= ~(st.valid & (st.ratio < 1 / 1.005))
    return lit


def session_reuse(repeats: int) -> None:
    from outcast_core.runtime.io.imageio import read_image

    sample = Path(__file__).resolve().parents[1] / "samples" / "exif_003_th_pool.jpg"
    img = read_image(sample).image_srgb
    print(f"\nSession on {sample.name} ({img.shape[1]}x{img.shape[0]}), classic mode:")
    print(f"{'preset':>9} {'set_image s':>12} {'shadow s':>9} {'preview s':>10} "
          f"{'relight s':>10} {'cached s':>9} {'full-res s':>11}")
    for name in PRESETS:
        s = RelightSession(mode="classic", preset=name)
        t_set, _ = best_of(lambda s=s: s.set_image(img), 1)
        t_sh = s.timings.get("shadow", 0.0)
        s.set_original_sun((0.3, -0.8, -0.5))
        t_sh = s.timings["shadow"]
        t_prev, _ = best_of(lambda s=s: s._compute_shadow((0.5, -0.6, -0.6), True), repeats)
        s.relight((-0.4, -0.5, -0.7))
        t_rel = s.timings["relight"] + s.timings["shadow"]
        t_cached, _ = best_of(lambda s=s: s.relight((-0.4, -0.5, -0.7)), repeats)
        t_full, _ = best_of(lambda s=s: s.relight_full((-0.4, -0.5, -0.7)), 1)
        print(f"{name:>9} {t_set:12.3f} {t_sh:9.3f} {t_prev:10.3f} {t_rel:10.3f} "
              f"{t_cached:9.5f} {t_full:11.3f}")
    lift_cost(img, repeats)
    deshadow_full_cost(repeats)
    found_marks_cost(repeats)


def found_marks_cost(repeats: int) -> None:
    """What finding the shadows their own lit ring calls shade costs (``photo_shadows.
    found_shade_marks``) on a 12 MP photo (balanced): made with ``S_o`` at the working size,
    and again at up to 1024 px for the full-size de-shadow, against ``set_original_sun``
    itself (the baseline, which includes the first)."""
    import cv2

    from outcast_core.runtime.io.imageio import read_image
    from outcast_core.runtime.pipeline.photo_shadows import found_shade_marks

    sample = Path(__file__).resolve().parents[1] / "samples" / "exif_003_th_pool.jpg"
    img = cv2.resize(read_image(sample).image_srgb, (4000, 3000), interpolation=cv2.INTER_LINEAR)
    s = RelightSession(preset="balanced")
    s.set_image(img)
    w = (0.3, -0.8, -0.5)
    t_sun, _ = best_of(lambda: s.set_original_sun(w), repeats)
    t_work, _ = best_of(lambda: found_shade_marks(s.image_srgb, s.shadow_probability,
                                                  s.sky), repeats)
    d = s.found_shadows_detail()
    t_detail, _ = best_of(lambda: found_shade_marks(d["image"], d["probability"],
                                                    d["excluded"]), repeats)
    print(f"  found shade marks, 12 MP, balanced: at the working size {t_work:.3f} s "
          f"(x{t_work / t_sun:.3f} of set_original_sun's {t_sun:.2f} s), at the de-shadow's "
          f"{d['image'].shape[1]} px {t_detail:.3f} s (x{t_detail / t_sun:.3f})")


def deshadow_full_cost(repeats: int) -> None:
    """The de-shadowed export of a 12 MP photo (balanced): the shadows found and lifted at
    ``found_shadows_detail``'s size (now) against the working size's lift upsampled (before,
    measured in the same run as the baseline)."""
    import cv2

    from outcast_core.runtime.io.imageio import read_image
    from outcast_core.runtime.pipeline.photo_shadows import deshadow
    from outcast_core.runtime.pipeline.relight import transfer_to_full_resolution

    sample = Path(__file__).resolve().parents[1] / "samples" / "exif_003_th_pool.jpg"
    img = cv2.resize(read_image(sample).image_srgb, (4000, 3000), interpolation=cv2.INTER_LINEAR)
    s = RelightSession(preset="balanced")
    s.set_image(img)
    s.set_original_sun((0.3, -0.8, -0.5))

    def before() -> object:
        out = deshadow(s.image_srgb, s.shadow_probability, s.sky)
        return transfer_to_full_resolution(s.full_image_srgb, s.image_srgb, out)

    def now() -> object:
        s._detail = None  # found again each time
        return s.deshadow_full()

    t_before, _ = best_of(before, repeats)
    t_now, _ = best_of(now, repeats)
    print(f"  de-shadowed 12 MP export, balanced: shadows found at up to 1024 px {t_now:.2f} s, "
          f"the working size's lift upsampled {t_before:.2f} s (x{t_now / t_before:.2f})")


def lift_cost(img: object, repeats: int) -> None:
    """The learned relighting's guards with and without the lift of newly lit surfaces (the
    session's ``lift_new_light``), balanced preset, working size: the relighting network and
    its guards for one new sun (shadow cached), and the lift's one-off inputs per original sun
    (material guard, de-shadowed photo)."""
    s = RelightSession(preset="balanced")
    s.set_image(img)
    s.set_original_sun((0.3, -0.8, -0.5))
    suns = [(-0.4, -0.5, -0.7), (0.5, -0.6, -0.6)]
    for w in suns:
        s.shadow(w)
    times = {}
    for lift in (False, True):
        s.lift_new_light = lift
        s.relight(suns[0])  # the lift's inputs made and cached here (counted below)

        def one(s: RelightSession = s) -> object:
            s._relight_cache.clear()
            return s.relight(suns[1])

        times[lift], _ = best_of(one, repeats)
    s.set_original_sun((0.3, -0.8, -0.5))  # new S_o: the lift's inputs are made again
    t0 = time.perf_counter()
    s._lift_inputs(s.image_srgb.shape[:2])
    t_inputs = time.perf_counter() - t0
    print(f"  learned relight, balanced, one sun: without the lift {times[False]:.3f} s, with "
          f"it {times[True]:.3f} s (x{times[True] / times[False]:.2f}); its inputs once per "
          f"original sun {t_inputs:.3f} s")


def find_sun_speed(repeats: int) -> None:
    """``auto_sun.find_sun`` on a 12 MP photo (the pool sample enlarged), balanced preset, with
    the models the app uses (issue 17: at most 2 s). Depth is set once and not counted. Also as a
    ratio to one shadow image at the working size (the overlay), measured in the same run, and
    per stage (best run)."""
    import cv2

    from outcast_core.runtime.geometry.camera import sun_vector
    from outcast_core.runtime.io.imageio import read_image
    from outcast_core.runtime.pipeline.auto_sun import find_sun

    sample = Path(__file__).resolve().parents[1] / "samples" / "exif_003_th_pool.jpg"
    img = cv2.resize(read_image(sample).image_srgb, (4000, 3000), interpolation=cv2.INTER_LINEAR)
    s = RelightSession(preset="balanced")
    s.set_image(img)

    cpu: list[float] = []

    def run() -> object:
        s.set_preset("balanced")  # same size: only the per-sun caches are cleared
        c0 = time.process_time()
        fit = find_sun(s)
        cpu.append(time.process_time() - c0)
        return fit

    def one_shadow() -> object:
        s.set_preset("balanced")
        return s.shadow(sun_vector(200.0, 35.0))

    t, fit = best_of(run, repeats)
    t_one, _ = best_of(one_shadow, repeats)
    stages = ", ".join(f"{k} {v:.2f}" for k, v in fit.stage_seconds.items())
    print(f"\nfind_sun on a 12 MP photo (4000x3000), balanced, {s.shadow_mode} shadows: "
          f"{t:.2f} s best of {repeats} ({fit.evaluations} suns tried; target 2 s)\n"
          f"  one working-size shadow {t_one:.3f} s: find_sun = {t / t_one:.1f} of them; "
          f"{min(cpu):.2f} CPU s (this process, least of the runs: less load-dependent)\n"
          f"  stages of the last run (s): {stages}")


def brush_cost(repeats: int) -> None:
    """Shadow corrections: ``shadow_edit_masks`` with 2000 brush dabs (ten strokes of 200,
    "not a shadow" and "Mark shadow" by turns) at 1024 x 768, against the same call with one
    "not a shadow" click, measured in the same run (the baseline). Each stroke is drawn into
    one window of the photo, never one photo-sized mask a dab (that took over a second)."""
    from outcast_core.runtime.pipeline.photo_shadows import ShadowEdit, shadow_edit_masks

    rng = np.random.default_rng(0)
    h, w = 768, 1024
    p = (rng.random((h, w)) > 0.6).astype(np.float32)
    img = np.clip(0.5 + 0.1 * rng.standard_normal((h, w, 3)), 0, 1).astype(np.float32)
    sky = np.zeros((h, w), bool)
    dabs = [ShadowEdit(0.05 + 0.9 * (i % 200) / 200, 0.1 + 0.08 * (i // 200), i // 200 % 2 == 0,
                       radius=0.02, start=i % 200 == 0) for i in range(2000)]
    click = [ShadowEdit(0.5, 0.5, shadow=False)]
    t_dabs, _ = best_of(lambda: shadow_edit_masks(p, img, sky, dabs), repeats)
    t_click, _ = best_of(lambda: shadow_edit_masks(p, img, sky, click), repeats)
    print(f"\nShadow corrections at {w}x{h}: 2000 brush dabs (10 strokes) {t_dabs:.3f} s, one "
          f"click {t_click:.4f} s (x{t_dabs / t_click:.1f})")


SECTIONS = ("direct", "session", "find_sun", "brush", "speed")


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--child":  # a measured pipeline (benchmarks/speed)
        from benchmarks.speed import child_main

        sys.exit(child_main(sys.argv[2:]))
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--quick", action="store_true",
                    help="smaller sizes, one repeat, 24 time-lapse frames, no 108 MP baseline")
    ap.add_argument("--only", default=",".join(SECTIONS),
                    help=f"comma-separated sections of {', '.join(SECTIONS)} (default: all)")
    ap.add_argument("--report", metavar="PATH", help="also write the tables to a Markdown report")
    args = ap.parse_args()
    rep = 1 if args.quick else args.repeats
    only = {x.strip() for x in args.only.split(",") if x.strip()}
    unknown = only - set(SECTIONS)
    if unknown:
        ap.error(f"expected sections among {', '.join(SECTIONS)}, got {', '.join(sorted(unknown))}")
    from benchmarks.report import report_to

    with report_to(args.report, "bench_runtime"):
        print(f"cpu cores: {os.cpu_count()}, load average at start: "
              f"{', '.join(f'{x:.2f}' for x in os.getloadavg())}")
        if "direct" in only:
            direct_trade(128 if args.quick else 256, rep)
            early_exit(128 if args.quick else 256, rep)
        if "session" in only:
            session_reuse(rep)
        if "find_sun" in only:
            find_sun_speed(rep)
        if "brush" in only:
            brush_cost(rep)
        if "speed" in only:
            from benchmarks.speed import run

            run(args.quick, rep)
        print(f"load average at the end: {', '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
