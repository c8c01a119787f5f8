"""Issue 19's speed figures, each beside a baseline measured in the same run (used by
``benchmarks/bench_runtime.py``; ``python benchmarks/bench_runtime.py --only speed``).

* Full resolution: read a synthesized JPEG, set it, confirm the sun, relight, write a JPEG, in a
  fresh process per size and pipeline (its peak resident memory is ``ru_maxrss``). The baseline
  is the pipeline as it was before the banded 8-bit path: float32 photo, the row-band ``remap``
  transfer with the ``pow`` colour curves (copied below), float output quantised by the writer.
* Step 2 drag: the relit preview per sun against the preview as it was (the new sun's shadow at
  the preview size, then ``L`` at the working size) and against the step-1 overlay.
* Time-lapse: 1080p MP4 frames against the sequential baseline (one frame after another, the
  remap transfer in float, encoding in the same thread with x264 "faster").

Large photos are synthesized (the pool sample enlarged with noise): nothing is downloaded.
"""

from __future__ import annotations

import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "samples" / "exif_003_th_pool.jpg"
W_FROM, W_TO = (200.0, 40.0), (90.0, 30.0)  # (azimuth, elevation)
SIZES = {"12 MP": (4000, 3000), "24 MP": (5657, 4243), "108 MP": (12000, 9000)}
GOALS = {"12 MP": (1.5, None), "24 MP": (3.0, 2.0), "108 MP": (12.0, 4.0)}  # seconds, GB


