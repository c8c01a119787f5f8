"""Step 1's "Find sun": runs in the worker, moves the sun (undoable), heat map on the dial, says
when the photo has no clear shadows; the EXIF button explains itself; a typed heading."""

from __future__ import annotations

import dataclasses
import os
import time

import numpy as np
import pytest

from app.state import Step
from outcast_core.runtime.geometry.camera import sun_vector
from outcast_core.runtime.pipeline import auto_sun
from outcast_core.runtime.pipeline.auto_sun import AgreementMap, SunFit

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _fit(az: float, el: float, *, found: bool = True, source: str = "shadows") -> SunFit:
    azs, els = np.arange(0.0, 360.0, 20.0), np.array([8.0, 22.0, 36.0, 50.0, 64.0, 78.0])
    scores = np.full((len(els), len(azs)), 0.55)
    scores[2, 10] = 0.9
    note = "sun found" if found else "no clear shadows in the photo: set it by eye"
    return SunFit(az, el, sun_vector(az, el), 0.9, 0.8 if found else 0.1, found, source,
                  note, AgreementMap(azs, els, scores), [(az, el, 0.9)],
                  unfound="" if found else "no-clear-shadows")


def _load(window, photo, settle) -> None:
    window.open_path(photo)
    settle()
    assert window.step is Step.ALIGN


def test_find_sun_moves_the_sun_undoably_and_shows_the_heat_map(
    window, photo, settle, monkeypatch
):
    _load(window, photo, settle)
    panel = window.align_panel.sun_panel
    before = panel.sun()
    monkeypatch.setattr(auto_sun, "find_sun", lambda session, **kw: _fit(200.0, 30.0))
    window.align_panel.find_button.click()
    settle()
    assert panel.sun() == pytest.approx((200.0, 30.0))
    assert panel.dial.has_heat_map()
    assert "Sun found" in window.stage_label.text()
    assert window.undo_stack.undoText() == "Find sun"
    window.undo_stack.undo()
    settle()
    assert panel.sun() == pytest.approx(before)
    window.undo_stack.redo()
    settle()
    assert panel.sun() == pytest.approx((200.0, 30.0))


def test_a_sun_the_compass_chose_says_where_the_shadows_alone_point(window, photo, settle,
                                                                    monkeypatch):
    from dataclasses import replace

    _load(window, photo, settle)
    fit = replace(_fit(0.0, 8.0), compass_decided=True)  # the map's cold corner
    assert fit.map.at(0.0, 8.0) == 0.0 and fit.map.best() == (200.0, 36.0)
    monkeypatch.setattr(auto_sun, "find_sun", lambda session, **kw: fit)
    window.find_sun()
    settle()
    text = window.stage_label.text()
    # The compass first: "Sun found" then "the compass chose it" read as a contradiction.
    assert text.startswith("Sun placed by the compass heading: azimuth 0.0°"), text
    assert "Sun found" not in text
    assert "shadows fit many suns about as well" in text
    assert "alone they fit best near 200°, 36°: the warm area of the dial" in text
    # A heading the user typed is said as theirs.
    window.user_heading = 120.0
    window.find_sun()
    settle()
    assert window.stage_label.text().startswith("Sun placed by the heading you typed:")


def test_a_seen_sun_below_the_level_plane_is_said_above_the_photo(window, photo, settle,
                                                                  monkeypatch):
    """A sun in the frame below the picture's centre (a sideways photo or an off-centre
    crop: a user trial) is placed on the horizon and said, in the status and above the
    photo, not only shown at elevation 0."""
    from dataclasses import replace

    _load(window, photo, settle)
    fit = replace(_fit(354.0, 0.0), source=auto_sun.SOURCE_SUN_IN_FRAME, confidence=1.0,
                  below_level=7.3)
    monkeypatch.setattr(auto_sun, "find_sun", lambda session, **kw: fit)
    window.find_sun()
    settle()
    text = window.stage_label.text()
    assert text.startswith("Sun found in the frame: azimuth 354.0°, elevation 0.0° · It stands "
                           "7° below the height of the picture's centre")
    assert "It stands 7°" in window.align_panel.notice.text()
    assert window.align_panel.sun_panel.sun() == pytest.approx((354.0, 0.0))
    level = replace(fit, below_level=0.0)  # in the frame and above it: nothing more to say
    monkeypatch.setattr(auto_sun, "find_sun", lambda session, **kw: level)
    window.find_sun()
    settle()
    assert "below the height" not in window.stage_label.text()


