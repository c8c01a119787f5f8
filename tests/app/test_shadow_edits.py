"""Correcting the found shadows in step 2: "Not a shadow" / "Mark shadow" clicks on the photo,
undoable, saved in the project, applied by every job that depends on the found shadows."""

from __future__ import annotations

import json
import math
import threading

import cv2
import numpy as np
import pytest
from PIL import Image
from PySide6.QtCore import QEvent, QPoint, QPointF, Qt
from PySide6.QtGui import QImage, QMouseEvent
from PySide6.QtWidgets import QApplication

from app.state import ProjectState, Step, load_project
from outcast_core.runtime.pipeline.photo_shadows import (
    MAX_SHADOW_CLICKS,
    MAX_SHADOW_EDITS,
    ShadowEdit,
)
from tests.app.conftest import make_photo, undo_texts
from tests.app.test_main_window import _confirm, _load, _timelapse

# make_photo's dark band (found as a shadow) at 128 x 96, and where to click it.
BAND = (slice(66, 72), slice(34, 62))
BAND_XY = (0.375, 0.7)
# The lighter patch of _photo_with_missed_shadow (not found: the band's darkness sets the
# threshold), and where to click it.
PATCH = (slice(54, 59), slice(82, 113))
PATCH_XY = (0.75, 0.585)
LIT = (slice(80, 90), slice(70, 120))  # lit ground below both


def _photo_with_missed_shadow(path) -> str:
    """make_photo with a second, lighter shadow (x 0.75) right of the band that is not found."""
    make_photo(path)
    a = np.asarray(Image.open(path)).astype(np.float32)
    a[53:60, 79:115] *= 0.75
    Image.fromarray(np.clip(a, 0, 255).astype(np.uint8)).save(path, quality=92)
    return str(path)


@pytest.fixture
def patch_photo(tmp_path):
    return _photo_with_missed_shadow(tmp_path / "patch.jpg")


def _rgb(img: QImage) -> np.ndarray:
    img = img.convertToFormat(QImage.Format.Format_RGB888)
    a = np.frombuffer(img.constBits(), np.uint8).reshape(img.height(), img.bytesPerLine())
    return a[:, : 3 * img.width()].reshape(img.height(), img.width(), 3).copy()


def _alpha(img: QImage) -> np.ndarray:
    img = img.convertToFormat(QImage.Format.Format_RGBA8888)
    a = np.frombuffer(img.constBits(), np.uint8).reshape(img.height(), img.bytesPerLine())
    return a[:, : 4 * img.width()].reshape(img.height(), img.width(), 4)[..., 3].copy()


def _widget_point(canvas, x: float, y: float) -> QPoint:
    """Where the image point at fractions ``(x, y)`` lies on the canvas."""
    r = canvas.image_rect()
    return QPoint(round(r.left() + x * r.width()), round(r.top() + y * r.height()))


def _click(qtbot, window, x: float, y: float) -> None:
    qtbot.mouseClick(window.canvas, Qt.MouseButton.LeftButton,
                     pos=_widget_point(window.canvas, x, y))


def _mouse(canvas, kind: QEvent.Type, pos: QPoint, buttons: Qt.MouseButton,
           button: Qt.MouseButton = Qt.MouseButton.LeftButton) -> None:
    if kind == QEvent.Type.MouseMove:
        button = Qt.MouseButton.NoButton
    event = QMouseEvent(kind, QPointF(pos), canvas.mapToGlobal(QPointF(pos)), button, buttons,
                        Qt.KeyboardModifier.NoModifier)
    QApplication.sendEvent(canvas, event)


def _shadows_view(window, photo, settle, view: str = "shadows_found") -> None:
    _load(window, photo, settle)
    _confirm(window, settle)
    window.relight_panel.set_view(view)
    settle()


def _tool(window, key: str) -> None:
    window.relight_panel.shadow_tool_buttons[key].click()
    assert window.relight_panel.shadow_tool() == key


def _drop_the_band(qtbot, window, photo, settle) -> None:
    """Step 2's "Shadows found", and "Not a shadow" on the photo's dark band."""
    _shadows_view(window, photo, settle)
    _tool(window, "not_shadow")
    _click(qtbot, window, *BAND_XY)
    settle()


def _handed_edits(window, settle) -> tuple:
    """The corrections the next job hands to the session (every job hands its own: a kept
    image shown after undo asks the worker for nothing)."""
    view = window.relight_panel.view()
    window.relight_panel.set_view("output")
    settle()
    edits = window.session.shadow_edits
    window.relight_panel.set_view(view)
    settle()
    return edits


def test_edit_menu_names_the_corrections():
    from app.history import EditState, describe_change

    a = EditState("relight", (10.0, 30.0), (10.0, 30.0), (90.0, 30.0), "fast")
    not_shadow = ShadowEdit(0.5, 0.5, shadow=False)
    b = EditState("relight", (10.0, 30.0), (10.0, 30.0), (90.0, 30.0), "fast",
                  shadow_edits=(not_shadow,))
    c = EditState("relight", (10.0, 30.0), (10.0, 30.0), (90.0, 30.0), "fast",
                  shadow_edits=(not_shadow, ShadowEdit(0.2, 0.8, shadow=True)))
    assert describe_change(a, b) == "Not a shadow"
    assert describe_change(b, c) == "Mark shadow"
    assert describe_change(c, a) == "Clear shadow corrections"
    stroke = tuple(ShadowEdit(0.1 + 0.01 * i, 0.5, False, radius=0.02) for i in range(40))
    d = EditState("relight", (10.0, 30.0), (10.0, 30.0), (90.0, 30.0), "fast",
                  shadow_edits=(*c.shadow_edits, *stroke))
    assert describe_change(c, d) == "Paint not a shadow"
    e = EditState("relight", (10.0, 30.0), (10.0, 30.0), (90.0, 30.0), "fast",
                  shadow_edits=tuple(ShadowEdit(s.x, s.y, True, s.radius) for s in stroke))
    assert describe_change(a, e) == "Paint shadow"


def test_not_a_shadow_drops_the_found_region(qtbot, window, photo, settle, errors):
    _shadows_view(window, photo, settle)
    rp = window.relight_panel
    assert rp.shadow_tools.isVisible() and not rp.clear_shadow_edits_button.isEnabled()
    assert window.session.shadow_probability[BAND].mean() > 0.8
    overlay = _alpha(window.canvas.overlay())
    assert overlay[BAND].mean() > 128  # the band is tinted as found
    _tool(window, "not_shadow")
    assert window.stage_label.text().startswith(
        "Click a marked area that is not a shadow (a dark object, foliage)")
    canvas = window.canvas  # a crosshair over the photo, the usual cursor beside it
    _mouse(canvas, QEvent.Type.MouseMove, _widget_point(canvas, *BAND_XY), Qt.MouseButton.NoButton)
    assert canvas.cursor().shape() == Qt.CursorShape.CrossCursor
    _mouse(canvas, QEvent.Type.MouseMove, QPoint(2, 2), Qt.MouseButton.NoButton)
    assert canvas.cursor().shape() == Qt.CursorShape.ArrowCursor
    _click(qtbot, window, *BAND_XY)
    settle()
    assert errors == []
    (edit,) = window.shadow_edits
    assert not edit.shadow and edit.x == pytest.approx(BAND_XY[0], abs=0.01)
    assert edit.y == pytest.approx(BAND_XY[1], abs=0.01)
    assert window.session.shadow_edits == window.shadow_edits
    assert window.session.shadow_probability[BAND].mean() < 0.1
    assert _alpha(window.canvas.overlay())[BAND].mean() < 30  # the shown overlay follows
    assert undo_texts(window)[-1] == "Not a shadow"
    assert window.has_unsaved_changes() and window.isWindowModified()
    assert rp.clear_shadow_edits_button.isEnabled() and rp.shadow_tool() == "not_shadow"
    # Said once its result is shown, not only the tool's hint (a user trial).
    assert window.stage_label.text() == 'Ready · applied "Not a shadow" · Ctrl+Z takes it back'


