"""Step 2's "Relighting" (learned or physics): ``RelightSession.relight_mode`` in the app,
undoable, kept in projects (an older project without it opens with the learned relighting),
taken by the view, the still and the time-lapse exports as they are asked for, and greyed out
where the learned relighting cannot run."""

from __future__ import annotations

import json

import pytest

from app.state import Step, load_project
from tests.app.conftest import check_timelapse_export_takes, spy_relit_full, undo_texts
from tests.app.test_main_window import _confirm, _load


def _choose(window, mode: str) -> None:
    combo = window.relight_panel.relighting_combo
    combo.setCurrentIndex(combo.findData(mode))


def test_the_choice_sets_the_session_s_relighting_relights_and_is_undoable(
        window, photo, settle, monkeypatch):
    _load(window, photo, settle)
    _confirm(window, settle)
    window.save_project()
    rp, session = window.relight_panel, window.session
    assert session.relight_mode == "learned" and rp.relighting() == "learned"  # the default
    assert rp.learned_available()
    assert "learned relighting" in window.mode_label.text()
    seen = spy_relit_full(monkeypatch, session, lambda s: s.relight_mode)
    _choose(window, "physics")
    settle()
    assert session.relight_mode == "physics" and seen == ["physics"]  # the view relit
    assert "physics relighting" in window.mode_label.text()
    assert undo_texts(window)[-1] == "Relighting: Physics"
    assert window.has_unsaved_changes()
    window.act_undo.trigger()
    settle()
    assert session.relight_mode == "learned" and rp.relighting() == "learned"
    assert seen[-1] == "learned" and not window.has_unsaved_changes()
    window.act_redo.trigger()
    settle()
    assert session.relight_mode == "physics" and rp.relighting() == "physics"


def test_a_project_keeps_the_relighting_and_an_older_one_opens_learned(
        window, photo, settle, reopen):
    _load(window, photo, settle)
    _confirm(window, settle)
    _choose(window, "physics")
    settle()
    path = window.save_project()
    with open(path, encoding="utf-8") as f:
        data = json.load(f)
    assert data["relighting"] == "physics" and load_project(path).relighting == "physics"
    with reopen(path, Step.RELIGHT) as other:
        assert other.session.relight_mode == "physics"
        assert other.relight_panel.relighting() == "physics"
        assert not other.has_unsaved_changes()
    del data["relighting"]  # as a project saved before the choice
    with open(path, "w", encoding="utf-8") as f:
        json.dump(data, f)
    with reopen(path, Step.RELIGHT) as other:
        assert other.session.relight_mode == "learned"
        assert other.relight_panel.relighting() == "learned"
        assert not other.has_unsaved_changes()


def test_jobs_take_the_relighting_shown_when_asked_and_a_new_photo_takes_the_default(
        window, photo, settle, tmp_path, monkeypatch):
    from tests.app.conftest import make_photo

    _load(window, photo, settle)
    _confirm(window, settle)
    seen = spy_relit_full(monkeypatch, window.session, lambda s: s.relight_mode)
    window.session.relight_mode = "physics"  # as a job asked for before left it
    window.export_still(str(tmp_path / "still.png"))  # asked for with "Learned" shown
    _choose(window, "physics")  # before the export has run
    settle()
    assert (tmp_path / "still.png").exists()
    assert seen == ["learned", "physics"]  # the export, then the view
    window.open_path(make_photo(tmp_path / "other.jpg"))
    settle()
    assert window.relight_panel.relighting() == "learned"
    assert window.session.relight_mode == "learned"


def test_the_time_lapse_export_takes_the_relighting(window, photo, settle, tmp_path,
                                                    monkeypatch):
    _load(window, photo, settle)
    _confirm(window, settle)
    check_timelapse_export_takes(
        window, settle, tmp_path, monkeypatch, lambda session: session.relight_mode,
        lambda: _choose(window, "physics"), "physics")
    caption = window._timelapse_dialog.caption.text()  # the dialog says which (a user trial)
    assert "quick preview, physics relighting" in caption
    _choose(window, "learned")
    settle()
    assert "physics" not in window._timelapse_dialog.caption.text()  # (the default: unsaid)


@pytest.mark.parametrize("why", ["classic", "not installed"])
def test_without_the_relighting_model_learned_is_greyed_out(qtbot, settings, photo,
                                                            monkeypatch, tmp_path, why):
    """``--classic``, or no ``models/relight.onnx``: physics, and the learned choice greyed
    out saying why; the user's choice (learned) is what the project keeps, for a machine that
    can run it."""
    from app.main_window import MainWindow

    if why == "not installed":
        monkeypatch.setenv("OUTCAST_MODEL_DIR", str(tmp_path))  # no models at all
    w = MainWindow(settings=settings, preset="fast",
                   session_mode="classic" if why == "classic" else "auto")
    qtbot.addWidget(w)
    try:
        w.open_path(photo)
        qtbot.waitUntil(lambda: w.step is Step.ALIGN and not w.runner.busy(), timeout=30000)
        rp = w.relight_panel
        assert w.session.relight_mode == "physics" and rp.relighting() == "physics"
        assert not rp.learned_available()
        item = rp.relighting_combo.model().item(rp.relighting_combo.findData("learned"))
        assert ("--classic" if why == "classic" else "relight.onnx") in item.toolTip()
        assert w.project_state().relighting == "learned"
        w.set_relighting("learned", refresh=False)  # (an undo to a learned state)
        assert rp.relighting() == "physics"
    finally:
        w.runner.shutdown()


def test_a_broken_relighting_model_falls_back_to_physics_keeping_the_choice(
        window, photo, settle, errors, tmp_path, monkeypatch):
    """``relight.onnx`` damaged: said, physics from then on (greyed-out Learned), the user's
    choice kept in the project, and the next edit is recorded as itself (a review: a forced
    physics was recorded as "Relighting: Physics" on the next sun move)."""
    import shutil
    from pathlib import Path

    shipped = Path(__file__).resolve().parents[2] / "models"
    models = tmp_path / "models"
    models.mkdir()
    for f in shipped.iterdir():
        if f.suffix in (".onnx", ".json"):
            shutil.copy(f, models / f.name)
    (models / "relight.onnx").write_bytes(b"garbage")
    monkeypatch.setenv("OUTCAST_MODEL_DIR", str(models))
    _load(window, photo, settle)
    window.confirm_original_sun()  # makes the drag preview ready: loads L
    settle()
    assert errors and "relight.onnx" in errors[0][1]
    assert window.session_mode == "classic"
    rp = window.relight_panel
    assert rp.relighting() == "physics" and not rp.learned_available()
    assert window.session.relight_mode == "physics"
    assert window.project_state().relighting == "learned"
    window.relight_panel.sun_panel.set_sun(200.0, 30.0)
    window._on_target_sun_committed(200.0, 30.0)
    settle()
    assert undo_texts(window)[-1] == "Move new sun"
