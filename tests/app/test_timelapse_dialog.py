"""The time-lapse dialog's status line and what it asks of the worker."""

from __future__ import annotations

from app.state import Step
from outcast_core.runtime.pipeline import timelapse as tl


def _relight(window, photo, settle) -> None:
    window.open_path(photo)
    settle()
    window.confirm_original_sun()
    settle()
    assert window.step is Step.RELIGHT


def _timelapse(window, frames: int, fmt: str = "mp4"):
    dialog = window.open_timelapse()
    s = dialog.settings()
    s.kind, s.frames, s.format, s.size = "sweep", frames, fmt, "working"
    dialog.load_settings(s)
    return dialog


def test_a_refused_export_is_said_in_the_status_line(window, photo, settle, errors, tmp_path):
    """A user trial exported 24 frames, then again to the same name without confirming: the
    export was refused (an error dialog) but the status line still said "Saved 24 frames"."""
    _relight(window, photo, settle)
    dialog = _timelapse(window, 3)
    settle()
    out = tmp_path / "clip.mp4"
    dialog.export(str(out))
    settle()
    assert dialog.status.text().startswith("Saved 3 frames")
    assert dialog.export(str(out)) is None  # not confirmed: refused
    assert errors[-1][0] == "Export failed" and "already exists" in errors[-1][1]
    assert "Saved" not in dialog.status.text()
    assert "already exists" in dialog.status.text() and "Nothing was overwritten" in (
        dialog.status.text())
    assert dialog.export(photo, force=True) is None  # the photo itself, never
    assert "the photo you opened" in dialog.status.text()


def test_a_folder_that_cannot_be_written_is_named_not_the_temporary_file(
        window, photo, settle, errors, tmp_path, monkeypatch):
    """A user trial's export into a read-only folder said "Export failed: [Errno 1] Operation
    not permitted: '/…/.c.p20hmmbi.part.mp4'" under the dialog."""
    _relight(window, photo, settle)
    dialog = _timelapse(window, 3)
    settle()
    folder = tmp_path / "read-only"

    def refused(*args, **kwargs):
        raise PermissionError(1, "Operation not permitted", str(folder / ".c.p20hmmbi.part.mp4"))

    monkeypatch.setattr(tl, "render_timelapse", refused)
    dialog.export(str(folder / "c.mp4"))
    settle()
    assert dialog.last_result == "failed"
    text = dialog.status.text()
    assert text.startswith(f"Export failed: Operation not permitted: cannot write in the "
                           f"folder '{folder}'"), text
    assert ".part" not in text and "Errno" not in text
    assert "Choose a folder you can write to" in text
    assert errors and ".part" not in errors[-1][1]


def test_a_closed_dialog_draws_no_frame(window, photo, settle):
    """A user trial changed the quality with the time-lapse dialog closed: the status bar said
    "rendering time-lapse frame took …" (the closed dialog's path was recomputed for the new
    ground plane, and its frame drawn). Reopened, the frame is drawn."""
    _relight(window, photo, settle)
    dialog = _timelapse(window, 3)
    settle()
    assert dialog.preview.pixmap() is not None and not dialog.preview.pixmap().isNull()
    dialog.close()
    started = []
    window.runner.started.connect(lambda i, channel, d: started.append(channel))
    window.set_preset("balanced")
    settle()
    assert "preset" in started and "tl_preview" not in started
    assert "time-lapse" not in window.stage_label.text()
    window.open_timelapse()
    settle()
    assert started.count("tl_preview") == 1
