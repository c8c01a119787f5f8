"""Issue 20, defect 4: SIGTERM quits the app cleanly (status 143), like Ctrl+C does the CLI."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from tests.app.conftest import make_photo

REPO = Path(__file__).resolve().parents[2]

_CHILD = """
import sys
from app import main_window
from app.main import main
opened = main_window.MainWindow.open_path
def open_and_say(self, path):
    opened(self, path)
    print("opened", flush=True)
main_window.MainWindow.open_path = open_and_say
sys.exit(main(sys.argv[1:]))
"""


def test_sigterm_quits_the_app_with_status_143(tmp_path) -> None:
    photos, home = tmp_path / "photos", tmp_path / "home"
    photos.mkdir()
    home.mkdir()
    photo = make_photo(photos / "scene.jpg")
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen", "HOME": str(home),
           "PYTHONPATH": str(REPO)}
    proc = subprocess.Popen([sys.executable, "-c", _CHILD, photo, "--classic"], cwd=REPO,
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "opened"
        time.sleep(0.5)
        t0 = time.perf_counter()
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert time.perf_counter() - t0 < 15
    assert proc.returncode == 143, err
    assert "Traceback" not in err
    assert sorted(p.name for p in photos.iterdir()) == ["scene.jpg"]
