"""The status bar: the message wins the room over the stage timings, the running job's progress
keeps its percentage in view, and what it says and shows is the job that is running."""

from __future__ import annotations

import pytest
from PySide6.QtWidgets import QApplication

from app.main_window import SHADOW_TOOL_HINTS, STAGE_WORDS
from app.state import Step

#: The timings a user trial saw take the bar at 1024 x 700.
TIMINGS = ("relight 1 ms · full_resolution 0.25 s · found_shadows_detail 0.17 s · "
           "deshadow_full 1.01 s")
MODES = "learned shadows · learned relighting · depth: model"


def _bar(qtbot, window, size):
    window.resize(*size)
    window.mode_label.setText(MODES)
    window.zoom_label.setText("30 %")
    window.photo_notes_button.show()
    window.timings_label.setText(TIMINGS)


def _laid_out(window) -> None:
    """The window's and the status bar's layouts, with what changed in them (their posted
    layout requests)."""
    QApplication.sendPostedEvents()
    window.layout().activate()
    window.statusBar().layout().activate()


@pytest.mark.parametrize("message", ["Ready · relighting took 0.25 s", "Stroke cancelled",
                                     "Ready · the click changed nothing"])
def test_the_message_takes_its_room_before_the_timings(qtbot, window, message):
    """At 1024 x 700 a user trial read "Ready · relig…" while the developer timings took the
    bar. A message that fits is shown whole; the timings get what it leaves, cut by whole
    entries, all of them in ``text()`` (and the tooltip)."""
    _bar(qtbot, window, (1024, 700))
    label, timings = window.stage_label, window.timings_label
    label.setText(message)
    _laid_out(window)
    assert label.shown() == message
    assert label.width() >= label.fontMetrics().horizontalAdvance(message)
    assert timings.text() == TIMINGS
    shown = timings.shown()
    assert shown != TIMINGS and (shown == "" or shown.endswith(" · …"))
    assert TIMINGS.startswith(shown.removesuffix("…"))  # whole entries, from the first
    assert timings.fontMetrics().horizontalAdvance(shown) <= timings.contentsRect().width()
    assert label.geometry().right() < timings.geometry().left()
    window.resize(2400, 700)  # room for both: both whole
    _laid_out(window)
    assert timings.shown() == TIMINGS and label.shown() == message


def test_a_tools_hint_is_not_cut_to_nothing_by_the_timings(qtbot, window):
    """With a correction tool on (its hint in the status bar) the message's width was 0 at
    1024 x 700: the hint, the "changed nothing" notes and "Stroke cancelled" were not seen. The
    hint now has the bar up to the permanent widgets; the timings have none of it."""
    _bar(qtbot, window, (1024, 700))
    hint = SHADOW_TOOL_HINTS["shadow"]
    label = window.stage_label
    label.setText(hint)
    _laid_out(window)
    assert label.shown().startswith("Click inside a shadow the app missed")
    assert window.timings_label.shown() == "" and window.timings_label.width() == 0
    notes = window.photo_notes_button.geometry()  # the first of the permanent widgets
    assert notes.left() - label.geometry().right() < 20  # (the layout's spacing)


def test_an_exports_progress_keeps_its_percentage_in_view(qtbot, window):
    """At 1280 px a user trial read "Exporting shadows removed: removing …" with the percentage
    cut off: it is the bar's own text, beside the message, never cut with it."""
    _bar(qtbot, window, (1280, 800))
    runner, bar = window.runner, window.progress_bar
    name = "a_rather_long_photo_name_from_a_phone_20240612_143210_shadows_removed.png"
    runner.started.emit(1, "export_shadows_removed", f"Exporting {name}")
    runner.progress.emit(1, "export_shadows_removed", "removing shadows", 0.45)
    _laid_out(window)
    assert bar.isVisible()
    assert window.stage_label.text() == f"{STAGE_WORDS['export_shadows_removed']}: removing shadows"
    assert bar.isTextVisible() and bar.text() == "45 %"
    assert bar.width() >= bar.fontMetrics().horizontalAdvance("100 %") + 20
    assert window.statusBar().rect().contains(bar.geometry())
    assert window.stage_label.geometry().right() < bar.geometry().left()
    window.resize(800, 600)  # narrower: the message is cut, not the percentage
    _laid_out(window)
    assert bar.text() == "45 %" and bar.width() >= bar.minimumWidth()
    assert window.statusBar().rect().contains(bar.geometry())
    assert window.stage_label.shown().endswith("…")
    runner.idle.emit()
    assert not bar.isVisible()


