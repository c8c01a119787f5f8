"""The time-lapse dialog's status line and what it asks of the worker."""

from __future__ import annotations

import pytest

from app.state import Step
from outcast_core.runtime.pipeline import timelapse as tl


def _relight(window, photo, settle) -> None:
    window.open_path(photo)
    settle()
    window.confirm_original_sun()
    settle()
    assert window.step is Step.RELIGHT


def _timelapse(window, frames: int, fmt: str = "mp4"):
    dialog = window.open_timelapse()
    s = dialog.settings()
    s.kind, s.frames, s.format, s.size = "sweep", frames, fmt, "working"
    dialog.load_settings(s)
    return dialog


def test_a_refused_export_is_said_in_the_status_line(window, photo, settle, errors, tmp_path):
    """A user trial exported 24 frames, then again to the same name without confirming: the
    export was refused (a warning) but the status line still said "Saved 24 frames"."""
    _relight(window, photo, settle)
    dialog = _timelapse(window, 3)
    settle()
    out = tmp_path / "clip.mp4"
    dialog.export(str(out))
    settle()
    assert dialog.status.text().startswith("Saved 3 frames")
    assert dialog.export(str(out)) is None  # not confirmed: refused
    assert errors[-1][0] == "Not exported" and "already exists" in errors[-1][1]
    assert errors.kinds[-1] == "warning"  # a file kept, nothing failed
    assert "Saved" not in dialog.status.text()
    assert "already exists" in dialog.status.text() and "Nothing was overwritten" in (
        dialog.status.text())
    assert dialog.export(photo, force=True) is None  # the photo itself, never
    assert "the photo you opened" in dialog.status.text()


def test_a_folder_that_cannot_be_written_is_named_not_the_temporary_file(
        window, photo, settle, errors, tmp_path, monkeypatch):
    """A user trial's export into a read-only folder said "Export failed: [Errno 1] Operation
    not permitted: '/…/.c.p20hmmbi.part.mp4'" under the dialog."""
    _relight(window, photo, settle)
    dialog = _timelapse(window, 3)
    settle()
    folder = tmp_path / "read-only"

    def refused(*args, **kwargs):
        raise PermissionError(1, "Operation not permitted", str(folder / ".c.p20hmmbi.part.mp4"))

    monkeypatch.setattr(tl, "render_timelapse", refused)
    dialog.export(str(folder / "c.mp4"))
    settle()
    assert dialog.last_result == "failed"
    text = dialog.status.text()
    assert text.startswith(f"Export failed: Operation not permitted: cannot write in the "
                           f"folder '{folder}'"), text
    assert ".part" not in text and "Errno" not in text
    assert "Choose a folder you can write to" in text
    assert errors and ".part" not in errors[-1][1]


def test_a_closed_dialog_draws_no_frame(window, photo, settle):
    """A user trial changed the quality with the time-lapse dialog closed: the status bar said
    "rendering time-lapse frame took …" (the closed dialog's path was recomputed for the new
    ground plane, and its frame drawn). Reopened, the frame is drawn."""
    _relight(window, photo, settle)
    dialog = _timelapse(window, 3)
    settle()
    assert dialog.preview.pixmap() is not None and not dialog.preview.pixmap().isNull()
    dialog.close()
    started = []
    window.runner.started.connect(lambda i, channel, d: started.append(channel))
    window.set_preset("balanced")
    settle()
    assert "preset" in started and "tl_preview" not in started
    assert "time-lapse" not in window.stage_label.text()
    window.open_timelapse()
    settle()
    assert started.count("tl_preview") == 1


def test_the_size_menu_lists_each_frame_size_once():
    """A user trial's menu for a 2016 x 1512 photo listed "4K · 2016 × 1512 (the photo's
    size)" and "Full resolution · 2016 × 1512"."""
    from app.timelapse_dialog import size_entries

    assert size_entries((1512, 2016), (288, 384)) == [
        ("working", "Working size · 384 × 288 (fastest)", ""),
        ("720p", "720p · 960 × 720", ""),
        ("1080p", "1080p · 1440 × 1080", ""),
        ("full", "Full resolution · 2016 × 1512", "The photo's size (4K would be larger)"),
    ]
    assert [entry[1:] for entry in size_entries((759, 1012), (192, 256))] == [
        ("Working size · 256 × 192 (fastest)", ""), ("720p · 960 × 720", ""),
        ("Full resolution · 1012 × 759", "The photo's size (1080p and 4K would be larger)")]
    assert [key for key, _, _ in size_entries((3000, 4000), (288, 384))] == [
        "working", "720p", "1080p", "4k", "full"]
    assert [key for key, _, _ in size_entries((96, 128), (96, 128))] == ["full"]  # tiny