def test_no_clear_shadows_is_said_and_the_sun_stays(window, photo, settle, monkeypatch):
    _load(window, photo, settle)
    panel = window.align_panel.sun_panel
    before = panel.sun()
    count = window.undo_stack.count()
    monkeypatch.setattr(auto_sun, "find_sun",
                        lambda session, **kw: _fit(10.0, 60.0, found=False))
    window.find_sun()
    settle()
    assert panel.sun() == pytest.approx(before)
    assert window.undo_stack.count() == count
    assert "No clear shadows" in window.stage_label.text()
    assert window.align_panel.notice.isVisibleTo(window)
    # No map: stretched to its full range it pointed at noise, and the words no longer say
    # "the dial shows where suns fit best" (a user trial followed it the wrong way).
    assert not panel.dial.has_heat_map() and "fit best" not in window.stage_label.text()
    # The message follows the fit's reason, not its note's words.
    for unfound, words in (("too-small", "too small or too narrow"),
                           ("no-fit", "No sun makes the predicted shadows fit"),
                           ("open-sky", "would stand in the photo's open sky")):
        fit = dataclasses.replace(_fit(10.0, 60.0, found=False), unfound=unfound)
        monkeypatch.setattr(auto_sun, "find_sun", lambda session, fit=fit, **kw: fit)
        window.find_sun()
        settle()
        assert words in window.stage_label.text()


def test_no_clear_shadows_with_gps_and_time_still_sets_the_elevation(
    window, settle, monkeypatch, tmp_path
):
    """The field path records GPS and time but no heading: when its shadows do not tell the
    sun, the elevation its time and place give is still set (undoably) and said."""
    import shutil

    from outcast_core.runtime.pipeline.timelapse import true_sun_position

    photo = tmp_path / "fieldpath.jpg"
    shutil.copyfile(os.path.join(ROOT, "samples", "exif_001_cz_fieldpath.jpg"), photo)
    _load(window, str(photo), settle)
    panel = window.align_panel.sun_panel
    panel.azimuth_box.setValue(150.0)  # typed, as a user would
    panel.elevation_box.setValue(20.0)
    settle()
    prior = window.exif_prior()
    assert prior is not None and prior.azimuth is None
    exif = window.loaded.exif
    assert prior.elevation == pytest.approx(
        true_sun_position(exif.capture_time, exif.latitude, exif.longitude)[1])
    monkeypatch.setattr(auto_sun, "find_sun",
                        lambda session, **kw: _fit(10.0, 60.0, found=False))
    window.find_sun()
    settle()
    az, el = window.align_panel.sun_panel.sun()
    # Round the true horizon the sun keeps its azimuth and takes the true elevation.
    expected = auto_sun.at_true_elevation(150.0, 20.0, prior.elevation, window.camera_tilt[:2])
    assert (az, el) == pytest.approx(expected, abs=0.05)
    text = window.stage_label.text()
    assert "No clear shadows" in text and f"set to {el:.1f}°" in text
    assert window.undo_stack.undoText() == "Sun elevation from EXIF"
    window.undo_stack.undo()
    settle()
    assert window.align_panel.sun_panel.sun() == pytest.approx((150.0, 20.0))


def test_at_true_elevation_keeps_the_horizon_azimuth():
    from outcast_core.runtime.geometry.camera import sun_angles

    tilt = (-20.0, 5.0)  # looking down, rolled
    az, el = auto_sun.at_true_elevation(60.0, 10.0, 40.0, tilt)
    h_before = sun_angles(sun_vector(60.0, 10.0), *tilt)
    h_after = sun_angles(sun_vector(az, el), *tilt)
    assert h_after[1] == pytest.approx(40.0, abs=1e-6)
    assert h_after[0] == pytest.approx(h_before[0], abs=1e-6)
    assert auto_sun.at_true_elevation(370.0, 10.0, 40.0) == (10.0, 40.0)


def test_find_sun_can_be_cancelled_and_never_blocks(qtbot, window, photo, settle, monkeypatch):
    _load(window, photo, settle)
    started = []

    def slow(session, *, prior=None, progress=None, **kw):
        started.append(True)
        for i in range(200):
            time.sleep(0.02)
            progress("trying", i / 200)  # the worker's progress raises once cancelled
        return _fit(1.0, 2.0)

    monkeypatch.setattr(auto_sun, "find_sun", slow)
    before = window.align_panel.sun_panel.sun()
    window.toggle_find_sun()
    qtbot.waitUntil(lambda: bool(started), timeout=5000)
    assert window.finding_sun()
    assert window.align_panel.find_button.text().startswith("Cancel")
    t0 = time.perf_counter()
    window.toggle_find_sun()  # the button again: cancel
    settle()
    assert time.perf_counter() - t0 < 2.0
    assert not window.finding_sun()
    assert window.align_panel.find_button.text() == "Find sun from shadows"
    assert window.align_panel.sun_panel.sun() == pytest.approx(before)


def test_find_sun_for_real_on_a_small_photo(window, photo, settle):
    _load(window, photo, settle)
    window.act_find_sun.trigger()
    settle(60000)
    assert window.sun_fit is not None
    assert window.align_panel.sun_panel.dial.has_heat_map()
    assert 0.0 <= window.sun_fit.confidence <= 1.0
    assert "find_sun" in window.timings.summary(limit=50)


