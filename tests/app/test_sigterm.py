"""Issue 20, defect 4: SIGTERM quits the app cleanly (status 143), like Ctrl+C does the CLI."""

from __future__ import annotations

from tests.app.conftest import make_photo
from tests.sigterm import terminate_when_ready

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
    env = {"QT_QPA_PLATFORM": "offscreen", "HOME": str(home)}
    ended = terminate_when_ready(["-c", _CHILD, photo, "--classic"], "opened", env=env,
                                 settle=0.5)
    assert ended.seconds < 15
    assert ended.returncode == 143, ended.stderr
    assert "Traceback" not in ended.stderr
    assert sorted(p.name for p in photos.iterdir()) == ["scene.jpg"]


_CHILD_BAD = """
import sys
from app import main_window
from app.main import main
shown = main_window.MainWindow.show_error
def say_and_show(self, exc, action):
    print("error", flush=True)
    shown(self, exc, action)
main_window.MainWindow.show_error = say_and_show
sys.exit(main(sys.argv[1:]))
"""


def test_sigterm_quits_the_app_while_it_shows_a_bad_photos_error(tmp_path) -> None:
    """The path given on the command line is not a photo: the app shows its error in a modal
    dialog, and SIGTERM still ends the app (before, it ended the dialog and the app ran on
    with no window)."""
    home = tmp_path / "home"
    home.mkdir()
    bad = tmp_path / "notes.jpg"
    bad.write_text("not a photo")
    env = {"QT_QPA_PLATFORM": "offscreen", "HOME": str(home)}
    ended = terminate_when_ready(["-c", _CHILD_BAD, str(bad), "--classic"], "error", env=env,
                                 settle=0.5)
    assert ended.seconds < 15
    assert ended.returncode == 143, ended.stderr
    assert "Traceback" not in ended.stderr
