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


def test_a_damaged_photo_and_a_wrong_export_name_get_advice_that_fits(tmp_path) -> None:
    """A truncated JPEG was told to "choose a JPEG, PNG ..."; an export named .xyz got a Python
    list and advice about free disk space (found by a user trial)."""
    import numpy as np
    from PIL import Image

    from outcast_core.runtime.io.imageio import read_image, write_image

    cut = tmp_path / "cut.jpg"
    Image.new("RGB", (64, 48), (90, 120, 30)).save(cut, "JPEG")
    cut.write_bytes(cut.read_bytes()[:300])
    try:
        read_image(cut)
    except ValueError as exc:
        damaged = message_for(exc, "open")
    assert "damaged or cut short" in damaged.todo and "Choose a JPEG" not in damaged.todo
    assert damaged.what.endswith("the file is truncated or corrupt")  # not the decoder's words
    assert "OSError" not in damaged.what and "cut.jpg" in damaged.what
    assert "Choose a JPEG" in message_for(ValueError("not an image file"), "open").todo
    try:
        write_image(tmp_path / "out.xyz", np.zeros((4, 4, 3), np.float32))
    except ValueError as exc:
        wrong = message_for(exc, "export")
    assert "[" not in wrong.what and ".jpg, .png, .tif, .tiff or .webp" in wrong.what
    assert "extensions above" in wrong.todo and "disk" not in wrong.todo


def test_an_export_over_the_open_photo_is_not_a_disk_problem() -> None:
    from app.errors import OwnFileError

    msg = message_for(OwnFileError("'pool.jpg' is the photo you opened; choose another name"),
                      "export")
    assert "never replaces the photo" in msg.todo and "disk" not in msg.todo