def test_exif_without_heading_explains_the_grey_button_and_takes_a_heading(
    window, settle, monkeypatch
):
    captured = {}

    def fake(session, *, prior=None, **kw):
        captured["prior"] = prior
        return _fit(120.0, prior.elevation if prior else 30.0)

    window.open_path(os.path.join(ROOT, "samples", "exif_001_cz_fieldpath.jpg"))
    settle()
    ap = window.align_panel
    assert not ap.exif_button.isEnabled()
    note = ap.exif_note.text()
    assert "No compass heading" in note and "from the photo's time and place" in note
    assert ap.exif_note.isVisibleTo(window) and ap.exif_button.toolTip() == note
    assert ap.heading_box.isEnabled()
    el = window.align_panel.sun_panel.dial.prior_elevation()
    assert el is not None and 0.0 < el < 90.0  # the EXIF elevation's ring on the dial
    monkeypatch.setattr(auto_sun, "find_sun", fake)
    window.find_sun()
    settle()
    prior = captured["prior"]
    assert prior is not None and prior.azimuth is None
    # The dial's angles only; the prior named without its (the horizon's) angles.
    assert window.stage_label.text().endswith(
        "· using the elevation from the photo's time and place")
    # A typed heading makes the EXIF sun a full guess.
    ap.heading_box.setValue(200.0)
    assert window.user_heading == pytest.approx(200.0)
    assert ap.exif_button.isEnabled() and not ap.exif_note.isVisibleTo(window)
    window.find_sun()
    settle()
    assert captured["prior"].azimuth is not None


def test_a_wrong_compass_heading_is_pointed_out(window, settle, monkeypatch):
    window.open_path(os.path.join(ROOT, "samples", "exif_003_th_pool.jpg"))
    settle()
    prior = window.exif_prior()
    assert prior is not None and prior.azimuth is not None  # the pool records its heading
    monkeypatch.setattr(auto_sun, "find_sun",
                        lambda session, **kw: _fit((prior.azimuth + 150.0) % 360.0, 60.0))
    window.find_sun()
    settle()
    notice = window.align_panel.notice
    assert notice.isVisibleTo(window) and "compass heading" in notice.text()


def test_a_recorded_heading_is_shown_and_can_be_corrected(window, settle):
    window.open_path(os.path.join(ROOT, "samples", "exif_003_th_pool.jpg"))
    settle()
    ap = window.align_panel
    assert ap.heading_box.isEnabled() and ap.heading_box.text() == "EXIF 163.7°"
    before = window.exif_sun()
    assert before is not None and window.user_heading is None
    ap.heading_box.setValue(183.7)  # the compass was 20° off: the sun moves 20° the other way
    assert window.user_heading == pytest.approx(183.7)
    assert ap.heading_box.prefix() == "" and "replaces" in ap.heading_box.toolTip()
    after = window.exif_sun()
    assert (before[0] - after[0]) % 360.0 == pytest.approx(20.0, abs=0.05)
    assert "the camera heading given" in window.exif_prior().description
    ap.heading_box.setValue(-1.0)  # "unknown": back to the recorded heading
    assert window.user_heading is None and ap.heading_box.text() == "EXIF 163.7°"
    assert window.exif_sun() == pytest.approx(before)


def test_typed_heading_is_saved_in_the_project_and_restored(
    qtbot, window, settle, reopen, tmp_path
):
    import shutil

    from app.state import load_project, project_path_for

    photo = tmp_path / "fieldpath.jpg"  # GPS and time, no compass heading
    shutil.copyfile(os.path.join(ROOT, "samples", "exif_001_cz_fieldpath.jpg"), photo)
    window.open_path(str(photo))
    settle()
    window.align_panel.heading_box.setValue(200.0)
    assert window.user_heading == pytest.approx(200.0)
    saved = window.save_project()
    assert saved == str(project_path_for(photo))
    assert load_project(saved).heading == pytest.approx(200.0)
    with reopen(saved) as other:
        assert other.user_heading == pytest.approx(200.0)
        assert other.align_panel.heading() == pytest.approx(200.0)
        assert other.align_panel.exif_button.isEnabled()  # the typed heading completes the sun
        assert other.exif_prior().azimuth is not None
        # Opening the photo itself (no project) starts without a heading.
        other.open_path(str(photo))
        qtbot.waitUntil(lambda: other.step is Step.ALIGN and not other.runner.busy(),
                        timeout=30000)
        assert other.user_heading is None and other.align_panel.heading() is None


def test_project_heading_is_checked():
    from app.state import ProjectState

    base = ProjectState(image_path="x.jpg").to_dict()
    assert base["heading"] is None
    assert ProjectState.from_dict(base).heading is None
    assert ProjectState.from_dict({**base, "heading": 360.0}).heading == 0.0
    for bad in (-5.0, 400.0, "north", float("nan"), True):
        with pytest.raises(ValueError, match="heading"):
            ProjectState.from_dict({**base, "heading": bad})