def test_a_quality_switch_says_the_job_that_runs(qtbot, window, settle, tmp_path):
    """After a quality switch the status bar kept "Changing quality: ready 100 %" and its bar
    at 100 % while the rest of the switch and the view's job that followed ran (a user trial).
    Each step of the switch says what it does ("ready" is not one), and the job after it has
    its own words and no bar left over: the de-shadow view's job shows a busy bar once it
    reports (a user trial waited 8 s on a 27 MP photo with no sign of work)."""
    from tests.app.conftest import make_photo

    photo = make_photo(tmp_path / "wide.jpg", 400, 300)  # fast and balanced differ in size
    window.open_path(photo)
    settle()
    window.confirm_original_sun()
    settle()
    assert window.step is Step.RELIGHT
    window.relight_panel.set_view("shadows_removed")
    settle()
    seen: list[tuple[str, str, str, bool, int, int]] = []
    runner, bar = window.runner, window.progress_bar

    def record(kind: str, channel: str) -> None:  # after the window's own slot
        seen.append((kind, channel, window.stage_label.text(), bar.isVisible(), bar.value(),
                     bar.maximum()))

    runner.started.connect(lambda i, ch, d: record("started", ch))
    runner.progress.connect(lambda i, ch, st, f: record("progress", ch))
    window.set_preset("balanced")
    settle()
    switch = [s for s in seen if s[1] == "preset"]
    steps = [text for kind, _, text, _, _, _ in switch if kind == "progress"]
    assert steps and all(text.startswith("Changing quality: ") for text in steps)
    assert not any("ready" in text for text in steps)
    assert steps[-1] == "Changing quality: camera tilt"
    assert all(value < 100 for _, _, _, _, value, _ in switch)
    after = [s for s in seen if s[1] != "preset"]
    assert after and after[0][0] == "started" and not after[0][3]  # its words, no bar
    assert any(kind == "progress" for kind, *_ in after)
    for kind, _, text, visible, _, most in after:
        assert text == "Removing the photo's shadows…"
        if kind == "progress":  # busy, not a percentage
            assert visible and most == 0
    window.runner.idle.emit()
    assert not bar.isVisible()


@pytest.mark.parametrize("change", ["light", "relighting"])
def test_a_change_with_the_time_lapse_dialog_open_ends_ready(window, photo, settle, change):
    """A light or relighting switched with the time-lapse dialog open: the view's relighting
    and then the dialog's frame run; the status says the relighting's end, not "Relighting…"
    for good (a user trial: the dialog's frame, which says nothing in the status bar, was
    still waiting when the relighting ended, so the end was never said)."""
    window.open_path(photo)
    settle()
    window.confirm_original_sun()
    settle()
    window.open_timelapse()
    settle()
    rp = window.relight_panel
    if change == "light":
        rp.keep_light_check.setChecked(True)
    else:
        rp.relighting_combo.setCurrentIndex(rp.relighting_combo.findData("physics"))
    settle()
    assert window.stage_label.text().startswith("Ready · relighting took")


def test_the_zoom_reads_as_a_share_of_the_photo_in_every_view(qtbot, window, settle,
                                                               tmp_path):
    """The buffer views show a working-size image: fitted to the same room, its zoom read
    several times the photo's (367 % against 47 %: a user trial). The zoom is read against
    the photo's own pixels in every view."""
    import numpy as np
    from PIL import Image

    rng = np.random.default_rng(0)
    img = rng.integers(120, 200, (480, 640, 3), dtype=np.uint8)
    img[300:360, 100:500] //= 3  # a shadow-like band
    photo = tmp_path / "big.png"
    Image.fromarray(img).save(photo)
    window.open_path(str(photo))
    settle()
    window.confirm_original_sun()
    settle()
    rp = window.relight_panel

    def zoom_in(view: str) -> int:
        rp.set_view(view)
        settle()
        qtbot.wait(50)
        return int(window.zoom_label.text().split()[1])

    output, depth = zoom_in("output"), zoom_in("depth")
    assert window.canvas.image_size().width() < window.loaded.original_size[0]  # (working)
    assert abs(depth - output) <= 2, (output, depth)