def test_a_project_s_size_the_menu_lists_under_another_name_is_chosen(window, photo, settle):
    _relight(window, photo, settle)  # 128 x 96: every video size is the photo's
    dialog = window.open_timelapse()
    s = dialog.settings()
    s.size = "4k"
    dialog.load_settings(s)
    assert dialog.size() == "full" and dialog.frame_shape() == (96, 128)


def test_the_estimate_times_a_short_export_as_the_export_runs(window, photo, settle,
                                                              monkeypatch):
    """A user trial: 3 s estimated for an export of 11.6 s at working size, 11 s for one of
    7.6 s at 720p. The estimate came from the last interactive relighting's stage times (its
    networks on every core, one after the other), not from what an export does (one thread
    each, side by side, then the frame made at its size and encoded). It now times a short
    export of the path at the chosen size and format in the worker, and shows the video's
    length."""
    import os

    _relight(window, photo, settle)
    calls = []
    real = tl.render_timelapse

    def spy(session, samples, path, **kw):
        calls.append((len(samples), os.path.dirname(path), kw["size"], kw["fmt"]))
        return real(session, samples, path, **kw)

    monkeypatch.setattr(tl, "render_timelapse", spy)
    window.session.timings.update({"shadow": 1000.0, "relight": 1000.0})  # not what it reads
    dialog = _timelapse(window, 48, "gif")
    assert dialog.estimate() is None and "timing a short export…" in (
        dialog.estimate_label.text())
    settle()
    assert calls == [(4, calls[0][1], "full", "gif")]  # (a tiny photo: working size is full)
    assert not os.path.exists(calls[0][1])  # its temporary folder is gone
    seconds = dialog.estimate()
    assert seconds is not None and seconds < 1000.0
    text = dialog.estimate_label.text()
    assert text.startswith("48 frames of 128 × 96, 4 s at 12 fps: about ") and text.endswith(
        " s to export")
    dialog.frames_box.setValue(96)  # more frames of the same: no new timing
    dialog.fps_box.setValue(24.0)
    settle()
    assert len(calls) == 1 and dialog.estimate() > seconds
    assert dialog.estimate_label.text().startswith("96 frames of 128 × 96, 4 s at 24 fps")
    dialog.format_combo.setCurrentIndex(dialog.format_combo.findData("mp4"))  # timed again
    settle()
    assert [c[3] for c in calls] == ["gif", "mp4"]


def test_an_estimate_that_cannot_be_timed_is_said_without_an_error_dialog(
        window, photo, settle, errors, monkeypatch):
    _relight(window, photo, settle)

    def broken(*args, **kwargs):
        raise RuntimeError("no encoder")

    monkeypatch.setattr(tl, "render_timelapse", broken)
    dialog = _timelapse(window, 5)
    settle()
    assert not errors and dialog.estimate() is None
    assert dialog.estimate_label.text().endswith(": the export could not be timed")


def test_a_timing_under_way_is_not_submitted_again(window, photo, settle, monkeypatch):
    """Settings changed while a short export is timed (frames, fps: the same key) do not queue
    the same timing again behind it (a review: each change resubmitted it, and the worker ran
    the whole short export twice); a timing that fails is said for its own settings."""
    import threading
    import time as _time

    from PySide6.QtWidgets import QApplication

    _relight(window, photo, settle)
    calls = []
    real = tl.render_timelapse
    running, release = threading.Event(), threading.Event()

    def spy(session, samples, path, **kw):
        calls.append(kw["fmt"])
        if kw["fmt"] == "mp4":
            raise OSError("no encoder")
        running.set()
        release.wait(10.0)  # the timing is under way while the settings change
        return real(session, samples, path, **kw)

    monkeypatch.setattr(tl, "render_timelapse", spy)
    submitted = []
    submit = window.runner.submit

    def counting(channel, fn, description=""):
        submitted.append(channel)
        return submit(channel, fn, description)

    monkeypatch.setattr(window.runner, "submit", counting)
    dialog = _timelapse(window, 48, "gif")
    deadline = _time.monotonic() + 10.0
    while not running.is_set() and _time.monotonic() < deadline:
        QApplication.processEvents()
        _time.sleep(0.01)
    assert running.is_set()
    before = submitted.count("tl_estimate")
    dialog.frames_box.setValue(60)  # while the timing runs
    dialog.fps_box.setValue(24.0)
    release.set()
    settle()
    # Not submitted again; the preview the changes asked for ran first (the timing gives way to
    # any other job, workers.JobQueue.background) and the same timing ran again after it.
    assert submitted.count("tl_estimate") == before
    assert calls in (["gif"], ["gif", "gif"])
    gif_key = dialog._estimate_key()
    assert gif_key in dialog._timings  # timed in the end, preempted or not
    calls.clear()
    dialog.format_combo.setCurrentIndex(dialog.format_combo.findData("mp4"))
    settle()
    assert calls == ["mp4"]
    assert "could not be timed" in dialog.estimate_label.text()
    assert gif_key not in dialog._untimed and dialog._estimate_key() in dialog._untimed