def test_find_sun_gets_the_camera_pose_from_the_photo(window, settle, monkeypatch, tmp_path):
    from PIL import Image

    captured = {}

    def fake(session, *, prior=None, pitch_roll=None, **kw):
        captured["pose"] = pitch_roll
        return _fit(120.0, prior.elevation if prior else 30.0)

    photo = tmp_path / "tilted.jpg"  # the field path's GPS and time, and a GPano pose
    with Image.open(os.path.join(ROOT, "samples", "exif_001_cz_fieldpath.jpg")) as im:
        im.save(photo, exif=im.info["exif"], xmp=b'<x:xmpmeta><rdf:Description '
                b'GPano:PosePitchDegrees="-8.5" GPano:PoseRollDegrees="2"/></x:xmpmeta>')
    window.open_path(str(photo))
    settle()
    monkeypatch.setattr(auto_sun, "find_sun", fake)
    window.find_sun()
    settle()
    assert captured["pose"] == (-8.5, 2.0, "XMP GPano") == window.camera_tilt
    # "Sun from EXIF" (here with a typed heading) in the camera's frame, not the horizon's.
    from outcast_core.runtime.pipeline.timelapse import exif_sun

    window.set_user_heading(100.0)
    level = exif_sun(window.loaded.exif, heading=100.0)
    tilted = exif_sun(window.loaded.exif, heading=100.0, tilt=(-8.5, 2.0))
    assert window.exif_sun() == pytest.approx(tilted)
    assert abs(tilted[1] - level[1]) > 3.0
    assert window.tilt_note() == "camera pitched 8.5° down and rolled 2.0° clockwise (XMP GPano)"


def test_the_camera_tilt_follows_the_photo_and_the_preset(window, settle):
    """The ski slope shows its sun: with the EXIF's elevation it gives the camera's pitch, the
    dials shade under that horizon and the EXIF sun is in that frame. The field path's tilt is
    its ground plane's, refitted when a preset changes the depth's working size. The pool,
    with neither, is level."""
    from outcast_core.runtime.pipeline.auto_sun import photo_camera_tilt
    from outcast_core.runtime.pipeline.timelapse import exif_sun

    ski = os.path.join(ROOT, "samples", "exif_005_es_skislope.jpg")
    window.open_path(ski)
    settle()
    pitch, roll, source = window.camera_tilt
    assert source == "sun in the frame" and 7.0 < pitch < 13.0 and roll == 0.0
    for panel in (window.align_panel, window.relight_panel):
        assert panel.sun_panel.dial.tilt() == (pitch, roll)
    # The seen sun gives the compass heading too (the EXIF's is about 126° off): it goes in
    # the heading box, and the EXIF sun is then the seen sun, in the camera's frame.
    from outcast_core.runtime.geometry.camera import sun_angles

    seen = sun_angles(window.session.sun_seen.w)
    compass = exif_sun(window.loaded.exif, tilt=(pitch, roll))
    assert window.user_heading is not None
    assert window.align_panel.heading() == pytest.approx(window.user_heading)
    assert window.exif_sun() == pytest.approx(seen, abs=0.1)
    assert abs((compass[0] - seen[0] + 180.0) % 360.0 - 180.0) > 90.0
    note = window.align_panel.exif_note.text()  # said under the EXIF button, and kept
    assert f"Camera heading {window.user_heading:.1f}° from the sun in the frame" in note
    assert "its EXIF compass says" in note
    window.set_user_heading(10.0)  # typed: the note goes
    assert window.align_panel.exif_note.text() == ""
    assert window.exif_sun() != pytest.approx(exif_sun(window.loaded.exif), abs=0.5)  # level
    assert "camera pitched" in window.tilt_note() and "(sun in the frame)" in window.tilt_note()
    field = os.path.join(ROOT, "samples", "exif_001_cz_fieldpath.jpg")
    window.open_path(field)
    settle()
    assert window.camera_tilt[2] == "ground plane"
    window.set_preset("balanced")
    settle()
    refit = photo_camera_tilt(window.session, field)
    assert window.camera_tilt == refit
    assert window.align_panel.sun_panel.dial.tilt() == refit[:2]
    assert window.user_heading is None  # another photo: its own heading
    window.open_path(os.path.join(ROOT, "samples", "exif_003_th_pool.jpg"))
    settle()
    assert window.camera_tilt[:2] == (0.0, 0.0) and window.tilt_note() == ""
    assert window.relight_panel.sun_panel.dial.tilt() == (0.0, 0.0)


def test_the_timelapse_heading_follows_a_realigned_sun_unless_typed(window, settle, tmp_path):
    """The real sun path's heading, filled in from the aligned sun, is solved again when the
    sun is re-aligned; one typed in the dialog stays (a user trial's time-lapse kept an old
    heading)."""
    import shutil

    photo = tmp_path / "fieldpath.jpg"
    shutil.copyfile(os.path.join(ROOT, "samples", "exif_001_cz_fieldpath.jpg"), photo)
    _load(window, str(photo), settle)
    panel = window.align_panel.sun_panel
    panel.azimuth_box.setValue(40.0)
    window.confirm_original_sun()
    settle()
    dialog = window.open_timelapse()
    first = dialog.heading_box.value()
    assert first == pytest.approx(dialog._solved_heading(), abs=0.05)
    dialog.close()
    window.back_to_align()
    settle()
    panel.azimuth_box.setValue(100.0)  # the sun 60 deg further right: the heading 60 less
    window.confirm_original_sun()
    settle()
    again = window.open_timelapse()
    assert again.heading_box.value() == pytest.approx(again._solved_heading(), abs=0.05)
    assert abs((again.heading_box.value() - first + 180.0) % 360.0 - 180.0) > 30.0
    again.heading_box.setValue(123.0)  # typed: kept from now on
    again.close()
    window.back_to_align()
    settle()
    panel.azimuth_box.setValue(160.0)
    window.confirm_original_sun()
    settle()
    assert window.open_timelapse().heading_box.value() == pytest.approx(123.0)