def test_clear_and_undo_say_what_they_did(qtbot, window, photo, settle):
    """"Clear corrections" says it cleared them and how to get them back; an undo says
    "Undone", not what the correction did."""
    _shadows_view(window, photo, settle)
    _tool(window, "not_shadow")
    _click(qtbot, window, *BAND_XY)
    settle()
    window.relight_panel.clear_shadow_edits_button.click()
    settle()
    assert window.shadow_edits == ()
    assert window.stage_label.text() == (
        "Ready · cleared the shadow corrections · Ctrl+Z brings them back")
    window.act_undo.trigger()
    settle()
    assert len(window.shadow_edits) == 1
    assert window.stage_label.text() == "Undone · Clear shadow corrections"


def test_mark_shadow_adds_a_missed_shadow_and_lifts_it(qtbot, window, patch_photo, settle):
    _shadows_view(window, patch_photo, settle, "shadows_removed")
    assert window.session.shadow_probability[PATCH].mean() < 0.1  # missed
    before = _rgb(window.canvas.after()).astype(np.float32)
    _tool(window, "shadow")
    assert window.stage_label.text().startswith("Click inside a shadow the app missed")
    _click(qtbot, window, *PATCH_XY)
    settle()
    assert window.shadow_edits[-1].shadow and undo_texts(window)[-1] == "Mark shadow"
    p = window.session.shadow_probability
    assert p[PATCH].mean() > 0.9 and p[LIT].mean() < 0.1  # the patch, not the ground round it
    after = _rgb(window.canvas.after()).astype(np.float32)  # redrawn without asking
    assert after[PATCH].mean() > before[PATCH].mean() + 15
    assert abs(after[LIT].mean() - before[LIT].mean()) < 4


def test_a_click_that_marks_much_of_the_photo_says_so(qtbot, window, patch_photo, settle,
                                                      monkeypatch):
    """A "Mark shadow" click that fills more than LARGE_MARK_SHARE of the photo says how much,
    and how to take it back (a user trial's click on a shadow's soft edge filled a whole court);
    a smaller one says nothing of it."""
    import app.main_window as mw

    _shadows_view(window, patch_photo, settle)
    _tool(window, "shadow")
    _click(qtbot, window, *PATCH_XY)
    settle()
    share = window.session.marked_share()
    assert 0.005 < share < mw.LARGE_MARK_SHARE
    assert "% of the photo" not in window.stage_label.text()
    window.act_undo.trigger()
    settle()
    assert window.shadow_edits == ()  # (the session takes them with the next job)
    monkeypatch.setattr(mw, "LARGE_MARK_SHARE", share / 2)
    _click(qtbot, window, PATCH_XY[0] + 0.02, PATCH_XY[1])  # beside the first click
    settle()
    text = window.stage_label.text()
    assert text == (f"Ready · marked {share * 100:.0f} % of the photo as shadow · "
                    "Ctrl+Z takes it back")
    # The same click again after an undo: its images are kept, and it still says so.
    window.act_undo.trigger()
    settle()
    assert window.stage_label.text() == "Undone · Mark shadow"
    _click(qtbot, window, PATCH_XY[0] + 0.02, PATCH_XY[1])
    settle()
    assert window.stage_label.text() == text


def test_a_kept_view_says_ready_not_an_earlier_timing(qtbot, window, photo, settle):
    """Views whose images are kept come back at once: the status says Ready (or the tool's
    hint), not the timing of the job that made the view shown before (a review)."""
    _shadows_view(window, photo, settle, "shadows_removed")
    window.relight_panel.set_view("shadows_found")
    settle()
    window.relight_panel.set_view("shadows_removed")  # kept: no job
    settle()
    assert window.stage_label.text() == "Ready"
    _tool(window, "shadow")
    window.relight_panel.set_view("shadows_found")  # kept too
    settle()
    assert window.stage_label.text().startswith("Click inside a shadow the app missed")


def test_a_click_on_the_before_after_line_says_so_and_adds_nothing(qtbot, window, patch_photo,
                                                                   settle):
    """The split line takes a press to move the line; a click tool's click there (not moved)
    was ignored without a word (a user trial)."""
    _shadows_view(window, patch_photo, settle, "shadows_removed")
    _tool(window, "shadow")
    canvas = window.canvas
    assert canvas.split() is not None
    r = canvas.image_rect()
    on_line = QPoint(round(r.left() + r.width() * canvas.split()), round(r.center().y()))
    qtbot.mouseClick(canvas, Qt.MouseButton.LeftButton, pos=on_line)
    settle()
    assert window.shadow_edits == ()
    assert "before | after line" in window.stage_label.text()
    # A drag of the line says nothing of the kind.
    window.stage_label.setText("")
    _mouse(canvas, QEvent.Type.MouseButtonPress, on_line, Qt.MouseButton.LeftButton)
    _mouse(canvas, QEvent.Type.MouseMove, on_line + QPoint(40, 0), Qt.MouseButton.LeftButton)
    _mouse(canvas, QEvent.Type.MouseButtonRelease, on_line + QPoint(40, 0),
           Qt.MouseButton.NoButton)
    settle()
    assert window.shadow_edits == () and "before | after" not in window.stage_label.text()


def test_a_correction_that_changes_nothing_is_said(qtbot, window, photo, settle):
    _shadows_view(window, photo, settle)
    _tool(window, "not_shadow")
    count, clean = window.undo_stack.count(), window.undo_stack.isClean()
    _click(qtbot, window, 0.85, 0.9)  # lit ground, far from any found shadow
    settle()
    assert "no found shadow there" in window.stage_label.text()
    # Not counted, not an undo step, no unsaved change (a user trial saw all three).
    assert window.shadow_edits == () and window.undo_stack.count() == count
    assert window.undo_stack.isClean() == clean
    assert not window.relight_panel.clear_shadow_edits_button.isEnabled()
    _click(qtbot, window, *BAND_XY)  # and the next, useful click works as before
    settle()
    assert len(window.shadow_edits) == 1 and window.undo_stack.count() == count + 1


def test_a_correction_that_changes_nothing_keeps_what_redo_offered(qtbot, window, photo,
                                                                   settle):
    """A useful click undone, then a click on lit ground: the idle click is taken back, and
    the first one can still be redone (its push had dropped the redo step: a user trial)."""
    _shadows_view(window, photo, settle)
    _tool(window, "not_shadow")
    _click(qtbot, window, *BAND_XY)
    settle()
    done = window.shadow_edits
    assert len(done) == 1
    window.undo_stack.undo()
    settle()
    assert window.shadow_edits == () and window.undo_stack.redoText() == "Not a shadow"
    _click(qtbot, window, 0.85, 0.9)  # lit ground: changes nothing
    settle()
    assert "no found shadow there" in window.stage_label.text()
    assert window.shadow_edits == () and window.undo_stack.redoText() == "Not a shadow"
    window.undo_stack.redo()
    settle()
    assert window.shadow_edits == done


def test_undo_and_redo_restore_the_edits_and_the_image(qtbot, window, photo, settle):
    _shadows_view(window, photo, settle)
    first = window.canvas.overlay()
    _tool(window, "not_shadow")
    _click(qtbot, window, *BAND_XY)
    settle()
    edits = window.shadow_edits
    dropped = _alpha(window.canvas.overlay())
    assert dropped[BAND].mean() < 30
    window.act_undo.trigger()
    settle()
    assert window.shadow_edits == ()
    assert window.canvas.overlay() is first  # the kept image, shown at once
    assert window.undo_stack.redoText() == "Not a shadow"
    # No job ran: the status says the undo, not the undone click's timing (a user trial).
    assert window.stage_label.text() == "Undone · Not a shadow"
    assert not window.relight_panel.clear_shadow_edits_button.isEnabled()
    window.act_redo.trigger()
    settle()
    assert window.shadow_edits == edits
    assert window.stage_label.text() == "Redone · Not a shadow"
    assert np.array_equal(_alpha(window.canvas.overlay()), dropped)
    assert window.relight_panel.clear_shadow_edits_button.isEnabled()
    assert _handed_edits(window, settle) == edits
    window.act_undo.trigger()
    settle()
    assert _handed_edits(window, settle) == ()
    assert window.session.shadow_probability[BAND].mean() > 0.8