def _wait_for(event) -> None:
    """Deliver the GUI's events until the worker sets ``event`` (a job under way)."""
    import time as _time

    from PySide6.QtWidgets import QApplication

    deadline = _time.monotonic() + 10.0
    while not event.is_set() and _time.monotonic() < deadline:
        QApplication.processEvents()
        _time.sleep(0.01)
    assert event.is_set()


def test_a_timing_of_other_settings_is_cancelled_for_the_new_one(window, photo, settle,
                                                                  monkeypatch):
    """A review: the short export timed for the settings before (another format) ran to its
    end ahead of the one for the settings now, its result for nobody."""
    import threading

    _relight(window, photo, settle)
    cancels: list[threading.Event] = []
    real = tl.render_timelapse
    running, release = threading.Event(), threading.Event()

    def spy(session, samples, path, **kw):
        cancels.append(kw["cancel"])
        if len(cancels) == 1:
            running.set()
            release.wait(10.0)  # the gif's timing is under way while the format changes
        return real(session, samples, path, **kw)

    monkeypatch.setattr(tl, "render_timelapse", spy)
    dialog = _timelapse(window, 48, "gif")
    _wait_for(running)
    gif_key = dialog._estimate_key()
    try:
        dialog.format_combo.setCurrentIndex(dialog.format_combo.findData("mp4"))
        assert cancels[0].is_set()  # the gif's timing: for nobody now
    finally:
        release.set()
    settle()
    assert len(cancels) == 2 and not cancels[1].is_set()
    assert gif_key not in dialog._timings and dialog.estimate() is not None


def test_an_estimate_that_fails_is_not_submitted_again(window, photo, settle, errors,
                                                       monkeypatch):
    """A review: the session's settings were set outside the timing's ``try``; when they failed
    the job failed, the dialog forgot the settings it was timing and timed them again, for
    ever. The failure is said for these settings, once."""
    _relight(window, photo, settle)

    def broken(edits):
        raise RuntimeError("no shadows")

    monkeypatch.setattr(window.session, "set_shadow_edits", broken)
    runner, submitted = window.runner, []
    real_submit = runner.submit

    def counting(channel, fn, description=""):
        if channel == "tl_estimate":
            submitted.append(channel)
            if len(submitted) > 3:  # (without the fix: ends the loop, not the test)
                return 0
        return real_submit(channel, fn, description)

    monkeypatch.setattr(runner, "submit", counting)
    dialog = _timelapse(window, 5)
    settle()
    assert len(submitted) == 1
    assert dialog.estimate() is None and dialog._estimate_key() in dialog._untimed
    assert dialog.estimate_label.text().endswith(": the export could not be timed")
    dialog.frames_box.setValue(6)  # the same settings' timing: not asked again
    settle()
    assert len(submitted) == 1


def test_the_dialogs_frames_and_bar_leave_the_users_status_alone(window, photo, settle):
    """A user trial: scrubbing put "Ready · rendering time-lapse frame took 0.00 s" (a cached
    frame) over what the relighting had said, and the export bar said "0 %" before any
    export."""
    _relight(window, photo, settle)
    said = window.stage_label.text()
    assert said.startswith("Ready")
    dialog = _timelapse(window, 6)
    settle()
    # Idle, no bar: an empty one looked like a text field (a user trial).
    assert not dialog.progress.isTextVisible() and dialog.progress.isHidden()
    dialog.scrubber.setValue(3)
    settle()
    dialog.scrubber.setValue(0)
    settle()
    assert "time-lapse frame" not in window.stage_label.text()
    assert window.stage_label.text() == said