def test_a_reopened_project_still_says_its_heading_came_from_the_sun_in_the_frame(
        window, settle, reopen, tmp_path):
    import shutil


    photo = tmp_path / "ski.jpg"
    shutil.copyfile(os.path.join(ROOT, "samples", "exif_005_es_skislope.jpg"), photo)
    _load(window, str(photo), settle)
    note = window.align_panel.exif_note.text()
    assert "from the sun in the frame" in note
    saved = window.save_project()
    with reopen(saved) as other:
        assert other.align_panel.exif_note.text() == note
        assert other.user_heading == pytest.approx(window.user_heading)


def test_a_night_photo_says_how_far_below_the_horizon_and_when(window, photo, settle):
    import datetime as dt
    import types

    from outcast_core.runtime.io.exif import PhotoMetadata

    _load(window, photo, settle)
    night = dt.datetime(2026, 6, 1, 23, 30, tzinfo=dt.timezone(dt.timedelta(hours=2)))
    window.loaded = types.SimpleNamespace(
        exif=PhotoMetadata(latitude=50.1, longitude=14.4, capture_time=night))
    note = window.exif_note()
    assert note.startswith("The sun was 15.0° below the horizon at the photo's time and place")
    assert "(2026-06-01 23:30 +02:00)" in note and "clock and time zone" in note


def test_the_dial_starts_at_the_exif_elevation_without_an_undo_step(window, settle):
    """The field path's EXIF gives the elevation (GPS and time) but no azimuth: the dial's sun
    starts on that elevation's ring (about 39° above the true horizon), not at the default
    45°, its azimuth about the horizon kept; opening the photo is no undo step."""
    from app.main_window import DEFAULT_SUN
    from outcast_core.runtime.geometry.camera import sun_angles

    _load(window, os.path.join(ROOT, "samples", "exif_001_cz_fieldpath.jpg"), settle)
    prior = window.exif_prior()
    assert prior is not None and prior.azimuth is None and 30.0 < prior.elevation < 45.0
    dial = window.align_panel.sun_panel.dial
    assert dial.prior_elevation() == pytest.approx(prior.elevation)  # the ring drawn
    pitch, roll = window.camera_tilt[:2]
    horizon_az, horizon_el = sun_angles(sun_vector(*dial.sun()), pitch, roll)
    assert horizon_el == pytest.approx(prior.elevation, abs=0.01)  # on the ring
    assert horizon_az == pytest.approx(sun_angles(sun_vector(*DEFAULT_SUN), pitch, roll)[0],
                                       abs=0.01)
    assert f"sun elevation {dial.elevation():.1f}°" in window.stage_label.text()
    assert window.undo_stack.count() == 0 and window.undo_stack.isClean()
    assert not window.has_unsaved_changes()


def _contrast(label) -> float:
    """The WCAG contrast ratio of a label's text as drawn: its darkest pixel against its
    background (the corner)."""
    img = label.grab().toImage()

    def luminance(colour) -> float:
        def lin(c: float) -> float:
            return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4

        return (0.2126 * lin(colour.redF()) + 0.7152 * lin(colour.greenF())
                + 0.0722 * lin(colour.blueF()))

    background = luminance(img.pixelColor(0, 0))
    text = min(luminance(img.pixelColor(x, y))
               for y in range(img.height()) for x in range(img.width()))
    return (max(background, text) + 0.05) / (min(background, text) + 0.05)


def test_step_1_fits_the_window_after_find_sun_on_the_field_path(window, settle, monkeypatch):
    """A user trial at 1400 x 900: after Find sun on the field path (GPS and time, no compass
    heading) the long notice pushed the camera heading box it speaks of, and the overlay
    slider, below the fold. All of step 1 fits, and the note under the greyed EXIF button is
    drawn in readable text (not greyed out like the button)."""
    from PySide6.QtWidgets import QApplication

    window.resize(1400, 900)
    _load(window, os.path.join(ROOT, "samples", "exif_001_cz_fieldpath.jpg"), settle)
    fit = dataclasses.replace(_fit(10.0, 60.0, found=False), unfound="no-fit")
    monkeypatch.setattr(auto_sun, "find_sun", lambda session, **kw: fit)  # as on the trial
    window.find_sun()
    settle()
    QApplication.processEvents()  # the layout follows the notice
    ap = window.align_panel
    assert ap.notice.isVisibleTo(window) and "around the ring" in ap.notice.text()
    assert "small network" in ap.notice.text()  # the load's note is kept under it
    viewport = window.side_scroll.viewport()
    assert window.side_scroll.verticalScrollBar().maximum() == 0
    for widget in (ap.heading_box, ap.opacity_slider, ap.exif_note):
        top_left = widget.mapTo(viewport, widget.rect().topLeft())
        assert viewport.rect().contains(widget.rect().translated(top_left)), widget
    assert not ap.exif_button.isEnabled() and ap.exif_note.isVisibleTo(window)
    assert _contrast(ap.exif_note) >= 4.5  # WCAG AA for body text


