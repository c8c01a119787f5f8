"""Benchmark the GUI: overlay update rate while dragging the sun, and the time of each stage.

Usage:
    QT_QPA_PLATFORM=offscreen python benchmarks/bench_gui.py [PHOTO] [--presets fast,balanced]
        [--seconds 4] [--hz 60] [--memory]

For each preset it opens the photo in the real main window and drags, with simulated mouse
events at ``--hz`` for ``--seconds`` (a slow arc: azimuth sweeps 180 degrees, elevation 20-60):

* in step 1 the original sun's handle, counting the shadow overlays that reach the canvas (the
  baseline of the run), then
* in step 2 the new sun's handle, counting the relit previews that reach the canvas, and prints
  the step 2 / step 1 ratio of the two rates (compare figures within one run: the machine is
  shared).

It then relights, exports a still and a short time-lapse, and prints the session's stage timings
and the wall time of each GUI step. All figures are measured on this machine at run time.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def drag(app, dial, point, seconds: float, hz: float, shown, arrivals: list, label: str,
         res: dict) -> None:
    """Drag ``dial``'s handle in a slow arc (azimuth +180 deg, elevation 20-60) with mouse
    events at ``hz`` for ``seconds``, release, wait for the full-quality result, and record how
    many images ``shown()`` counts reached the canvas while the mouse moved."""
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    from app.main_window import process_until_idle

    win = dial.window()
    dial.set_sun(90.0, 40.0)
    QTest.mousePress(dial, Qt.MouseButton.LeftButton, pos=point(90.0, 40.0))
    n0 = shown()
    arrivals.clear()
    moves = int(seconds * hz)
    t_start = time.perf_counter()
    for k in range(moves):
        t = k / max(1, moves - 1)
        az = 90.0 + 180.0 * t
        el = 40.0 + 20.0 * math.sin(2 * math.pi * t)
        QTest.mouseMove(dial, point(az, el))
        app.processEvents()
        next_tick = t_start + (k + 1) / hz
        while time.perf_counter() < next_tick:
            app.processEvents()
            time.sleep(0.001)
    t_drag = time.perf_counter() - t_start
    during = shown() - n0
    t_rel = time.perf_counter()
    QTest.mouseRelease(dial, Qt.MouseButton.LeftButton, pos=point(270.0, 40.0))
    process_until_idle(win, 300.0)
    res[f"{label}: images per second while dragging"] = during / t_drag
    res[f"{label}: images during the drag ({moves} mouse moves, {t_drag:.1f} s)"] = during
    gaps = [b - a for a, b in zip(arrivals, arrivals[1:], strict=False) if b < t_rel]
    if gaps:
        res[f"{label}: median seconds between images"] = statistics.median(gaps)
    res[f"{label}: release -> full-quality result (s)"] = time.perf_counter() - t_rel


def run_preset(app, photo: str, preset: str, seconds: float, hz: float, tmp: Path) -> dict:
    from PySide6.QtCore import QPoint, QSettings

    from app import sun_dial_math as dm
    from app.main_window import MainWindow, process_until_idle

    settings = QSettings(str(tmp / "settings.ini"), QSettings.Format.IniFormat)
    win = MainWindow(settings=settings, preset=preset)
    win.resize(1280, 800)
    win.show()
    res: dict = {"preset": preset}

    def settle(timeout: float = 300.0) -> None:
        process_until_idle(win, timeout)

    def timed(label: str, fn) -> None:
        t0 = time.perf_counter()
        fn()
        settle()
        res[label] = time.perf_counter() - t0

    timed("open photo (read + depth + normals + first overlay)", lambda: win.open_path(photo))
    res["session stages after open"] = dict(win.session.timings)

    def pointer(dial):
        def point(az: float, el: float) -> QPoint:
            cx, cy, r = dial.dial_geometry()
            x, y = dm.sun_to_point(az, el, cx, cy, r)
            return QPoint(round(x), round(y))
        return point

    arrivals: list[float] = []

    def arrived(_i, channel, result, _s) -> None:
        if channel in ("shadow", "relight") and isinstance(result, dict) and result.get("preview"):
            arrivals.append(time.perf_counter())

    win.runner.finished.connect(arrived)
    # Step 1 (the baseline of this run): shadow overlays while dragging the photo's sun.
    dial1 = win.align_panel.sun_panel.dial
    drag(app, dial1, pointer(dial1), seconds, hz, lambda: win.canvas.overlay_updates, arrivals,
         "step 1 drag (shadow overlay)", res)
    res["session stages after step 1 drag"] = dict(win.session.timings)

    timed("confirm original sun (refine + light estimate)", win.confirm_original_sun)
    # Step 2: relit previews while dragging the new sun; the full-resolution result on release.
    dial2 = win.relight_panel.sun_panel.dial
    drag(app, dial2, pointer(dial2), seconds, hz, lambda: win.canvas.after_updates, arrivals,
         "step 2 drag (relit preview)", res)
    one = res["step 1 drag (shadow overlay): images per second while dragging"]
    two = res["step 2 drag (relit preview): images per second while dragging"]
    res["step 2 / step 1 rate (same run)"] = two / one if one else float("nan")
    res["session stages after step 2 drag"] = dict(win.session.timings)

    win.relight_panel.sun_panel.set_sun(200.0, 25.0)
    timed("relight preview (working size)", lambda: win.request_relight(preview=True))
    timed("relight full pass (full resolution)", lambda: win.request_relight(preview=False))
    timed("export still PNG (full resolution)",
          lambda: win.export_still(str(tmp / f"still_{preset}.png"), force=True))  # fmt: skip
    dialog = win.open_timelapse()
    s = dialog.settings()
    s.kind, s.frames, s.format, s.size = "sweep", 12, "mp4", "working"
    dialog.load_settings(s)
    settle()
    timed("time-lapse 12 frames MP4 (working size)",
          lambda: dialog.export(str(tmp / f"tl_{preset}.mp4"), force=True))  # fmt: skip
    res["session stages at end"] = dict(win.session.timings)
    h, w = win.session.image_srgb.shape[:2]
    res["working size"] = f"{w}x{h}"
    dialog.close()
    win.close_without_asking()
    return res


def memory_child(photo: str, variant: str) -> int:
    """Open ``photo`` in the main window, confirm, relight at full resolution, export a JPEG;
    print the wall times and the process's peak resident memory as JSON.

    ``variant`` ``baseline`` is the app's pipeline as it was: the photo decoded to float32
    (kept by the window and copied by the session) and the full-resolution result in float32
    before its 8-bit copy for the screen.
    """
    import json
    import resource

    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    from PySide6.QtCore import QSettings
    from PySide6.QtWidgets import QApplication

    from app.main_window import MainWindow, process_until_idle
    from outcast_core.runtime.io import imageio, session

    if variant == "baseline":
        read = imageio.read_image
        imageio.read_image = lambda path, max_pixels=None, **_k: read(path, max_pixels)
        full = session.RelightSession.relight_full
        session.RelightSession.relight_full = lambda self, w, **_k: full(self, w)
    app = QApplication.instance() or QApplication([])
    res: dict = {}
    with tempfile.TemporaryDirectory() as d:
        settings = QSettings(str(Path(d) / "settings.ini"), QSettings.Format.IniFormat)
        win = MainWindow(settings=settings, preset="balanced")
        win.resize(1280, 800)
        win.show()

        def timed(label: str, fn) -> None:
            t0 = time.perf_counter()
            fn()
            process_until_idle(win, 600.0)
            res[label] = time.perf_counter() - t0

        timed("open", lambda: win.open_path(photo))
        timed("confirm", win.confirm_original_sun)
        win.relight_panel.sun_panel.set_sun(200.0, 25.0)
        timed("relight full", lambda: win.request_relight(preview=False))
        timed("export JPEG", lambda: win.export_still(str(Path(d) / "still.jpg"), force=True))
        win.close_without_asking()
        app.processEvents()
    res["peak GB"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024**2
    print(json.dumps(res))
    return 0


def memory(args: argparse.Namespace) -> None:
    """The app with a 12000 x 9000 photo, in a fresh process per pipeline (peak RSS)."""
    import json
    import subprocess

    print("\n== the app with a 108 MP photo (12000x9000, synthesized), balanced preset: "
          "open, confirm, full-resolution relight, export JPEG; one fresh process each")
    with tempfile.TemporaryDirectory() as d:
        photo = Path(d) / "photo_12000x9000.jpg"
        env = {**os.environ, "PYTHONPATH": str(ROOT)}
        subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_runtime.py"), "--child",
                        "make", str(photo), "12000", "9000"], check=True, env=env)
        rows = {}
        for variant in ("baseline", "now"):
            r = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--child-memory",
                                str(photo), variant], capture_output=True, text=True, env=env,
                               check=False)
            lines = r.stdout.strip().splitlines()
            if r.returncode != 0 or not lines:
                print(f"  {variant}: failed ({r.stderr.strip()[-300:]})")
                continue
            rows[variant] = json.loads(lines[-1])
        for variant, r in rows.items():
            base = rows.get("baseline")
            ratio = (f"  x baseline: peak {r['peak GB'] / base['peak GB']:.2f}"
                     if variant == "now" and base else "")
            print(f"  {variant:>8}: " + ", ".join(
                f"{k} {v:.2f} {'GB' if k == 'peak GB' else 's'}".replace("peak GB", "peak")
                for k, v in r.items()) + ratio)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--child-memory"]:
        return memory_child(argv[1], argv[2])
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("photo", nargs="?", default=str(ROOT / "samples" / "exif_003_th_pool.jpg"))
    p.add_argument("--presets", default="fast,balanced")
    p.add_argument("--seconds", type=float, default=4.0)
    p.add_argument("--hz", type=float, default=60.0)
    p.add_argument("--memory", action="store_true",
                   help="also open a synthesized 108 MP photo (peak memory; about a minute)")
    p.add_argument("--report", metavar="PATH", help="also write the figures to a Markdown report")
    args = p.parse_args(argv)
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    from PySide6.QtWidgets import QApplication

    from benchmarks.report import report_to

    app = QApplication.instance() or QApplication([])
    with report_to(args.report, "bench_gui"):
        return _run(app, args)


def _run(app, args: argparse.Namespace) -> int:
    print(
        f"photo: {args.photo}  cpu cores: {os.cpu_count()}  drag: {args.seconds} s at {args.hz} Hz"
    )
    with tempfile.TemporaryDirectory() as d:
        for preset in args.presets.split(","):
            res = run_preset(app, args.photo, preset.strip(), args.seconds, args.hz, Path(d))
            print(f"\n== preset {res.pop('preset')} (working size {res.pop('working size')})")
            for k, v in res.items():
                if isinstance(v, dict):
                    stages = ", ".join(f"{s} {t * 1000:.0f} ms" for s, t in v.items())
                    print(f"  {k}: {stages}")
                elif isinstance(v, float):
                    print(f"  {k}: {v:.3f}")
                else:
                    print(f"  {k}: {v}")
    if args.memory:
        memory(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
