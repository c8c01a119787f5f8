"""Step 2's "Keep the photo's light": ``RelightSession.daylight`` off in the app, undoable, kept
in projects (an older project without it opens with the new sun's daylight), and taken by the
view, the still and the time-lapse exports as they are asked for."""

from __future__ import annotations

import json

import pytest

from app.state import ProjectState, Step, load_project
from tests.app.conftest import check_timelapse_export_takes, spy_relit_full, undo_texts
from tests.app.test_main_window import _confirm, _load


def test_the_checkbox_sets_the_session_s_light_relights_and_is_undoable(
        window, photo, settle, monkeypatch):
    _load(window, photo, settle)
    _confirm(window, settle)
    window.save_project()
    rp, session = window.relight_panel, window.session
    assert session.daylight and not rp.keep_light_check.isChecked()  # the default: daylight
    assert rp.keep_light_check.text() == "Keep the photo's light"
    assert "weaker and redder" in rp.keep_light_check.toolTip()
    assert not window.has_unsaved_changes()
    seen = spy_relit_full(monkeypatch, session, lambda s: s.daylight)
    rp.keep_light_check.setChecked(True)
    settle()
    assert session.daylight is False and seen == [False]  # the view relit in the photo's light
    assert undo_texts(window)[-1] == "Keep the photo's light"
    assert window.has_unsaved_changes() and window.isWindowModified()
    window.act_undo.trigger()
    settle()
    assert session.daylight is True and not rp.keep_light_check.isChecked()
    assert seen[-1] is True
    assert not window.has_unsaved_changes()
    window.act_redo.trigger()
    settle()
    assert session.daylight is False and rp.keep_light_check.isChecked()
    assert seen[-1] is False
    rp.keep_light_check.setChecked(False)
    settle()
    assert session.daylight is True
    assert undo_texts(window)[-1] == "Take the new sun's daylight"


def test_a_project_keeps_the_photo_s_light(window, photo, settle, reopen):
    _load(window, photo, settle)
    _confirm(window, settle)
    window.relight_panel.keep_light_check.setChecked(True)
    settle()
    path = window.save_project()
    assert not window.has_unsaved_changes()
    with open(path, encoding="utf-8") as f:
        assert json.load(f)["daylight"] is False
    assert load_project(path).daylight is False
    with reopen(path, Step.RELIGHT) as other:
        assert other.session.daylight is False
        assert other.relight_panel.keep_light_check.isChecked()
        assert not other.has_unsaved_changes()


def test_an_older_project_without_the_key_opens_in_the_new_sun_s_daylight(
        window, photo, settle, reopen):
    _load(window, photo, settle)
    _confirm(window, settle)
    window.relight_panel.keep_light_check.setChecked(True)
    settle()
    path = window.save_project()
    with open(path, encoding="utf-8") as f:
        data = json.load(f)
    del data["daylight"]  # as a project saved before the setting
    with open(path, "w", encoding="utf-8") as f:
        json.dump(data, f)
    assert load_project(path).daylight is True
    with reopen(path, Step.RELIGHT) as other:
        assert other.session.daylight is True
        assert not other.relight_panel.keep_light_check.isChecked()
        assert not other.has_unsaved_changes()


def test_the_project_format_reads_the_light():
    d = ProjectState(image_path="a.jpg", daylight=False).to_dict()
    assert d["outcast_project"] == 1 and d["daylight"] is False
    assert ProjectState.from_dict(d).daylight is False
    del d["daylight"]
    assert ProjectState.from_dict(d).daylight is True
    with pytest.raises(ValueError, match="daylight"):
        ProjectState.from_dict({**d, "daylight": "no"})


def test_jobs_take_the_light_shown_when_asked_and_a_new_photo_takes_the_daylight(
        window, photo, settle, tmp_path, monkeypatch):
    """A still asked for in the new sun's daylight stays so when the box is ticked before it
    runs (as the exposure); another photo opens with the default."""
    from tests.app.conftest import make_photo

    _load(window, photo, settle)
    _confirm(window, settle)
    seen = spy_relit_full(monkeypatch, window.session, lambda s: s.daylight)
    window.export_still(str(tmp_path / "still.png"))
    window.relight_panel.keep_light_check.setChecked(True)  # before the export has run
    settle()
    assert (tmp_path / "still.png").exists()
    assert seen[0] is True and seen[1:] == [False]  # the export, then the view
    window.open_path(make_photo(tmp_path / "other.jpg"))
    settle()
    assert not window.relight_panel.keep_light_check.isChecked()
    assert window.session.daylight is True


def test_the_time_lapse_export_takes_the_light(window, photo, settle, tmp_path, monkeypatch):
    _load(window, photo, settle)
    _confirm(window, settle)
    check_timelapse_export_takes(
        window, settle, tmp_path, monkeypatch, lambda session: session.daylight,
        lambda: window.relight_panel.keep_light_check.setChecked(True), False)
