"""``outcast-gui --self-test OUT.png PHOTO``: drive the real window once, report as JSON.

Used by the packaging smoke tests (the wheel in a fresh virtual environment, the PyInstaller
bundle), where only the installed program can run: open ``PHOTO``, take the sun from its EXIF,
confirm it, relight to a fixed sun and export a still to ``OUT.png`` at full resolution; print one
JSON line with what happened (the EXIF sun, the modes used, the model folder, the output size and
the seconds taken). Settings go to a temporary file, so the user's recent files are untouched.
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import time
from typing import Any

#: The new sun of the self-test's still (azimuth, elevation in degrees, camera-relative).
SELF_TEST_SUN = (90.0, 30.0)


def run_self_test(photo: str, output: str, preset: str = "fast",
                  timeout: float = 300.0) -> dict[str, Any]:
    """Open ``photo`` in a :class:`app.main_window.MainWindow`, align from EXIF, export a still.

    Needs a ``QApplication`` (any platform, offscreen included).

    Args:
        photo: a photo with EXIF GPS, time and heading (e.g. ``samples/exif_003_th_pool.jpg``).
        output: the still to write (PNG, JPEG or TIFF); replaced if it exists.
        preset: the quality preset.
        timeout: seconds each stage may take.

    Returns:
        ``{"exif_sun": [az, el], "mode": ..., "models": folder, "output": path,
        "size": [w, h], "seconds": s}``.

    Raises:
        RuntimeError: a stage failed (the window's error text) or the photo has no EXIF sun.
    """
    from PySide6.QtCore import QSettings

    from app import sun_dial_math as dm
    from app.main_window import MainWindow, process_until_idle
    from app.state import Step
    from outcast_core.runtime.io.models import ModelRegistry

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="outcast-self-test-") as tmp:
        settings = QSettings(os.path.join(tmp, "settings.ini"), QSettings.Format.IniFormat)
        window = MainWindow(settings=settings, preset=preset)
        errors: list[str] = []
        window.show_error = lambda exc, action: errors.append(f"{action}: {exc}")  # type: ignore[method-assign]
        try:
            window.open_path(photo)
            process_until_idle(window, timeout)
            if errors or window.step is not Step.ALIGN:
                raise RuntimeError(f"opening {photo} failed: {'; '.join(errors) or window.step}")
            sun = window.exif_sun()
            if sun is None:
                raise RuntimeError(f"{photo} has no EXIF sun (GPS, time and heading)")
            window.use_exif_sun()
            process_until_idle(window, timeout)
            shown = window.align_panel.sun_panel.sun()
            if not dm.same_sun(shown, sun, tol=0.5):
                raise RuntimeError(f"the dial shows {shown}, not the EXIF sun {sun}")
            window.confirm_original_sun()
            process_until_idle(window, timeout)
            window.relight_panel.sun_panel.set_sun(*SELF_TEST_SUN)
            window.request_relight(preview=False)
            process_until_idle(window, timeout)
            if window.step is not Step.RELIGHT:
                raise RuntimeError(f"confirming the sun failed: {'; '.join(errors)}")
            if os.path.exists(output):
                os.remove(output)
            window.export_still(output, force=True)
            process_until_idle(window, timeout)
            if errors or not os.path.isfile(output):
                raise RuntimeError(f"exporting {output} failed: {'; '.join(errors)}")
            from PIL import Image

            with Image.open(output) as img:
                size = list(img.size)
            return {
                "exif_sun": [round(sun[0], 3), round(sun[1], 3)],
                "mode": window.mode_label.text(),
                "models": str(ModelRegistry().directory_for("relight")),
                "output": os.path.abspath(output),
                "size": size,
                "seconds": round(time.perf_counter() - t0, 2),
            }
        finally:
            window.close_without_asking()
            window.runner.shutdown()


def main_self_test(photo: str | None, output: str, preset: str) -> int:
    """Entry of ``outcast-gui --self-test``: one JSON line on stdout, or one error line (status 2).

    Args:
        photo: the photo to open (required).
        output: the still to write.
        preset: the quality preset.

    Returns:
        The exit status.
    """
    from PySide6.QtWidgets import QApplication

    if not photo:
        print("outcast-gui: error: --self-test needs a photo with EXIF GPS, time and heading",
              file=sys.stderr)
        return 2
    app = QApplication.instance() or QApplication(sys.argv[:1])
    app.setApplicationName("OutCast")
    try:
        report = run_self_test(photo, output, preset=preset)
    except (RuntimeError, TimeoutError, OSError) as exc:
        print(f"outcast-gui: error: self-test: {exc}", file=sys.stderr)
        return 2
    print(json.dumps(report))
    return 0
