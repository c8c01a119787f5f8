"""Screenshots of step 1's "Find sun" (the sun found and the agreement heat map on the dial).

Usage:
    QT_QPA_PLATFORM=offscreen python scripts/screenshots_find_sun.py [PHOTO ...]
        [--out out/screenshots] [--preset balanced]

Default photos: the three samples. Each is copied into the output folder first (no project file
lands next to the samples); per photo it saves the window and the dial enlarged
(``find_sun_NAME.png``, ``find_sun_NAME_dial.png``) and prints what was found.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("photos", nargs="*", default=sorted(str(x) for x in
                                                         (ROOT / "samples").glob("*.jpg")))
    p.add_argument("--out", default=str(ROOT / "out" / "screenshots"))
    p.add_argument("--preset", default="balanced", choices=("fast", "balanced", "accurate"))
    args = p.parse_args(argv)
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

    from PySide6.QtCore import QSettings
    from PySide6.QtWidgets import QApplication

    from app.main_window import MainWindow, process_until_idle

    out = Path(args.out)
    work = out / "work"
    work.mkdir(parents=True, exist_ok=True)
    app = QApplication.instance() or QApplication([])
    settings = QSettings(str(work / "settings.ini"), QSettings.Format.IniFormat)
    win = MainWindow(settings=settings, preset=args.preset)
    win.resize(1280, 800)
    win.show()
    for src in args.photos:
        photo = work / Path(src).name
        shutil.copyfile(src, photo)
        win.open_path(str(photo))
        process_until_idle(win, 120.0)
        win.find_sun()
        process_until_idle(win, 120.0)
        app.processEvents()
        fit = win.sun_fit
        name = photo.stem
        win.grab().save(str(out / f"find_sun_{name}.png"))
        dial = win.align_panel.sun_panel.dial
        dial.grab().scaled(dial.width() * 2, dial.height() * 2).save(
            str(out / f"find_sun_{name}_dial.png"))
        print(f"{name}: azimuth {fit.azimuth:.1f}, elevation {fit.elevation:.1f}, confidence "
              f"{fit.confidence:.2f}, {fit.source}; status: {win.stage_label.text()}; "
              f"note: {win.align_panel.exif_note.text()!r}")
        win.undo_stack.setClean()  # no question about unsaved edits before the next photo
    win.close_without_asking()
    return 0


if __name__ == "__main__":
    sys.exit(main())