def test_a_dark_frame_says_to_meter_the_new_light(window, photo, settle, monkeypatch):
    """A day's first and last frames came out near black with the photo's exposure kept, and
    nothing said why (a user trial): a dark preview frame's caption names step 2's "Meter the
    new light"; metered, or a bright frame, it says nothing of it."""
    from app.timelapse_dialog import DARK_FRAME_WORDS

    _relight(window, photo, settle)
    shares: list[float] = []

    def share(photo_srgb, frame_srgb) -> float:
        shares.append(level)
        return level

    monkeypatch.setattr("app.timelapse_dialog.exposure_level", share)
    level = 0.2
    dialog = _timelapse(window, 3)
    settle()
    assert shares and dialog.caption.text().endswith(DARK_FRAME_WORDS)
    assert dialog.caption.text().startswith("Frame 1/3")
    window.relight_panel.meter_check.setChecked(True)  # the frame is drawn again, metered
    settle()
    assert "Meter the new light" not in dialog.caption.text()
    window.relight_panel.meter_check.setChecked(False)
    level = 0.9
    dialog.scrubber.setValue(1)
    settle()
    assert dialog.caption.text().startswith("Frame 2/3")
    assert "Meter the new light" not in dialog.caption.text()


def test_from_photo_says_why_it_is_off_for_a_night_time_clock(window, photo, settle):
    """A photo whose EXIF time puts the sun below the horizon solves no heading (a
    robustness trial's night-time copy solved one 28 degrees off): "From photo" is off, and
    its tooltip says why; with a daytime clock it is on."""
    import datetime as dt
    from dataclasses import replace

    from app.timelapse_dialog import SOLVE_TIP

    _relight(window, photo, settle)
    exif = window.loaded.exif
    night = dt.datetime(2019, 8, 21, 19, 0, tzinfo=dt.UTC)  # 02:00 at the pool
    window.loaded = replace(window.loaded, exif=replace(exif, latitude=7.83, longitude=98.3,
                                                        capture_time=night))
    dialog = window.open_timelapse()
    settle()
    assert not dialog.solve_button.isEnabled()
    assert dialog.solve_button.toolTip().startswith("Off: the sun was 60.")
    assert "check the camera's clock and time zone" in dialog.solve_button.toolTip()
    dialog.close()
    day = dt.datetime(2019, 8, 21, 3, 57, tzinfo=dt.UTC)
    window.loaded = replace(window.loaded, exif=replace(window.loaded.exif, capture_time=day))
    dialog = window.open_timelapse()
    settle()
    assert dialog.solve_button.isEnabled() and dialog.solve_button.toolTip() == SOLVE_TIP


def test_a_utc_offset_guessed_from_the_longitude_says_so_and_follows_the_longitude(
        window, photo, settle):
    """A photo without a time zone in its EXIF: the dialog guessed the local time's offset
    from the longitude without a word, kept it when the user typed the place's longitude, and
    a project saved it as if it had been typed. Now the hint says it is a guess, a longitude
    typed re-guesses it, an offset typed stays, and only a typed one is kept."""
    import datetime as dt
    from dataclasses import replace

    _relight(window, photo, settle)
    exif = window.loaded.exif
    wall = dt.datetime(2019, 8, 21, 10, 57)  # a bare camera clock: no zone
    window.loaded = replace(window.loaded, exif=replace(exif, latitude=7.83, longitude=98.3,
                                                        capture_time=wall, tz_offset=None))
    dialog = window.open_timelapse()
    settle()
    assert dialog.offset_box.value() == 7.0
    assert "UTC+7\u00a0h is guessed from the longitude" in dialog.place_hint.text()
    assert window._timelapse_to_save().utc_offset is None  # a guess: guessed again next time
    dialog.lon_box.setValue(-3.7)  # the place typed: the guess follows it
    assert dialog.offset_box.value() == 0.0
    assert "UTC+0\u00a0h is guessed" in dialog.place_hint.text()
    dialog.offset_box.setValue(2.0)  # the user's own: kept, and no longer called a guess
    dialog.lon_box.setValue(-3.0)
    assert dialog.offset_box.value() == 2.0
    assert "guessed" not in dialog.place_hint.text()
    assert window._timelapse_to_save().utc_offset == 2.0
    dialog.close()
    zoned = dt.datetime(2019, 8, 21, 10, 57, tzinfo=dt.timezone(dt.timedelta(hours=7)))
    window.timelapse_settings = replace(window.timelapse_settings, utc_offset=None)
    window.loaded = replace(window.loaded, exif=replace(
        window.loaded.exif, longitude=98.3, capture_time=zoned,
        tz_offset=dt.timedelta(hours=7)))
    dialog = window.open_timelapse()
    settle()
    assert dialog.offset_box.value() == 7.0
    assert "from the photo's EXIF" in dialog.place_hint.text()
    assert "guessed" not in dialog.place_hint.text()