def baseline_transfer(full_srgb, work_before_srgb, work_after_srgb, band_rows: int = 1024):
    """The full-resolution transfer as it was before ``runtime.geometry.fullres`` (float32 only)."""
    from outcast_core.runtime.geometry.colour import linear_to_srgb, srgb_to_linear

    before = srgb_to_linear(work_before_srgb)
    after = srgb_to_linear(work_after_srgb)
    gain = (after + 1e-3) / (before + 1e-3)
    h, w = full_srgb.shape[:2]
    gh, gw = gain.shape[:2]
    out = np.empty((h, w, 3), np.float32)
    xs = ((np.arange(w, dtype=np.float32) + 0.5) * gw / w - 0.5).astype(np.float32)
    for r0 in range(0, h, band_rows):
        r1 = min(h, r0 + band_rows)
        ys = ((np.arange(r0, r1, dtype=np.float32) + 0.5) * gh / h - 0.5).astype(np.float32)
        map_x = np.broadcast_to(xs[None, :], (r1 - r0, w))
        map_y = np.broadcast_to(ys[:, None], (r1 - r0, w))
        g = cv2.remap(gain, np.ascontiguousarray(map_x), np.ascontiguousarray(map_y),
                      interpolation=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        band = srgb_to_linear(full_srgb[r0:r1])
        out[r0:r1] = linear_to_srgb((band + 1e-3) * g - 1e-3)
    return out


# ----------------------------------------------------------------------------- child processes
def _make_photo(path: str, width: int, height: int) -> None:
    src = cv2.imread(str(SAMPLE))
    big = cv2.resize(src, (width, height), interpolation=cv2.INTER_CUBIC)
    noise = np.random.default_rng(0).integers(-6, 7, size=(height, width, 1), dtype=np.int16)
    big = np.clip(big.astype(np.int16) + noise, 0, 255).astype(np.uint8)
    cv2.imwrite(path, big, [cv2.IMWRITE_JPEG_QUALITY, 92])


def _relight_pipeline(path: str, out: str, variant: str, preset: str) -> dict:
    from outcast_core.runtime.geometry.camera import sun_vector
    from outcast_core.runtime.io.imageio import read_image, write_image
    from outcast_core.runtime.pipeline.session import RelightSession

    session = RelightSession(preset=preset)
    for name in ("depth", "shadow", "relight"):  # loading the models is not the relighting
        if session.registry.available(name):
            session.registry.load(name)
    t: dict[str, float] = {}
    t0 = start = time.perf_counter()

    def lap(stage: str) -> None:
        nonlocal t0
        now = time.perf_counter()
        t[stage] = now - t0
        t0 = now

    loaded = read_image(path, keep_uint8=variant == "now")
    lap("read")
    session.set_image(loaded.image_srgb)
    lap("set image")
    session.set_original_sun(sun_vector(*W_FROM))
    lap("original sun")
    relit = session.relight(sun_vector(*W_TO))
    lap("relight")
    if variant == "now":
        full = session.relight_full(sun_vector(*W_TO), dtype=np.uint8)
    else:
        full = baseline_transfer(session.full_image_srgb, session.image_srgb, relit)
    lap("full res")
    write_image(out, full, force=True, exif=loaded.exif_bytes)
    lap("write")
    t["total"] = time.perf_counter() - start
    t["peak GB"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024**2
    return t


def child_main(argv: list[str]) -> int:
    """``--child make PATH W H`` or ``--child relight PATH OUT VARIANT PRESET``."""
    if argv[0] == "make":
        _make_photo(argv[1], int(argv[2]), int(argv[3]))
        return 0
    print(json.dumps(_relight_pipeline(*argv[1:5])))
    return 0


def _child(*args: str) -> dict | None:
    cmd = [sys.executable, str(ROOT / "benchmarks" / "bench_runtime.py"), "--child", *args]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    res = subprocess.run(cmd, capture_output=True, text=True, env=env, check=False)
    if res.returncode != 0:
        print(f"  (child {' '.join(args[:2])} failed: {res.stderr.strip()[-400:]})")
        return None
    line = res.stdout.strip().splitlines()
    return json.loads(line[-1]) if line else {}


# ----------------------------------------------------------------------------- sections
def full_resolution(folder: Path, quick: bool, repeats: int, preset: str = "balanced") -> Path:
    """Relight at 12, 24 and 108 MP, each pipeline in a fresh process. Returns the 12 MP file."""
    print(f"\nFull-resolution relight, end to end in one process per run ({preset} preset, "
          "learned models loaded before the clock; read JPEG -> set -> confirm sun -> relight ->"
          f" write JPEG q95). Best total of {repeats} runs (stages of that run; peak GB: the "
          "highest of the runs); the 108 MP baseline runs once.")
    print("Baseline: the float32 pipeline before the banded 8-bit transfer (same run).")
    cols = ["read", "set image", "original sun", "relight", "full res", "write", "total"]
    print(f"{'size':>7} {'pipeline':>9} " + " ".join(f"{c:>12}" for c in cols)
          + f" {'peak GB':>8} {'x baseline':>11} {'goal':>12}")
    first = None
    for label, (w, h) in SIZES.items():
        photo = folder / f"photo_{w}x{h}.jpg"
        if not photo.exists():
            _child("make", str(photo), str(w), str(h))
        first = first or photo
        skip_base = quick and label == "108 MP"
        rows = {}
        for variant in ("baseline", "now"):
            if variant == "baseline" and skip_base:
                continue
            n = 1 if (variant == "baseline" and label == "108 MP") else repeats
            runs = [_child("relight", str(photo), str(folder / "out.jpg"), variant, preset)
                    for _ in range(n)]
            runs = [r for r in runs if r is not None]
            if runs:
                best = min(runs, key=lambda r: r["total"])
                rows[variant] = {**best, "peak GB": max(r["peak GB"] for r in runs)}
                rows[variant]["totals"] = [r["total"] for r in runs]
        for variant, r in rows.items():
            if r is None:
                continue
            base = rows.get("baseline")
            ratio = (f"{r['total'] / base['total']:11.2f}" if variant == "now" and base
                     else f"{'':>11}")
            secs, gb = GOALS[label]
            goal = f"<= {secs:g} s" + (f", {gb:g} GB" if gb else "") if variant == "now" else ""
            print(f"{label:>7} {variant:>9} " + " ".join(f"{r[c]:12.2f}" for c in cols)
                  + f" {r['peak GB']:8.2f} {ratio} {goal:>12}"
                  + ("  (totals " + ", ".join(f"{x:.2f}" for x in r["totals"]) + ")"
                     if len(r["totals"]) > 1 else ""))
        if skip_base:
            print(f"{label:>7} {'baseline':>9}  (skipped in --quick: about 40 s and 7 GB)")
    return first


def _drag_times(img: np.ndarray, preset: str, n: int) -> tuple[float, float, float]:
    """Median seconds per sun: step-1 overlay, step-2 preview as it was, step-2 preview now."""
    from outcast_core.runtime.geometry.camera import sun_vector
    from outcast_core.runtime.pipeline.session import RelightSession

    s = RelightSession(preset=preset)
    s.set_image(img)
    s.set_original_sun(sun_vector(*W_FROM))
    s.prepare_relight_preview()
    s.relight(sun_vector(100.0, 40.0), preview=True)  # warm
    real_shadow = s.shadow

    def suns(offset: float) -> list[np.ndarray]:
        return [sun_vector(90.0 + offset + 170.0 * k / n, 40.0 + 15.0 * math.sin(k / 3))
                for k in range(n)]

    def timed(fn, ws) -> float:
        ts = []
        for w in ws:
            t0 = time.perf_counter()
            fn(w)
            ts.append(time.perf_counter() - t0)
        return float(np.median(ts))

    def before(w):  # the preview as it was: S at the preview size, L at the working size
        s.shadow = lambda w2, preview=False: real_shadow(w2, preview=True)
        try:
            return s._compute_relight(w, False, s.exposure)
        finally:
            del s.shadow

    t1 = timed(lambda w: s._compute_shadow(w, True), suns(0.3))
    tb = timed(before, suns(0.6))
    tn = timed(lambda w: s._compute_relight(w, True, s.exposure), suns(0.9))
    return t1, tb, tn


def drag_preview(quick: bool) -> None:
    """Step 2's relit preview per sun, beside the preview as it was and the step-1 overlay."""
    from outcast_core.runtime.io.imageio import read_image

    img = read_image(SAMPLE, keep_uint8=True).image_srgb
    n = 10 if quick else 30
    print(f"\nDrag previews on {SAMPLE.name} ({img.shape[1]}x{img.shape[0]}), learned models, "
          f"{n} suns each, median ms per sun (rate per second), session only (the GUI's own "
          "rate: benchmarks/bench_gui.py):")
    print(f"{'preset':>9} {'step 1 overlay':>16} {'step 2 before':>16} {'step 2 now':>16} "
          f"{'now/before':>11} {'now/step 1':>11} {'goal':>9}")
    for preset, goal in (("fast", 25), ("balanced", 15)):
        t1, tb, tn = _drag_times(img, preset, n)
        print(f"{preset:>9} {t1 * 1e3:9.0f} ({1 / t1:4.1f}) {tb * 1e3:9.0f} ({1 / tb:4.1f}) "
              f"{tn * 1e3:9.0f} ({1 / tn:4.1f}) {tn / tb:11.2f} {tn / t1:11.2f} "
              f"{'>= ' + str(goal) + '/s':>9}")


def timelapse(photo: Path, quick: bool, preset: str = "balanced") -> None:
    """A 1080p MP4 time-lapse of a 12 MP photo: now against the sequential baseline."""
    from outcast_core.runtime.geometry.camera import sun_vector
    from outcast_core.runtime.io.imageio import read_image
    from outcast_core.runtime.pipeline import timelapse as tl
    from outcast_core.runtime.pipeline.session import RelightSession, resize

    frames = 24 if quick else 120
    loaded = read_image(photo, keep_uint8=True)
    samples = tl.sweep_path((60.0, 20.0), (300.0, 50.0), frames)
    results = {}
    with tempfile.TemporaryDirectory() as d:
        for variant in ("baseline", "now"):
            s = RelightSession(preset=preset)
            s.set_image(loaded.image_srgb)
            s.set_original_sun(sun_vector(*W_FROM))
            s.relight(sun_vector(*W_TO))  # models loaded and warm for both
            out = Path(d) / f"{variant}.mp4"
            t0 = time.perf_counter()
            if variant == "now":
                tl.render_timelapse(s, samples, out, size="1080p")
            else:
                shape = tl.frame_shape("1080p", s.full_image_srgb.shape[:2],
                                       s.image_srgb.shape[:2])
                photo_f = resize(s.full_image_srgb, shape).astype(np.float32) / 255.0
                writer = tl.Mp4Writer(out)
                old_preset, tl.X264_PRESET = tl.X264_PRESET, "faster"
                try:
                    for w in tl.sun_vectors(samples):
                        writer.write(baseline_transfer(photo_f, s.image_srgb, s.relight(w)))
                    writer.commit()
                finally:
                    tl.X264_PRESET = old_preset
            results[variant] = time.perf_counter() - t0
    base, now = results["baseline"], results["now"]
    scale = 120 / frames
    print(f"\nTime-lapse, {frames} frames of 1080p MP4 from a 12 MP photo ({preset} preset):")
    print(f"  baseline (sequential, float transfer, x264 faster): {base:6.1f} s "
          f"({base / frames * 1e3:.0f} ms/frame)")
    print(f"  now (shadow beside relighting, 8-bit transfer, write-behind, veryfast): "
          f"{now:6.1f} s ({now / frames * 1e3:.0f} ms/frame); x baseline {now / base:.2f}")
    if frames != 120:
        print(f"  120 frames at these rates: baseline {base * scale:.0f} s, now {now * scale:.0f} s"
              " (goal <= 60 s; the full run measures 120)")
    else:
        print("  goal: 120 frames <= 60 s")


def run(quick: bool, repeats: int = 1) -> None:
    with tempfile.TemporaryDirectory(prefix="outcast-bench-") as d:
        photo12 = full_resolution(Path(d), quick, repeats)
        drag_preview(quick)
        timelapse(photo12, quick)