def test_step_1_notice_drops_find_sun_advice_that_no_longer_holds(window, settle,
                                                                  monkeypatch):
    """A user trial: after Find sun on the field path said to turn the sun around the EXIF
    ring, they typed the camera heading and placed the EXIF sun; the notice above the photo
    still said to turn the sun around the ring (the status bar was right). The load's own
    notice (the depth source) stays."""
    _load(window, os.path.join(ROOT, "samples", "exif_001_cz_fieldpath.jpg"), settle)
    loaded = window.align_panel.notice.text()
    fit = dataclasses.replace(_fit(10.0, 60.0, found=False), unfound="no-fit")
    monkeypatch.setattr(auto_sun, "find_sun", lambda session, **kw: fit)
    window.find_sun()
    settle()
    notice = window.align_panel.notice
    assert "around the ring" in notice.text()
    window.align_panel.heading_box.setValue(200.0)  # typed
    assert "around the ring" not in notice.text() and notice.text() == loaded
    window.find_sun()  # said again, then the EXIF sun placed with the typed heading
    settle()
    assert "No sun makes" in notice.text()
    window.align_panel.exif_button.click()
    settle()
    assert "Sun from EXIF" in window.stage_label.text()
    assert "No sun makes" not in notice.text() and notice.text() == loaded


def test_step_1_notice_can_be_closed_until_it_says_something_else(window, settle,
                                                                   monkeypatch):
    """A user trial at 1024 x 700: the notice above the photo (Find sun's advice and the
    depth source) took a sixth of the window. It closes; the same words do not bring it back,
    new ones do."""
    from PySide6.QtWidgets import QApplication

    window.resize(1024, 700)
    _load(window, os.path.join(ROOT, "samples", "exif_001_cz_fieldpath.jpg"), settle)
    ap = window.align_panel
    notice, close = ap.notice, ap.notice_close
    QApplication.processEvents()
    assert notice.isVisibleTo(window) and close.isVisibleTo(window)
    assert notice.rect().contains(close.geometry())  # in its top right corner
    assert close.geometry().right() > notice.width() - 40 and close.y() < 12
    loaded = notice.text()
    canvas_height = window.canvas.height()
    close.click()
    QApplication.processEvents()
    assert not notice.isVisibleTo(window) and notice.text() == loaded
    assert window.canvas.height() > canvas_height  # the photo takes the room
    ap.show_notice(loaded)  # the same words again: still closed
    assert not notice.isVisibleTo(window)
    fit = dataclasses.replace(_fit(10.0, 60.0, found=False), unfound="no-fit")
    monkeypatch.setattr(auto_sun, "find_sun", lambda session, **kw: fit)
    window.find_sun()  # something new to say
    settle()
    assert notice.isVisibleTo(window) and "around the ring" in notice.text()
    close.click()
    window.align_panel.heading_box.setValue(200.0)  # the advice goes: the load's words again
    assert notice.isVisibleTo(window) and notice.text() == loaded


def test_the_exif_button_s_tooltip_follows_its_note(window, settle):
    """A user trial: "No compass heading in the photo's EXIF…" stayed in the EXIF button's
    tooltip after a heading was typed, and for the next photo, which records one."""
    from app.panels import EXIF_BUTTON_TIP

    button = window.align_panel.exif_button
    _load(window, os.path.join(ROOT, "samples", "exif_001_cz_fieldpath.jpg"), settle)
    assert button.toolTip().startswith("No compass heading in the photo's EXIF")
    window.align_panel.heading_box.setValue(200.0)
    assert button.isEnabled() and button.toolTip() == EXIF_BUTTON_TIP
    window.align_panel.heading_box.setValue(-1.0)  # "unknown" again
    assert button.toolTip().startswith("No compass heading in the photo's EXIF")
    _load(window, os.path.join(ROOT, "samples", "exif_003_th_pool.jpg"), settle)
    assert button.isEnabled() and button.toolTip() == EXIF_BUTTON_TIP


def _slow_search(monkeypatch) -> list[bool]:
    """A search that takes 0.4 s and finds (200, 30); the list it appends to as each starts."""
    started: list[bool] = []

    def slow(session, **kw):
        started.append(True)
        time.sleep(0.4)  # finishes even when cancelled: its progress is never asked
        return _fit(200.0, 30.0)

    monkeypatch.setattr(auto_sun, "find_sun", slow)
    return started


def test_confirming_while_the_search_runs_keeps_the_confirmed_sun(qtbot, window, photo, settle,
                                                                 monkeypatch):
    """A user trial confirmed while Find sun ran: step 2 opened with the dial's sun, then the
    search's sun moved step 1's dial and a "Find sun" step was recorded after the confirm.
    Confirming cancels the search; a result that arrives anyway is not applied."""
    _load(window, photo, settle)
    started = _slow_search(monkeypatch)
    panel = window.align_panel.sun_panel
    confirmed = panel.sun()
    window.toggle_find_sun()
    qtbot.waitUntil(lambda: bool(started), timeout=5000)
    window.act_confirm.trigger()
    settle()
    assert window.step is Step.RELIGHT
    assert window.original_sun.as_tuple() == pytest.approx(confirmed)
    assert panel.sun() == pytest.approx(confirmed)  # step 1's dial too
    assert window.undo_stack.undoText() == "Confirm original sun"
    assert "Sun found" not in window.stage_label.text()
    assert not panel.dial.has_heat_map()