def test_clear_corrections_is_one_undo_step(qtbot, window, patch_photo, settle):
    _shadows_view(window, patch_photo, settle)
    _tool(window, "not_shadow")
    _click(qtbot, window, *BAND_XY)
    _tool(window, "shadow")
    _click(qtbot, window, *PATCH_XY)
    settle()
    assert len(window.shadow_edits) == 2 and window.relight_panel.shadow_tool() == "shadow"
    window.relight_panel.clear_shadow_edits_button.click()
    settle()
    assert window.shadow_edits == () and _handed_edits(window, settle) == ()
    assert undo_texts(window)[-3:] == ["Not a shadow", "Mark shadow", "Clear shadow corrections"]
    assert not window.relight_panel.clear_shadow_edits_button.isEnabled()
    window.act_undo.trigger()
    settle()
    assert len(_handed_edits(window, settle)) == 2


def test_edits_are_saved_and_restored_with_the_project(qtbot, window, photo, settle, reopen):
    _drop_the_band(qtbot, window, photo, settle)
    edits = window.shadow_edits
    saved = window.save_project()
    assert not window.has_unsaved_changes()
    with open(saved, encoding="utf-8") as f:
        data = json.load(f)
    assert data["shadow_edits"] == [{"x": round(edits[0].x, 5), "y": round(edits[0].y, 5),
                                     "shadow": False}]
    assert load_project(saved).shadow_edits == tuple(
        ShadowEdit(round(e.x, 5), round(e.y, 5), e.shadow) for e in edits)
    with reopen(saved, Step.RELIGHT) as other:
        assert len(other.shadow_edits) == 1 and not other.shadow_edits[0].shadow
        assert other.session.shadow_edits == other.shadow_edits
        assert other.session.shadow_probability[BAND].mean() < 0.1
        assert other.relight_panel.view() == "shadows_found"
        assert not other.has_unsaved_changes()  # reopened as saved
        assert other.relight_panel.clear_shadow_edits_button.isEnabled()
        other.act_undo.trigger()  # the history starts at the reopened state
        assert other.shadow_edits == other.session.shadow_edits


def test_an_older_project_has_no_edits_and_a_bad_value_is_refused(window, photo, errors,
                                                                   tmp_path):
    base = ProjectState(image_path=photo).to_dict()
    del base["shadow_edits"]  # saved before corrections existed
    assert ProjectState.from_dict(base).shadow_edits == ()
    assert ProjectState.from_dict({**base, "shadow_edits": None}).shadow_edits == ()
    bad_values = (5, [{"x": 0.5, "y": 0.5}], [{"x": 1.5, "y": 0.5, "shadow": True}],
                  [{"x": 10**400, "y": 0.5, "shadow": True}], ["a"],
                  [{"x": 0.5, "y": 0.5, "shadow": 1}],
                  [{"x": 0.5, "y": 0.5, "shadow": True, "r": 0.9}],
                  [{"x": 0.1, "y": 0.1, "shadow": True}] * (MAX_SHADOW_EDITS + 1),
                  [{"x": 0.1, "y": 0.1, "shadow": True}] * (MAX_SHADOW_CLICKS + 1),
                  [{"x": 0.5, "y": 0.5, "shadow": True, "start": True}])
    for bad in bad_values:
        with pytest.raises(ValueError, match="^shadow_edits: ") as info:
            ProjectState.from_dict({**base, "shadow_edits": bad})
        assert type(info.value) is ValueError and "\n" not in str(info.value)
    project = tmp_path / "scene.outcast.json"
    project.write_text(json.dumps({**base, "shadow_edits": [{"x": 2, "y": 0, "shadow": True}]}))
    window.open_path(str(project))
    assert len(errors) == 1 and "shadow_edits" in errors[0][1]
    assert window.step is Step.EMPTY


def test_another_photo_clears_the_edits_realigning_keeps_them(qtbot, window, photo, settle,
                                                             tmp_path):
    _drop_the_band(qtbot, window, photo, settle)
    edits = window.shadow_edits
    window.back_to_align()  # re-aligning the sun and a new preset keep them
    settle()
    assert window.shadow_edits == edits
    _confirm(window, settle)
    window.set_preset("balanced")
    settle()
    assert window.shadow_edits == edits and window.session.shadow_edits == edits
    assert window.session.shadow_probability[BAND].mean() < 0.1
    other = make_photo(tmp_path / "other.jpg")
    _load(window, other, settle)
    assert window.shadow_edits == () and window.session.shadow_edits == ()
    assert not window.relight_panel.clear_shadow_edits_button.isEnabled()
    _confirm(window, settle)
    assert window.session.shadow_probability[BAND].mean() > 0.8


def test_tools_are_unavailable_in_step_1_and_in_other_views(qtbot, window, photo, settle):
    rp = window.relight_panel
    _load(window, photo, settle)
    assert not window.shadow_tools_available() and not rp.shadow_tools.isVisible()
    assert not window.add_shadow_edit(*BAND_XY, shadow=False)
    _confirm(window, settle)
    assert rp.view() == "output" and rp.shadow_tools.isHidden()
    rp.set_view("shadows_removed")
    settle()
    assert rp.shadow_tools.isVisible()
    _tool(window, "not_shadow")
    assert window.canvas.click_tool() and window.act_end_shadow_tool.isEnabled()
    rp.set_view("output")  # the tool ends with the view
    settle()
    assert rp.shadow_tool() == "" and rp.shadow_tools.isHidden()
    assert not window.canvas.click_tool() and not window.act_end_shadow_tool.isEnabled()
    _click(qtbot, window, *BAND_XY)
    assert not window.add_shadow_edit(*BAND_XY, shadow=False)
    rp.set_view("shadows_found")
    settle()
    _tool(window, "shadow")
    window.back_to_align()  # step 1: off too
    settle()
    assert rp.shadow_tool() == "" and not window.canvas.click_tool()
    _click(qtbot, window, *BAND_XY)
    settle()
    assert window.shadow_edits == () and "Not a shadow" not in undo_texts(window)


def test_tools_are_exclusive_and_esc_ends_them(qtbot, window, photo, settle):
    _shadows_view(window, photo, settle)
    rp = window.relight_panel
    _tool(window, "not_shadow")
    _tool(window, "shadow")
    assert not rp.shadow_tool_buttons["not_shadow"].isChecked()
    rp.shadow_tool_buttons["shadow"].click()  # both may be off
    assert rp.shadow_tool() == "" and not window.canvas.click_tool()
    _tool(window, "not_shadow")
    assert all(b.toolTip() for b in rp.shadow_tool_buttons.values())
    window.activateWindow()
    window.canvas.setFocus()
    qtbot.keyClick(window.canvas, Qt.Key.Key_Escape)
    assert rp.shadow_tool() == "" and not window.canvas.click_tool()


def test_the_middle_button_pans_with_a_tool_on_and_adds_nothing(qtbot, window, photo, settle):
    _shadows_view(window, photo, settle)
    _tool(window, "not_shadow")
    canvas = window.canvas
    start = _widget_point(canvas, *BAND_XY)
    left = canvas.image_rect().left()
    middle = Qt.MouseButton.MiddleButton
    _mouse(canvas, QEvent.Type.MouseButtonPress, start, middle, middle)
    for dx in (10, 25, 40):
        _mouse(canvas, QEvent.Type.MouseMove, start + QPoint(dx, 5), middle)
    _mouse(canvas, QEvent.Type.MouseButtonRelease, start + QPoint(40, 5), Qt.MouseButton.NoButton,
           middle)
    settle()
    assert canvas.image_rect().left() == pytest.approx(left + 40)  # it panned
    assert window.shadow_edits == () and window.undo_stack.count() == 1  # (the confirm)
    # A left drag from beside the image pans too (nothing to paint there).
    outside = QPoint(round(canvas.image_rect().right()) + 5, start.y())
    _mouse(canvas, QEvent.Type.MouseButtonPress, outside, Qt.MouseButton.LeftButton)
    _mouse(canvas, QEvent.Type.MouseMove, outside + QPoint(-30, 0), Qt.MouseButton.LeftButton)
    _mouse(canvas, QEvent.Type.MouseButtonRelease, outside + QPoint(-30, 0),
           Qt.MouseButton.NoButton)
    assert canvas.image_rect().left() == pytest.approx(left + 10)
    assert window.shadow_edits == ()
    _click(qtbot, window, 1.02, 0.5)  # outside the image (right of it): nothing either
    assert window.shadow_edits == ()
    _click(qtbot, window, *BAND_XY)  # a click still works after the drag
    settle()
    assert len(window.shadow_edits) == 1


