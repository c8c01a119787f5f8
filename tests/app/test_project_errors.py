"""Malformed project files: one error dialog naming the bad field, never a traceback."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from app.state import Step

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize(
    "timelapse, field",
    [({"date": 20240101}, "timelapse.date"), ({"start": 5}, "timelapse.start"),
     ({"frames": 10**12}, "timelapse.frames"), ({"latitude": "abc"}, "timelapse.latitude"),
     ({"full_resolution": "yes"}, "timelapse.full_resolution")],
)
def test_open_malformed_project_shows_one_dialog(window, errors, photo, tmp_path, timelapse,
                                                 field):
    project = tmp_path / "scene.outcast.json"
    project.write_text(json.dumps({"outcast_project": 1, "image": photo, "timelapse": timelapse}))
    window.open_path(str(project))
    assert len(errors) == 1 and field in errors[0][1]
    assert errors[0][0] == "Could not open the project"
    assert window.step is Step.EMPTY


@pytest.mark.parametrize("problem", ["missing", "not a map", "another aspect ratio"])
def test_a_projects_broken_depth_map_is_said_as_the_maps_problem(window, errors, photo,
                                                                 settle, tmp_path, problem):
    """A project whose depth map is gone, unreadable or for another photo: the dialog is about
    the depth map (what to do with it), not "Could not open the photo" with advice on photo
    formats; the work that was open stays."""
    import numpy as np

    depth = tmp_path / "scene_depth.npy"
    if problem == "not a map":
        depth.write_text("hello")
    elif problem == "another aspect ratio":
        np.save(depth, np.ones((10, 40), np.float32))
    project = tmp_path / "scene.outcast.json"
    project.write_text(json.dumps({"outcast_project": 1, "image": photo,
                                   "depth_path": str(depth)}))
    window.open_path(str(project))
    settle()
    assert len(errors) == 1
    title, text = errors[0]
    assert title == "Could not open the project's depth map", (title, text)
    assert "scene_depth.npy" in text or "aspect ratio" in text
    assert "Choose a JPEG" not in text
    assert window.step is Step.EMPTY


def test_gui_started_with_a_nested_project_does_not_abort(tmp_path):
    project = tmp_path / "deep.outcast.json"
    project.write_text('{"outcast_project": 1, "timelapse": ' + "[" * 50000 + "]" * 50000 + "}")
    code = (
        "import sys\n"
        "from PySide6.QtWidgets import QApplication, QMessageBox\n"
        "seen = []\n"
        "QMessageBox.critical = staticmethod(lambda *a, **k: seen.append(a[2]))\n"
        "app = QApplication([])\n"
        "from app.main_window import MainWindow\n"
        "w = MainWindow()\n"
        "w.open_path(sys.argv[1])\n"
        "print(len(seen), 'nested' in seen[0])\n"
        "w.runner.shutdown()\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code, str(project)], capture_output=True, text=True, cwd=REPO,
        env={"QT_QPA_PLATFORM": "offscreen", "PATH": "/usr/bin:/bin",
             "HOME": str(tmp_path), "PYTHONPATH": str(REPO)}, timeout=120,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.split() == ["1", "True"]
    assert "Traceback" not in result.stderr


_JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=10),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner,
                                                                max_size=3),
    max_leaves=10,
)
_TOP = ["image", "image_absolute", "photo", "preset", "depth_source", "depth_path", "original_sun",
        "target_sun", "overlay_opacity", "split", "buffer_view", "timelapse", "shadow_edits"]
_TL = ["kind", "sweep_from", "sweep_to", "way", "frames", "easing", "date", "latitude",
       "longitude", "heading", "start", "end", "utc_offset", "fps", "format", "full_resolution"]


@settings(max_examples=200, deadline=10_000)
@given(top=st.dictionaries(st.sampled_from(_TOP), _JSON, max_size=4),
       timelapse=st.dictionaries(st.sampled_from(_TL), _JSON, max_size=4))
def test_fuzzed_projects_load_or_raise_one_value_error(top, timelapse):
    from app.state import ProjectState

    data = {"outcast_project": 1, **top}
    if timelapse or "timelapse" not in data:
        data["timelapse"] = timelapse
    try:
        state = ProjectState.from_dict(data)
    except ValueError as exc:
        assert type(exc) is ValueError and "\n" not in str(exc)
        return
    state.timelapse.validate()  # what loads also opens in the time-lapse dialog