def test_a_search_that_lands_where_the_sun_stands_records_nothing(window, photo, settle,
                                                                 monkeypatch):
    """The EXIF sun came back from the search 1e-14 degrees off the dial's and was recorded as
    a "Find sun" move: the photo was marked unsaved for nothing (a user trial)."""
    _load(window, photo, settle)
    panel = window.align_panel.sun_panel
    az, el = panel.sun()
    count = window.undo_stack.count()
    fit = dataclasses.replace(_fit(az, el + 1e-12), source=auto_sun.SOURCE_EXIF)
    monkeypatch.setattr(auto_sun, "find_sun", lambda session, **kw: fit)
    window.find_sun()
    settle()
    assert window.undo_stack.count() == count and not window.has_unsaved_changes()


def test_the_search_notice_goes_when_the_sun_leaves_the_found_one(window, photo, settle,
                                                                 monkeypatch):
    """A notice about the found sun (here: the compass chose it) stayed above the photo after
    Undo of Find sun and after the sun was moved by hand (a user trial)."""
    _load(window, photo, settle)
    notice = window.align_panel.notice
    loaded = notice.text()
    fit = dataclasses.replace(_fit(0.0, 8.0), compass_decided=True)
    monkeypatch.setattr(auto_sun, "find_sun", lambda session, **kw: fit)
    window.find_sun()
    settle()
    assert "Sun placed by the compass heading" in notice.text()
    window.undo_stack.undo()
    settle()
    assert notice.text() == loaded
    window.undo_stack.redo()  # the found sun again: its notice is not said again (the status is)
    settle()
    window.find_sun()
    settle()
    assert "Sun placed by the compass heading" in notice.text()
    window.align_panel.sun_panel.set_sun(30.0, 40.0)  # moved on the dial,
    window.request_shadow(preview=False)  # its overlay asked for, as a drag's end does
    settle()
    assert notice.text() == loaded
    # Advice that holds anywhere on the dial stays while the user follows it.
    fit = dataclasses.replace(_fit(10.0, 60.0, found=False), unfound="no-fit")
    monkeypatch.setattr(auto_sun, "find_sun", lambda session, **kw: fit)
    window.find_sun()
    settle()
    said = notice.text()
    window.align_panel.sun_panel.set_sun(50.0, 40.0)
    window.request_shadow(preview=False)
    settle()
    assert notice.text() == said != loaded


def test_the_dial_says_what_the_heat_map_is(window, photo, settle, monkeypatch):
    _load(window, photo, settle)
    dial = window.align_panel.sun_panel.dial
    assert "Coloured cells" not in dial.toolTip()
    monkeypatch.setattr(auto_sun, "find_sun", lambda session, **kw: _fit(200.0, 30.0))
    window.find_sun()
    settle()
    assert "Coloured cells" in dial.toolTip()
    dial.set_heat_map(None)
    assert "Coloured cells" not in dial.toolTip()


def test_a_cancelled_search_s_late_result_is_not_applied(qtbot, window, photo, settle,
                                                         monkeypatch):
    """Cancel (the button again) while the search finishes: its result, already on its way,
    does not move the sun nor record a step, and the button reads "Find sun" at once (a
    review: only a confirm had stopped a late result)."""
    _load(window, photo, settle)
    started = []

    def slow(session, **kw):
        started.append(True)
        time.sleep(0.4)  # never asks its progress: cancelling cannot stop it
        return _fit(200.0, 30.0)

    monkeypatch.setattr(auto_sun, "find_sun", slow)
    panel = window.align_panel.sun_panel
    before, count = panel.sun(), window.undo_stack.count()
    window.toggle_find_sun()
    qtbot.waitUntil(lambda: bool(started), timeout=5000)
    window.toggle_find_sun()  # cancel
    assert window.align_panel.find_button.text() == "Find sun from shadows"
    settle()
    assert panel.sun() == pytest.approx(before) and window.undo_stack.count() == count
    assert not panel.dial.has_heat_map()


