"""Fixtures for the GUI tests: offscreen Qt, small photos, a main window with private settings."""

from __future__ import annotations

import os

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from PIL import Image  # noqa: E402


def make_photo(path, width: int = 128, height: int = 96) -> str:
    """A small outdoor-ish JPEG: sky gradient on top, warm ground, a dark shadow band."""
    rng = np.random.default_rng(0)
    y = np.linspace(0.0, 1.0, height)[:, None, None]
    sky = np.concatenate([0.45 + 0.3 * y, 0.6 + 0.25 * y, 0.95 + 0 * y], axis=-1)
    ground = np.concatenate([0.65 + 0 * y, 0.55 + 0 * y, 0.45 + 0 * y], axis=-1)
    img = np.where(y < 0.45, sky, ground) * np.ones((1, width, 1))
    img[int(0.65 * height) : int(0.75 * height), width // 4 : width // 2] *= 0.45
    img += rng.normal(0, 0.01, img.shape)
    arr = (np.clip(img, 0, 1) * 255).astype(np.uint8)
    Image.fromarray(arr).save(path, quality=92)
    return str(path)


def undo_texts(window) -> list[str]:
    """The names of the window's undo steps, oldest first."""
    stack = window.undo_stack
    return [stack.text(i) for i in range(stack.count())]


def spy_relit_full(monkeypatch, session, read) -> list:
    """What ``read(session)`` gives each time ``session`` relights at full resolution (the
    view on release, the still export), in order."""
    seen: list = []
    real = session.relight_full

    def spy(w, **kw):
        seen.append(read(session))
        return real(w, **kw)

    monkeypatch.setattr(session, "relight_full", spy)
    return seen


def check_timelapse_export_takes(window, settle, tmp_path, monkeypatch, read, change,
                                 value) -> None:
    """A step-2 setting changed with the time-lapse dialog open (a 3-frame sweep): the
    export's time is measured again for it, its timing and its export run with ``value``
    (what ``read(session)`` gives as ``render_timelapse`` starts)."""
    from outcast_core.runtime.pipeline import timelapse as tl

    dialog = window.open_timelapse()
    s = dialog.settings()
    s.kind, s.frames, s.format, s.size = "sweep", 3, "png", "working"
    dialog.load_settings(s)
    settle()
    timed = dialog._estimate_key()
    real = tl.render_timelapse
    seen: list[tuple[object, int]] = []

    def spy(session, samples, *args, **kwargs):
        seen.append((read(session), len(samples)))
        return real(session, samples, *args, **kwargs)

    monkeypatch.setattr(tl, "render_timelapse", spy)
    change()
    settle()
    assert dialog._estimate_key() != timed  # timed again for the new setting
    assert seen and all(v == value for v, _ in seen)
    seen.clear()
    dialog.export(str(tmp_path / "frames"))
    settle()
    assert dialog.status.text().startswith("Saved 3 frames")
    assert seen == [(value, 3)]


@pytest.fixture
def photo(tmp_path):
    return make_photo(tmp_path / "scene.jpg")


@pytest.fixture
def reopen(qtbot, settings):
    """``with reopen(path) as other:`` a project opened in a second window (as after a
    restart), once it reached ``step`` (default step 1) and its worker is idle."""
    from contextlib import contextmanager

    from app.main_window import MainWindow
    from app.state import Step

    @contextmanager
    def opened(path, step=Step.ALIGN):
        other = MainWindow(settings=settings, preset="fast")
        qtbot.addWidget(other)
        try:
            other.open_path(path)
            qtbot.waitUntil(lambda: other.step is step and not other.runner.busy(),
                            timeout=30000)
            yield other
        finally:
            other.runner.shutdown()

    return opened


@pytest.fixture
def settings(tmp_path):
    from PySide6.QtCore import QSettings

    return QSettings(str(tmp_path / "settings.ini"), QSettings.Format.IniFormat)


@pytest.fixture
def errors(monkeypatch):
    """Record error and warning dialogs instead of showing them (a modal box would block the
    test): ``(title, text)`` of each, and in ``.kinds`` which box it was (``"critical"`` or
    ``"warning"``)."""
    from PySide6.QtWidgets import QMessageBox

    class Seen(list):
        kinds: list[str]

    seen = Seen()
    seen.kinds = []

    def box(kind):
        def fake(parent, title, text, *args, **kwargs):
            seen.append((title, text))
            seen.kinds.append(kind)
            return QMessageBox.StandardButton.Ok
        return staticmethod(fake)

    monkeypatch.setattr(QMessageBox, "critical", box("critical"))
    monkeypatch.setattr(QMessageBox, "warning", box("warning"))
    return seen


@pytest.fixture
def window(qtbot, settings, errors):
    from app.main_window import MainWindow

    w = MainWindow(settings=settings, preset="fast")
    qtbot.addWidget(w)
    w.resize(900, 600)
    w.show()
    yield w
    w.runner.shutdown()


@pytest.fixture
def settle(qtbot, window):
    """``settle()`` waits until the worker is idle and every result has reached the GUI."""
    from PySide6.QtWidgets import QApplication

    def _settle(timeout: int = 30000) -> None:
        def done() -> bool:
            if window.runner.busy():
                return False
            QApplication.processEvents()  # deliver queued results (they may submit more work)
            return not window.runner.busy()

        qtbot.waitUntil(done, timeout=timeout)

    return _settle


@pytest.fixture(autouse=True)
def leave_answers(monkeypatch):
    """Answer the quit / open-another prompts without a modal box (it would block the test).

    By default the answer goes ahead (stop the export, don't save); a test scripts other answers
    by appending to ``leave_answers.script`` and reads the questions in ``leave_answers.asked``.
    """
    from types import SimpleNamespace

    from app.leave_prompts import DISCARD, STOP
    from app.main_window import MainWindow

    record = SimpleNamespace(asked=[], script=[])

    def fake_ask(self, question):
        record.asked.append(question)
        if record.script:
            return record.script.pop(0)
        return STOP if any(c.key == STOP for c in question.choices) else DISCARD

    monkeypatch.setattr(MainWindow, "ask", fake_ask)
    return record
