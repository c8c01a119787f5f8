"""Issue 16 item 2 in the app: the "Shadows removed" and "Shadows found" views and their export."""

from __future__ import annotations

import os
import threading
import time

import cv2
import numpy as np
import pytest
from PIL import Image
from PySide6.QtGui import QImage

from app.state import BUFFER_VIEWS, load_project, project_path_for
from tests.app.conftest import make_photo, undo_texts
from tests.app.test_main_window import _confirm, _load, _results

BAND = (slice(66, 72), slice(34, 62))  # inside make_photo's dark band at 128 x 96
LIT = (slice(55, 62), slice(70, 120))  # lit ground right of it


def _rgb(img: QImage) -> np.ndarray:
    """A QImage as ``H x W x 3`` uint8."""
    img = img.convertToFormat(QImage.Format.Format_RGB888)
    a = np.frombuffer(img.constBits(), np.uint8).reshape(img.height(), img.bytesPerLine())
    return a[:, : 3 * img.width()].reshape(img.height(), img.width(), 3).copy()


def _relight_step(window, photo, settle) -> None:
    _load(window, photo, settle)
    _confirm(window, settle)


def _photo_with_exif(path, width: int, height: int) -> str:
    """``make_photo`` at ``width x height`` with an EXIF camera make to find in the export."""
    make_photo(path, width, height)
    with Image.open(path) as im:
        exif = im.getexif()
        exif[0x010F] = "OutCastTestCamera"  # Make
        im.save(path, quality=92, exif=exif.tobytes())
    return str(path)


def _slow_deshadow(monkeypatch, session, seconds: float, threads: list[str]) -> None:
    real = session.deshadow_full

    def slow(**kwargs) -> np.ndarray:  # (dtype: the view and the export ask for 8 bits)
        threads.append(threading.current_thread().name)
        time.sleep(seconds)
        return real(**kwargs)

    monkeypatch.setattr(session, "deshadow_full", slow)


def test_view_choices_are_the_project_views():
    from app.panels import VIEW_CHOICES

    assert tuple(k for k, _ in VIEW_CHOICES) == BUFFER_VIEWS
    assert {"shadows_removed", "shadows_found"} <= set(BUFFER_VIEWS)


def test_shadows_removed_view_lifts_the_dark_shadow(window, photo, settle, errors):
    _relight_step(window, photo, settle)
    photo_rgb = _rgb(window.canvas.before()).astype(np.float32)
    window.relight_panel.set_view("shadows_removed")
    settle()
    assert errors == []
    after = window.canvas.after()
    assert after is not None and after.size() == window.canvas.before().size()
    shown = _rgb(after).astype(np.float32)
    assert shown[BAND].mean() > photo_rgb[BAND].mean() + 20  # the dark band is lifted
    assert abs(shown[LIT].mean() - photo_rgb[LIT].mean()) < 6  # lit ground stays as it was
    assert window.canvas.split() == pytest.approx(0.5)  # compared with the photo, as the relit
    assert window.relight_panel.split_slider.isEnabled()
    assert window.canvas.overlay() is None


def test_shadows_found_view_tints_the_shadow(window, photo, settle):
    _relight_step(window, photo, settle)
    window.relight_panel.set_view("shadows_found")
    settle()
    overlay = window.canvas.overlay()
    assert overlay is not None and window.canvas.after() is None
    alpha = np.asarray(
        [[overlay.pixelColor(x, y).alpha() for x in range(0, 128, 4)] for y in range(96)]
    )
    assert alpha[BAND[0], 9:15].mean() > 128  # the band is found
    assert alpha[:30].max() == 0  # the sky never is
    assert not window.relight_panel.split_slider.isEnabled()
    window.relight_panel.set_view("output")
    settle()
    assert window.canvas.overlay() is None and window.canvas.after() is not None