def test_the_ring_notice_stays_while_the_sun_is_turned_round_the_ring(window, settle,
                                                                      monkeypatch):
    """With GPS and time, "no sun fits" sets the EXIF elevation and says to turn the sun
    around the ring: turning it keeps the notice; leaving the ring (an undo) takes it down."""
    _load(window, os.path.join(ROOT, "samples", "exif_001_cz_fieldpath.jpg"), settle)
    notice = window.align_panel.notice
    loaded = notice.text()
    fit = dataclasses.replace(_fit(10.0, 60.0, found=False), unfound="no-fit")
    monkeypatch.setattr(auto_sun, "find_sun", lambda session, **kw: fit)
    panel = window.align_panel.sun_panel
    panel.set_sun(200.0, 70.0)  # off the ring, so the search moves it
    window._record()
    window.find_sun()
    settle()
    assert "around the ring" in notice.text()
    az, el = panel.sun()
    # Turned round it by hand: 40 degrees round the ring (on the dial, the ring's elevation
    # changes with the azimuth by the camera's tilt: 3 degrees here, read from the ground
    # plane), half a degree off it.
    ring = window._above_horizon(az, el)
    az2, el2 = auto_sun.at_true_elevation((az + 40.0) % 360.0, el, ring, window.camera_tilt[:2])
    assert abs(window._above_horizon(az2, el2) - ring) < 0.01
    panel.set_sun(az2, el2 + 0.5)
    window.request_shadow(preview=False)
    settle()
    assert "around the ring" in notice.text()
    panel.set_sun(az, 70.0)
    window.request_shadow(preview=False)
    settle()
    assert notice.text() == loaded


def test_find_sun_waits_out_a_confirm_on_its_way(window, photo, settle, monkeypatch):
    """Ctrl+F right after Ctrl+Return (the confirm's job not done, step 1 still showing)
    starts no search: its result would be thrown away in step 2 (a review)."""
    _load(window, photo, settle)
    calls = []
    monkeypatch.setattr(auto_sun, "find_sun",
                        lambda session, **kw: calls.append(1) or _fit(200.0, 30.0))
    window.act_confirm.trigger()
    assert window.find_sun() is None
    settle()
    assert window.step is Step.RELIGHT and calls == []


def test_moving_the_sun_while_the_search_runs_cancels_it(qtbot, window, photo, settle,
                                                         monkeypatch):
    """A user trial dragged step 1's sun while Find sun ran: when the search ended, the dial
    jumped to the found sun. Moving the sun by hand (a drag, its keys, the number fields)
    cancels the search, as Confirm does; the sun set by hand stands and nothing is recorded
    after it."""
    _load(window, photo, settle)
    started = _slow_search(monkeypatch)
    panel = window.align_panel.sun_panel
    window.toggle_find_sun()
    qtbot.waitUntil(lambda: bool(started), timeout=5000)
    assert window.finding_sun()
    panel.azimuth_box.setValue(60.0)  # typed: emits as a drag's end does
    assert window.align_panel.find_button.text() == "Find sun from shadows"  # at once
    qtbot.waitUntil(lambda: not window.finding_sun(), timeout=5000)
    settle()
    assert panel.sun()[0] == pytest.approx(60.0)
    assert "Sun found" not in window.stage_label.text()
    assert not panel.dial.has_heat_map()
    assert window.undo_stack.undoText() != "Find sun"


def test_a_sun_moved_otherwise_while_the_search_runs_stands(qtbot, window, photo, settle,
                                                           monkeypatch):
    """Moved while Find sun ran by a way that emits nothing (undo, "Sun from EXIF"), the dial
    jumped to the found sun when the search ended (a review): the moved sun stands and the
    status says why nothing was applied. Cancel (Find sun again) with a number still being
    typed cancels, and does not start a new search."""
    _load(window, photo, settle)
    started = _slow_search(monkeypatch)
    panel = window.align_panel.sun_panel
    window.toggle_find_sun()
    qtbot.waitUntil(lambda: bool(started), timeout=5000)
    panel.set_sun(70.0, 20.0)  # as undo moves it
    qtbot.waitUntil(lambda: not window.finding_sun(), timeout=5000)
    settle()
    assert panel.sun() == pytest.approx((70.0, 20.0))
    assert "not applied, the sun was moved" in window.stage_label.text()
    assert not panel.dial.has_heat_map()
    # Cancel with a number half typed in the azimuth field, the search still waiting for the
    # worker (taken in first, the number cancelled it, and the button started a new one).
    window.runner.submit("busy", lambda ctx: time.sleep(0.5), "busy")
    window.toggle_find_sun()
    assert window.finding_sun()
    panel.azimuth_box.lineEdit().setText("75.0°")
    window.toggle_find_sun()  # cancel
    qtbot.wait(700)
    settle()
    assert len(started) == 1 and not window.finding_sun()
    assert window.align_panel.find_button.text() == "Find sun from shadows"


def test_an_exif_sun_the_shadows_do_not_tell_is_said_above_the_photo(window, photo, settle,
                                                                     monkeypatch):
    """Where the shadows tell nothing and the EXIF's sun is placed, the advice to check it
    was only in the status bar, cut short (a user trial on the field path): it stands in the
    notice above the photo too, and goes when the sun is moved off it."""
    _load(window, photo, settle)
    notice = window.align_panel.notice
    loaded = notice.text()
    fit = dataclasses.replace(_fit(100.0, 40.0, found=False), source=auto_sun.SOURCE_EXIF)
    monkeypatch.setattr(auto_sun, "find_sun", lambda session, **kw: fit)
    window.find_sun()
    settle()
    assert "the photo's shadows do not tell it" in notice.text()
    assert notice.isVisibleTo(window)
    window.align_panel.sun_panel.set_sun(30.0, 40.0)
    window.request_shadow(preview=False)
    settle()
    assert notice.text() == loaded
