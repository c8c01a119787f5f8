"""Dialog texts for exceptions (``app.errors``, Qt-free)."""

from __future__ import annotations

from app.errors import message_for


def test_os_errors_read_as_plain_words_and_never_name_a_temporary_file() -> None:
    temp = PermissionError(13, "Permission denied", "/photos/.day.qza7hje1.part.gif")
    msg = message_for(temp, "export")
    assert msg.title == "Export failed"
    assert msg.what == "Permission denied: cannot write in the folder '/photos'"
    assert "Errno" not in msg.text() and ".part" not in msg.text()
    assert "folder you can write to" in msg.todo
    frames = OSError(28, "No space left on device", "/photos/.day.part-x1/frame_0007.png")
    assert message_for(frames, "export").what == ("No space left on device: cannot write in "
                                                  "the folder '/photos'")
    plain = message_for(FileNotFoundError(2, "No such file or directory", "/x/p.jpg"), "open")
    assert plain.what == "No such file or directory: '/x/p.jpg'"
    assert message_for(ValueError("expected a photo\nmore"), "open").what == "expected a photo"


def test_a_frames_folder_with_other_files_never_offers_to_replace() -> None:
    """A PNG-sequence folder holding the user's files is refused even when confirmed: the
    message says so instead of offering to replace."""
    folder = message_for(IsADirectoryError("'/p/day' holds files other than frames"), "export")
    assert "new or empty folder" in folder.todo and "confirm" not in folder.todo
    exists = message_for(FileExistsError("'/p/a.mp4' already exists"), "export")
    assert "confirm replacing" in exists.todo