def test_the_split_line_still_drags_with_a_tool_on(qtbot, window, photo, settle):
    _shadows_view(window, photo, settle, "shadows_removed")
    _tool(window, "shadow")
    canvas = window.canvas
    r = canvas.image_rect()
    x = QPoint(round(r.left() + 0.5 * r.width()), round(r.top() + 0.8 * r.height()))
    _mouse(canvas, QEvent.Type.MouseButtonPress, x, Qt.MouseButton.LeftButton)
    _mouse(canvas, QEvent.Type.MouseMove, x + QPoint(round(0.2 * r.width()), 0),
           Qt.MouseButton.LeftButton)
    _mouse(canvas, QEvent.Type.MouseButtonRelease, x + QPoint(round(0.2 * r.width()), 0),
           Qt.MouseButton.NoButton)
    assert canvas.split() == pytest.approx(0.7, abs=0.02) and window.shadow_edits == ()


def test_the_relit_view_and_its_undo_use_the_edits(qtbot, window, photo, settle):
    _drop_the_band(qtbot, window, photo, settle)
    window.relight_panel.set_view("output")
    window.relight_panel.sun_panel.set_sun(300.0, 70.0)  # another sun: the band's shade goes
    window.request_relight(preview=False)
    settle()
    edited = _rgb(window.canvas.after()).astype(np.float32)
    window.act_undo.trigger()  # undone in the relit view: it is drawn again
    settle()
    assert window.session.shadow_edits == ()
    undone = _rgb(window.canvas.after()).astype(np.float32)
    # Drawn again with the found shadows (and the light estimated from them) as they are now.
    assert np.abs(undone[BAND] - edited[BAND]).mean() > 1.5


def test_exports_use_the_edits_asked_with_them(qtbot, window, settle, errors, tmp_path):
    photo = make_photo(tmp_path / "big.jpg", 400, 300)
    _shadows_view(window, photo, settle)
    src = window.loaded.image_srgb.astype(np.float32)
    band = (slice(200, 220), slice(110, 190))  # the dark band at 400 x 300
    _tool(window, "not_shadow")
    _click(qtbot, window, *BAND_XY)
    settle()
    # Hold the worker, ask for the export, then correct again before it runs: the export
    # keeps the corrections it was asked with.
    gate = threading.Event()
    window.runner.submit("hold", lambda ctx: gate.wait(10), "Holding")
    path = str(tmp_path / "out.png")
    window.export_shadows_removed(path)
    window.act_undo.trigger()  # the band is a shadow again, for later jobs
    gate.set()
    settle()
    assert errors == [] and window.last_export == path
    rgb = cv2.imread(path)[..., ::-1].astype(np.float32)
    assert abs(rgb[band].mean() - src[band].mean()) < 6  # not lifted: "not a shadow"
    window.export_shadows_removed(str(tmp_path / "lifted.png"))
    settle()
    lifted = cv2.imread(str(tmp_path / "lifted.png"))[..., ::-1].astype(np.float32)
    assert lifted[band].mean() > src[band].mean() + 20


def test_still_and_timelapse_jobs_set_the_edits(qtbot, window, photo, settle, monkeypatch,
                                                tmp_path):
    from outcast_core.runtime.pipeline import timelapse as tl

    _drop_the_band(qtbot, window, photo, settle)
    edits = window.shadow_edits
    session = window.session
    seen: dict[str, tuple] = {}
    real_full = session.relight_full

    def relight_full(*args, **kwargs):
        seen["still"] = session.shadow_edits
        return real_full(*args, **kwargs)

    def render(session_, samples, path, **kwargs):
        seen["timelapse"] = session_.shadow_edits
        raise RuntimeError("not rendered in this test")

    monkeypatch.setattr(session, "relight_full", relight_full)
    monkeypatch.setattr(tl, "render_timelapse", render)
    session.set_shadow_edits(())  # as if another job had left other corrections
    window.export_still(str(tmp_path / "still.png"))
    settle()
    assert seen["still"] == edits
    dialog = _timelapse(window, 3)
    settle()
    session.set_shadow_edits(())
    dialog.scrubber.setValue(2)  # the preview job
    settle()
    assert session.shadow_edits == edits
    session.set_shadow_edits(())
    dialog.export(str(tmp_path / "clip.mp4"))
    settle()
    assert seen["timelapse"] == edits


def test_moving_the_new_sun_over_kept_images_submits_no_work(qtbot, window, photo, settle):
    """The views of the found shadows do not depend on the new sun: a drag there shows the
    kept images and asks the worker for nothing (it queued a job per mouse move); an undo
    there still brings the session's corrections along."""
    _drop_the_band(qtbot, window, photo, settle)
    submitted = []
    real = window.runner.submit
    window.runner.submit = lambda channel, *a, **k: submitted.append(channel) or real(
        channel, *a, **k)
    panel = window.relight_panel.sun_panel
    az, el = panel.sun()
    for step in range(5):  # as a drag does: the dial's preview signal for each move
        window._on_target_sun_changed(az + 10.0 * (step + 1), el, True)
    window._on_target_sun_committed(az + 50.0, el)
    settle()
    assert submitted.count("relight") == 0
    window.act_undo.trigger()
    settle()
    assert _handed_edits(window, settle) == ()


def test_the_panel_says_what_the_tool_that_is_on_does(qtbot, window, photo, settle):
    """In full, in the panel: the status bar cut it in a 1280-px window (a user trial)."""
    from app.panels import SHADOW_TOOL_IDLE, SHADOW_TOOLS

    _shadows_view(window, photo, settle)
    hint = window.relight_panel.shadow_tool_hint
    assert hint.text() == SHADOW_TOOL_IDLE
    for key, _text, _tip, words in SHADOW_TOOLS:
        _tool(window, key)
        assert hint.text() == words
    window.relight_panel.set_shadow_tool("")
    assert hint.text() == SHADOW_TOOL_IDLE


# ---------------------------------------------------------------- the brush


def _drag(window, points: list[tuple[float, float]]) -> None:
    """Press on the first image point, move through the others (as fractions; big jumps, as a
    fast drag's mouse events come), release on the last."""
    canvas = window.canvas
    left = Qt.MouseButton.LeftButton
    _mouse(canvas, QEvent.Type.MouseButtonPress, _widget_point(canvas, *points[0]), left)
    for x, y in points[1:]:
        _mouse(canvas, QEvent.Type.MouseMove, _widget_point(canvas, x, y), left)
    _mouse(canvas, QEvent.Type.MouseButtonRelease, _widget_point(canvas, *points[-1]),
           Qt.MouseButton.NoButton)


