"""Drive OutCast through its states on a sample photo and save screenshots.

Usage:
    QT_QPA_PLATFORM=offscreen python scripts/screenshots.py [PHOTO] [--out out/screenshots]
        [--preset balanced]

The photo is copied into the output folder first, so project files never land next to the
samples. Screenshots: empty window, photo loaded, sun aligned, mid-drag preview, relit with the
before/after split (learned, and physics relighting), the Edit menu (undo), the photo with its
shadows removed and the shadows found, buffers grid, time-lapse dialog with its sizes, the
prompt when quitting during an export, an error dialog.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("photo", nargs="?", default=str(ROOT / "samples" / "exif_003_th_pool.jpg"))
    p.add_argument("--out", default=str(ROOT / "out" / "screenshots"))
    p.add_argument("--preset", default="balanced", choices=("fast", "balanced", "accurate"))
    args = p.parse_args(argv)
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

    from PySide6.QtCore import QPoint, QSettings, Qt
    from PySide6.QtTest import QTest
    from PySide6.QtWidgets import QApplication, QMessageBox

    from app import sun_dial_math as dm
    from app.errors import message_for
    from app.main_window import MainWindow, process_until_idle
    from outcast_core.runtime.io.imageio import ImageReadError, ImageReadReason

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    work = out / "work"
    work.mkdir(exist_ok=True)
    photo = work / Path(args.photo).name
    shutil.copyfile(args.photo, photo)
    for stale in work.glob("*.outcast.json"):
        stale.unlink()

    app = QApplication.instance() or QApplication([])
    settings = QSettings(str(work / "settings.ini"), QSettings.Format.IniFormat)
    win = MainWindow(settings=settings, preset=args.preset)
    win.resize(1280, 800)
    win.show()

    def settle(timeout: float = 120.0) -> None:
        process_until_idle(win, timeout)

    def shot(widget, name: str) -> None:
        app.processEvents()
        path = out / name
        widget.grab().save(str(path))
        print(f"saved {path}")

    def dial_point(dial, az, el) -> QPoint:
        cx, cy, r = dial.dial_geometry()
        x, y = dm.sun_to_point(az, el, cx, cy, r)
        return QPoint(round(x), round(y))

    settle()
    shot(win, "01_empty.png")

    win.open_path(str(photo))
    settle()
    shot(win, "02_loaded.png")

    # Align: drag toward the sun the photo's EXIF says, then snap to it with the EXIF button.
    target = win.exif_sun() or (250.0, 40.0)
    dial = win.align_panel.sun_panel.dial
    QTest.mousePress(dial, Qt.MouseButton.LeftButton, pos=dial_point(dial, *dial.sun()))
    start = dial.sun()
    for k in range(1, 9):
        t = k / 8
        az = start[0] + ((target[0] - start[0] + 180) % 360 - 180) * t
        el = start[1] + (target[1] - start[1]) * t
        QTest.mouseMove(dial, dial_point(dial, az, el))
        app.processEvents()
        time.sleep(0.03)
    settle()
    shot(win, "03_dragging.png")
    QTest.mouseRelease(dial, Qt.MouseButton.LeftButton, pos=dial_point(dial, *target))
    settle()
    if win.align_panel.exif_button.isEnabled():
        win.align_panel.exif_button.click()
        settle()
    shot(win, "04_aligned.png")

    win.confirm_original_sun()
    settle()
    win.relight_panel.sun_panel.set_sun(200.0, 22.0)
    win.request_relight(preview=False)
    settle()
    shot(win, "05_relit_split.png")
    combo = win.relight_panel.relighting_combo  # step 2's "Relighting": physics, and back
    combo.setCurrentIndex(combo.findData("physics"))
    settle()
    shot(win, "05a_relit_physics.png")
    combo.setCurrentIndex(combo.findData("learned"))
    settle()

    # The Edit menu after a few edits: drawn onto the window where it pops up.
    win.relight_panel.sun_panel.azimuth_box.setValue(230.0)
    settle()
    bar = win.menuBar()
    edit_pos = bar.actionGeometry(win.edit_menu.menuAction()).bottomLeft()
    win.edit_menu.popup(bar.mapToGlobal(edit_pos))
    app.processEvents()
    canvas = win.grab()
    from PySide6.QtGui import QPainter

    painter = QPainter(canvas)
    painter.drawPixmap(win.mapFromGlobal(win.edit_menu.pos()), win.edit_menu.grab())
    painter.end()
    canvas.save(str(out / "05b_edit_menu.png"))
    print(f"saved {out / '05b_edit_menu.png'}")
    win.edit_menu.hide()

    # The photo's own shadows: lifted (split with the photo), then the shadows found, tinted.
    win.relight_panel.set_view("shadows_removed")
    settle()
    shot(win, "05c_shadows_removed.png")
    win.relight_panel.set_view("shadows_found")
    settle()
    shot(win, "05d_shadows_found.png")

    win.relight_panel.set_view("all")
    settle()
    shot(win, "06_buffers.png")
    win.relight_panel.set_view("output")
    settle()

    dialog = win.open_timelapse()
    s = dialog.settings()
    s.kind, s.frames = "sun", 24
    dialog.load_settings(s)
    dialog.solve_heading()
    dialog.scrubber.setValue(8)
    settle()
    shot(dialog, "07_timelapse.png")
    combo = dialog.size_combo
    combo.showPopup()
    app.processEvents()
    popup = combo.view().window()
    picture = dialog.grab()
    painter = QPainter(picture)
    painter.drawPixmap(dialog.mapFromGlobal(popup.pos()), popup.grab())
    painter.end()
    picture.save(str(out / "07a_timelapse_sizes.png"))
    print(f"saved {out / '07a_timelapse_sizes.png'}")
    combo.hidePopup()

    # Quit (Ctrl+Q) while the time-lapse exports: the real prompt, grabbed, answered "Keep".
    from app.leave_prompts import KEEP

    def grab_and_keep(question):
        box = win.question_box(question)
        box.show()
        app.processEvents()
        shot(box, "07b_quit_during_export.png")
        box.close()
        return KEEP

    win.ask = grab_and_keep
    seen = []
    win.runner.progress.connect(lambda i, ch, st, f: seen.append(f) if ch == "tl_export" else 0)
    dialog.export(str(work / "timelapse.mp4"), force=True)
    while len(seen) < 2 and win.runner.busy():
        app.processEvents()
        time.sleep(0.01)
    win.act_quit.trigger()
    dialog.cancel_export()
    settle()
    del win.ask
    dialog.close()

    win.save_project()
    msg = message_for(ImageReadError(f"cannot read image '{work / 'broken.jpg'}': the file is "
                                     "truncated or corrupt", ImageReadReason.DAMAGED),
                      "open")  # fmt: skip
    box = QMessageBox(QMessageBox.Icon.Critical, msg.title, msg.text(), parent=win)
    box.show()
    app.processEvents()
    shot(box, "08_error_dialog.png")
    box.close()

    print("timings:", win.timings.summary(limit=20))
    win.close_without_asking()
    return 0


if __name__ == "__main__":
    sys.exit(main())