def test_dragging_the_new_sun_recomputes_nothing(qtbot, window, photo, settle, monkeypatch):
    _relight_step(window, photo, settle)
    threads: list[str] = []
    _slow_deshadow(monkeypatch, window.session, 0.0, threads)
    window.relight_panel.set_view("shadows_removed")
    settle()
    shown = _rgb(window.canvas.after())
    jobs = _results(window, "relight")
    for az in (150.0, 170.0, 190.0):
        window.relight_panel.sun_panel.set_sun(az, 30.0)
        window.request_relight(preview=True)
    window.relight_panel.set_view("shadows_found")
    window.relight_panel.set_view("shadows_removed")
    settle()
    assert len(threads) == 1 and jobs == []  # the kept images, shown at once
    assert np.array_equal(_rgb(window.canvas.after()), shown)


def test_view_runs_off_the_ui_thread(qtbot, window, photo, settle, monkeypatch):
    from PySide6.QtCore import QTimer

    _relight_step(window, photo, settle)
    threads: list[str] = []
    _slow_deshadow(monkeypatch, window.session, 0.6, threads)
    ticks: list[float] = []
    timer = QTimer()
    timer.timeout.connect(lambda: ticks.append(time.perf_counter()))
    timer.start(20)
    t0 = time.perf_counter()
    window.relight_panel.set_view("shadows_removed")
    assert time.perf_counter() - t0 < 0.3  # the view change returned before the work
    settle()
    timer.stop()
    assert threads and threads[0] != threading.main_thread().name
    assert len(ticks) >= 15 and max(b - a for a, b in zip(ticks, ticks[1:], strict=False)) < 0.3


def test_the_split_says_what_shows_while_shadows_are_removed(window, photo, settle,
                                                             monkeypatch):
    """Until the de-shadowed photo comes, the relit photo still shown is labelled so (a user
    trial read it as "Shadows removed" for 8 s on a 27 MP photo); then the view's label."""
    _relight_step(window, photo, settle)
    _slow_deshadow(monkeypatch, window.session, 0.3, [])
    window.relight_panel.set_view("shadows_removed")
    assert window.canvas.split_labels() == ("Original", "Relit · removing shadows…")
    settle()
    assert window.canvas.split_labels() == ("Original", "Shadows removed")


def test_a_new_original_sun_or_preset_recomputes_the_view(window, photo, settle):
    _relight_step(window, photo, settle)
    window.relight_panel.set_view("shadows_found")
    settle()
    first = window._deshadow_images
    window.act_undo.trigger()  # back to step 1
    settle()
    window.act_redo.trigger()  # the same confirmed sun: the kept images are shown again
    settle()
    assert window.relight_panel.view() == "shadows_found"
    assert window._deshadow_images is first and window.canvas.overlay() is first[1]
    window.back_to_align()
    settle()
    window.align_panel.sun_panel.set_sun(273.0, 67.0)
    _confirm(window, settle)
    assert window._deshadow_images is not first
    assert window.canvas.overlay() is window._deshadow_images[1]
    second = window._deshadow_images
    window.set_preset("balanced")
    settle()
    assert window._deshadow_images is not second
    # The view choices made along the way are no undo steps.
    texts = undo_texts(window)
    assert texts == [
        "Confirm original sun", "Re-align original sun", "Confirm original sun", "Quality: Balanced"
    ]  # fmt: skip


def test_view_is_saved_in_the_project(qtbot, window, photo, settle):
    _relight_step(window, photo, settle)
    steps = window.undo_stack.count()
    window.relight_panel.set_view("shadows_removed")
    settle()
    assert window.undo_stack.count() == steps  # a view is no edit
    saved = window.save_project()
    assert load_project(saved).buffer_view == "shadows_removed"
    window.relight_panel.set_view("output")
    settle()
    window.open_path(str(project_path_for(photo)))
    settle()
    assert window.relight_panel.view() == "shadows_removed"
    assert window.canvas.after() is not None and window._deshadow_images is not None


@pytest.mark.parametrize("name, dtype", [("clean.jpg", np.uint8), ("clean.png", np.uint8),
                                         ("clean.tif", np.uint16)])  # fmt: skip