def test_a_drag_paints_one_stroke_that_undo_takes_back_whole(qtbot, window, photo, settle,
                                                               reopen):
    """"Not a shadow" painted over the left part of the band: only what the brush covered is
    dropped (a click drops the whole band), one undo step, sent to the worker once."""
    _shadows_view(window, photo, settle)
    _tool(window, "not_shadow")
    rp, canvas = window.relight_panel, window.canvas
    rp.set_brush(0.03)
    assert canvas.brush() == pytest.approx(0.03)
    count, left = window.undo_stack.count(), canvas.image_rect().left()
    submitted = []
    real = window.runner.submit
    window.runner.submit = lambda channel, *a, **k: submitted.append(channel) or real(
        channel, *a, **k)
    path = [(0.27, 0.7), (0.30, 0.69), (0.36, 0.71), (0.40, 0.7)]
    unpainted = _rgb(window.grab().toImage())
    _mouse(canvas, QEvent.Type.MouseButtonPress, _widget_point(canvas, *path[0]),
           Qt.MouseButton.LeftButton)
    for x, y in path[1:]:
        _mouse(canvas, QEvent.Type.MouseMove, _widget_point(canvas, x, y),
               Qt.MouseButton.LeftButton)
    assert canvas.painting() and submitted == []  # drawn on the canvas, not sent yet
    painted = _rgb(window.grab().toImage())
    _mouse(canvas, QEvent.Type.MouseButtonRelease, _widget_point(canvas, *path[-1]),
           Qt.MouseButton.NoButton)
    assert not canvas.painting() and submitted == ["relight"]  # once, on release
    settle()
    window.runner.submit = real
    assert canvas.image_rect().left() == left  # painted, not panned
    dabs = window.shadow_edits
    assert len(dabs) >= 8 and all(not d.shadow and d.radius == pytest.approx(0.03) for d in dabs)
    # No gap however far apart the mouse events: a dab at least every half radius.
    gaps = [np.hypot((a.x - b.x) * 128, (a.y - b.y) * 96)
            for a, b in zip(dabs, dabs[1:], strict=False)]
    assert max(gaps) <= 0.5 * 0.03 * 128 + 1e-6
    assert dabs[0].x == pytest.approx(0.27, abs=0.01) and dabs[-1].x == pytest.approx(0.40,
                                                                                       abs=0.01)
    assert window.undo_stack.count() == count + 1
    assert undo_texts(window)[-1] == "Paint not a shadow"
    assert rp.shadow_edits_label.text() == "1 correction"  # a stroke, not its dabs
    assert window.has_unsaved_changes()
    p = window.session.shadow_probability
    assert p[66:72, 38:48].max() < 0.05  # under the brush: dropped
    assert p[66:72, 58:62].mean() > 0.8  # the band beyond it: still a shadow
    assert _alpha(canvas.overlay())[66:72, 38:48].mean() < 30
    # While painting, the stroke showed on the canvas (a translucent band over the photo).
    on_path = canvas.mapTo(window, _widget_point(canvas, 0.33, 0.7))
    seen = [a[on_path.y() - 1:on_path.y() + 2, on_path.x() - 1:on_path.x() + 2].astype(int)
            for a in (unpainted, painted)]
    assert np.abs(seen[1] - seen[0]).mean() > 40
    # A "Mark shadow" stroke back over the band's dropped part and a click on what is left of
    # the band: three corrections, three undo steps.
    _tool(window, "shadow")
    _drag(window, [(0.33, 0.55), (0.33, 0.7)])  # from lit ground into the band
    settle()
    assert undo_texts(window)[-1] == "Paint shadow"
    prob = window.session.shadow_probability
    assert prob[64:67, 41:44].min() > 0.9  # the band's, fading out where the stroke ends:
    assert 0.5 < prob[67:70, 41:44].min() < 0.9  # a soft brush
    assert window.session.shadow_probability[50:59, 41:44].max() < 0.05  # not the lit ground
    _tool(window, "not_shadow")
    _click(qtbot, window, 0.48, 0.7)
    settle()
    assert undo_texts(window)[-1] == "Not a shadow" and window.shadow_edits[-1].radius == 0
    assert rp.shadow_edits_label.text() == "3 corrections"
    window.act_undo.trigger()
    window.act_undo.trigger()
    settle()
    assert window.shadow_edits == dabs
    window.act_undo.trigger()  # the whole stroke at once
    settle()
    assert window.shadow_edits == () and _handed_edits(window, settle) == ()
    assert window.session.shadow_probability[66:72, 38:48].mean() > 0.8
    window.act_redo.trigger()
    settle()
    assert window.shadow_edits == dabs and _handed_edits(window, settle) == dabs
    # Saved in the project, with each dab's radius.
    saved = window.save_project()
    with open(saved, encoding="utf-8") as f:
        data = json.load(f)
    assert len(data["shadow_edits"]) == len(dabs)
    assert all(d["r"] == pytest.approx(0.03) for d in data["shadow_edits"])
    with reopen(saved, Step.RELIGHT) as other:
        assert len(other.shadow_edits) == len(dabs)
        assert other.session.shadow_probability[66:72, 38:48].max() < 0.05
        assert other.relight_panel.shadow_edits_label.text() == "1 correction"


def test_a_press_without_a_drag_is_still_a_region_click(qtbot, window, photo, settle):
    _shadows_view(window, photo, settle)
    _tool(window, "not_shadow")
    canvas = window.canvas
    at = _widget_point(canvas, *BAND_XY)
    _mouse(canvas, QEvent.Type.MouseButtonPress, at, Qt.MouseButton.LeftButton)
    _mouse(canvas, QEvent.Type.MouseMove, at + QPoint(1, 0), Qt.MouseButton.LeftButton)  # a jitter
    _mouse(canvas, QEvent.Type.MouseButtonRelease, at + QPoint(1, 0), Qt.MouseButton.NoButton)
    settle()
    (edit,) = window.shadow_edits
    assert edit.radius == 0 and undo_texts(window)[-1] == "Not a shadow"
    assert window.session.shadow_probability[BAND].max() < 0.05  # the whole band


def test_the_brackets_size_the_brush_and_it_is_remembered(qtbot, window, photo, settle,
                                                          settings):
    from app.main_window import MainWindow
    from app.panels import BRUSH_DEFAULT, BRUSH_RANGE

    rp = window.relight_panel
    assert rp.brush_box.value() == BRUSH_DEFAULT and window.canvas.brush() == BRUSH_DEFAULT / 100
    _shadows_view(window, photo, settle)
    _tool(window, "shadow")
    window.activateWindow()
    window.canvas.setFocus()
    qtbot.keyClick(window.canvas, Qt.Key.Key_BracketRight)
    grown = rp.brush_box.value()
    assert grown > BRUSH_DEFAULT and window.canvas.brush() == pytest.approx(grown / 100)
    # The status bar says the size (the box beside the tools is out of sight: a user trial).
    assert window.stage_label.text().startswith(f"Brush {grown:.1f} % of the photo's")
    for _ in range(3):
        qtbot.keyClick(window.canvas, Qt.Key.Key_BracketLeft)
    assert rp.brush_box.value() < BRUSH_DEFAULT
    for _ in range(60):  # within its range
        qtbot.keyClick(window.canvas, Qt.Key.Key_BracketLeft)
    assert rp.brush_box.value() == BRUSH_RANGE[0]
    qtbot.keyClick(window.canvas, Qt.Key.Key_BracketRight)
    assert rp.brush_box.value() > BRUSH_RANGE[0]
    rp.brush_box.setFocus()  # the keys work while the box has focus too
    qtbot.keyClick(rp.brush_box, Qt.Key.Key_BracketRight)
    size = rp.brush_box.value()
    assert size > BRUSH_RANGE[0] + 0.1
    # The canvas draws the brush's circle under the cursor, and a crosshair.
    canvas = window.canvas
    at = _widget_point(canvas, 0.5, 0.8)
    _mouse(canvas, QEvent.Type.MouseMove, at, Qt.MouseButton.NoButton)
    assert canvas.cursor().shape() == Qt.CursorShape.CrossCursor
    assert canvas._hover == QPointF(at)
    # Remembered: a new window starts with it; a broken setting gives the default.
    other = MainWindow(settings=settings, preset="fast")
    qtbot.addWidget(other)
    assert other.relight_panel.brush_box.value() == pytest.approx(size)
    other.runner.shutdown()
    settings.setValue("brush_size", "nan")
    third = MainWindow(settings=settings, preset="fast")
    qtbot.addWidget(third)
    assert third.relight_panel.brush_box.value() == BRUSH_DEFAULT
    third.runner.shutdown()
    # Without the tools ([ and ] are left to others): the size stays.
    window.relight_panel.set_view("output")
    settle()
    qtbot.keyClick(window.canvas, Qt.Key.Key_BracketRight)
    assert rp.brush_box.value() == size