def test_the_sweep_starts_from_the_two_suns_until_the_user_sets_it(window, photo, settle,
                                                                    tmp_path):
    """The dialog offered a sweep from (80, 15) to (280, 50) whatever the suns were (a user
    trial). It now runs from the confirmed sun to the new sun; that is filled in, not the
    user's: not unsaved work, not kept by a project, filled in again from the suns of the day
    when the dialog reopens. A sweep the user sets is kept."""
    from app.state import load_project

    _relight(window, photo, settle)
    a0, e0 = window.original_sun.azimuth, window.original_sun.elevation
    window.relight_panel.sun_panel.set_sun(200.0, 30.0)
    settle()
    dialog = window.open_timelapse()
    settle()
    assert dialog.kind_combo.currentData() == "sweep"
    assert (dialog.from_az.value(), dialog.from_el.value()) == pytest.approx((a0 % 360, e0),
                                                                             abs=0.1)
    assert (dialog.to_az.value(), dialog.to_el.value()) == pytest.approx((200.0, 30.0), abs=0.1)
    assert "the time-lapse settings" not in window.unsaved_parts()
    window.project_state()  # (reads the dialog back, as saving does)
    assert window._timelapse_to_save().sweep_from.azimuth == 80.0  # filled in: not kept
    dialog.close()
    window.relight_panel.sun_panel.set_sun(120.0, 20.0)
    settle()
    dialog = window.open_timelapse()
    settle()
    assert (dialog.to_az.value(), dialog.to_el.value()) == pytest.approx((120.0, 20.0), abs=0.1)
    dialog.to_el.setValue(45.0)  # the user's own
    path = window.save_project(str(tmp_path / "p.outcast.json"))
    assert path and load_project(path).timelapse.sweep_to.elevation == 45.0
    dialog.close()


def test_a_sweep_filled_in_again_is_not_unsaved_work(window, photo, settle, tmp_path):
    """A user trial: saved, the new sun moved, the dialog opened and closed (the sweep filled
    in again from the moved sun), the move undone: the window stayed modified, "your changes
    to the time-lapse settings are not saved"."""
    _relight(window, photo, settle)
    window.relight_panel.sun_panel.set_sun(270.0, 30.0)
    settle()
    window.open_timelapse().close()
    settle()
    assert window.save_project(str(tmp_path / "p.outcast.json"))
    assert not window.has_unsaved_changes()
    before = window.undo_stack.index()
    window.relight_panel.sun_panel.set_sun(200.0, 20.0)
    settle()
    dialog = window.open_timelapse()
    settle()
    assert dialog.to_az.value() == pytest.approx(200.0, abs=0.1)
    dialog.close()
    while window.undo_stack.index() > before:
        window.undo_stack.undo()
        settle()
    assert "the time-lapse settings" not in window.unsaved_parts()
    assert not window.has_unsaved_changes()


def test_the_estimate_is_whole_at_the_dialog_s_smallest_size(window, photo, settle, qtbot):
    """At the dialog's smallest size the estimate's second line ("... s to export") was cut
    in half (a user trial): the label has room for both lines of a long estimate."""
    _relight(window, photo, settle)
    dialog = _timelapse(window, 48)
    settle()
    dialog.estimate_label.setText("48 frames of 1012 × 759, 4 s at 12 fps: about 15 s to "
                                  "export")  # (the trial's)
    dialog.resize(dialog.minimumSizeHint())
    qtbot.wait(50)
    label = dialog.estimate_label
    assert label.height() >= label.heightForWidth(label.width()) > 0