def test_export_writes_full_resolution(window, settle, errors, tmp_path, name, dtype):
    big = _photo_with_exif(tmp_path / "big.jpg", 400, 300)  # larger than the fast preset's 256
    _relight_step(window, big, settle)
    assert window.session.image_srgb.shape[:2] == (192, 256)
    menu = [a.text() for a in window.menuBar().actions()[0].menu().actions()]
    assert "Export shadows &removed…" in menu and window.act_export_deshadow.isEnabled()
    path = str(tmp_path / name)
    window.export_shadows_removed(path)
    settle()
    assert errors == [] and window.last_export == path
    written = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    assert written.shape == (300, 400, 3) and written.dtype == dtype
    expected = window.session.deshadow_full()
    rgb = written[..., ::-1].astype(np.float32) / np.iinfo(dtype).max
    assert np.abs(rgb - expected).mean() < 0.02  # the de-shadowed photo, not the relit one
    src = window.loaded.image_srgb / 255.0  # 8-bit photos are kept as read (uint8)
    band = (slice(200, 220), slice(110, 190))  # the dark band at 400 x 300
    assert rgb[band].mean() > src[band].mean() + 0.1
    with Image.open(path) as im:  # every format keeps the photo's EXIF, 16-bit TIFF too
        assert im.getexif().get(0x010F) == "OutCastTestCamera"


def test_export_refuses_to_overwrite(window, photo, settle, errors, tmp_path):
    _relight_step(window, photo, settle)
    path = tmp_path / "clean.png"
    path.write_bytes(b"mine")
    assert window.export_shadows_removed(str(path)) is None
    settle()
    assert errors and errors[-1][0] == "Not exported"
    assert "Nothing was overwritten" in errors[-1][1]
    assert path.read_bytes() == b"mine"
    errors.clear()
    window.export_shadows_removed(str(tmp_path / "other.png"))
    (tmp_path / "other.png").write_bytes(b"raced")  # appears while the job waits in the worker
    settle()
    assert errors and errors[-1][0] == "Not exported"
    assert (tmp_path / "other.png").read_bytes() == b"raced"


def test_export_dialog_confirms_replacing(window, photo, settle, errors, tmp_path, monkeypatch):
    from PySide6.QtWidgets import QFileDialog

    _relight_step(window, photo, settle)
    path = tmp_path / "clean.png"
    path.write_bytes(b"old")
    asked = []

    def fake_save(*args, **kwargs):  # the dialog itself asked "replace?" and the user said yes
        asked.append(args)
        return str(path), args[3]

    monkeypatch.setattr(QFileDialog, "getSaveFileName", staticmethod(fake_save))
    window.act_export_deshadow.trigger()
    settle()
    assert asked[0][1] == "Export shadows removed"
    assert asked[0][2].endswith("scene_shadows_removed.png")
    assert errors == [] and cv2.imread(str(path)).shape == (96, 128, 3)


def test_export_runs_off_the_ui_thread_with_progress_and_cancel(qtbot, window, photo, settle,
                                                                tmp_path, monkeypatch):  # fmt: skip
    _relight_step(window, photo, settle)
    threads: list[str] = []
    _slow_deshadow(monkeypatch, window.session, 0.6, threads)
    seen: list[tuple[str, float]] = []
    window.runner.progress.connect(
        lambda i, ch, st, f: seen.append((st, f)) if ch == "export_shadows_removed" else None
    )
    t0 = time.perf_counter()
    window.export_shadows_removed(str(tmp_path / "a.png"))
    assert time.perf_counter() - t0 < 0.3
    qtbot.waitUntil(lambda: bool(seen), timeout=10000)
    assert window.progress_bar.isVisible()
    assert [e.name for e in window.running_exports()] == ["a.png"]  # the quit prompt sees it
    settle()
    assert threads and threads[0] != threading.main_thread().name
    assert [f for _, f in seen] == [0.1, 0.8] and (tmp_path / "a.png").is_file()
    assert window.stage_label.text().startswith("Saved a.png")

    seen.clear()
    before = set(os.listdir(tmp_path))
    window.export_shadows_removed(str(tmp_path / "b.png"))
    qtbot.waitUntil(lambda: bool(seen), timeout=10000)
    window.runner.cancel("export_shadows_removed")  # as "Stop the export" when quitting does
    settle()
    assert set(os.listdir(tmp_path)) == before  # nothing written, no temp file either
    assert window.stage_label.text() == "Exporting shadows removed: cancelled"