def test_the_mark_shadow_brush_is_soft_and_its_circle_says_so(window, photo, settle):
    """"Mark shadow" fades in over the outer part of its radius (the runtime's
    STROKE_FEATHER): the brush's circle has a dashed inner circle where it works at full
    strength. "Not a shadow" is a hard brush: one circle."""
    from app.main_window import BRUSH_SOFTNESS
    from outcast_core.runtime.pipeline.photo_shadows import STROKE_FEATHER

    assert BRUSH_SOFTNESS == {"shadow": 0.5 * STROKE_FEATHER, "not_shadow": 0.0}
    _shadows_view(window, photo, settle)
    canvas = window.canvas
    window.relight_panel.set_brush(0.12)
    at = _widget_point(canvas, 0.5, 0.5)
    inner = canvas.brush_pixels() * canvas._zoom * (1.0 - BRUSH_SOFTNESS["shadow"])
    turns = np.linspace(0.0, 2.0 * np.pi, 180, endpoint=False)
    ring = (np.round(at.y() + inner * np.sin(turns)).astype(int),
            np.round(at.x() + inner * np.cos(turns)).astype(int))
    seen = {}
    for tool in ("not_shadow", "shadow"):
        _tool(window, tool)
        _mouse(canvas, QEvent.Type.MouseMove, at, Qt.MouseButton.NoButton)
        seen[tool] = _rgb(canvas.grab().toImage())[ring].astype(int)
    assert canvas.brush_soft() == BRUSH_SOFTNESS["shadow"]
    changed = np.abs(seen["shadow"] - seen["not_shadow"]).max(axis=-1) > 40
    assert 0.2 < changed.mean() < 0.9  # dashes
    _tool(window, "not_shadow")
    assert canvas.brush_soft() == 0.0


def test_a_correction_on_the_originals_side_moves_the_split_to_show_it(qtbot, window, photo,
                                                                       settle):
    """In "Shadows removed", a correction made wholly left of the before | after line (on the
    original) would show no change: once shown, the line moves to just left of it (never to
    the photo's edge), and the status bar says so. One that reaches the de-shadowed side, or
    one that changed nothing, leaves the line where the user put it (a user trial)."""
    from app.main_window import SPLIT_LEAST, SPLIT_MARGIN

    _shadows_view(window, photo, settle, view="shadows_removed")
    rp = window.relight_panel
    assert rp.split_slider.value() == 50
    _tool(window, "not_shadow")
    rp.set_brush(0.03)
    _click(qtbot, window, 0.2, 0.3)  # lit ground: changes nothing, taken back
    settle()
    assert window.shadow_edits == () and rp.split_slider.value() == 50
    reach = 0.03 * max(window.session.image_srgb.shape[:2]) / window.session.image_srgb.shape[1]
    _drag(window, [(0.27, 0.7), (0.33, 0.7)])  # the band's left part
    settle()
    moved = rp.split_slider.value()  # (the first dab lies where the mouse's pixel put it)
    assert abs(moved - math.floor(100 * (0.27 - reach - SPLIT_MARGIN))) <= 1
    assert window.canvas.split() == pytest.approx(moved / 100)
    assert "line moved left" in window.stage_label.text()
    rp.split_slider.setValue(30)
    _drag(window, [(0.25, 0.72), (0.4, 0.72)])  # across the line: stays
    settle()
    assert rp.split_slider.value() == 30
    # Reaching the photo's left edge (the band's dropped part painted back with a wide brush):
    # the line stops short of it.
    rp.split_slider.setValue(45)
    _tool(window, "shadow")
    rp.set_brush(0.15)
    _drag(window, [(0.2, 0.7), (0.22, 0.7)])
    settle()
    assert window.shadow_edits[-1].shadow
    assert rp.split_slider.value() == round(100 * SPLIT_LEAST)
    rp.split_slider.setValue(30)
    # Wholly left of SPLIT_LEAST, moving the line would not show it either: it stays.
    assert not window._show_correction_side((ShadowEdit(0.01, 0.7, True, 0.005),))
    assert rp.split_slider.value() == 30
    # In "Shadows found" (no split) nothing moves.
    rp.set_view("shadows_found")
    settle()
    _tool(window, "not_shadow")
    _click(qtbot, window, 0.1, 0.7)
    settle()
    assert rp.split_slider.value() == 30


def test_a_stroke_that_changed_nothing_is_taken_back(qtbot, window, photo, settle):
    _shadows_view(window, photo, settle)
    _tool(window, "not_shadow")
    count, clean = window.undo_stack.count(), window.undo_stack.isClean()
    _drag(window, [(0.75, 0.9), (0.85, 0.88), (0.95, 0.9)])  # lit ground, no found shadow
    settle()
    assert "no found shadow under the stroke" in window.stage_label.text()
    assert window.shadow_edits == () and window.undo_stack.count() == count
    assert window.undo_stack.isClean() == clean
    assert not window.relight_panel.clear_shadow_edits_button.isEnabled()
    # A stroke of which some dabs changed something is kept whole, whichever they are.
    for path in ([(0.75, 0.9), (0.6, 0.9), (0.45, 0.75)], [(0.3, 0.7), (0.6, 0.9), (0.75, 0.9)]):
        edits = window.shadow_edits
        _drag(window, path)
        settle()
        assert len(window.shadow_edits) > len(edits) + 5
        used = window.session.shadow_edits_used[len(edits):]
        assert any(used) and not all(used)
    assert window.undo_stack.count() == count + 2


def test_a_mark_shadow_stroke_on_lit_ground_is_refused(qtbot, window, photo, settle):
    """A "Mark shadow" stroke adds only the shadow under it: on lit ground nothing (it was
    lifted into pale hard-edged discs, a user trial), and it is taken back as a click there."""
    _shadows_view(window, photo, settle)
    _tool(window, "shadow")
    count, before = window.undo_stack.count(), window.session.shadow_probability.copy()
    _drag(window, [(0.6, 0.9), (0.7, 0.88), (0.8, 0.9)])
    settle()
    assert "no shadow under the stroke" in window.stage_label.text()
    assert window.shadow_edits == () and window.undo_stack.count() == count
    assert np.array_equal(window.session.shadow_probability, before)


def test_a_mark_shadow_stroke_over_a_shadow_shown_already_is_taken_back(qtbot, window, photo,
                                                                        settle):
    """A "Mark shadow" stroke along the found band, which "Shadows found" shows and the
    de-shadow lifts already, changes (almost) nothing: no correction counted, no undo step,
    and the status bar says so (on the ski slope such a stroke added 160 pixels of a trunk
    and was counted: a user trial)."""
    _shadows_view(window, photo, settle)
    assert window.session.lifted_shadows()[64:70, 36:58].min() > 0.85  # under the stroke
    _tool(window, "shadow")
    count, clean = window.undo_stack.count(), window.undo_stack.isClean()
    before = window.session.shadow_probability.copy()
    _drag(window, [(0.3, 0.7), (0.375, 0.7), (0.45, 0.7)])
    settle()
    assert "no shadow under the stroke" in window.stage_label.text()
    assert window.shadow_edits == () and window.undo_stack.count() == count
    assert window.undo_stack.isClean() == clean
    assert window.relight_panel.shadow_edits_label.text() == "No corrections"
    assert np.array_equal(window.session.shadow_probability, before)


