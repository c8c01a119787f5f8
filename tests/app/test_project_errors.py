"""Malformed project files: one error dialog naming the bad field, never a traceback."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

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
