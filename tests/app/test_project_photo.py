"""A project's photo: moved (located again, the work kept), or replaced by another picture
under its name (a warning before the project's work is laid over it)."""

from __future__ import annotations

import json
import os
import shutil

import numpy as np
import pytest
from PIL import Image
from PySide6.QtWidgets import QFileDialog

from app.leave_prompts import CANCEL, CONTINUE, LOCATE
from app.state import PhotoIdentity, Step, load_project, project_path_for
from tests.app.conftest import make_photo

EDITS = [{"x": 0.3, "y": 0.7, "shadow": False}, {"x": 0.6, "y": 0.2, "shadow": True}]


def _project(image: str, **extra) -> str:
    """A project of ``image`` saved in step 2 with two shadow corrections (as written by
    OutCast; ``extra`` replaces fields, e.g. ``photo``)."""
    path = str(project_path_for(image))
    data = {"outcast_project": 1, "image": os.path.basename(image), "preset": "fast",
            "original_sun": {"azimuth": 100.0, "elevation": 35.0},
            "target_sun": {"azimuth": 220.0, "elevation": 25.0}, "shadow_edits": EDITS,
            **extra}
    with open(path, "w", encoding="utf-8") as f:
        json.dump(data, f)
    return path


@pytest.fixture
def file_dialog(monkeypatch):
    """The photo a "Locate photo…" file dialog answers (``file_dialog.answer``), and what it was
    asked (``file_dialog.asked``: title, folder)."""
    from types import SimpleNamespace

    record = SimpleNamespace(answer="", asked=[])

    def fake(parent, title, folder, *args, **kwargs):
        record.asked.append((title, folder))
        return record.answer, ""

    monkeypatch.setattr(QFileDialog, "getOpenFileName", staticmethod(fake))
    return record


def _identity(photo: str) -> dict:
    from outcast_core.runtime.io.imageio import read_image

    return PhotoIdentity.of(read_image(photo, keep_uint8=True).image_srgb).to_dict()


def test_a_moved_photo_is_located_and_the_project_keeps_its_work(
        window, photo, settle, tmp_path, leave_answers, file_dialog, errors):
    """A user trial's project whose photo had moved was a dead end ("Could not open the
    photo"); opening the photo from its new place started afresh, without the project's suns
    and corrections."""
    project = _project(photo, photo=_identity(photo))
    moved = tmp_path / "elsewhere" / "renamed.jpg"
    moved.parent.mkdir()
    shutil.move(photo, moved)
    leave_answers.script = [LOCATE]
    file_dialog.answer = str(moved)
    window.open_path(project)
    settle()
    assert not errors
    assert [q.title for q in leave_answers.asked] == ["The project's photo is missing"]
    assert "scene.jpg" in leave_answers.asked[0].text
    assert file_dialog.asked == [("Locate scene.jpg", str(tmp_path))]
    assert window.image_path == str(moved) and window.step is Step.RELIGHT
    assert window.original_sun.as_tuple() == pytest.approx((100.0, 35.0))
    assert window.relight_panel.sun_panel.sun() == pytest.approx((220.0, 25.0))
    assert [(e.x, e.y, e.shadow) for e in window.shadow_edits] == [
        (0.3, 0.7, False), (0.6, 0.2, True)]
    # The project now says another place: modified, so saving (or leaving) records it.
    assert window.has_unsaved_changes() and window.isWindowModified()
    assert window.stage_label.text().startswith(  # first: a long message is cut at its end
        f"Opened renamed.jpg for the project, whose photo was {photo}: save the project")
    window.undo_stack.undo()  # (nothing to undo: still modified)
    assert window.has_unsaved_changes()
    assert window.save_project() == project  # the opened project, not asked to replace it
    assert [q.title for q in leave_answers.asked] == ["The project's photo is missing"]
    assert load_project(project).image_path == str(moved)
    assert not window.has_unsaved_changes()


def test_a_missing_photo_not_located_leaves_the_work_on_screen(
        window, photo, settle, tmp_path, leave_answers, file_dialog, errors):
    other = make_photo(tmp_path / "other.jpg")
    window.open_path(other)
    settle()
    project = _project(photo)
    os.remove(photo)
    leave_answers.script = [CANCEL]
    window.open_path(project)
    settle()
    assert not file_dialog.asked and not errors
    assert window.image_path == other and window.step is Step.ALIGN
    assert "Not opened" in window.stage_label.text()
    leave_answers.script = [LOCATE]  # then the file dialog's Cancel
    window.open_path(project)
    settle()
    assert file_dialog.asked and window.image_path == other and not errors


def test_a_project_warns_when_its_photo_is_another_picture(
        window, photo, settle, tmp_path, leave_answers, errors):
    """A user trial's project laid the ski slope's suns and corrections over the pool, a file
    of the same name: the project records its photo's size and a fingerprint of it."""
    window.open_path(photo)
    settle()
    saved = window.save_project()
    recorded = load_project(saved).photo
    assert (recorded.width, recorded.height) == (128, 96) and len(recorded.fingerprint) == 128
    other = make_photo(tmp_path / "other.jpg")
    window.open_path(other)
    settle()
    project = _project(photo, photo=recorded.to_dict())
    upside_down = np.asarray(Image.open(photo))[::-1].copy()
    Image.fromarray(upside_down).save(photo, quality=92)  # replaced: another picture
    leave_answers.script = [CANCEL]
    window.open_path(project)
    settle()
    question = leave_answers.asked[-1]
    assert question.title == "Another photo than the project's?"
    assert "scene.jpg" in question.text and "not the one" in question.text
    assert window.image_path == other and window.step is Step.ALIGN  # as it was
    assert "Not opened" in window.stage_label.text()
    leave_answers.script = [CONTINUE]
    window.open_path(project)
    settle()
    assert window.image_path == photo and window.step is Step.RELIGHT
    assert len(window.shadow_edits) == 2 and window.has_unsaved_changes()
    assert window.stage_label.text().startswith(
        "Opened scene.jpg for the project, which was saved with another photo: save")
    window.save_project()
    assert load_project(project).photo.to_dict() == _identity(photo)  # the picture now
    asked = len(leave_answers.asked)
    window.open_path(project)  # saved for this picture: no question now
    settle()
    assert len(leave_answers.asked) == asked and not window.has_unsaved_changes()
    assert not errors


def test_a_located_photo_of_another_size_is_questioned(
        window, photo, settle, tmp_path, leave_answers, file_dialog):
    project = _project(photo, photo=_identity(photo))
    os.remove(photo)
    file_dialog.answer = make_photo(tmp_path / "wrong.jpg", 96, 128)
    leave_answers.script = [LOCATE, CANCEL]
    window.open_path(project)
    settle()
    assert [q.title for q in leave_answers.asked] == [
        "The project's photo is missing", "Another photo than the project's?"]
    assert "96 × 128 pixels" in leave_answers.asked[1].text
    assert window.step is Step.EMPTY


def test_an_older_project_without_the_photo_s_identity_opens_as_before(
        window, photo, settle, leave_answers, errors):
    project = _project(photo)
    window.open_path(project)
    settle()
    assert not leave_answers.asked and not errors
    assert window.step is Step.RELIGHT and not window.has_unsaved_changes()