def test_undo_while_painting_cancels_the_stroke_only(qtbot, window, photo, settle):
    """Ctrl+Z in the middle of a stroke undid the step before, and the stroke was still added
    on release (its redo lost): now it cancels the stroke, as Esc does, and nothing else."""
    _drop_the_band(qtbot, window, photo, settle)
    click = window.shadow_edits
    assert len(click) == 1
    canvas, left = window.canvas, Qt.MouseButton.LeftButton
    count = window.undo_stack.count()

    def cancelled_by(act, edits: tuple) -> None:
        index = window.undo_stack.index()
        _mouse(canvas, QEvent.Type.MouseButtonPress, _widget_point(canvas, 0.6, 0.9), left)
        _mouse(canvas, QEvent.Type.MouseMove, _widget_point(canvas, 0.7, 0.9), left)
        assert canvas.painting() and act.isEnabled()
        act.trigger()
        assert not canvas.painting() and window.stage_label.text() == "Stroke cancelled"
        _mouse(canvas, QEvent.Type.MouseMove, _widget_point(canvas, 0.8, 0.9), left)
        _mouse(canvas, QEvent.Type.MouseButtonRelease, _widget_point(canvas, 0.8, 0.9),
               Qt.MouseButton.NoButton)
        settle()
        assert window.shadow_edits == edits and window.undo_stack.count() == count
        assert window.undo_stack.index() == index  # neither undone nor redone

    cancelled_by(window.act_undo, click)
    # Without a stroke, undo and redo work as before; the tool is still on.
    assert window.relight_panel.shadow_tool() == "not_shadow"
    window.act_undo.trigger()
    settle()
    assert window.shadow_edits == ()
    cancelled_by(window.act_redo, ())
    window.act_redo.trigger()
    settle()
    assert window.shadow_edits == click


def test_the_brush_and_the_command_line_share_one_largest_radius(window, photo, errors,
                                                                  tmp_path):
    """The app's brush topped out at 15 % while the command line took 0.25: one limit now; a
    project with a larger dab is refused, saying so."""
    from outcast_core.runtime.cli.main import build_parser, parse_shadow_edit
    from outcast_core.runtime.pipeline.photo_shadows import MAX_BRUSH_RADIUS

    assert window.relight_panel.brush_box.maximum() == pytest.approx(100 * MAX_BRUSH_RADIUS)
    assert parse_shadow_edit(f"0.5,0.5,{MAX_BRUSH_RADIUS}", shadow=True).radius == (
        MAX_BRUSH_RADIUS)
    with pytest.raises(ValueError, match="brush radius R"):
        parse_shadow_edit(f"0.5,0.5,{MAX_BRUSH_RADIUS + 0.01}", shadow=True)
    sub = next(a for a in build_parser()._actions if a.dest == "command").choices["deshadow"]
    helps = " ".join(a.help or "" for a in sub._actions)
    assert f"at most {MAX_BRUSH_RADIUS}:" in helps
    base = ProjectState(image_path=photo).to_dict()
    project = tmp_path / "wide.outcast.json"
    project.write_text(json.dumps({**base, "shadow_edits": [
        {"x": 0.5, "y": 0.5, "shadow": True, "r": MAX_BRUSH_RADIUS + 0.05}]}))
    window.open_path(str(project))
    assert len(errors) == 1 and "shadow_edits" in errors[0][1]
    assert f"brush radius 0-{MAX_BRUSH_RADIUS}" in errors[0][1]
    assert window.step is Step.EMPTY


def test_a_correction_is_said_by_its_own_result_only(qtbot, window, photo, settle):
    """What a correction did is said once, by the result that shows it: after a quick switch
    of views and a sun move, the status said "applied ... Ctrl+Z takes it back" again, where
    Ctrl+Z undid the sun (a review)."""
    _shadows_view(window, photo, settle)
    _tool(window, "not_shadow")
    _click(qtbot, window, *BAND_XY)
    settle()
    assert "applied" in window.stage_label.text()
    window.relight_panel.set_view("shadows_removed")
    window.relight_panel.set_view("shadows_found")  # before the de-shadowed photo came
    window.relight_panel.sun_panel.set_sun(200.0, 15.0)
    window._on_target_sun_committed(200.0, 15.0)  # (what the dial's release sends)
    settle()
    assert undo_texts(window)[-1] == "Move new sun"
    assert "applied" not in window.stage_label.text()


def test_a_clear_is_said_with_no_tool_on_when_its_images_are_made(qtbot, window, photo,
                                                                  settle):
    """A clear whose images are not kept (a reopened project's corrections: the photo
    without them never shown) says what it did with no tool on, as a kept one does (a
    review)."""
    _shadows_view(window, photo, settle)
    assert window.add_shadow_edit(*BAND_XY, shadow=False)
    settle()
    window._deshadow_kept.clear()
    window.clear_shadow_edits()
    settle()
    assert window.relight_panel.shadow_tool() is None or not window.relight_panel.shadow_tool()
    assert window.stage_label.text() == (
        "Ready · cleared the shadow corrections · Ctrl+Z brings them back")


def test_opening_shadows_found_reports_no_timing_for_work_not_done(qtbot, window, photo,
                                                                   settle):
    """The shadows are found when the sun is confirmed: opening "Shadows found" afterwards
    said "finding shadows took 0.00 s"."""
    _shadows_view(window, photo, settle)
    assert window.stage_label.text() == "Ready"
    assert window.add_shadow_edit(*BAND_XY, shadow=False)  # work done: what it did is said
    settle()
    assert window.stage_label.text() == 'Ready · applied "Not a shadow" · Ctrl+Z takes it back'
    window.relight_panel.set_view("shadows_removed")  # the de-shadowed photo made: timed
    settle()
    assert "removing shadows took" in window.stage_label.text()


def test_each_stroke_is_marked_and_a_retraced_one_is_another(qtbot, window, photo, settle):
    """Each stroke's first dab is marked as its start: a stroke painted on from where the last
    one of its kind and size ended counted with it (the panel said "1 correction" for two undo
    steps; a retraced one that changed nothing was never taken back: the runtime's tests)."""
    _shadows_view(window, photo, settle)
    _tool(window, "not_shadow")
    window.relight_panel.set_brush(0.03)
    _drag(window, [(0.27, 0.7), (0.40, 0.7)])
    settle()
    first = window.shadow_edits
    assert first[0].start and not any(d.start for d in first[1:])
    count = window.undo_stack.count()
    _drag(window, [(first[-1].x, 0.7), (0.5, 0.7)])  # on, over the rest of the band
    settle()
    second = window.shadow_edits[len(first):]
    assert second[0].start and not any(d.start for d in second[1:])
    assert window.undo_stack.count() == count + 1
    assert window.relight_panel.shadow_edits_label.text() == "2 corrections"


def test_a_stroke_keeps_the_brush_size_it_began_with(qtbot, window, photo, settle):
    """[ or ] in the middle of a stroke: its dabs were spaced for the old size and added with
    the new one (gaps)."""
    _shadows_view(window, photo, settle)
    _tool(window, "not_shadow")
    rp, canvas, left = window.relight_panel, window.canvas, Qt.MouseButton.LeftButton
    rp.set_brush(0.03)
    _mouse(canvas, QEvent.Type.MouseButtonPress, _widget_point(canvas, 0.27, 0.7), left)
    _mouse(canvas, QEvent.Type.MouseMove, _widget_point(canvas, 0.33, 0.7), left)
    rp.set_brush(0.06)
    assert canvas.brush() == pytest.approx(0.06)  # the circle under the cursor: the new size
    _mouse(canvas, QEvent.Type.MouseMove, _widget_point(canvas, 0.45, 0.7), left)
    _mouse(canvas, QEvent.Type.MouseButtonRelease, _widget_point(canvas, 0.45, 0.7),
           Qt.MouseButton.NoButton)
    settle()
    dabs = window.shadow_edits
    assert len(dabs) > 5 and all(d.radius == pytest.approx(0.03) for d in dabs)
    gaps = [np.hypot((a.x - b.x) * 128, (a.y - b.y) * 96)
            for a, b in zip(dabs, dabs[1:], strict=False)]
    assert max(gaps) <= 0.5 * 0.03 * 128 + 1e-6


