"""The app's depth sources: the photo's own depth map, a remembered ONNX depth model."""

from __future__ import annotations

import numpy as np
import pytest

from app.state import Step
from tests.runtime.depth_fixtures import (
    encode_inverse_image,
    gdepth_jpeg,
    outdoor_scene,
    png_bytes,
    range_inverse,
    tiny_depth_model,
)

pytest.importorskip("onnx")


def _scene_photo(tmp_path, *, broken: bool = False):
    truth, _ = outdoor_scene(96, 128)
    image, _ = encode_inverse_image(truth)
    stored = np.where(np.isfinite(truth), np.minimum(truth, 200.0), 200.0)
    q = np.round(range_inverse(stored, 1.0, 200.0) * 65535).astype(np.uint16)
    return str(gdepth_jpeg(tmp_path / "phone.jpg", image, b"junk" if broken else png_bytes(q),
                           fmt="RangeInverse", near=1.0, far=200.0)), truth


def _model(tmp_path):
    return str(tiny_depth_model(tmp_path / "da.onnx", input_name="pixel_values",
                                output_name="predicted_depth", size=None, block=14, gain=7.0,
                                offset=0.3))


def test_phone_depth_is_used_and_shown(window, settle, errors, tmp_path):
    photo, truth = _scene_photo(tmp_path)
    window.open_path(photo)
    settle()
    assert window.step is Step.ALIGN and errors == []
    assert window.session.depth_source == "phone"
    assert "depth: phone" in window.mode_label.text()
    assert window.align_panel.notice.text() == ""  # no "rough depth" warning


def test_broken_phone_depth_is_said_and_falls_back(window, settle, errors, tmp_path):
    photo, _ = _scene_photo(tmp_path, broken=True)
    window.open_path(photo)
    settle()
    assert window.step is Step.ALIGN and errors == []
    assert window.session.depth_source != "phone"
    assert "The photo's own depth map is not used" in window.align_panel.notice.text()


def test_depth_model_is_used_remembered_and_forgotten(qtbot, window, photo, settle, settings,
                                                      errors, tmp_path):
    from app.main_window import MainWindow

    window.open_path(photo)
    settle()
    window.align_panel.sun_panel.set_sun(100.0, 35.0)
    model = _model(tmp_path)
    window.set_depth_model(model)
    settle()
    assert errors == []
    assert window.session.depth_source.startswith("model da.onnx (")
    assert "depth: model da.onnx" in window.mode_label.text()
    assert window.align_panel.sun_panel.sun() == pytest.approx((100.0, 35.0))  # sun kept
    assert settings.value("depth_model") == model
    other = MainWindow(settings=settings, preset="fast")
    qtbot.addWidget(other)
    try:
        assert other.depth_model == model and other.act_builtin_depth.isEnabled()
        other.open_path(photo)
        qtbot.waitUntil(lambda: other.step is Step.ALIGN and not other.runner.busy(),
                        timeout=30000)
        assert other.session.depth_source.startswith("model da.onnx")
    finally:
        other.runner.shutdown()
    window.set_depth_model("")
    settle()
    assert not window.session.depth_source.startswith("model da.onnx")
    assert settings.value("depth_model") == "" and not window.act_builtin_depth.isEnabled()


def test_a_bad_depth_model_is_refused_and_a_vanished_one_noted(window, photo, settle, errors,
                                                               tmp_path):
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"not a model")
    window.set_depth_model(str(bad))
    assert errors and errors[0][0] == "Could not use the depth model"
    assert window.depth_model == ""
    model = _model(tmp_path)
    window.set_depth_model(model)
    (tmp_path / "da.onnx").unlink()  # the remembered file is gone by the next photo
    window.open_path(photo)
    settle()
    assert window.step is Step.ALIGN and len(errors) == 1
    assert "The depth model is not used" in window.align_panel.notice.text()


def test_the_photos_own_depth_can_be_turned_off_and_it_is_remembered(qtbot, window, settle,
                                                                     settings, tmp_path):
    from app.main_window import MainWindow

    photo, _ = _scene_photo(tmp_path)
    window.open_path(photo)
    settle()
    assert window.session.depth_source == "phone"
    window.act_phone_depth.trigger()  # off
    settle()
    assert window.session.depth_source != "phone" and settings.value("phone_depth") == "false"
    other = MainWindow(settings=settings, preset="fast")
    qtbot.addWidget(other)
    try:
        assert not other.act_phone_depth.isChecked()
    finally:
        other.runner.shutdown()
    window.set_use_phone_depth(True)
    settle()
    assert window.session.depth_source == "phone" and window.act_phone_depth.isChecked()