def test_too_many_clicks_or_edits_are_refused_saying_which(qtbot, window, photo, settle):
    """A click costs far more than a dab: at most MAX_SHADOW_CLICKS clicks, and
    MAX_SHADOW_EDITS edits in all; the status bar says which limit was reached."""
    _shadows_view(window, photo, settle)
    count = window.undo_stack.count()
    clicks = (ShadowEdit(0.9, 0.9, True),) * MAX_SHADOW_CLICKS
    window._show_shadow_edits(clicks)  # (as if made: no job)
    assert not window.add_shadow_edit(0.5, 0.5, shadow=False)
    assert window.stage_label.text().startswith(f"At most {MAX_SHADOW_CLICKS} clicks (")
    dabs = (ShadowEdit(0.9, 0.9, True, radius=0.02),) * (MAX_SHADOW_EDITS - 5)
    window._show_shadow_edits(dabs)
    assert not window.add_shadow_stroke([(0.5, 0.5 + 0.001 * k) for k in range(10)], True, 0.02)
    assert window.stage_label.text().startswith(
        f"At most {MAX_SHADOW_EDITS} clicks and brush dabs in all:")
    assert window.undo_stack.count() == count and len(window.shadow_edits) == len(dabs)


# ---------------------------------------------------------------- the canvas's strokes


@pytest.fixture
def painting(qtbot):
    """A canvas (a 128 x 96 image fitted in 600 x 600: margins above and below it) with the
    click tool on, a brush of 0.03, and the strokes it emits."""
    from app.canvas import ImageCanvas

    canvas = ImageCanvas()
    qtbot.addWidget(canvas)
    canvas.resize(600, 600)
    canvas.show()
    image = QImage(128, 96, QImage.Format.Format_RGB888)
    image.fill(Qt.GlobalColor.gray)
    canvas.set_image(image)
    canvas.set_click_tool(True)
    canvas.set_brush(0.03)
    strokes: list = []
    canvas.stroke_painted.connect(lambda points, radius: strokes.append((points, radius)))
    clicks: list = []
    canvas.image_clicked.connect(lambda x, y: clicks.append((x, y)))
    return canvas, strokes, clicks


def _max_gap(points) -> float:
    return max(np.hypot((a[0] - b[0]) * 128, (a[1] - b[1]) * 96)
               for a, b in zip(points, points[1:], strict=False))


def test_a_stroke_just_outside_the_edge_paints_along_it(painting):
    """Dabs whose centres were off the image were left out: a drag just below its edge
    painted nothing along it, though the band drawn covered it. Their discs reach the image:
    moved onto its edge; those whose discs miss it (far outside) are left out."""
    canvas, strokes, _ = painting
    left = Qt.MouseButton.LeftButton
    path = [(0.2, 0.95), (0.3, 1.02), (0.7, 1.02), (0.75, 1.5), (0.8, 1.02), (0.85, 0.95)]
    _mouse(canvas, QEvent.Type.MouseButtonPress, _widget_point(canvas, *path[0]), left)
    for x, y in path[1:]:
        _mouse(canvas, QEvent.Type.MouseMove, _widget_point(canvas, x, y), left)
    _mouse(canvas, QEvent.Type.MouseButtonRelease, _widget_point(canvas, *path[-1]),
           Qt.MouseButton.NoButton)
    ((points, radius),) = strokes
    assert radius == pytest.approx(0.03)
    assert all(0 <= x <= 1 and 0 <= y <= 1 for x, y in points)
    along = [p for p in points if p[1] == 1.0 and 0.3 <= p[0] <= 0.7]
    assert len(along) > 10 and _max_gap(along) <= 0.5 * 0.03 * 128 + 0.1
    assert not any(0.74 < x < 0.76 for x, _ in points)  # far below: its discs miss the image


def test_another_button_pressed_while_painting_is_ignored(painting):
    """A middle (or right) press during a stroke ended its painting (and panned): the stroke
    lost what was painted after it."""
    canvas, strokes, _ = painting
    left, mid = Qt.MouseButton.LeftButton, Qt.MouseButton.MiddleButton
    both = left | mid
    rect = canvas.image_rect()
    _mouse(canvas, QEvent.Type.MouseButtonPress, _widget_point(canvas, 0.2, 0.5), left)
    _mouse(canvas, QEvent.Type.MouseMove, _widget_point(canvas, 0.3, 0.5), left)
    _mouse(canvas, QEvent.Type.MouseButtonPress, _widget_point(canvas, 0.35, 0.5), both, mid)
    _mouse(canvas, QEvent.Type.MouseMove, _widget_point(canvas, 0.5, 0.8), both)
    _mouse(canvas, QEvent.Type.MouseButtonRelease, _widget_point(canvas, 0.5, 0.8), left, mid)
    assert canvas.painting()
    _mouse(canvas, QEvent.Type.MouseMove, _widget_point(canvas, 0.7, 0.5), left)
    _mouse(canvas, QEvent.Type.MouseButtonRelease, _widget_point(canvas, 0.7, 0.5),
           Qt.MouseButton.NoButton)
    assert canvas.image_rect() == rect  # not panned
    ((points, _),) = strokes
    assert max(y for _, y in points) > 0.78 and points[-1][0] == pytest.approx(0.7, abs=0.01)
    assert _max_gap(points) <= 0.5 * 0.03 * 128 + 1e-6


def test_a_lost_release_ends_the_stroke(painting):
    """A move without the left button (its release went to a modal box) kept painting on
    hover: the stroke ends where it was last painted and is emitted, once."""
    canvas, strokes, clicks = painting
    left, none = Qt.MouseButton.LeftButton, Qt.MouseButton.NoButton
    _mouse(canvas, QEvent.Type.MouseButtonPress, _widget_point(canvas, 0.2, 0.5), left)
    _mouse(canvas, QEvent.Type.MouseMove, _widget_point(canvas, 0.4, 0.5), left)
    _mouse(canvas, QEvent.Type.MouseMove, _widget_point(canvas, 0.6, 0.7), none)
    assert not canvas.painting()
    ((points, _),) = strokes
    assert points[-1][0] == pytest.approx(0.4, abs=0.01) and max(y for _, y in points) < 0.52
    _mouse(canvas, QEvent.Type.MouseMove, _widget_point(canvas, 0.8, 0.7), none)
    assert len(strokes) == 1
    # A press that never moved, its release lost: no click, and the next click works.
    _mouse(canvas, QEvent.Type.MouseButtonPress, _widget_point(canvas, 0.5, 0.5), left)
    _mouse(canvas, QEvent.Type.MouseMove, _widget_point(canvas, 0.6, 0.6), none)
    _mouse(canvas, QEvent.Type.MouseButtonPress, _widget_point(canvas, 0.3, 0.3), left)
    _mouse(canvas, QEvent.Type.MouseButtonRelease, _widget_point(canvas, 0.3, 0.3), none)
    assert len(strokes) == 1 and clicks == [pytest.approx((0.3, 0.3), abs=0.01)]


def test_shadows_found_shows_what_the_de_shadow_lifts(window, photo, settle) -> None:
    """The "Shadows found" tint is the session's ``lifted_shadows`` (what "Shadows removed"
    lifts), not the bare probability: a thin shadow the lift leaves as texture was tinted and
    then left dark (a user trial)."""
    _shadows_view(window, photo, settle)
    lifted = window.session.lifted_shadows()
    alpha = _alpha(window.canvas.overlay()).astype(int)
    assert alpha.shape == lifted.shape
    expected = np.round(255 * np.where(window.session.sky, 0.0, lifted)).astype(int)
    assert np.abs(alpha - expected).max() <= 1
    assert np.abs(alpha - np.round(255 * window.session.shadow_probability)).max() > 10


def test_the_found_shadows_show_with_step_1_s_overlay_at_zero(window, photo, settle):
    """Step 1's overlay slider at 0 left step 2's "Shadows found" blank, with no control there
    to bring it back (a user trial): the found tint has a least opacity; step 1's overlay
    keeps the slider's."""
    from app.main_window import FOUND_LEAST_OPACITY

    _load(window, photo, settle)
    window.align_panel.opacity_slider.setValue(0)
    _confirm(window, settle)
    window.relight_panel.set_view("shadows_found")
    settle()
    assert window.canvas.overlay() is not None
    assert window.canvas.overlay_opacity() == pytest.approx(FOUND_LEAST_OPACITY)
    window.back_to_align()
    settle()
    assert window.canvas.overlay_opacity() == 0.0
